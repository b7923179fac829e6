"""Several ranks against one: bit-for-bit rank independence, conservation through migration, and the
switch of equal masses that every rank must agree on.

Run under mpirun (pytest-mpi), e.g.

    mpirun -n 2 .venv/bin/python -m pytest -q --with-mpi -m mpi tests/test_mpi_parallel.py
    mpirun -n 3 --oversubscribe .venv/bin/python -m pytest -q --with-mpi -m mpi tests/test_mpi_parallel.py

Without ``--with-mpi`` (a plain serial pytest run) every test here is skipped.
Every assertion is taken on every rank from the same broadcast data, so all
ranks pass or fail a test alike and no rank is left waiting in a collective.
A watchdog ends a rank that is stuck (a hang in a collective call) after
WATCHDOG_S seconds with a traceback of every thread, which ends the job.
"""
import faulthandler
import math
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from parsph.setup import config
from parsph.sph.particles import GRAIN, MOVING_WALL, WALL
from parsph.errors import DecompositionError
from parsph.parallel.slabs import min_length
from parsph.sph.cells import CELLS_PER_CUTOFF
from parsph.simulation.solver import Simulation

PAPER = Path(__file__).resolve().parents[1] / "run" / "couette_paper.toml"
DX = 2.0e-4       # lattice spacing of the paper [m]
CUTOFF = 2.4 * 2.5e-4  # neighbour-list cutoff 2h + skin of the paper case (skin 0.4 h)


def short_rows(P, least=8):
    """Lattice rows of a short box: ``least``, more where P slabs need more for their ghost rows."""
    return max(least, math.ceil(min_length(P, CUTOFF, CELLS_PER_CUTOFF) / DX - 1e-9))

WATCHDOG_S = 150  # the whole module takes 10-25 s on 2-3 ranks

pytestmark = pytest.mark.mpi(min_size=2)


@pytest.fixture(scope="module", autouse=True)
def watchdog():
    faulthandler.dump_traceback_later(WATCHDOG_S, exit=True, file=sys.stderr)
    yield
    faulthandler.cancel_dump_traceback_later()


def load(*overrides):
    return config.load(PAPER, ["output.times=[]", *overrides])


def idle_wait(comm):
    """Wait for rank 0 without busy-polling (the tests share two cores with rank 0's serial run)."""
    req = comm.Ibarrier()
    while not req.Test():
        time.sleep(0.005)


def gathered_state(sim):
    """Every particle's state on rank 0, sorted by gid (None elsewhere)."""
    ps = sim.ps
    n = ps.n_own
    mine = {k: getattr(ps, k)[:n].copy() for k in ("gid", "kind", "mass", "pos", "vel", "acc", "rho", "theta")}
    parts = sim.comm.gather(mine, root=0)
    if parts is None:
        return None
    out = {k: np.concatenate([p[k] for p in parts]) for k in mine}
    order = np.argsort(out["gid"], kind="stable")
    return {k: v[order] for k, v in out.items()}


def compare_with_one_rank(cfg, comm):
    """Run cfg on ``comm`` and, on rank 0, on COMM_SELF; broadcast a comparison to every rank."""
    sim = Simulation(cfg, comm)
    sim.run(output=None)
    prof = sim.profile()
    par = gathered_state(sim)
    verdict = None
    if comm.rank == 0:
        try:
            verdict = _compare(cfg, sim, par, prof)
        except Exception as e:  # noqa: BLE001 - every rank must learn of it
            verdict = {"error": f"{type(e).__name__}: {e}"}
    else:
        idle_wait(comm)
    if comm.rank == 0:
        idle_wait(comm)
    verdict = comm.bcast(verdict, root=0)
    if "error" in verdict:
        pytest.fail(f"the 1-rank reference run on rank 0 failed: {verdict['error']}")
    return verdict


