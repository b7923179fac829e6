"""The compiled step (parsph.simulation.block, messages through parsph.parallel.native_mpi) against the
Python path (the same numba stages, messages through mpi4py): the same state bit for bit.

Serial tests run every integrator, the auto time step with its landing on output times, the scenes
with walls, without walls (x images), in 3-D (z images) and with the consistent pressure form, on one
rank (the rank is its own neighbour, so every message still goes through MPI). The mpi-marked tests
do the same on 2 and 3 ranks, and check the bindings themselves against mpi4py on a communicator
that is not COMM_WORLD.

    .venv/bin/python -m pytest -q tests/test_compiled_step.py
    mpirun -n 2 .venv/bin/python -m pytest -q --with-mpi -m mpi tests/test_compiled_step.py
"""
import faulthandler
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from parsph.parallel import native_mpi
from parsph.physics import limits
from parsph.setup import config
from parsph.simulation.solver import Simulation

RUN = Path(__file__).resolve().parents[1] / "run"
FIELDS = ("gid", "pos", "vel", "acc", "rho", "theta")
SHORT = "domain.Ly=0.0024"  # 12 rows of the paper lattice: 3 slabs fit their ghost rows

# (run file, overrides): every step variant the compiled block has
CASES = {
    "paper": ("couette_paper.toml", (SHORT, "output.t_end=0.0025")),
    "midpoint": ("couette_paper.toml", (SHORT, "output.t_end=0.0015", 'numerics.integrator="midpoint"')),
    "auto": ("couette_paper.toml", (SHORT, 'numerics.dt="auto"', "output.t_end=0.004",
                                     "output.times=[0.001, 0.0015, 0.004]")),
    "box": ("periodic_box.toml", ("domain.Ly=0.003", "output.t_end=0.002")),
    "settling": ("settling.toml", (SHORT, "output.t_end=0.002")),
    "3d": ("couette_3d.toml", ("output.t_end=0.0003",)),
    # in a gas: explicit drag under the auto rule (its drag limit), and implicit drag with the midpoint scheme
    "box_gas": ("periodic_box.toml", ("domain.Ly=0.003", "output.t_end=0.002", 'gas.drag="wen_yu"',
                                      'gas.flow="column"', "body_force.g=[-9.81, 0.0]", "gas.rho=1000.0",
                                      "gas.mu=1e-3", "material.d=1e-4", "scene.amplitude=2.0",
                                      'numerics.drag_update="explicit"', 'numerics.dt="auto"')),
    "settling_gas": ("settling.toml", (SHORT, "output.t_end=0.002", 'gas.drag="gidaspow"', 'gas.flow="column"',
                                       "gas.U=0.05", 'numerics.integrator="midpoint"')),
    # the layer scenes (floor walls of another mass than the fluid's, a free top): the sedimenting layer under
    # the auto rule, the fluidised bed with the midpoint scheme
    "sedimentation": ("sedimentation.toml", (SHORT, "domain.L=0.004", "numerics.Nx=20", "scene.height=0.002",
                                             "output.t_end=0.05", "output.times=[0.01, 0.05]")),
    "fluidized_bed": ("fluidized_bed.toml", (SHORT, "domain.L=0.004", "numerics.Nx=20", "scene.height=0.0016",
                                             "output.t_end=0.02", "numerics.dt=1e-4",
                                             'numerics.integrator="midpoint"')),
    # the solved gas: the block returns for the gas stage at each evaluation and resumes (the midpoint's middle
    # one, a step's last, a new list's first), Gidaspow's slip-dependent closure under the auto rule
    "bed_solved": ("fluidized_bed.toml", (SHORT, "domain.L=0.004", "numerics.Nx=20", "scene.height=0.0016",
                                          "output.t_end=0.02", 'numerics.integrator="midpoint"', 'gas.flow="solved"',
                                          'gas.drag="gidaspow"', 'numerics.dt="auto"')),
}

WATCHDOG_S = 300  # a rank stuck in a collective ends the job with every thread's traceback


