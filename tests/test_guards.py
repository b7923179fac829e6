"""The run-time guards of Simulation.check (docs/stability.md, "The guards"): tests that fail if a guard
names the wrong particle, misses the theta range, or lets a particle jump a slab unreported.

- worst particle: two fluid particles beyond the walls by different depths, one on each of 2 ranks
  (and the other way round): the message names the deeper one's position on every rank;
- theta range (check 3): the particle furthest from theta_0 is named; a real run with a tight
  checks.theta_change stops with check 3;
- an observer passed to ``run`` sees every step and changes nothing (bit for bit);
- the criteria as an observer reads them (``guards.read``: the stability map's and the stability
  tests'), on particles whose depths, theta, energy and speeds are written here;
- the per-rank report the compiled blocks and ``check`` share (``guards.check_report``), on
  particles written here: the first failing check in CHECKS order, its worst particle, the
  fluid's kinetic energy and mass, the fastest fluid particle;
- the compiled blocks' checks (every ``checks.every`` steps inside a block) stop a run at the
  first checked step where the deviation an observer reads exceeds the limit, with the same
  GuardResult as the Python path;
- check 5 ("moved more than h in one step"): ``mpirun -n 2 parsph run`` with the plate moving
  4h in one step exits 3 with one message line, at the first step (the jump is counted with the
  non-finite states in the per-step all-reduce).
"""
import math
import re
import textwrap

import numpy as np
import pytest
from mpi4py import MPI

from parsph.setup import config
from parsph.sph.particles import GRAIN
from parsph.errors import GuardError
from parsph.simulation.guards import CHECKS
from parsph.simulation.solver import Simulation

from conftest import PAPER_TOML

from mpi_helpers import launch  # noqa: E402

needs_mpirun = pytest.mark.skipif(launch.under_mpirun(), reason="launches mpirun itself")
L = 0.01
SMALL = ["domain.Ly=0.002", "output.times=[]", "output.progress_interval=0"]


def mpirun(n, *argv, timeout=120):
    """``mpirun -n N ARGV`` with launch.run's hard timeout and the shared numba cache."""
    return launch.run(launch.mpirun_cmd(n, *argv), timeout=timeout, shared_cache=True)


# ---- the worst particle, across ranks ---------------------------------------------------------------
WORST = textwrap.dedent("""
    import sys
    import numpy as np
    from mpi4py import MPI
    from parsph.setup import config
    from parsph.sph.particles import GRAIN
    from parsph.errors import GuardError
    from parsph.simulation.solver import Simulation
    comm = MPI.COMM_WORLD
    cfg = config.load(sys.argv[1], sys.argv[3:])
    sim = Simulation(cfg, comm)
    sim.compute_rates()
    ps = sim.ps
    k = int(np.flatnonzero(ps.kind[:ps.n_own] == GRAIN)[0])     # one fluid particle of this rank
    x0 = ps.pos[k, 0]
    out = []
    for deep_rank in (1, 0):
        # this rank's particle: 3e-5 m beyond the moving plate if it is deep_rank's, else 1e-5 m below the floor
        ps.pos[k, 0] = cfg.L + 3e-5 if comm.rank == deep_rank else -1e-5
        try:
            sim.check()
            out.append("no guard fired")
        except GuardError as e:
            out.append(f"{e}")
        ps.pos[k, 0] = x0
    with open(f"{sys.argv[2]}/rank{comm.rank}.txt", "w") as f:
        f.write(f"{int(ps.gid[k])} {float(ps.pos[k, 1])!r}\\n" + "\\n".join(out))
""")


@needs_mpirun
def test_worst_wall_offender_is_named_across_ranks(tmp_path):
    """Two fluid particles beyond the walls, 1e-5 m and 3e-5 m deep, on different ranks (each order):
    every rank raises the same GuardError naming check 2 and the deeper particle's id and position."""
    script = tmp_path / "worst.py"
    script.write_text(WORST)
    r = mpirun(2, launch.PYTHON, script, PAPER_TOML, tmp_path, *SMALL, "output.t_end=1e-5", timeout=90)
    assert r.returncode == 0, r
    ranks = [(tmp_path / f"rank{k}.txt").read_text().splitlines() for k in (0, 1)]
    gid_y = [line[0].split() for line in ranks]
    for case, deep in enumerate((1, 0)):
        msgs = {lines[1 + case] for lines in ranks}
        assert len(msgs) == 1, msgs                                   # the same message on every rank
        msg = msgs.pop()
        assert msg.startswith(f"check failed: {CHECKS[2]}"), msg
        gid, y = gid_y[deep]
        assert f"particle {gid} at x = {L + 3e-5:.6g} m, y = {float(y):.6g} m" in msg, (deep, msg)
        assert "3e-05 m beyond the plate" in msg, msg