def _compare(cfg, sim, par, prof):
    """On rank 0: the 1-rank run and its comparison with the gathered P-rank state."""
    one = Simulation(cfg, MPI.COMM_SELF)
    one.run(output=None)
    ref = gathered_state(one)
    prof1 = one.profile()
    verdict = {"n_par": len(par["gid"]), "n_one": len(ref["gid"]), "n_total": sim.n_total,
               "gid": np.array_equal(par["gid"], ref["gid"]),
               "kind": np.array_equal(par["kind"], ref["kind"]),
               "clock": (sim.step, sim.t, sim.dt) == (one.step, one.t, one.dt), "steps": one.step}
    for k in ("pos", "vel", "acc", "rho", "theta", "mass"):
        same_shape = par[k].shape == ref[k].shape
        verdict[k] = same_shape and np.array_equal(par[k], ref[k])
        verdict[k + "_maxdiff"] = float(np.max(np.abs(par[k] - ref[k]))) if same_shape else math.inf
    verdict["moved"] = float(np.max(np.abs(ref["vel"][ref["kind"] == GRAIN])))
    verdict["prof_x"] = np.array_equal(prof["x"], prof1["x"])
    verdict["prof_count"] = np.array_equal(prof["count"], prof1["count"])
    vy, vy1 = prof["vy"], prof1["vy"]
    verdict["prof_vy_rel"] = float(np.max(np.abs(vy - vy1) / np.maximum(np.abs(vy1), 1e-300)))
    verdict["prof_vy_abs"] = float(np.max(np.abs(vy - vy1)))
    verdict["prof_vy_equal"] = np.array_equal(vy, vy1)
    verdict["prof_err"] = (prof["err"], prof1["err"])
    verdict["prof_vy_scale"] = float(np.max(np.abs(vy1)))
    th, th1 = prof["theta"], prof1["theta"]
    verdict["prof_theta_rel"] = float(np.max(np.abs(th - th1) / np.abs(th1)))
    verdict["prof_exact"] = all(np.array_equal(prof[k], prof1[k], equal_nan=True)
                                for k in ("vy_exact", "theta_exact"))
    return verdict


# ---- (a) rank independence ----------------------------------------------------------------
@pytest.fixture(scope="module")
def paper_verdict():
    """The paper case for 300 steps (t = 0.003 s) on all ranks and on one."""
    return compare_with_one_rank(load("output.t_end=0.003"), MPI.COMM_WORLD)


def test_same_particles(paper_verdict):
    v = paper_verdict
    assert v["n_par"] == v["n_one"] == v["n_total"] == 2800
    assert v["gid"] and v["kind"] and v["mass"]
    assert v["clock"] and v["steps"] == 300


def test_fluid_has_moved(paper_verdict):
    """Guard against a vacuous comparison: the flow has started."""
    assert paper_verdict["moved"] > 0.05


@pytest.mark.parametrize("field", ["pos", "vel"])
def test_bit_for_bit_state(paper_verdict, field):
    v = paper_verdict
    assert v[field], f"{field} differs from the 1-rank run by up to {v[field + '_maxdiff']:.3e}"


@pytest.mark.parametrize("field", ["rho", "theta", "acc"])
def test_bit_for_bit_rates(paper_verdict, field):
    """Density, volume fraction and acceleration of the last evaluation, per particle."""
    v = paper_verdict
    assert v[field], f"{field} differs from the 1-rank run by up to {v[field + '_maxdiff']:.3e}"


def test_profile_matches_one_rank(paper_verdict):
    """The all-reduced profiles: bins and counts exact, v_y and theta to 1e-14 relative (sums in
    rank order), the references identical."""
    v = paper_verdict
    assert v["prof_x"] and v["prof_count"]
    assert v["prof_vy_rel"] <= 1e-14 or v["prof_vy_abs"] <= 1e-14 * v["prof_vy_scale"], \
        (v["prof_vy_rel"], v["prof_vy_abs"])
    assert v["prof_theta_rel"] <= 1e-14, v["prof_theta_rel"]  # theta(x), summed the same way
    assert v["prof_exact"]
    e, e1 = v["prof_err"]
    assert e[0] == pytest.approx(e1[0], rel=1e-12, abs=1e-15)
    assert e[1] == pytest.approx(e1[1], rel=1e-12, abs=1e-15)


