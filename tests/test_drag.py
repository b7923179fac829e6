"""The solid phase in a gas (docs/physics.md, "The solid phase in a gas"): the drag term in the step against exact
references, on the periodic box (uniform theta: Eq. (5)'s sums vanish but for the wave).

- drag relaxation in a stream (reference 1): every particle on Eq. (7)'s discrete solution to round-off,
  for each integrator with the drag explicit and implicit, and on the continuous one to O(dt/tau);
  Wen & Yu against the ODE;
- hindered settling (reference 2): the steady velocity within 1% of -u_t eps0^4.65 (Stokes) at
  theta0 = 0.05, 0.2, 0.4, and of the Wen & Yu root;
- a wall particle gets neither gravity nor drag;
- each integrator's order in time, with and without drag.

The references are written out here from docs/physics.md (tau = rho_s d^2 eps^3.65 / (18 mu_g) across,
eps^4.65 along a column), not taken from the code under test.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from parsph.physics import gas_references
from parsph.setup import config
from parsph.simulation.solver import Simulation
from parsph.sph.particles import GRAIN
from conftest import ROOT

BOX = ROOT / "run" / "periodic_box.toml"
WATER = ('gas.rho=1000.0', 'gas.mu=1e-3')  # glass (2000 kg/m^3, 0.3 mm) in water: tau ~ 1e-2 s
D, RHO_S, MU, RHO_G, G = 3.0e-4, 2000.0, 1e-3, 1000.0, 9.81


def box(*sets, nx=8):
    return config.load(BOX, [f"numerics.Nx={nx}", f"domain.L={nx * 2e-4!r}", "output.times=[]",
                             "scene.amplitude=0.0", "material.k=0.01", *sets])


def run(cfg, steps=None):
    """The run stepped on the Python path: these boxes' terms (no pressure, a gas) are a combination no
    other case runs, so the compiled route would compile a block for each integrator and update (about
    10 s each); the passes alone compile in about 2 s, and test_compiled_step shows both routes give the
    same bits with the drag explicit, implicit and under the auto rule's drag limit."""
    sim = Simulation(cfg, MPI.COMM_SELF, native=False)
    sim.take_steps(steps if steps is not None else cfg.nsteps)
    return sim


def fluid(sim, field):
    ps = sim.ps
    f = ps.kind[:ps.n_own] == GRAIN
    return getattr(ps, field)[:ps.n_own][f]


def stokes_tau(theta, column=False):
    eps = 1.0 - theta
    return RHO_S * D * D * eps ** (4.65 if column else 3.65) / (18.0 * MU)


def amplification(integrator, update, z):
    """One step's factor on the slip of dv/dt = -v/tau, z = dt/tau (docs/physics.md; integrators' doc)."""
    if integrator == "paper":
        return 1.0 - z if update == "explicit" else 1.0 / (1.0 + z)
    return 1.0 - z + z * z / 2 if update == "explicit" else (1.0 - z / 2) / (1.0 + z / 2)


def literal_beta(model, theta, slip, rho_g, mu_g, d):
    """docs/physics.md's closures as written there (powers, Re, MFiX's blend), in plain Python."""
    eps = 1.0 - theta
    re = eps * rho_g * slip * d / mu_g
    stokes = 18.0 * mu_g * theta * eps ** -2.65 / d ** 2
    if re < 1000.0:
        wy = stokes * (1.0 + 0.15 * re ** 0.687)
    else:
        wy = 0.33 * rho_g * theta * eps ** -1.65 * slip / d
    if model == "stokes":
        return stokes
    if model == "wen_yu":
        return wy
    ergun = 150.0 * theta ** 2 * mu_g / (eps * d ** 2) + 1.75 * theta * rho_g * slip / d
    phi = math.atan(150.0 * 1.75 * (eps - 0.8)) / math.pi + 0.5
    return (1.0 - phi) * ergun + phi * wy


@pytest.mark.parametrize("model", ["stokes", "wen_yu", "gidaspow"])
def test_closures_are_physics_md_formulas(model):
    """drag.beta (the log-domain form the step uses, via drag.rate) against the closures written with
    powers: to 1e-13 relative from theta = 1e-3 to 0.64, slips from 0 to Re = 1e5 (both Wen & Yu branches,
    both sides of Gidaspow's blend), air and water."""
    from parsph.physics import drag
    rng = np.random.default_rng(7)
    worst = 0.0
    for rho_g, mu_g in ((1.2, 1.8e-5), (1000.0, 1e-3)):
        for theta in (1e-3, 0.05, 0.15, 0.2, 0.3, 0.45, 0.64):
            for slip in (0.0, *np.exp(rng.uniform(np.log(1e-6), np.log(2e3), 40))):
                want = literal_beta(model, theta, slip, rho_g, mu_g, D)
                got = drag.beta(drag.MODELS[model], theta, slip, rho_g, mu_g, D)
                worst = max(worst, abs(got / want - 1.0))
    assert worst < 1e-13