@pytest.fixture(scope="module", autouse=True)
def watchdog():
    faulthandler.dump_traceback_later(WATCHDOG_S, exit=True, file=sys.stderr)
    yield
    faulthandler.cancel_dump_traceback_later()


needs_native = pytest.mark.skipif(not native_mpi.available()[0],
                                  reason=f"no MPI from compiled code here: {native_mpi.available()[1]}")


def run_case(name, comm, native):
    runfile, sets = CASES[name]
    sets = ("output.times=[]",) + sets
    cfg = config.load(RUN / runfile, list(sets))
    sim = Simulation(cfg, comm, native=native)
    assert sim.native == (native is not False)
    outs = []
    sim.run(output=lambda frame, snapshot=None: outs.append((frame.t, frame.step)))
    ps, n = sim.ps, sim.ps.n_own
    mine = {k: getattr(ps, k)[:n] for k in FIELDS}
    every = comm.allgather(mine)
    state = {k: np.concatenate([part[k] for part in every]) for k in FIELDS}
    order = np.argsort(state["gid"])
    state = {k: v[order] for k, v in state.items()}
    return sim, state, outs


def assert_same(a, b):
    sim_a, state_a, outs_a = a
    sim_b, state_b, outs_b = b
    assert (sim_a.step, sim_a.t, sim_a.dt) == (sim_b.step, sim_b.t, sim_b.dt)
    assert sim_a.rebuilds == sim_b.rebuilds
    assert outs_a == outs_b
    for k in FIELDS:
        assert np.array_equal(state_a[k], state_b[k]), k


@needs_native
@pytest.mark.parametrize("name", sorted(CASES))
def test_compiled_equals_python_path(name):
    """One rank: the compiled blocks give the Python path's state, step, t, dt, list builds and outputs."""
    comm = MPI.COMM_SELF
    compiled = run_case(name, comm, native=None)
    python = run_case(name, comm, native=False)
    if not name.startswith("settling"):  # the column barely moves in a short run: no build after the first
        assert compiled[0].rebuilds >= 2, "the case must cross a list build after the first"
    assert_same(compiled, python)


@needs_native
def test_auto_dt_lands_on_output_times():
    """The compiled auto rule lands on every output time exactly (the Python path's rule)."""
    sim, _, outs = run_case("auto", MPI.COMM_SELF, native=None)
    assert [t for t, _ in outs] == [0.001, 0.0015, 0.004]
    steps = [s for _, s in outs]
    assert steps == sorted(set(steps)) and sim.step == steps[-1]


@needs_native
def test_auto_rule_table_holds_the_linear_limits():
    """The blocks' table of linear limits per theta bucket holds, where filled, the limit of
    parsph.physics.limits at the bucket's theta (k THETA_STEP, at most 0.999), and the run filled one."""
    sim, _, _ = run_case("auto", MPI.COMM_SELF, native=None)
    table = sim.blocks.rule.linear
    known = np.flatnonzero(~np.isnan(table))
    assert len(known) >= 1
    for k in known:
        theta = min(k * limits.THETA_STEP, 0.999)
        assert table[k] == min(limits.run_limits(sim.cfg, theta, 0.0, 0.0).values()), k


def test_fallback_is_named():
    """native=False takes the mpi4py path and says so."""
    cfg = config.load(RUN / "couette_paper.toml", [SHORT, "output.times=[]", "output.t_end=0.0002"])
    sim = Simulation(cfg, MPI.COMM_SELF, native=False)
    assert not sim.native and sim.native_why


# ---- several ranks ------------------------------------------------------------------------------
@needs_native
@pytest.mark.mpi(min_size=2)
@pytest.mark.parametrize("name", ["paper", "midpoint", "auto", "box", "settling", "box_gas", "settling_gas",
                                  "sedimentation", "fluidized_bed"])
def test_compiled_on_several_ranks(name):
    """P ranks, compiled blocks: the state of the Python path on the same ranks, and of one rank."""
    comm = MPI.COMM_WORLD
    compiled = run_case(name, comm, native=None)
    python = run_case(name, comm, native=False)
    assert_same(compiled, python)
    one = run_case(name, MPI.COMM_SELF, native=None) if comm.rank == 0 else None
    one = comm.bcast(one[1:] if one else None)
    assert compiled[2] == one[1]
    for k in FIELDS:
        assert np.array_equal(compiled[1][k], one[0][k]), k


