"""The walls of the free-surface scenes (parsph.sph.walls) against independent forms: the mirror's theta
against the closure's pressure, Eq. (3) renormalised against a brute-force sum over every pair, the reflection
against its definition, and a loose layer dropped without gas, which must come to rest on the floor."""
import math

import numpy as np
import pytest
from mpi4py import MPI

from parsph.physics.closures import modulus
from parsph.physics.kernels import kernel_w_f
from parsph.simulation.solver import Simulation
from parsph.sph import walls
from parsph.sph.particles import GRAIN
from parsph.sph.pass_data import OFF, ON
from parsph.studies import layers

G_A, G_B, RHO_S = 8.76, -2.0, 2000.0


def pressure(theta, consistent):
    """p(theta) of each pressure form, from the closure's G (docs/physics.md, Eq. (5))."""
    G = modulus(theta, G_A, G_B)
    return G / (G_A * math.log(10.0)) if consistent else G * theta


@pytest.mark.parametrize("consistent", [True, False])
@pytest.mark.parametrize("theta", [0.05, 0.2, 0.45, 0.6])
@pytest.mark.parametrize("rise", [0.0, 1e-4, 1e-2, 3.0])
def test_mirror_theta_has_the_extrapolated_pressure(consistent, theta, rise):
    """p(theta_w) = p(theta_i) + rho_s theta_i rise for both pressure forms, over five decades of p_w / p_i."""
    th_w = walls.mirror_theta(theta, rise, G_A, G_B, RHO_S, ON if consistent else OFF, OFF, 0.0, 0.0)
    want = pressure(theta, consistent) + RHO_S * theta * rise
    assert th_w >= theta
    assert pressure(th_w, consistent) == pytest.approx(want, rel=1e-9)


def test_reflect_puts_grains_on_the_plates():
    pos = np.array([[-1e-5, 0.0], [0.5, 0.0], [1.2, 0.1], [-0.3, 0.0]])
    vel = np.array([[-1.0, 0.5], [-1.0, 0.0], [2.0, 1.0], [-1.0, 0.0]])
    kind = np.array([GRAIN, GRAIN, GRAIN, 1])
    assert walls.reflect(pos, vel, kind, 4, 1.0, 0.0, 1.0) == 2
    np.testing.assert_array_equal(pos, [[0.0, 0.0], [0.5, 0.0], [1.0, 0.1], [-0.3, 0.0]])
    np.testing.assert_array_equal(vel, [[0.0, 0.5], [-1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])


def test_reflect_puts_grains_on_the_side_walls_in_their_own_frame():
    """Side walls at y = 0 and y = 1 with rows beyond y = 1 up to the period 1.25: a grain in those rows goes
    to the nearer wall (y = 1, or y = 0 as the period's multiple it is nearest, positions wrapping at rebuilds
    only), its normal velocity removed; a grain between the walls, or a wall particle, stays."""
    pos = np.array([[0.5, 1.05], [0.5, 1.2], [0.5, -0.01], [0.5, 2.26], [0.5, 0.7], [0.5, 1.1]])
    vel = np.array([[0.0, 1.0], [0.0, -1.0], [0.0, -2.0], [0.0, 3.0], [0.0, 1.0], [0.0, 1.0]])
    kind = np.array([GRAIN, GRAIN, GRAIN, GRAIN, GRAIN, 1])
    assert walls.reflect(pos, vel, kind, 6, 1.0, 1.0, 1.25) == 4
    np.testing.assert_allclose(pos[:, 1], [1.0, 1.25, 0.0, 2.25, 0.7, 1.1], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(vel[:, 1], [0.0, 0.0, 0.0, 0.0, 1.0, 1.0])


def test_density_next_to_the_floor_is_the_fluid_sum_renormalised():
    """Eq. (3) with mirrored walls: theta_i = sum over fluid j of m_j W_ij / (rho_s (1 - V_w sum over walls of
    W_iw)), summed here over every pair of the rank's particles (owned and periodic images) with numpy, after
    the particles were displaced at random so that no lattice symmetry helps."""
    cfg = layers.load(layers.SEDIMENTATION, ["scene.height=0.004", "domain.L=0.006", "numerics.Nx=30",
                                             "domain.Ly=0.0012"], layers.NO_GAS + ("gas.drag",))
    sim = Simulation(cfg, MPI.COMM_SELF)
    ps = sim.ps
    rng = np.random.default_rng(3)
    fluid = ps.kind[:ps.n_own] == GRAIN
    ps.pos[:ps.n_own][fluid] += rng.uniform(-0.2, 0.2, (fluid.sum(), 2)) * cfg.dx
    ps.pos[:ps.n_own][fluid, 0] = np.maximum(ps.pos[:ps.n_own][fluid, 0], 0.05 * cfg.dx)
    sim.compute_rates()
    n, n_own = ps.n, ps.n_own
    pos, kind, mass = ps.pos[:n], ps.kind[:n], ps.mass[:n]
    kern = sim.kernel
    norm, inv_h = kern.norm(cfg.h, cfg.dim), 1.0 / cfg.h
    V_w = cfg.mass / (cfg.rho_s * cfg.theta0)
    checked = 0
    for i in np.flatnonzero(kind[:n_own] == GRAIN):  # (the build reordered the particles)
        r = np.linalg.norm(pos - pos[i], axis=1)
        W = np.array([kernel_w_f(kern.kid, x, inv_h, norm)[0] for x in r])
        S = np.sum(np.where(kind == GRAIN, mass * W, 0.0))
        phi = V_w * np.sum(np.where(kind != GRAIN, W, 0.0))
        assert ps.theta[i] == pytest.approx(S / (cfg.rho_s * (1.0 - phi)), rel=1e-12)
        checked += phi > 0.1
    assert checked >= 6  # the first row's particles saw the floor


def test_a_loose_layer_dropped_without_gas_comes_to_rest():
    """theta0 = 0.2 (G = 0.57 Pa: a dust that falls freely) on the floor without gas: the walls' pressure
    stops every grain (walls.reflect, the backstop, never acts), and the layer comes to rest at the
    hydrostatic sediment (its top, the theta0/2 level, within 2h of the end state's at the last two times;
    the mass-weighted rms speed below 2% of the impact speed sqrt(2 g H0) by then)."""
    r = layers.free_surface(theta0=0.2, H0=0.005, t_end=0.6, n_times=6,
                            extra=['numerics.integrator="midpoint"',
                                   "domain.L=0.008", "numerics.Nx=40", "material.k=1.0"])
    h = r["h"]
    assert min(r["low"]) > 0.0
    assert all(abs(t - r["top_ref"]) < 2 * h for t in r["top"][-2:]), (r["top"], r["top_ref"])
    impact = math.sqrt(2 * 9.81 * r["H0"])
    assert max(r["rms_speed"][-2:]) < 0.02 * impact, (r["rms_speed"], impact)
    assert r["reflected"] == 0  # the walls' pressure stopped every grain: the backstop never acted
