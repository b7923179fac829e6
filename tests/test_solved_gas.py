"""The solved gas (docs/physics.md, "The solved gas"; docs/validation.md, "The solved gas"):

- reference 6, Darcy flow past a circular inclusion: the closed form checked as a solution (Laplace's
  equation, p' and the normal flux continuous at r = a, the far field), then the grid solve against it: the
  flux through the inclusion within 2% of 2 kappa U / (1 + kappa) for kappa = 1e3 and 0.1 with a on 16 cells,
  first order over three grids;
- the solve's finite volumes against independent forms: layers in series (p' at the floor = U times the sum
  of the resistances), no divergence on a random field, the banded Cholesky (or, past BAND_MAX, SuperLU
  ordered by minimum degree) against SuperLU in its default order;
- the deposit: the particles' volume conserved, the same bits in any particle order, the interpolation the
  deposit's transpose (the same weights both ways), a linear field interpolated exactly;
- K = eps^2 / beta against Stokes's closed form d^2 eps^4.65 / (18 mu theta), and its cap;
- reference 7, the dispersion relation of voidage waves against its long-wave (Wallis) limit and closed forms;
- the new run-file keys' one-line errors, the cadence of the solve.
The runs against references 5 and 7 are tests/test_solved_gas_runs.py.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from parsph.errors import ConfigError
from parsph.gas import darcy, deposit
from parsph.gas import permeability
from parsph.physics import inclusion
from parsph.physics import drag
from parsph.physics.drag import STOKES
from parsph.setup import config
from parsph.simulation.solver import Simulation
from parsph.sph.particles import GRAIN
from parsph.studies import layers


# ---- reference 6 --------------------------------------------------------------------------------------
@pytest.mark.parametrize("kappa", [1e3, 0.1, 1.0])
def test_inclusion_closed_form_solves_darcy(kappa):
    a, K, U = 0.3, 2.0, 0.7
    p = lambda x, y: inclusion.pressure(x, y, a, kappa, K, U)
    rng = np.random.default_rng(3)
    h = 1e-4
    for r in (0.5 * a, 1.7 * a, 4.0 * a):  # Laplace's equation inside and outside (5-point stencil)
        phi = rng.uniform(0, 2 * math.pi, 8)
        x, y = r * np.cos(phi), r * np.sin(phi)
        lap = (p(x + h, y) + p(x - h, y) + p(x, y + h) + p(x, y - h) - 4 * p(x, y)) / h ** 2
        assert np.all(np.abs(lap) < 1e-4 * U / K / a)
    phi = np.linspace(0.1, 3.0, 7)
    e = 1e-7
    inner, outer = p((a - e) * np.cos(phi), (a - e) * np.sin(phi)), p((a + e) * np.cos(phi), (a + e) * np.sin(phi))
    assert np.allclose(inner, outer, atol=1e-6 * U / K * a)
    # the normal flux -K_local dp'/dr on both sides of r = a
    d = 1e-5

    def radial(r, Kl):
        return -Kl * (p((r + d) * np.cos(phi), (r + d) * np.sin(phi)) - p((r - d) * np.cos(phi), (r - d) * np.sin(phi))) / (2 * d)
    assert np.allclose(radial(a - 3 * d, kappa * K), radial(a + 3 * d, K), rtol=1e-3, atol=1e-9)
    # inside: the uniform flux; far away: U
    assert radial(0.5 * a, kappa * K)[0] == pytest.approx(inclusion.inside_flux(kappa, U) * math.cos(phi[0]), rel=1e-6)
    far = -K * (p(1e3 * a + d, 0.0) - p(1e3 * a - d, 0.0)) / (2 * d)
    assert far == pytest.approx(U, rel=1e-5)


def inclusion_flux_error(cells_per_radius, kappa, box=4.0):
    """The grid's flux through the inclusion (the face row on its diameter across the flow) against
    2 kappa U / (1 + kappa): a box of 2 box a per side, K by the cell centre's side of the circle, the exact
    p' on the box's sides (the box's effect removed)."""
    a, U = 1.0, 1.0
    h = a / cells_per_radius
    n = int(round(2 * box * a / h))
    B = n * h / 2
    xc = -B + (np.arange(n) + 0.5) * h
    X, Y = np.meshgrid(xc, xc, indexing="ij")
    K = np.where(X ** 2 + Y ** 2 < a * a, kappa, 1.0)
    exact = lambda x, y: inclusion.pressure(x, y, a, kappa, 1.0, U)
    sol = darcy.solve(K, np.zeros((n, n, 2)), h, h,
                      (darcy.Side("pressure", exact(-B, xc)), darcy.Side("pressure", exact(B, xc))),
                      (darcy.Side("pressure", exact(xc, -B)), darcy.Side("pressure", exact(xc, B))))
    lo, hi = np.clip(xc - h / 2, -a, a), np.clip(xc + h / 2, -a, a)
    Q = np.sum(sol.jx[n // 2] * (hi - lo))
    return Q / (2 * a) / inclusion.inside_flux(kappa, U) - 1.0


@pytest.mark.parametrize("kappa", [1e3, 0.1])
def test_grid_solve_against_the_inclusion(kappa):
    assert abs(inclusion_flux_error(16, kappa)) < 0.02


def test_inclusion_flux_converges_at_first_order():
    errs = [abs(inclusion_flux_error(n, 1e3)) for n in (8, 16, 32)]
    orders = [math.log2(errs[i] / errs[i + 1]) for i in range(2)]
    assert all(0.7 < q < 1.6 for q in orders), (errs, orders)


# ---- the finite volumes --------------------------------------------------------------------------------
def test_layers_in_series():
    """K varying along x alone, the floor fed at U, p' = 0 at the top: the flux is U through every face and p'
    at a cell is U times the resistances above it: half its own cell, then each face's h / K_f, then the
    top half-cell h / (2 K)."""
    rng = np.random.default_rng(5)
    nx, ny, hx, hy, U = 9, 4, 0.3, 0.2, 0.05
    Kx = rng.uniform(0.1, 3.0, nx)
    K = np.repeat(Kx[:, None], ny, axis=1)
    sol = darcy.solve(K, np.zeros((nx, ny, 2)), hx, hy,
                      (darcy.Side("flux", U), darcy.Side("pressure", 0.0)), None)
    assert np.allclose(sol.jx, U, rtol=1e-12)
    assert np.allclose(sol.jy, 0.0, atol=1e-14)
    Kf = 2 * Kx[:-1] * Kx[1:] / (Kx[:-1] + Kx[1:])
    above = np.array([sum(hx / Kf[i:]) + hx / (2 * Kx[-1]) for i in range(nx)])
    assert np.allclose(sol.p[:, 0], U * above, rtol=1e-12)


def test_moving_layers_in_series_carry_the_pressure_drop_of_their_drag():
    """K and the solids' V varying along x alone (grains moving through the gas, as in a bubbling bed), the
    floor fed at U, p' = 0 at the top: j = U through every face, and p' at a cell is the integral of
    (U - V) / K over the half cells above it (its own upper half, then each whole cell, each with its own K
    and V: the pressure drop that Darcy's law gives through layers in series). The floor's p' is then
    sum_c h (U - V_c) / K_c, the drag of every cell: what a bed's pressure drop must equal. (With V_f the
    plain mean of the two cells, the floor's p' is off by 53% of the drop here.)"""
    rng = np.random.default_rng(7)
    nx, ny, hx, hy, U = 9, 4, 0.3, 0.2, 0.05
    Kx = rng.uniform(0.1, 3.0, nx)
    Vx = rng.uniform(-0.2, 0.2, nx)
    Vx[-1] = 0.0  # clear gas under the open top (no solids cross a side: its face has V_f = 0)
    K = np.repeat(Kx[:, None], ny, axis=1)
    V = np.zeros((nx, ny, 2))
    V[:, :, 0] = Vx[:, None]
    sol = darcy.solve(K, V, hx, hy, (darcy.Side("flux", U), darcy.Side("pressure", 0.0)), None)
    assert np.allclose(sol.jx, U, rtol=1e-12)
    drop = hx * (U - Vx) / Kx   # each whole cell's
    above = np.array([0.5 * drop[i] + drop[i + 1:].sum() for i in range(nx)])
    assert np.allclose(sol.p[:, 0], above, rtol=1e-11, atol=1e-13 * np.abs(drop).sum())
    floor = sol.p[0, 0] + 0.5 * drop[0]
    assert floor == pytest.approx(drop.sum(), rel=1e-11)


# the band along y first; along x with the y ring folded; a band too wide (168 > BAND_MAX): SuperLU, minimum degree
@pytest.mark.parametrize("nx, ny", [(12, 7), (5, 30), (84, 168)])
def test_random_fields_have_no_divergence_and_two_solvers_agree(nx, ny):
    rng = np.random.default_rng(11)
    hx, hy = 0.1, 0.15
    K = rng.uniform(0.01, 10.0, (nx, ny))
    V = rng.normal(size=(nx, ny, 2))
    sides = (darcy.Side("flux", rng.uniform(0, 1, ny)), darcy.Side("pressure", 0.0))
    sol = darcy.solve(K, V, hx, hy, sides, None)  # banded Cholesky, or SuperLU ordered by minimum degree
    d = darcy.Darcy(nx, ny, hx, hy, sides, None)
    assert d.width == min(ny, 2 * nx) and d.banded == (d.width <= darcy.BAND_MAX) and d.ordered == (not d.banded)
    div = (sol.jx[1:] - sol.jx[:-1]) / hx + (sol.jy[:, 1:] - sol.jy[:, :-1]) / hy
    assert np.abs(div).max() < 1e-11 * np.abs(V).max() / hx
    lu = darcy.Darcy(nx, ny, hx, hy, sides, None)
    lu.banded = lu.ordered = False  # the same matrix through SuperLU, its default column order
    other = lu.solve(K, V)
    assert np.allclose(sol.p, other.p, rtol=1e-10, atol=1e-12 * np.abs(sol.p).max())


def test_every_side_fed_pins_the_constant():
    """Fed at U through the floor and out through a top fed at U too: p' is defined up to a constant, the
    first cell holds 0, and the flux is U everywhere."""
    K = np.ones((5, 4))
    sol = darcy.solve(K, np.zeros((5, 4, 2)), 1.0, 1.0, (darcy.Side("flux", 2.0), darcy.Side("flux", 2.0)), None)
    assert sol.p[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert np.allclose(sol.jx, 2.0)


# ---- the deposit and the interpolation -----------------------------------------------------------------
def _particles(n, Lx, Ly, seed=2):
    rng = np.random.default_rng(seed)
    pos = np.column_stack([rng.uniform(-0.05 * Lx, 1.05 * Lx, n), rng.uniform(-0.3 * Ly, 1.3 * Ly, n)])
    vel = rng.normal(size=(n, 2))
    mass = rng.uniform(0.5, 1.5, n) * 1e-3
    kind = np.where(rng.random(n) < 0.9, GRAIN, 1).astype(np.int64)
    return pos, vel, mass, kind


def _places(pos, kind, nx, ny, Lx, Ly, sides, ring):
    """The particles' cells and weights on the 2-D grid (deposit.weights)."""
    cells, w = np.zeros((len(pos), 4), np.int32), np.zeros((len(pos), 4))
    deposit.weights(pos, kind, len(pos), nx, ny, 1, Lx / nx, Ly / ny, 1.0, Lx, Ly, 0.0, True, sides, ring or Ly,
                    cells, w)
    return cells, w


def _deposit(pos, vel, mass, kind, nx, ny, Lx, Ly, rho_s=2000.0, sides=False, ring=None):
    out = np.zeros((nx, ny, 4), np.int64)
    rates = np.abs(vel[:, 0]) * 100.0  # any drag rates [1/s]
    cells, w = _places(pos, kind, nx, ny, Lx, Ly, sides, ring)
    deposit.deposit(cells, w, vel, mass, len(mass), rho_s, Lx / nx, Ly / ny, 1.0, out[:, :, None], rates,
                    np.zeros(len(mass)), 30.0)
    return out


def _interpolate(pos, kind, field, nx, ny, Lx, Ly, sides=False, ring=None):
    """The 2-D field (nx, ny, c) at the particles."""
    at = np.zeros((len(pos), field.shape[-1]))
    cells, w = _places(pos, kind, nx, ny, Lx, Ly, sides, ring)
    deposit.interpolate(cells, w, len(pos), field[:, :, None, :], at)
    return at


def test_side_walls_fold_the_deposit_so_a_uniform_state_stays_uniform():
    """Grains on a lattice filling the box between plates and side walls (4 x 4 to a cell, theta0 each) deposit
    theta0 in every cell, the cells along the walls included (their weight beyond a wall folds back); the
    same bits where grains are shown in another frame of the period (y + ring, y - ring: positions wrap at
    rebuilds only); the transpose (interpolation) of a uniform field is that field at every grain."""
    nx, ny, Lx, Ly, rho_s, theta0 = 5, 4, 0.5, 0.4, 2000.0, 0.3
    ring = 1.25 * Ly
    d = Lx / nx / 4
    X, Y = np.meshgrid((np.arange(4 * nx) + 0.5) * d, (np.arange(4 * ny) + 0.5) * d, indexing="ij")
    pos = np.column_stack([X.ravel(), Y.ravel()])
    n = len(pos)
    mass = np.full(n, rho_s * theta0 * d * d)
    kind, vel = np.zeros(n, np.int64), np.zeros((n, 2))
    sums = _deposit(pos, vel, mass, kind, nx, ny, Lx, Ly, rho_s, sides=True, ring=ring)
    np.testing.assert_allclose(sums[..., 0] / deposit.SCALE, theta0, rtol=0, atol=1e-9)
    shifted = pos.copy()
    shifted[::3, 1] += ring
    shifted[1::3, 1] -= ring
    assert np.array_equal(_deposit(shifted, vel, mass, kind, nx, ny, Lx, Ly, rho_s, sides=True, ring=ring), sums)
    at = _interpolate(shifted, kind, np.full((nx, ny, 1), 2.5), nx, ny, Lx, Ly, True, ring)
    np.testing.assert_allclose(at[:, 0], 2.5, rtol=1e-14)


def test_deposit_conserves_volume_and_drag_in_any_order():
    nx, ny, Lx, Ly, rho_s = 7, 5, 0.7, 0.4, 2000.0
    pos, vel, mass, kind = _particles(400, Lx, Ly)
    sums = _deposit(pos, vel, mass, kind, nx, ny, Lx, Ly)
    fluid = kind == GRAIN
    area = Lx / nx * Ly / ny
    rounding = 4 * fluid.sum() * 0.5 / deposit.SCALE * area  # each of the 4 terms a particle adds rounds once
    assert abs(sums[..., 0].sum() / deposit.SCALE * area - (mass[fluid] / rho_s).sum()) <= rounding
    # the resistance: sum of m C over the particles (C = 100 |v_x| here), and of m C v (the drag's velocity)
    C = 100.0 * np.abs(vel[fluid, 0])
    _, R, V_R = deposit.cells_of(sums, rho_s, 30.0)
    r_rounding = 4 * fluid.sum() * 0.5 / deposit.RATE_SCALE * rho_s * 30.0 * area
    assert abs(R.sum() * area - (mass[fluid] * C).sum()) <= r_rounding
    for c in (0, 1):
        assert abs((R * V_R[..., c]).sum() * area - (mass[fluid] * C * vel[fluid, c]).sum()) <= r_rounding * 10
    perm = np.random.default_rng(9).permutation(len(mass))
    again = _deposit(pos[perm], vel[perm], mass[perm], kind[perm], nx, ny, Lx, Ly)
    assert np.array_equal(sums, again)  # integers: the same bits in any order
    half = len(mass) // 2  # two "ranks" summed
    parts = _deposit(pos[:half], vel[:half], mass[:half], kind[:half], nx, ny, Lx, Ly) + \
        _deposit(pos[half:], vel[half:], mass[half:], kind[half:], nx, ny, Lx, Ly)
    assert np.array_equal(sums, parts)


def test_interpolation_is_the_deposits_transpose():
    """sum_i vol_i f(x_i) = sum_c f_c theta_c A: the grid's force on the particles is the reaction of what
    they put on it (the wall folding and the periodic wrap included)."""
    nx, ny, Lx, Ly, rho_s = 6, 5, 0.6, 0.5, 2000.0
    pos, vel, mass, kind = _particles(300, Lx, Ly, seed=4)
    f = np.random.default_rng(1).normal(size=(nx, ny, 1))
    at = _interpolate(pos, kind, f, nx, ny, Lx, Ly)
    theta = _deposit(pos, vel, mass, kind, nx, ny, Lx, Ly)[..., 0] / deposit.SCALE
    fluid = kind == GRAIN
    lhs = (mass[fluid] / rho_s * at[fluid, 0]).sum()
    rhs = (f[:, :, 0] * theta).sum() * (Lx / nx) * (Ly / ny)
    assert lhs == pytest.approx(rhs, rel=1e-10)
    assert np.all(at[~fluid] == 0.0)


def test_linear_fields_are_interpolated_exactly_inside():
    nx, ny, Lx, Ly = 8, 6, 0.8, 0.6
    xc, yc = (np.arange(nx) + 0.5) * Lx / nx, (np.arange(ny) + 0.5) * Ly / ny
    f = (2.0 * xc[:, None] - 3.0 + 0.0 * yc[None, :])[:, :, None]
    rng = np.random.default_rng(0)
    pos = np.column_stack([rng.uniform(xc[0], xc[-1], 50), rng.uniform(0, Ly, 50)])
    at = _interpolate(pos, np.zeros(50, np.int64), f, nx, ny, Lx, Ly)
    assert np.allclose(at[:, 0], 2.0 * pos[:, 0] - 3.0, rtol=0, atol=1e-12)


def test_permeability_is_stokes_closed_form_and_capped():
    """K of a uniform state from the particles' drag rate C (Stokes) is d^2 eps^4.65 / (18 mu theta); the cap."""
    theta = np.array([0.05, 0.2, 0.45, 0.6])
    mu, d, rho_s = 1e-3, 3e-4, 2500.0
    C = np.array([drag.rate(STOKES, t, 0.0, rho_s, 1000.0, mu, d) / (1 - t) for t in theta])
    K = permeability.of_uniform(theta, C, rho_s)
    assert np.allclose(K, d * d * (1 - theta) ** 4.65 / (18 * mu * theta), rtol=1e-12)
    capped = permeability.from_resistance(np.array([0.0, 1e-9, 2e3]), 1e-3)
    assert capped[0] == capped[1] == 1e-3 and capped[2] == pytest.approx(5e-4)


# ---- the keys ----------------------------------------------------------------------------------------------
BED_TOML = (layers.BED.read_text())


@pytest.mark.parametrize("sets, key", [
    (['gas.flow="column"', "gas.cell=0.001"], "gas.cell"),
    (['gas.flow="column"', "gas.K_max=1.0"], "gas.K_max"),
    (['gas.flow="column"', "gas.solve_every=2"], "gas.solve_every"),
    (['gas.flow="solved"', "gas.cell=0.002"], "gas.cell"),        # Ly = 2.4 mm: fewer than 3 cells along y
    (['gas.flow="solved"', "gas.cell=-1.0"], "gas.cell"),
    (['gas.flow="solved"', "gas.solve_every=0"], "gas.solve_every"),
    (['gas.flow="solved"', "gas.K_max=0.0"], "gas.K_max"),
    (['gas.flow="solved"', "scene.dim=3", "body_force.g=[-9.81, 0.0, -1.0]"], "body_force.g"),
    (['gas.flow="solved"', "body_force.g=[9.81, 0.0]"], "body_force.g"),
    (['gas.flow="column"', "gas.jet=[0.0, 0.001, 0.1]"], "gas.jet"),
    (['gas.flow="solved"', "gas.jet=[0.0, 0.1]"], "gas.jet"),
    (['gas.flow="solved"', "gas.jet=[0.002, 0.001, 0.1]"], "gas.jet"),
    (['gas.flow="solved"', "gas.jet=[0.0, 0.001, -0.1]"], "gas.jet"),
    (['gas.flow="solved"', "gas.jet=[0.0, 0.001, 0.1, 0.0]"], "gas.jet"),
    (['gas.flow="solved"', "gas.jet=[0.0, 0.001, 0.1, 0.2, 0.3]"], "gas.jet"),
    (["perturbation.amplitude=1e-5", "perturbation.wavelength=0.06", "perturbation.wavelength_y=0.005"],
     "perturbation.wavelength_y"),                                 # does not divide Ly = 2.4 mm
    (["perturbation.wavelength_y=0.0024"], "perturbation.wavelength_y"),   # no amplitude
])
def test_solved_gas_keys_are_checked(sets, key):
    with pytest.raises(ConfigError) as e:
        config.loads(BED_TOML, sets)
    assert e.value.key == key
    assert "\n" not in str(e.value)


def test_solve_every_reuses_the_flux_between_solves():
    cfg = layers.load(layers.BED, ['gas.flow="solved"', "gas.solve_every=5", "domain.L=0.004", "numerics.Nx=20",
                                   "domain.Ly=0.0024", "scene.height=0.0016", "numerics.dt=5e-5",
                                   "output.t_end=0.01", "output.times=[0.01]", "output.snapshots=false"])
    sim = Simulation(cfg, MPI.COMM_SELF)
    sim.take_steps(20)
    assert sim.gas.solves == 5  # steps 0, 5, 10, 15 and 20's state


# ---- reference 7: voidage waves -------------------------------------------------------------------------
from parsph.physics import voidage_waves  # noqa: E402


def glass_in_water(theta0=0.4, dp=5.0, mu_s=0.004):
    return voidage_waves.Bed(theta0=theta0, rho_s=2500.0, rho_g=1000.0, mu_g=1e-3, d=3e-4, g=9.81, mu_s=mu_s, dp=dp)


def test_voidage_waves_stokes_closed_forms():
    """Stokes drag: U_f = u_t eps0^4.65 (Richardson & Zaki) and c_k = 4.65 theta0 u_t eps0^3.65."""
    bed = glass_in_water()
    u_t = drag.terminal_velocity(bed.rho_s, bed.rho_g, bed.g, bed.d, bed.mu_g)
    eps = 1 - bed.theta0
    assert bed.fluidising_velocity() == pytest.approx(u_t * eps ** 4.65, rel=1e-12)
    assert bed.kinematic_speed() == pytest.approx(4.65 * bed.theta0 * u_t * eps ** 3.65, rel=1e-6)


@pytest.mark.parametrize("dp", [0.5, 5.0, 50.0])  # on both sides of Wallis's bound
def test_voidage_waves_long_wave_limit_is_wallis(dp):
    """As k -> 0: s = -i k c_k + k^2 theta0 rho_s (c_k^2 - c_d^2) / B + O(k^3) (the expansion of the quadratic):
    the wave speed tends to c_k, and long waves grow iff c_k > c_d."""
    bed = glass_in_water(dp=dp, mu_s=0.0)
    c_k, c_d = bed.kinematic_speed(), bed.elastic_speed()
    f_theta, B = bed.derivatives()
    for wavelength in (5.0, 10.0):
        k = 2 * math.pi / wavelength
        growth, speed = bed.growth_and_speed(wavelength)
        assert speed == pytest.approx(c_k, rel=1e-3)
        assert growth == pytest.approx(k * k * bed.theta0 * bed.rho_s * (c_k ** 2 - c_d ** 2) / B, rel=2e-2)
        assert (growth > 0) == (c_k > c_d)


def test_voidage_waves_root_solves_the_quadratic():
    bed = glass_in_water()
    f_theta, B = bed.derivatives()
    k = 2 * math.pi / 0.01
    s = bed.rate(k)
    residual = bed.theta0 * bed.rho_s * s * s + (bed.theta0 * bed.mu_s * k * k + B) * s \
        + 1j * k * bed.theta0 * f_theta + k * k * bed.theta0 * bed.dp
    assert abs(residual) < 1e-9 * (B * abs(s) + k * k * bed.theta0 * bed.dp)


def test_a_jet_feeds_its_faces_and_the_gas_leaves_through_the_lid():
    """gas.jet: the floor faces under it fed at U_jet, the rest at U; the gas through the lid is the sum."""
    cfg = layers.load(layers.BED, ['gas.flow="solved"', "domain.Ly=0.0048", "gas.jet=[0.0016, 0.0032, 0.05]",
                                   "output.t_end=0.001", "output.times=[0.001]", "output.snapshots=false"])
    sim = Simulation(cfg, MPI.COMM_SELF)
    sim.take_steps(2)
    g, sol = sim.gas.grid, sim.gas.solution
    y = (np.arange(g.ny) + 0.5) * g.hy
    under = (y >= 0.0016) & (y < 0.0032)
    assert under.sum() == 2 and np.allclose(sol.jx[0][under], 0.05) and np.allclose(sol.jx[0][~under], cfg.gas.U)
    assert sol.jx[-1].sum() == pytest.approx(sol.jx[0].sum(), rel=1e-9)  # what comes in leaves at the top
    assert sol.jy.std() > 0  # the jet spreads sideways


def test_a_jet_with_t_off_stops_then():
    """gas.jet = [y0, y1, U_jet, t_off]: the faces under it fed at U_jet before t_off, at U from then on (the
    matrix unchanged: the same factor serves)."""
    cfg = layers.load(layers.BED, ['gas.flow="solved"', "domain.Ly=0.0048", "gas.jet=[0.0016, 0.0032, 0.05, 2e-4]",
                                   "output.t_end=0.001", "output.times=[0.001]", "output.snapshots=false"])
    sim = Simulation(cfg, MPI.COMM_SELF)
    g = sim.gas.grid
    under = ((np.arange(g.ny) + 0.5) * g.hy >= 0.0016) & ((np.arange(g.ny) + 0.5) * g.hy < 0.0032)
    sim.take_steps(1)
    assert sim.t < 2e-4 and np.allclose(sim.gas.solution.jx[0][under], 0.05)
    while sim.t <= 2e-4:
        sim.take_steps(1)
    sim.take_steps(1)
    assert np.allclose(sim.gas.solution.jx[0], cfg.gas.U)
    assert sim.gas.solution.jx[-1].sum() == pytest.approx(g.ny * cfg.gas.U, rel=1e-9)


def test_a_seed_across_y_displaces_by_its_mode():
    """perturbation.wavelength_y: each grain moved along x by A sin(2 pi x / lambda) cos(2 pi y / lambda_y), from
    the unperturbed lattice (the same scene without the perturbation)."""
    from parsph.simulation.start import perturb
    base = ["domain.Ly=0.0048"]
    seed = ["perturbation.amplitude=4e-5", "perturbation.wavelength=0.06", "perturbation.wavelength_y=0.0024"]
    cfg0, cfg1 = layers.load(layers.BED, base), layers.load(layers.BED, base + seed)
    _, kind, _, pos, _ = cfg0.scene.particles(cfg0, 0.0, cfg0.Ly)
    moved = pos.copy()
    perturb(cfg1, kind, moved)
    f = kind == 0
    want = 4e-5 * np.sin(2 * np.pi * pos[f, 0] / 0.06) * np.cos(2 * np.pi * pos[f, 1] / 0.0024)
    assert np.allclose(moved[f, 0] - pos[f, 0], want, rtol=0, atol=1e-18)
    assert np.array_equal(moved[~f], pos[~f]) and np.array_equal(moved[:, 1], pos[:, 1])
    assert want.max() > 3e-5 and want.min() < -3e-5   # both signs across y


def test_a_failed_solve_is_one_line_naming_step_and_time():
    """A solve without a finite answer ends every rank alike with SolveError (step and time named), which the
    command reports in one line with the exit code of a failed check (3)."""
    from parsph.cli.exits import EXIT_GUARD
    from parsph.cli.world import reporting
    from parsph.errors import SolveError
    cfg = layers.load(layers.BED, ['gas.flow="solved"', "output.t_end=0.01", "output.times=[0.01]",
                                   "output.snapshots=false"])
    sim = Simulation(cfg, MPI.COMM_SELF)
    sim.take_steps(3)

    class Singular:  # what darcy.Darcy raises where LAPACK or SuperLU finds no answer
        def start(self):
            return None, None

        def solve(self, K, V):
            raise darcy.SolveFailed("the pressure is not finite")
    sim.gas.darcy = Singular()
    with pytest.raises(SolveError) as e:
        sim.take_steps(1)
    msg = str(e.value)
    assert "\n" not in msg and f"step {sim.step}" in msg and f"t = {sim.t:.6g} s" in msg

    def failing():
        raise SolveError(msg)
    assert reporting(MPI.COMM_SELF, failing) == EXIT_GUARD


class _Singular:
    """A Darcy whose every solve raises what darcy.Darcy raises where LAPACK or SuperLU finds no answer; what
    a solve starts from is the real one's."""

    def __init__(self, real):
        self.real = real

    def start(self):
        return self.real.start()

    def solve(self, K, V):
        raise darcy.SolveFailed("the pressure is not finite")


@pytest.mark.parametrize("integrator, back", [("paper", 0), ("midpoint", 1)])
def test_a_failed_solve_writes_its_whole_state_as_a_restart_point(tmp_path, integrator, back):
    """The solve fails at the next evaluation after 3 steps: with Eqs. (6)-(7) at the end of step 4, whose
    state is whole; with the midpoint scheme at step 4's middle, so the state written is step 4's start (3).
    The file is that state bit for bit (against a run that did not fail), and a restart from it continues as
    the run that did not fail does, bit for bit (the gas stage's start kept with it)."""
    import h5py
    from parsph.errors import SolveError
    from parsph.output import Output, read_state
    sets = ['gas.flow="solved"', f'numerics.integrator="{integrator}"', "output.t_end=0.01", "output.times=[0.01]",
            "output.snapshots=false"]
    cfg = layers.load(layers.BED, sets)
    whole = Simulation(cfg, MPI.COMM_SELF)
    states = {}
    for k in range(1, 7):
        whole.take_steps(1)
        states[whole.step] = {key: v.copy() for key, v in whole.particles().items()}
    failing = Simulation(cfg, MPI.COMM_SELF)
    failing.take_steps(3)
    failing.gas.darcy = _Singular(failing.gas.darcy)
    out = Output(MPI.COMM_SELF, str(tmp_path), "s", cfg, cfg.n_particles)
    with pytest.raises(SolveError) as e:
        failing.run(output=out)
    at = 4 - back
    assert f"a restart point written at step {at}" in str(e.value) and "\n" not in str(e.value)
    path = tmp_path / "s_0000.h5"
    snap = read_state(str(path))
    assert int(snap["attrs"]["step"]) == at
    with h5py.File(path, "r") as f:
        written = {key: f[f"particles/{key}"][()] for key in ("id", "position", "velocity")}
    order = np.argsort(written["id"])
    ref = states[at]
    ref_order = np.argsort(ref["id"])
    for key in ("position", "velocity"):
        assert np.array_equal(written[key][order], ref[key][ref_order]), key
    resumed = Simulation(cfg, MPI.COMM_SELF, snap)
    resumed.take_steps(6 - at)
    got = resumed.particles()
    g_order, r_order = np.argsort(got["id"]), np.argsort(states[6]["id"])
    for key in ("position", "velocity"):
        assert np.array_equal(got[key][g_order], states[6][key][r_order]), key


# ---- the preconditioned solves: an earlier K's factor, warm started -------------------------------------
@pytest.mark.parametrize("periodic", [False, True])
def test_preconditioned_solves_agree_with_factorising_ones(periodic):
    """A sequence of K drifting by 0.3% a solve (in every cell, at random) (and one jump by 100x in a block of cells): the solves that
    reuse an old factor give the factorising solve's p' and fluxes within 1e-8, and factorise half as often or less."""
    rng = np.random.default_rng(5)
    nx, ny, hx, hy = 20, 30, 1e-3, 1e-3
    if periodic:
        args = (None, None, 0.02)
    else:
        args = ((darcy.Side("flux", rng.uniform(0.01, 0.02, ny)), darcy.Side("pressure", 0.0)), None, None)
    reusing = darcy.Darcy(nx, ny, hx, hy, *args)
    fresh = darcy.Darcy(nx, ny, hx, hy, *args, reuse=False)
    K = 10 ** rng.uniform(-6, -5, (nx, ny))
    V = rng.normal(scale=1e-3, size=(nx, ny, 2))
    for step in range(30):
        K = K * (1 + 0.003 * rng.normal(size=K.shape))
        V = V + 1e-4 * rng.normal(size=V.shape)
        if step == 15:
            K[5:9, 10:14] *= 100.0
        a, b = reusing.solve(K, V), fresh.solve(K, V)
        scale = np.abs(b.p).max()
        assert np.abs(a.p - b.p).max() < 1e-8 * scale, step
        assert np.abs(a.jx - b.jx).max() < 1e-8 * np.abs(b.jx).max(), step
    assert fresh.factorisations == 30
    assert reusing.factorisations <= 15, reusing.factorisations


def test_restored_start_makes_the_same_solve():
    """start() and restore() (a restart point's /grid/start: the factor's K and the last two solves' p', from
    which the next starts): the next solve is the same to the bit."""
    rng = np.random.default_rng(8)
    nx, ny = 12, 16
    sides = (darcy.Side("flux", 0.01), darcy.Side("pressure", 0.0))
    a = darcy.Darcy(nx, ny, 1e-3, 1e-3, sides, None)
    K = 10 ** rng.uniform(-6, -5, (nx, ny))
    V = rng.normal(scale=1e-3, size=(nx, ny, 2))
    a.solve(K, V)
    K = K * (1 + 1e-4 * rng.normal(size=K.shape))
    a.solve(K, V)
    K2 = K * (1 + 0.02 * rng.normal(size=K.shape))
    factor_K, warm = a.start()
    assert factor_K is not None and len(warm) == 2
    b = darcy.Darcy(nx, ny, 1e-3, 1e-3, sides, None)
    b.restore(factor_K, list(warm))
    pa, pb = a.solve(K2, V), b.solve(K2, V)
    assert a.iterations > 0 and a.iterations == b.iterations
    assert np.array_equal(pa.p, pb.p) and np.array_equal(pa.jx, pb.jx)


def test_outputs_hold_the_grid_and_its_theta_holds_the_grains_volume(tmp_path):
    """Each output of a solved run has /grid (docs/output.md): theta on the cells, whose sum times the cell's
    area is the grains' volume per metre of z (sum of m / rho_s, to the deposit's fixed point), and p', j, u_g
    of the same shape; /grid/start for a restart; the XDMF sidecar shows the cells."""
    import h5py
    from parsph.simulation.case import run_case
    cfg = layers.load(layers.BED, ['gas.flow="solved"', "domain.L=0.004", "numerics.Nx=20", "domain.Ly=0.0024",
                                   "scene.height=0.0016", "numerics.dt=5e-5", "output.t_end=0.004",
                                   "output.times=[0.002, 0.004]", "output.snapshots=true"])
    run_case(MPI.COMM_SELF, cfg, str(tmp_path), "bed")
    with h5py.File(tmp_path / "bed_0001.h5", "r") as f:
        g = f["grid"]
        hx, hy = g.attrs["cell"]
        theta = g["theta"][()]
        fluid = f["particles/kind"][()] == 0
        volume = f["particles/mass"][()][fluid].sum() / cfg.rho_s
        assert theta.sum() * hx * hy == pytest.approx(volume, rel=1e-9)
        assert g["p"].shape == theta.shape and g["j"].shape == g["u_g"].shape == theta.shape + (2,)
        assert "start/warm" in g and g.attrs["start_solved_at"] >= 0
        nx, ny = theta.shape
        for key in ("u_g", "j"):  # ParaView's display copies: 3 components, a bed upright (x along its Y)
            v, view = g[key][()], g[key + "_xyz"][()]
            assert view.shape == (nx, ny, 3) and np.array_equal(view[..., 0], v[..., 1])
            assert np.array_equal(view[..., 1], v[..., 0]) and not view[..., 2].any()
    # the ParaView sidecar: a "gas grid" collection, one structured grid an output, its nodes (i h_x, j h_y) as
    # ParaView places them: a bed upright, (j h_y, i h_x), as its particles (test_xdmf)
    import xml.etree.ElementTree as ET
    dom = ET.parse(tmp_path / "bed.xdmf").getroot().find("Domain")
    gas = [g for g in dom.findall("Grid") if g.get("Name") == "gas grid"]
    assert len(gas) == 1 and len(gas[0].findall("Grid")) == 2
    vectors = {a.get("Name"): a for a in gas[0].find("Grid").findall("Attribute") if a.get("AttributeType") == "Vector"}
    assert sorted(vectors) == ["j", "u_g"] and all(a.get("Center") == "Cell" for a in vectors.values())
    assert vectors["u_g"].find("DataItem").text.endswith(":/grid/u_g_xyz")
    topo = gas[0].find("Grid/Topology")
    assert topo.get("TopologyType") == "2DSMesh" and topo.get("Dimensions") == f"{nx + 1} {ny + 1}"
    with h5py.File(tmp_path / "bed.cells.h5", "r") as f:
        nodes = f["grid_nodes"][()].reshape(nx + 1, ny + 1, 2)
    assert np.allclose(nodes[:, 0, 1], np.arange(nx + 1) * hx) and np.allclose(nodes[0, :, 0], np.arange(ny + 1) * hy)


def test_plot_grid_draws_each_output_and_animates_them(tmp_path):
    """``parsph plot --grid``: a PNG per output with a grid and a GIF with one frame per output; a field the
    grid lacks, or an animation name of another kind, is one line and exit 2 (nothing written)."""
    from PIL import Image
    from parsph.cli.command import main
    from parsph.simulation.case import run_case
    cfg = layers.load(layers.BED, ['gas.flow="solved"', "domain.L=0.004", "numerics.Nx=20", "domain.Ly=0.0024",
                                   "scene.height=0.0016", "numerics.dt=5e-5", "output.t_end=0.004",
                                   "output.times=[0.0, 0.002, 0.004]", "output.snapshots=false"])
    run_case(MPI.COMM_SELF, cfg, str(tmp_path), "bed")
    gif = tmp_path / "bed.gif"
    assert main(["plot", str(tmp_path), "--grid", "--animate", str(gif)]) == 0
    assert sorted(p.name for p in tmp_path.glob("*.png")) == [f"bed_grid_theta_000{k}.png" for k in range(3)]
    with Image.open(gif) as im:
        assert im.n_frames == 3
    assert main(["plot", str(tmp_path), "--grid", "--field", "vy"]) == 2
    assert main(["plot", str(tmp_path), "--grid", "--field", "p", "--animate", str(tmp_path / "x.avi")]) == 2
    assert main(["plot", str(tmp_path), "--particles", "--animate", str(tmp_path / "p.gif")]) == 2
    assert not list(tmp_path.glob("*_grid_p_*.png")) and not (tmp_path / "p.gif").exists()
    # --field or --animate alone: the grid's pictures, as the outputs hold a grid
    for png in tmp_path.glob("*.png"):
        png.unlink()
    gif.unlink()
    assert main(["plot", str(tmp_path), "--field", "p", "--times", "0.004"]) == 0
    assert [p.name for p in tmp_path.glob("*.png")] == ["bed_grid_p_0002.png"]
    assert main(["plot", str(tmp_path), "--animate", str(gif)]) == 0
    with Image.open(gif) as im:
        assert im.n_frames == 3 and len(list(tmp_path.glob("bed_grid_theta_*.png"))) == 3


@pytest.mark.parametrize("extra", [["gas.solve_every=3"], ['gas.drag="wen_yu"']])
def test_a_restart_between_solves_is_bit_for_bit(tmp_path, extra):
    """gas.solve_every = 3 and an output between two solves: a run restarted from it (its /grid/start: the
    flux held since the last solve, the warm start, the factor's K) ends with the uninterrupted run's bits;
    likewise a slip-dependent closure solving every step, whose C takes the slip toward the last solve's j."""
    import shutil
    import h5py
    from parsph.output import read_state
    from parsph.simulation.case import run_case
    sets = ['gas.flow="solved"', *extra, "domain.L=0.004", "numerics.Nx=20", "domain.Ly=0.0024",
            "scene.height=0.0016", "numerics.dt=5e-5", "output.t_end=0.004", "output.times=[0.00205, 0.004]",
            "output.snapshots=true"]
    whole, resumed = tmp_path / "whole", tmp_path / "resumed"
    run_case(MPI.COMM_SELF, layers.load(layers.BED, sets), str(whole), "bed")
    resumed.mkdir()
    shutil.copy(whole / "bed_0000.h5", resumed / "bed_0000.h5")
    with h5py.File(resumed / "bed_0000.h5", "r") as f:
        assert f.attrs["step"] % 3 != 0  # the restart point lies between two solves (with solve_every = 3)
    run_case(MPI.COMM_SELF, layers.load(layers.BED, sets), str(resumed), "bed",
             state=read_state(str(resumed / "bed_0000.h5")))
    with h5py.File(whole / "bed_0001.h5", "r") as a, h5py.File(resumed / "bed_0001.h5", "r") as b:
        assert a.attrs["step"] == b.attrs["step"]
        for key in ("restart/position", "particles/velocity", "grid/p", "grid/j"):
            assert np.array_equal(a[key][()], b[key][()]), key