@pytest.mark.parametrize("integrator", ["paper", "midpoint"])
@pytest.mark.parametrize("update", ["explicit", "implicit"])
def test_relaxation_is_the_discrete_solution(integrator, update):
    """Stokes, a stream (0.004, 0.01) m/s: v_n = u_g (1 - r^n) at every particle, to round-off."""
    u = np.array([0.004, 0.01])
    cfg = box('gas.drag="stokes"', "gas.velocity=[0.004, 0.01]", *WATER, f'numerics.drag_update="{update}"',
              f'numerics.integrator="{integrator}"', "numerics.dt=2e-4", "output.t_end=0.006")
    sim = run(cfg)
    theta = fluid(sim, "theta")
    assert np.ptp(theta) < 1e-13 * theta[0]  # uniform to round-off: one tau
    z = cfg.dt / stokes_tau(theta[0])
    assert 0.01 < z < 0.1
    exact = u * (1.0 - amplification(integrator, update, z) ** sim.step)
    v = fluid(sim, "vel")
    assert sim.step == 30
    np.testing.assert_allclose(v, np.broadcast_to(exact, v.shape), rtol=1e-13, atol=0)


def test_relaxation_converges_to_the_continuous_solution_at_first_order():
    """Eqs. (6)-(7) with explicit drag: |v_n - u_g (1 - exp(-t/tau))| falls as dt/tau (halving dt halves it)."""
    errs, zs = [], []
    for dt in (4e-4, 2e-4, 1e-4):
        cfg = box('gas.drag="stokes"', "gas.velocity=[0.0, 0.01]", *WATER, 'numerics.drag_update="explicit"',
                  f"numerics.dt={dt!r}", "output.t_end=0.008")
        sim = run(cfg)
        tau = stokes_tau(fluid(sim, "theta")[0])
        exact = 0.01 * -math.expm1(-sim.t / tau)
        errs.append(abs(fluid(sim, "vel")[:, 1].max() - exact) / 0.01)
        zs.append(dt / tau)
    ratios = [errs[0] / errs[1], errs[1] / errs[2]]
    assert all(1.8 < r < 2.2 for r in ratios), (errs, ratios)
    # Euler's error on exp(-t/tau) is at most (dt/tau) max(x exp(-x)) / 2 = 0.18 dt/tau
    assert all(0.01 * z < e < 0.19 * z for e, z in zip(errs, zs)), (errs, zs)


@pytest.mark.parametrize("closure", ["wen_yu", "gidaspow"])
def test_relaxation_follows_the_ode(closure):
    """Wen & Yu and Gidaspow in a fast stream (Re ~ 50: far from Stokes): the midpoint scheme's v(t) on the
    ODE of parsph.physics.gas_references to O(dt^2)."""
    u = 0.2
    cfg = box(f'gas.drag="{closure}"', f"gas.velocity=[0.0, {u}]", *WATER, 'numerics.integrator="midpoint"',
              "numerics.dt=2e-5", "output.t_end=0.001", "material.theta0=0.3")
    sim = run(cfg)
    theta = fluid(sim, "theta")[0]
    ref = float(gas_references.relaxation_ode(sim.t, u, theta, gas_references.Phases(RHO_S, RHO_G, MU, D, G, closure)))
    v = fluid(sim, "vel")[:, 1]
    assert np.ptp(v) < 1e-12 * u
    assert abs(v[0] - ref) < 1e-4 * u, (v[0], ref)
    assert 0.3 * u < ref < 0.99 * u  # the run covers the relaxation, not its end


def settle(theta0, closure, t_end, dt="2e-4"):
    cfg = box(f'gas.drag="{closure}"', 'gas.flow="column"', *WATER, f"material.theta0={theta0}",
              "body_force.g=[-9.81, 0.0]", f"numerics.dt={dt}", f"output.t_end={t_end}")
    sim = run(cfg)
    return sim, fluid(sim, "vel")


@pytest.mark.parametrize("theta0", [0.05, 0.2, 0.4])
def test_hindered_settling_stokes(theta0):
    """A uniform suspension in a closed column settles at -u_t eps0^4.65 (Richardson & Zaki, n = 4.65)."""
    tau = stokes_tau(theta0, column=True)
    sim, v = settle(theta0, "stokes", round(12 * tau, 4))
    u_t = (RHO_S - RHO_G) * G * D * D / (18 * MU)
    expect = -u_t * (1 - theta0) ** 4.65
    assert abs(v[:, 1]).max() < 1e-15
    assert np.ptp(v[:, 0]) < 1e-12 * abs(expect)
    assert abs(v[0, 0] / expect - 1) < 0.01, (v[0, 0], expect)


