"""Every scene on several ranks against one rank, bit for bit, and restarts across rank counts.

    mpirun -n 2 .venv/bin/python -m pytest -q --with-mpi -m mpi tests/test_mpi_scenes.py
    mpirun -n 3 --oversubscribe .venv/bin/python -m pytest -q --with-mpi -m mpi tests/test_mpi_scenes.py
    .venv/bin/python -m pytest -q tests/test_mpi_scenes.py      # the threaded case (launches mpirun -n 2)

test_mpi_parallel.py does this for the 2-D paper case; here the other scenes,
each in a short box that 3 slabs fit (scene_ranks.CASES): 3-D Couette (the z
images), the periodic box with pressure on (x images of the y-ghosts, corner
copies), the settling column (gravity, walls whose theta varies, the
consistent pressure form; driven along y as well, so that it crosses slab
edges), Poiseuille flow (a body force along y), and two in a gas: the periodic box falling through a
stream along y (Gidaspow, implicit drag) and the settling column sheared by a stream of water along y
(Wen & Yu, explicit drag), and the layer scenes: the sedimenting layer and the fluidised bed in water (a free
top with the lattice empty above it, floor walls holding the end state's theta and mass), and both again in
the solved gas (the grid's deposits summed over the ranks, its pressure solved on each), the bed also between
side walls (walls.sides: their rows across the ring's seam, the grid's y closed). The fluid gets a random
velocity (a function of the global id, the same on every rank count), so that
particles leave the lattice and cross slab edges and the periodic boundaries
in x and z. Compared after the run, sorted by global id: the state (position,
velocity) and the rates of the last evaluation (acceleration, density,
theta), with ``np.array_equal``; each run is checked to have rebuilt its list
after the first build and to have migrated particles between ranks.
Restarts: 3-D Couette, the periodic box, the box in a gas, the two layer scenes and the bed in the solved gas,
P -> 1 and 1 -> P ranks. Threads: the same six and the bed between side walls on ``mpirun -n 2`` with 2
threads per rank
against 1 rank with 1 thread (a launched job: the MPI phases run 1 thread).

The one-rank reference runs on rank 0 on COMM_SELF inside the same job
while the other ranks wait; every assertion is taken on every rank from
broadcast data. Only the public API: ``Simulation(cfg, comm, state)``,
``run(output, observe=...)``, ``particles()``, ``ps`` (owned rows),
``rebuilds``, the output writer and ``read_state``.
"""
import faulthandler
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from parsph.sph.particles import GRAIN

from mpi_helpers import launch  # noqa: E402
from mpi_helpers.scene_ranks import CASES, differences, idle_wait, load, run_scene, state  # noqa: E402

HELPER = Path(__file__).resolve().parent / "mpi_helpers" / "scene_ranks.py"
WATCHDOG_S = 240


def on_rank0(comm, work):
    """``work()`` on rank 0 while the others wait; its result (or its error) broadcast to every rank."""
    result = None
    if comm.rank == 0:
        try:
            result = work()
        except Exception as e:  # noqa: BLE001 - every rank must learn of it
            result = {"error": f"{type(e).__name__}: {e}"}
    idle_wait(comm)
    result = comm.bcast(result, root=0)
    if isinstance(result, dict) and "error" in result:
        pytest.fail(f"the one-rank run on rank 0 failed: {result['error']}")
    return result


@pytest.fixture(scope="module", autouse=True)
def watchdog():
    """Under mpirun: end a rank stuck in a collective call (a hang) with a traceback of every thread."""
    if not launch.under_mpirun():
        yield
        return
    faulthandler.dump_traceback_later(WATCHDOG_S, exit=True, file=sys.stderr)
    yield
    faulthandler.cancel_dump_traceback_later()


# ---- every scene, P ranks against one -------------------------------------------------------------------
@pytest.mark.mpi(min_size=2)
@pytest.mark.parametrize("scene", sorted(CASES))
def test_scene_bit_for_bit_on_several_ranks(scene):
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    cfg = load(scene)
    amplitude = CASES[scene][2]
    sim, moves = run_scene(cfg, comm, amplitude)
    par = state(sim)
    rebuilt = comm.allreduce(moves.rebuilds, op=MPI.MIN)
    migrated = comm.allreduce(moves.left)

    def reference():
        one, _ = run_scene(cfg, MPI.COMM_SELF, amplitude)
        ref = state(one)
        fluid = ref["kind"] == GRAIN
        return {"diff": differences(par, ref), "clock": [one.step, one.t, one.dt],
                "n": [len(par["gid"]), len(ref["gid"])], "moved": float(np.abs(ref["vel"][fluid]).max())}
    v = on_rank0(comm, reference)
    assert v["n"][0] == v["n"][1] == sim.n_total == cfg.n_particles
    assert v["clock"] == [sim.step, sim.t, sim.dt], "step count, time or last dt differ from the 1-rank run"
    assert rebuilt >= 2, f"the list was built {rebuilt} times: no rebuild after the first build"
    assert migrated > 0, "no particle changed rank: migration is not covered"
    assert v["moved"] > 0.01
    assert not v["diff"], f"{scene} on {comm.size} ranks differs from 1 rank (max |diff| per field): {v['diff']}"