@needs_native
@pytest.mark.mpi(min_size=2)
def test_bindings_against_mpi4py():
    """exchange_rows, allreduce and iallreduce + wait on a duplicated communicator: what mpi4py's calls deliver."""
    comm = MPI.COMM_WORLD.Dup()
    try:
        r, P = comm.rank, comm.size
        left, right = (r - 1) % P, (r + 1) % P
        h = native_mpi.handles(comm)
        reqs, stats = native_mpi.requests(4)
        rng = np.random.default_rng(r)
        n_up, n_down = 3 + r, 5 + 2 * r
        up, down = rng.random((n_up + 2, 4)), rng.random((n_down, 4))
        n_below = comm.sendrecv(n_up, dest=right, source=left)
        n_above = comm.sendrecv(n_down, dest=left, source=right)
        below, above = np.zeros((n_below, 4)), np.zeros((n_above + 1, 4))
        err = native_mpi.exchange_rows(h, left, right, 21, 22, up, n_up, down, n_down, below, n_below, above,
                                       n_above, reqs, stats)
        want_below = comm.sendrecv(up[:n_up], dest=right, source=left)
        want_above = comm.sendrecv(down[:n_down], dest=left, source=right)
        checks = {"error code": err == 0, "rows from below": np.array_equal(below, want_below),
                  "rows from above": np.array_equal(above[:n_above], want_above)}
        values = np.array([float(r), -float(r), 0.5 * r])
        for op, mpi_op, label in ((native_mpi.OP_MAX, MPI.MAX, "max"), (native_mpi.OP_SUM, MPI.SUM, "sum")):
            want, out = np.zeros(3), np.zeros(3)
            comm.Allreduce(values, want, op=mpi_op)
            checks[label] = native_mpi.allreduce(h, op, values, out) == 0 and np.array_equal(out, want)
            req, stat = native_mpi.requests(1)
            started = np.full(3, np.nan)
            err = native_mpi.iallreduce(h, op, values, started, req)
            err |= native_mpi.wait(req, stat)
            checks[label + ", started then waited for"] = err == 0 and np.array_equal(started, want)
        failed = comm.allgather(sorted(k for k, ok in checks.items() if not ok))  # every rank asserts alike
        assert not any(failed), failed
    finally:
        comm.Free()


@needs_native
def test_outputs_of_a_bubbling_bed_equal_the_python_paths():
    """run/bubbling_bed.toml (the solved gas, the midpoint scheme, auto dt landing on each output) to 0.08 s,
    outputs every 0.02 s: the compiled blocks' outputs are the Python path's, bit for bit. Between 0.06 and
    0.08 s a list build falls in the middle of a step that lands on an output; the blocks once put that step's
    t back at its start there (the evaluation after the build reset the landing's target)."""
    cfg = config.load(RUN / "bubbling_bed.toml", ["output.times=[0.02, 0.04, 0.06, 0.08]", "output.t_end=0.08",
                                                 "checks.settle=0.04"])
    runs = []
    for native in (None, False):
        sim = Simulation(cfg, MPI.COMM_SELF, native=native)
        outs = []

        def output(frame, snapshot=None, sim=sim, outs=outs):
            n = sim.ps.n_own
            order = np.argsort(sim.ps.gid[:n])
            outs.append((frame.t, sim.step, sim.ps.pos[:n][order].copy(), sim.ps.vel[:n][order].copy()))
        sim.run(output=output)
        runs.append(outs)
    assert [o[:2] for o in runs[0]] == [o[:2] for o in runs[1]]
    assert [o[0] for o in runs[0]] == [0.02, 0.04, 0.06, 0.08]
    for a, b in zip(*runs):
        assert np.array_equal(a[2], b[2]) and np.array_equal(a[3], b[3]), a[0]