def test_bit_for_bit_thinnest_slabs():
    """The thinnest slabs the ghost rows allow (a neighbour's slab is mostly ghosts), the wall wrapping."""
    comm = MPI.COMM_WORLD
    Ly = short_rows(comm.size, least=1) * DX
    cfg = load(f"domain.Ly={Ly!r}", "output.t_end=0.003")
    if comm.size > 1:
        thinner = load(f"domain.Ly={Ly - DX!r}", "output.t_end=0.003")
        with pytest.raises(DecompositionError):
            Simulation(thinner, comm)
    v = compare_with_one_rank(cfg, comm)
    assert v["gid"] and v["kind"] and v["n_par"] == v["n_one"]
    for k in ("pos", "vel", "rho", "theta", "acc"):
        assert v[k], f"{k} differs from the 1-rank run by up to {v[k + '_maxdiff']:.3e}"


def test_bit_for_bit_midpoint_auto_dt_symmetric():
    """Midpoint integrator (its saved state migrates with the particles when a rebuild falls between its
    two evaluations), dt = "auto" (recomputed every step from all-reduced maxima) and the symmetric
    viscosity, on a short box where the moving wall wraps 1.5 times: still bit for bit."""
    comm = MPI.COMM_WORLD
    rows = short_rows(comm.size, least=10)
    cfg = load(f"domain.Ly={rows * DX!r}", "output.t_end=0.003", "numerics.integrator=midpoint",
               'numerics.dt="auto"', "numerics.viscosity_form=symmetric")
    assert cfg.dt_auto and cfg.integrator == "midpoint"
    v = compare_with_one_rank(cfg, comm)
    assert v["clock"], "step count, time or last dt differ from the 1-rank run"
    assert v["steps"] >= 20  # dt about 1e-4 s (the midpoint scheme's linear limit, parsph.physics.limits)
    assert v["gid"] and v["kind"] and v["n_par"] == v["n_one"]
    assert v["moved"] > 0.05
    for k in ("pos", "vel", "rho", "theta", "acc"):
        assert v[k], f"{k} differs from the 1-rank run by up to {v[k + '_maxdiff']:.3e}"