# ---- restart across rank counts -----------------------------------------------------------------------
@pytest.mark.mpi(min_size=2)
@pytest.mark.parametrize("scene", ["couette_3d", "periodic_box", "box_gas", "sedimentation", "fluidized_bed",
                                   "fluidized_bed_solved", "fluidized_bed_solved_3d"])
def test_restart_across_rank_counts(scene, mpi_tmp_path):
    """A snapshot halfway, written on P ranks and on 1, continued on the other count: both end bit for
    bit where the uninterrupted runs end (which agree with each other)."""
    from mpi4py import MPI
    from parsph.output import Output, read_state
    comm = MPI.COMM_WORLD
    steps = CASES[scene][3]
    base = load(scene)
    assert not base.dt_auto
    t_half = round(steps // 2 * base.dt, 12)
    cfg = load(scene, f"output.times=[{t_half!r}]")
    amplitude = CASES[scene][2]
    many, one = mpi_tmp_path / "written_on_P", mpi_tmp_path / "written_on_1"
    if comm.rank == 0:
        many.mkdir()
        one.mkdir()
    comm.Barrier()
    sim, _ = run_scene(cfg, comm, amplitude, output=Output(comm, str(many), "s", cfg, cfg.n_particles))
    whole_p = state(sim)

    def written_on_one():
        one_sim, _ = run_scene(cfg, MPI.COMM_SELF, amplitude,
                               output=Output(MPI.COMM_SELF, str(one), "s", cfg, cfg.n_particles))
        return one_sim.step
    assert on_rank0(comm, written_on_one) == steps
    # 1 -> P: every rank reads its slab of the file the one-rank run wrote
    snap = read_state(str(one / "s_0000.h5"))
    assert int(snap["attrs"]["step"]) == steps // 2
    resumed, _ = run_scene(cfg, comm, amplitude, state_in=snap)
    from_one = state(resumed)

    def continue_on_one():
        # P -> 1: the one-rank run reads the whole file the P-rank run wrote
        back, _ = run_scene(cfg, MPI.COMM_SELF, amplitude, state_in=read_state(str(many / "s_0000.h5")))
        ref = state(back)
        return {"P_vs_1_restart": differences(whole_p, ref), "1_to_P_vs_1_restart": differences(from_one, ref),
                "steps": back.step}
    v = on_rank0(comm, continue_on_one)
    assert v["steps"] == resumed.step == sim.step == steps
    assert not v["P_vs_1_restart"], f"{scene}: P -> 1 restart differs from the uninterrupted P-rank run: " \
                                    f"{v['P_vs_1_restart']}"
    assert not v["1_to_P_vs_1_restart"], f"{scene}: 1 -> {comm.size} restart differs: {v['1_to_P_vs_1_restart']}"


# ---- threads on several ranks (a launched mpirun: the MPI phases run one thread per rank) ---------------
@pytest.mark.skipif(launch.under_mpirun(), reason="launches mpirun itself (nested mpirun fails)")
@pytest.mark.parametrize("scene", ["couette_3d", "periodic_box", "box_gas", "sedimentation", "fluidized_bed",
                                   "fluidized_bed_solved", "fluidized_bed_sides"])
def test_threads_on_two_ranks_bit_for_bit(scene):
    """``mpirun -n 2`` with 2 numba threads per rank (NUMBA_NUM_THREADS=2 set for the job, so this
    runs on a one-core machine too) against one rank with one thread, bit for bit."""
    r = launch.run(launch.mpirun_cmd(2, launch.PYTHON, HELPER, scene), timeout=240, shared_cache=True,
                   NUMBA_NUM_THREADS="2")
    assert r.returncode == 0, r
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("verdict ")]
    assert len(lines) == 1, r
    v = json.loads(lines[0][len("verdict "):])
    assert v["threads"] == [2, 1]
    assert v["clock_equal"] and v["n"][0] == v["n"][1]
    assert v["rebuilt"] >= 2 and v["migrated"] > 0
    assert not v["diff"], f"{scene}: 2 ranks x 2 threads differ from 1 rank x 1 thread: {v['diff']}"