# ---- theta out of range (check 3) ------------------------------------------------------------------
def _sim(*extra, native=None):
    cfg = config.load(str(PAPER_TOML), [*SMALL, "output.t_end=1e-4", *extra])
    return Simulation(cfg, MPI.COMM_SELF, native=native)


def test_theta_range_names_the_furthest_particle():
    """Two fluid particles with theta 60 % and 90 % above theta_0 (limit 50 %): check 3, the 90 % one named."""
    sim = _sim()
    sim.compute_rates()
    sim.check()                                    # the undisturbed lattice passes
    ps, th0 = sim.ps, sim.cfg.theta0
    a, b = np.flatnonzero(ps.kind[:ps.n_own] == GRAIN)[[3, 200]]
    ps.theta[a], ps.theta[b] = 1.6 * th0, 1.9 * th0
    with pytest.raises(GuardError) as e:
        sim.check()
    msg = str(e.value)
    assert msg.startswith(f"check failed: {CHECKS[3]} at step 0") and f"particle {ps.gid[b]} " in msg, msg
    assert f"x = {ps.pos[b, 0]:.6g} m, y = {ps.pos[b, 1]:.6g} m (theta = {1.9 * th0:.4g}, theta0 = 0.35)" in msg
    ps.theta[a], ps.theta[b] = th0, 0.3 * th0       # 70 % below: out of range too
    with pytest.raises(GuardError, match=re.escape(f"particle {ps.gid[b]} ")):
        sim.check()


def test_theta_range_stops_a_run():
    """A real run whose accepted theta change (1e-12 of theta_0) is below what the impulsive start
    produces: the run stops with check 3 within its 10 steps, not with another check."""
    sim = _sim("checks.every=1", "checks.theta_change=1e-12", "output.t_end=1e-4")
    with pytest.raises(GuardError) as e:
        sim.run()
    assert str(e.value).startswith(f"check failed: {CHECKS[3]} at step "), e.value
    assert sim.step <= 10


def test_check_report_by_hand(paper_cfg):
    """check_report on five particles written here: each check's worst particle in CHECKS order as
    the particles are made worse one check at a time; the kinetic energy and mass of the fluid only."""
    from parsph.simulation.guards import N_FASTEST, N_REPORT, check_report, bounds_of
    from parsph.sph.particles import WALL
    cfg = paper_cfg()
    lim = bounds_of(cfg, 4.0)
    assert lim.ke_bound == pytest.approx(0.5 * 4.0 * cfg.V_w ** 2, rel=1e-15)
    assert lim.theta_tol == pytest.approx(cfg.get("checks.theta_change") * cfg.theta0, rel=1e-15)
    kind = np.array([GRAIN, GRAIN, GRAIN, WALL, GRAIN])
    pos = np.array([[1e-3, 0.0], [2e-3, 1e-3], [5e-3, 2e-3], [-5e-4, 0.0], [7e-3, 3e-3]])
    vel = np.array([[0.0, 1.0], [0.3, 0.4], [0.0, -0.5], [0.0, 9.0], [0.0, 0.0]])
    acc = np.zeros((5, 2))
    theta = np.full(5, cfg.theta0)
    jump = np.zeros(5)
    mass = np.array([2.0, 1.0, 1.0, 50.0, 0.0])
    report, fastest = np.zeros(N_REPORT), np.zeros(N_FASTEST)

    def run(n=5):
        return check_report(pos, vel, acc, theta, jump, kind, mass, n, lim, report, fastest)

    assert run() == pytest.approx(0.5 * (2 * 1.0 + 0.25 + 0.25), rel=1e-15)   # the wall's 9 m/s does not count
    assert report[0] == 0 and list(fastest) == [1.0, 0, 4.0]
    jump[1], jump[2] = 1.5 * cfg.h, 2.0 * cfg.h                                # check 5: the longer jump
    run()
    assert list(report) == [5, 2 * cfg.h, 2, pos[2, 0], pos[2, 1], 2 * cfg.h]
    theta[0], theta[4] = 1.6 * cfg.theta0, 0.2 * cfg.theta0                  # check 3 comes first: 0.8 theta_0 off
    run()
    assert list(report[:3]) == [3, pytest.approx(0.8 * cfg.theta0, rel=1e-14), 4] and report[5] == theta[4]
    pos[1, 0], pos[2, 0] = L + 1e-5, -3e-5                                  # check 2: the deeper, below the floor
    run()
    assert list(report[:3]) == [2, pytest.approx(3e-5, rel=1e-12), 2] and report[5] == report[1]
    pos[3, 0] = -1.0                                                         # a wall particle beyond: not check 2
    run()
    assert report[2] == 2
    acc[3, 1] = np.nan                                                       # check 1: any particle, the first
    vel[4, 0] = np.inf
    run()
    assert list(report[:3]) == [1, 1.0, 3]
    assert list(fastest) == [1.0, 0, 4.0]                                  # the non-finite fluid is not fastest
    assert report[0] == 1 and run(3) >= 0 and report[0] == 2                # particles past n are not read