# ---- (b) conservation through migration -----------------------------------------------------
def test_conservation_through_migration():
    """A short box, V_w = 1 m/s: the wall wraps 4.5 times.

    After every step: the global count and the mass are exact, every gid is owned
    exactly once, with its kind and mass unchanged; after every rebuild of the
    neighbour list (the only time particles migrate) by the rank whose slab holds its y.
    """
    comm = MPI.COMM_WORLD
    rows = short_rows(comm.size)
    Ly = rows * DX
    t_end = round(4.5 * Ly, 12)              # V_w = 1 m/s: 4.5 wraps, ending half a box from the start
    cfg = load(f"domain.Ly={Ly!r}", "walls.V_w=1.0", f"output.t_end={t_end!r}", "numerics.dt=1.0e-5")
    assert cfg.dt <= min(cfg.limits.values())
    assert cfg.V_w * t_end >= 4 * Ly
    sim = Simulation(cfg, comm)
    ring, ps = sim.ring, sim.ps

    def snapshot():
        n = ps.n_own
        ids = np.column_stack([ps.gid[:n], ps.kind[:n], np.full(n, comm.rank)])
        return ids, ps.mass[:n].copy(), ps.pos[:n, 1].copy()

    def everyone(ids, mass):
        parts = comm.allgather((ids, mass))
        all_ids = np.concatenate([p[0] for p in parts])
        all_mass = np.concatenate([p[1] for p in parts])
        o = np.argsort(all_ids[:, 0], kind="stable")
        return all_ids[o], all_mass[o]

    ref_ids, ref_mass = everyone(*snapshot()[:2])
    owner = ref_ids[:, 2].copy()
    ref_ids = ref_ids[:, :2]
    N0 = len(ref_ids)
    M0 = math.fsum(ref_mass)
    assert N0 == sim.n_total == rows * 56
    assert len(np.unique(ref_ids[:, 0])) == N0

    failures = []
    moves = {GRAIN: 0, WALL: 0, MOVING_WALL: 0}
    for _ in range(cfg.nsteps):
        rebuilds = sim.rebuilds
        sim.compute_rates()
        rebuilt = sim.rebuilds > rebuilds
        ids, mass, y = snapshot()
        sim.integrate(sim.dt)
        n_global = comm.allreduce(ps.n_own)
        plain = comm.allreduce(float(np.sum(mass)))       # the plain sum over ranks
        all_ids, all_mass = everyone(ids, mass)
        in_slab = comm.allreduce(bool(not rebuilt or np.all((y >= ring.lo) & (y < ring.hi))), op=MPI.LAND)
        problems = []
        if n_global != N0:
            problems.append(f"count {n_global} != {N0}")
        if len(all_ids) != N0 or not np.array_equal(all_ids[:, :2], ref_ids):
            problems.append("gid/kind set changed (lost, duplicated or altered particles)")
        else:
            if not np.array_equal(all_mass, ref_mass):
                problems.append("a particle's mass changed")
            hops = (all_ids[:, 2] - owner) % comm.size  # slab edges crossed upward (the wall moves up)
            for kind in moves:
                moves[kind] += int(hops[ref_ids[:, 1] == kind].sum())
            owner = all_ids[:, 2].copy()
        if math.fsum(all_mass) != M0:                      # exact, order-independent
            problems.append(f"total mass {math.fsum(all_mass)!r} != {M0!r}")
        if not math.isclose(plain, M0, rel_tol=1e-13):
            problems.append(f"summed mass {plain!r} != {M0!r}")
        if not in_slab:
            problems.append("a rank owns a particle outside its slab")
        if problems:
            failures.append((sim.step, problems))
            if len(failures) >= 3:
                break
    assert not failures, failures
    assert sim.step == cfg.nsteps
    sim.compute_rates()
    sim.check()  # still finite and inside the channel
    # the moving wall really went round: each of its 3 * rows particles crossed every slab edge 4 times
    assert moves[MOVING_WALL] >= 3 * rows * 4 * comm.size, moves
    assert moves[WALL] == 0, moves
    # every moving-wall particle travelled V_w t_end: its y is (y0 + V_w t) mod Ly, to rounding
    ncol = cfg.Nx + 2 * cfg.layers
    errs = []
    for gid, kind, y in zip(ps.gid[:ps.n_own], ps.kind[:ps.n_own], ps.pos[:ps.n_own, 1]):
        if kind == MOVING_WALL:
            y0 = (gid // ncol + 0.5) * cfg.dy
            d = (y - (y0 + cfg.V_w * t_end)) % Ly
            errs.append(min(d, Ly - d))
    worst = comm.allreduce(max(errs, default=0.0), op=MPI.MAX)
    assert worst < 1e-12


def test_kinds_counts_conserved():
    """The three kinds keep their counts over a short wrapping run (fluid 50, walls 3 + 3 per row)."""
    comm = MPI.COMM_WORLD
    rows = short_rows(comm.size)
    cfg = load(f"domain.Ly={rows * DX!r}", "output.t_end=0.002")
    sim = Simulation(cfg, comm)
    sim.run(output=None)
    k = sim.ps.kind[:sim.ps.n_own]
    counts = comm.allreduce(np.array([(k == GRAIN).sum(), (k == WALL).sum(), (k == MOVING_WALL).sum()]))
    assert counts.tolist() == [rows * 50, rows * 3, rows * 3]


# ---- (c) the switch of equal masses ---------------------------------------------------------
def test_equal_masses_agreed_by_every_rank():
    """The serial passes load no mass only where every particle on every rank has the same one: one
    heavier particle in the last rank's slab turns that off on all ranks."""
    comm = MPI.COMM_WORLD
    cfg = load()
    gid, kind, mass, pos, vel = cfg.scene.particles(cfg, 0.0, cfg.Ly)
    state = {"id": gid, "kind": kind, "mass": mass, "position": pos, "velocity": vel,
             "attrs": {"step": 0, "time": 0.0, "dt": cfg.dt}}
    sim = Simulation(cfg, comm, state=state)
    equal = comm.allgather((sim.rates.switches.uniform_mass, sim.rates.consts.mass))
    assert equal == [((1,), mass[0])] * comm.size
    heavy = mass.copy()
    top = int(np.argmax(pos[:, 1]))  # in the last rank's slab
    heavy[top] *= 1.5
    sim = Simulation(cfg, comm, state={**state, "mass": heavy})
    holds = bool(np.any(sim.ps.mass[:sim.ps.n_own] != mass[0]))
    unequal = comm.allgather((holds, sim.rates.switches.uniform_mass))
    assert unequal == [(False, ())] * (comm.size - 1) + [(True, ())]
