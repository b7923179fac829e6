"""Short transient Couette runs with the real solver on one rank (COMM_SELF), against Eq. (8)."""
import numpy as np
import pytest
from mpi4py import MPI

from parsph import config
from parsph.analytic import couette_velocity, couette_velocity_images
from parsph.solver import Simulation

from conftest import PAPER_TOML, paper_raw

T_END = 0.02  # s: 2,000 steps of the paper's dt = 1e-5 s


def run_couette(Nx, **numerics):
    """The paper case at Nx particles across, h = 1.25 dx, to T_END; profiles at T_END/2 and T_END.

    ``numerics`` overrides keys of [numerics] (e.g. dt="auto", integrator="midpoint")."""
    raw = paper_raw()
    raw["numerics"]["Nx"] = Nx
    raw["numerics"].update(numerics)
    del raw["numerics"]["h"]  # the config takes exactly one of h and h_over_dx
    raw["numerics"]["h_over_dx"] = 1.25
    raw["output"]["t_end"] = T_END
    raw["output"]["times"] = [T_END / 2, T_END]
    raw["output"]["progress_interval"] = 0.0
    cfg = config.build(raw, config.dumps(raw))
    if not numerics:
        assert cfg.dt == 1e-5 and cfg.nsteps == 2000
    assert cfg.h == pytest.approx(1.25 * cfg.L / Nx, rel=1e-12)
    profiles = {}
    steps = []

    def output(sim, snapshot=None):  # called once per output time, in time order
        steps.append(sim.step)
        p = sim.profile
        profiles[len(profiles)] = (sim.t,) + tuple(np.copy(p[key]) for key in ("x", "vy", "count", "vy_exact")) \
            + (p["err"],)

    sim = Simulation(cfg, MPI.COMM_SELF)
    sim.run(output=output)
    assert sorted(profiles) == [0, 1]
    if not cfg.dt_auto:
        assert steps == [1000, 2000]  # fixed dt: output at step round(t / dt)
    return cfg, profiles


@pytest.fixture(scope="module")
def fine():
    return run_couette(50)


@pytest.fixture(scope="module")
def coarse():
    return run_couette(20)


def test_paper_resolution_error(fine):
    cfg, prof = fine
    t, x, vy, counts, exact, (emax, erms) = prof[1]
    assert t == pytest.approx(T_END, rel=1e-12)
    # the reported errors are those of the profile against an independent evaluation of Eq. (8)
    ref = couette_velocity(x, t, cfg.nu, cfg.L, cfg.V_w)
    np.testing.assert_allclose(exact, ref, rtol=0, atol=1e-14)
    e = np.abs(vy - ref) / cfg.V_w
    assert emax == pytest.approx(e.max(), rel=1e-12)
    assert erms == pytest.approx(np.sqrt(np.mean(e ** 2)), rel=1e-12)
    assert counts.sum() == cfg.Nx * cfg.Ny  # no fluid particle lost
    # Tolerances: the run gives max 0.0116 and rms 0.0046 (of V_w) at t = 0.02 s; 0.015 and
    # 0.006 leave ~25% headroom for harmless changes (summation order, integrator details)
    # while a wrong viscosity (nu off by 10%) or wall treatment fails them.
    assert emax < 0.015
    assert erms < 0.006
    # the flow has developed: the layer next to the plate moves; the quarter by the fixed plate,
    # 4 diffusion lengths sqrt(nu t) = 1.9 mm away, barely does (Eq. (8): erfc(2) = 0.005)
    assert vy[-1] > 0.5 * cfg.V_w
    assert np.all(np.abs(vy[: cfg.Nx // 4]) < 0.01 * cfg.V_w)


def test_coarse_is_worse(fine, coarse):
    """Nx = 20 (dx = 5e-4 m, h = 6.25e-4 m) against Nx = 50 at the same time and dt:
    the ordering of both error norms, with a 1.5x margin (measured: about 2.6x and 3x)."""
    ef = fine[1][1][-1]
    ec = coarse[1][1][-1]
    assert ec[1] > 1.5 * ef[1]  # rms
    assert ec[0] > 1.5 * ef[0]  # max
    # and the coarse run still follows the solution (not a blow-up)
    assert ec[0] < 0.06


def test_error_decreases_in_time(fine):
    """The impulsive start is hardest to resolve: the error at 0.01 s exceeds that at 0.02 s."""
    _, prof = fine
    assert prof[0][-1][0] > prof[1][-1][0]
    assert prof[0][0] == pytest.approx(T_END / 2, rel=1e-12)


def test_auto_dt_midpoint_lands_on_output_times(coarse):
    """dt = "auto" (recomputed every step) with the midpoint integrator, Nx = 20: the steps are
    shortened to land exactly on the output times, and at the largest stable dt (1.3e-4 s, 13x
    the fixed one) the error is still the spatial one: both norms within 5% of the fixed-dt
    coarse run's (measured: 0.1%)."""
    cfg, prof = run_couette(20, dt="auto", integrator="midpoint")
    assert cfg.dt_auto and cfg.integrator == "midpoint"
    assert cfg.dt > 10 * 1e-5
    assert [prof[k][0] for k in (0, 1)] == [T_END / 2, T_END]  # exactly
    for k in (0, 1):
        ea, ef = prof[k][-1], coarse[1][k][-1]
        assert ea[0] == pytest.approx(ef[0], rel=0.05)
        assert ea[1] == pytest.approx(ef[1], rel=0.05)
        assert ea[0] < 0.06


def test_plot_reference_lines_reach_the_plates():
    """`parsph plot` draws Eq. (8) on a fine grid over [0, L]: 0 at the fixed plate, V_w at the moving one."""
    from parsph.cli import reference_lines
    text = PAPER_TOML.read_text()
    cfg = config.loads(text)
    times = np.array([1e-4, 0.01, 0.5])
    p = {"attrs": {"run_file": text, "L": cfg.L}, "time": times,
         "vy_exact": np.zeros((3, 50)), "theta_exact": np.full((3, 50), np.nan)}
    x, lines = reference_lines(p, points=101)
    assert x[0] == 0.0 and x[-1] == cfg.L
    for t, line in zip(times, lines):
        assert line[0] == pytest.approx(0.0, abs=1e-12)
        assert line[-1] == pytest.approx(cfg.V_w, rel=1e-9)
        np.testing.assert_allclose(line, couette_velocity_images(x, t, cfg.nu, cfg.L, cfg.V_w), atol=1e-12)
    p["vy_exact"][1] = np.nan  # an output without a reference gets no line
    assert reference_lines(p)[1][1] is None