@pytest.mark.parametrize("theta0", [0.05, 0.2, 0.4])
def test_hindered_settling_wen_yu(theta0):
    """With Wen & Yu the settling velocity is the root of beta(theta0, |v|/eps0) |v| = theta0 eps0^2 (rho_s -
    rho_g) |g| (Re ~ 1-10 here, so 10-40% slower than Stokes's)."""
    tau = stokes_tau(theta0, column=True)
    sim, v = settle(theta0, "wen_yu", round(12 * tau, 4))
    root = gas_references.hindered_settling_velocity(theta0, gas_references.Phases(RHO_S, RHO_G, MU, D, G, "wen_yu"))
    u_t = (RHO_S - RHO_G) * G * D * D / (18 * MU)
    assert abs(root) < 0.95 * u_t * (1 - theta0) ** 4.65
    assert abs(v[0, 0] / root - 1) < 0.01, (v[0, 0], root)


def test_walls_get_neither_gravity_nor_drag():
    """In the settling column with a gas, every wall particle's acceleration is exactly 0 after an
    evaluation, and the fluid's is gravity with buoyancy where it rests (no slip, uniform interior)."""
    cfg = config.load(ROOT / "run" / "settling.toml", ["numerics.Nx=20", "domain.L=0.004", "domain.Ly=0.0024",
                                                        'gas.drag="wen_yu"', 'gas.flow="column"', "gas.U=0.001",
                                                        "output.times=[]"])
    sim = Simulation(cfg, MPI.COMM_SELF, native=False)
    sim.take_steps(3)
    ps = sim.ps
    walls = ps.kind[:ps.n_own] != GRAIN
    assert walls.sum() > 0
    assert np.all(ps.acc[:ps.n_own][walls] == 0.0)
    assert np.all(ps.acc[:ps.n_own][~walls] != 0.0)


def order_runs(integrator, drag):
    """v at t = 2 ms of the shear wave with dt, dt/2, dt/4; the order in time from their differences."""
    sets = ["scene.amplitude=0.05", f'numerics.integrator="{integrator}"', "output.t_end=0.002"]
    if drag != "none":
        sets += ['gas.drag="stokes"', "gas.velocity=[0.01, 0.02]", *WATER, f'numerics.drag_update="{drag}"',
                 "material.d=2e-4"]  # tau = 0.9 ms: drag and viscosity (nu k^2 = 670/s) of one size
    vs = []
    for dt in (2e-5, 1e-5, 5e-6):
        cfg = config.load(BOX, ["numerics.Nx=16", "domain.L=0.0032", "output.times=[]", f"numerics.dt={dt!r}",
                                *sets])
        sim = run(cfg)
        order = np.argsort(sim.ps.gid[:sim.ps.n_own])
        vs.append(sim.ps.vel[:sim.ps.n_own][order].copy())
    e1 = np.abs(vs[0] - vs[1]).max()
    e2 = np.abs(vs[1] - vs[2]).max()
    return math.log2(e1 / e2)


@pytest.mark.parametrize("integrator, expect", [("paper", 1.0), ("midpoint", 2.0)])
@pytest.mark.parametrize("drag", ["none", "explicit", "implicit"])
def test_order_in_time(integrator, expect, drag):
    """Error against dt at a fixed N_x: about 1 for "paper" (Eqs. (6)-(7)), 2 for "midpoint", with the drag
    explicit and implicit too (Richardson: the differences of runs at dt, dt/2, dt/4)."""
    p = order_runs(integrator, drag)
    assert abs(p - expect) < 0.15, p


def test_every_scene_honours_gravity():
    """The periodic box under g = (0, 9.81) m/s^2 with no gas falls freely: v_y = g t at every particle, and
    v_x stays 0 (the scene ignored body_force.g)."""
    sim = run(box("body_force.g=[0.0, 9.81]", "numerics.dt=1e-4", "output.t_end=0.002"))
    v = fluid(sim, "vel")
    assert sim.step == 20
    assert np.all(v[:, 0] == 0.0)
    np.testing.assert_allclose(v[:, 1], 9.81 * sim.t, rtol=1e-13)


@pytest.mark.parametrize("gas, expect", [((), "errors of v_y"), (('gas.drag=wen_yu', "gas.velocity=[0.0, 0.01]"),
                                                                  "no reference")])
def test_a_box_at_rest_reports_numbers_or_no_reference(tmp_path, gas, expect):
    """``scene.amplitude = 0``: the table holds numbers (errors in m/s where nothing flows: the box stays at
    rest, so they are 0), and a run whose scene has no reference (Wen & Yu) says so; neither prints nan."""
    from conftest import run_cli
    sets = ["scene.amplitude=0.0", "numerics.Nx=10", "domain.L=0.002", "output.t_end=2e-4", "output.times=[2e-4]",
            *gas]
    rc, out, err = run_cli("run", BOX, "--out", tmp_path / "box", "--quiet",
                           *[a for s in sets for a in ("--set", s)], timeout=300)
    assert rc == 0, err
    assert "nan" not in out.lower(), out
    assert expect in out, out
    if not gas:
        row = [ln.split() for ln in out.splitlines() if ln.strip().startswith("0.0002")][-1]
        assert float(row[1]) == 1.0 and float(row[2]) == 0.0 and float(row[3]) == 0.0, row  # scale, max, rms