def _first_crossing(comm, every, *extra):
    """The checks.theta_change between two of the deviations an observer reads (numpy, guards.read,
    the largest over the ranks) at the steps checked every ``every`` of the first 24, and the first
    checked step whose deviation exceeds it."""
    from parsph.simulation.guards import read
    devs = []
    cfg = config.load(str(PAPER_TOML), [*SMALL, "output.t_end=2.4e-4", *extra])
    Simulation(cfg, comm).run(observe=lambda s: devs.append(read(s.particles(), s.cfg).theta_dev))
    devs = np.array(devs)
    comm.Allreduce(MPI.IN_PLACE, devs, op=MPI.MAX)
    steps = [s for s in range(1, len(devs)) if s % every == 0]
    values = sorted({devs[s] for s in steps})
    frac = float(0.5 * (values[len(values) // 2 - 1] + values[len(values) // 2]))
    expected = next(s for s in steps if devs[s] > frac)
    assert 0 < expected < len(devs) - 1 and devs[0] < frac
    return frac, expected


def _stopped(comm, every, frac, native, *extra):
    cfg = config.load(str(PAPER_TOML), [*SMALL, "output.t_end=2.4e-4", f"checks.every={every}",
                                        f"checks.theta_change={frac!r}", *extra])
    sim = Simulation(cfg, comm, native=native)
    assert sim.native == (native is None)
    with pytest.raises(GuardError) as e:
        sim.run()
    return e.value.result


@pytest.mark.parametrize("every", [1, 4])
def test_compiled_checks_stop_where_an_observer_sees_the_limit_crossed(every):
    """A run whose checks.theta_change lies between two of the deviations an observer reads: the compiled
    blocks' checks (every ``every`` steps) stop it at the first checked step whose deviation exceeds the
    limit, with the GuardResult of the Python path."""
    frac, expected = _first_crossing(MPI.COMM_SELF, every)
    compiled, python = (_stopped(MPI.COMM_SELF, every, frac, native) for native in (None, False))
    assert compiled == python
    assert compiled.code == 3 and compiled.step == expected


@pytest.mark.mpi(min_size=2)
def test_compiled_checks_on_several_ranks():
    """As above on P ranks (checks every 3 steps, L_y = 4 mm for up to 4 slabs): the step the ranks'
    largest deviation says, the same GuardResult on every rank, on the Python path and on one rank."""
    comm, ly = MPI.COMM_WORLD, "domain.Ly=0.004"
    frac, expected = _first_crossing(comm, 3, ly)
    compiled, python = (_stopped(comm, 3, frac, native, ly) for native in (None, False))
    assert compiled == python and compiled.code == 3 and compiled.step == expected
    assert comm.allgather(compiled) == [compiled] * comm.size
    assert _stopped(MPI.COMM_SELF, 3, frac, None, ly) == compiled


# ---- an observer of the run (what the stability map uses instead of overriding the checks) -----------
def test_observer_sees_every_step_and_changes_nothing():
    """``run(observe=...)`` calls the observer once per step 0..N, before the checks, with read-only
    particles; the run ends bit for bit where a run without one ends; an observer that raises ends it."""
    seen = []

    def observe(sim):
        p = sim.particles()
        assert not p["velocity"].flags.writeable and not p["theta"].flags.writeable
        seen.append((sim.step, p["velocity"].copy()))

    plain, watched = _sim(), _sim()
    plain.run()
    watched.run(observe=observe)
    assert [s for s, _ in seen] == list(range(plain.cfg.nsteps + 1))
    assert np.array_equal(seen[-1][1], plain.particles()["velocity"])
    for f in ("position_raw", "velocity", "theta"):
        assert np.array_equal(plain.particles()[f], watched.particles()[f]), f

    class Stop(Exception):
        pass

    def stop_at_3(sim):
        if sim.step == 3:
            raise Stop
    sim = _sim()
    with pytest.raises(Stop):
        sim.run(observe=stop_at_3)
    assert sim.step == 3


# ---- the criteria read without stopping (guards.read) ----------------------------------------------
def test_read_measures_the_checks_criteria_on_particles_written_here(paper_cfg):
    """Three fluid particles (one 1e-4 m below the floor, one 3e-4 m beyond the plate) and two wall
    particles, whose positions, theta and velocities never count: depth, theta deviation, kinetic
    energy, speed and v_y range by hand, and which criteria fail."""
    from parsph.simulation.guards import read
    from parsph.sph.particles import WALL
    cfg = paper_cfg()
    fields = {"kind": np.array([GRAIN, GRAIN, GRAIN, WALL, WALL]),
              "position": np.array([[-1e-4, 0.0], [L + 3e-4, 1e-3], [5e-3, 2e-3], [-5e-4, 0.0], [L + 1e-3, 0.0]]),
              "velocity": np.array([[0.0, 1.0], [0.3, 0.4], [0.0, -0.5], [0.0, 9.0], [9.0, 0.0]]),
              "theta": np.array([0.35, 0.42, 0.28, 0.9, 0.0]), "mass": np.array([2.0, 1.0, 1.0, 50.0, 50.0])}
    r = read(fields, cfg)
    assert not r.nonfinite
    assert r.depth == pytest.approx(3e-4, rel=1e-12)
    assert r.theta_dev == pytest.approx(0.07 / 0.35, rel=1e-12)
    assert r.kinetic_energy == pytest.approx(0.5 * (2 * 1.0 + 0.25 + 0.25), rel=1e-12) and r.mass == 4.0
    assert r.speed == pytest.approx(1.0, rel=1e-12) and (r.vy_min, r.vy_max) == (-0.5, 1.0)
    # the bound of Couette flow: 1/2 M V_w^2 = 2 J/m, above 1.25
    assert r.failed(cfg, 0.0, 0.1) == {"nonfinite": False, "wall": True, "theta": True, "energy": False}
    assert not r.failed(cfg, 0.0, 0.25)["theta"]
    # against a theta of 0.4 everywhere: the furthest is 0.28, 0.3 of it
    assert read(fields, cfg, theta_ref=lambda x: np.full(len(x), 0.4)).theta_dev == pytest.approx(0.3, rel=1e-12)
    fields["velocity"][3, 0] = np.nan       # a wall particle: does not count
    assert not read(fields, cfg).nonfinite
    fields["velocity"][2, 0] = np.nan       # a fluid particle: non-finite
    assert read(fields, cfg).nonfinite
    fields["theta"][1] = np.inf
    assert read(fields, cfg).theta_dev == math.inf


# ---- check 5: a particle moved more than h in one step (2 ranks) ---------------------------------
@needs_mpirun
def test_particle_jumping_stops_the_run(tmp_path):
    """mpirun -n 2, dt = 1 ms with the override: the plate moves 1 mm = 4h in the first step.
    Exit 3, one "check failed" line naming check 5 and the jump, within the timeout."""
    out = tmp_path / "out"
    sets = []
    for s in [*SMALL, "numerics.dt=1e-3", "numerics.allow_unstable_dt=true", "output.t_end=2e-2",
              "checks.every=20"]:
        sets += ["--set", s]
    r = mpirun(2, launch.PYTHON, "-m", "parsph", "run", PAPER_TOML, *sets, "--out", out, "--quiet", timeout=300)
    assert r.returncode == 3, r
    lines = [ln for ln in r.output.splitlines() if "check failed" in ln]
    assert len(lines) == 1, r
    assert lines[0].startswith(f"parsph: error: check failed: {CHECKS[5]} at step 1, t = 0.001 s"), lines[0]
    m = re.search(r"particle \d+ at x = [0-9.e+-]+ m, y = [0-9.e+-]+ m \(([0-9.e+-]+) m;", lines[0])
    assert m and float(m.group(1)) >= 1e-3, lines[0]  # the worst jump: at least the plate's 1 mm
