"""Stopping a run: SIGINT / SIGTERM end it with a restart point; SIGKILL leaves only whole outputs.

    .venv/bin/python -m pytest -q tests/test_interrupt.py
    mpirun -n 2 .venv/bin/python -m pytest -q --with-mpi -m mpi tests/test_interrupt.py

The serial tests launch real runs (1 rank, and ``mpirun -n 2``) and are
skipped inside an mpirun job; the test marked ``mpi`` stops a run in process
on COMM_WORLD (pytest-mpi).

What Open MPI 4.1's ``mpirun`` does with a signal (measured here; it decides
what the ranks see):

* SIGINT or SIGTERM to ``mpirun``: it sends SIGCONT to the ranks at once,
  SIGTERM one second later (``odls_base_sigkill_timeout`` = 1 s), and SIGKILL
  after one more second to ranks still alive. So parsph sees SIGTERM even for
  a Ctrl-C, has one second to finish its step and write the final snapshot,
  and ``mpirun`` exits 1 (the ranks' 143 is not passed on). Measured on the
  short box: snapshot complete 0.2 s after the ranks' SIGTERM (1.2 s after
  the signal to mpirun); the ranks then need about 1.5 s more to exit
  (teardown), so mpirun's SIGKILL at 2.0 s ends them after the snapshot but
  before they exit by themselves. A step plus an output that take longer
  than one second (large runs, or a loaded machine) would lose the final
  snapshot (``--mca odls_base_sigkill_timeout N`` lengthens the grace; the
  tests set it to MPIRUN_GRACE, so that a slow machine does not fail them).
  The ranks have process groups of their own, so a terminal's Ctrl-C reaches
  only ``mpirun``.
* SIGINT/SIGTERM sent to the ranks themselves (a batch system, ``kill``):
  parsph exits 130 / 143 on every rank and ``mpirun`` passes the code on.
* SIGKILL to ``mpirun``'s process group does not reach the ranks (they lived
  about 1.5 s longer); the SIGKILL tests kill mpirun and every rank by id.

Long runs: t_end = 0.5 s on the short box (50 000 steps, minutes), with no
output before the end, stopped after the first progress line. How many steps
run before the ranks see the signal depends on the machine (and mpirun
passes it on MPIRUN_GRACE late), so each restart goes to a time just
past the step where its run stopped and is compared with an uninterrupted
1-rank run to that same time.

No test asserts how fast a run stops: the waits below are hang guards, set for
a slow, loaded CI machine. ``scripts/signal_timing.py`` measures the times.
"""
import os
import re
import time

import h5py
import numpy as np
import pytest

from reliability_helpers import common as C  # noqa: E402

launches = pytest.mark.skipif(C.under_mpirun(), reason="launches parsph/mpirun itself (nested mpirun fails)")

# long enough that no run ends before the signal reaches its ranks (mpirun forwards it MPIRUN_GRACE later):
# 500,000 steps, over a minute at 5,000 steps a second
LONG_T_END = 5.0
LONG = (*C.SHORT, f"output.t_end={LONG_T_END}", f"output.times=[{LONG_T_END}]", "output.progress_interval=0.05")
RESUME_STEPS = 100  # a restart runs this many steps past the stop
STOPPED = re.compile(r"^parsph: (SIG[A-Z]+|signal): stopped at step (\d+), t = (\S+) s; "
                     r"the last output is a restart point$")
CODE = {"SIGINT": 130, "SIGTERM": 143}
HANG_GUARD = 300  # s: from the signal to the end of every process, and from the start to the first
                  # progress line (a cold numba cache compiles first); beyond it the test fails as a hang
MPIRUN_GRACE = 5  # s: mpirun's delay from a signal to SIGTERM to the ranks, and on to SIGKILL
                  # (odls_base_sigkill_timeout; 1 s by default, in which a loaded machine may not write;
                  # 25 times the 0.2 s the snapshot takes). A test of a signal to mpirun waits about twice
                  # this (the ranks run on until the SIGTERM, and are killed in their teardown)


def name(k):
    return f"{C.STEM}_{k:04d}.h5"


def resume_sets(step):
    """Run-file overrides that end a run RESUME_STEPS steps after ``step``."""
    t_end = round((step + RESUME_STEPS) * C.DT, 10)
    return C.sets(*C.SHORT, f"output.t_end={t_end!r}", f"output.times=[{t_end!r}]")


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """reference(step): an uninterrupted 1-rank run to RESUME_STEPS past ``step`` (the restarts must equal it)."""
    def run_to(step):
        d = tmp_path_factory.mktemp("interrupt_ref")
        r = C.run(C.run_cmd(0, "--out", d, "--quiet", *resume_sets(step)), timeout=HANG_GUARD)
        assert r.returncode == 0, r
        return C.read_final(d / name(0))
    return run_to


def interrupted_run(ranks, out, send, **env):
    """Start a long run, wait for its first progress line, call send(live); return the result."""
    live = C.Live(C.run_cmd(ranks, "--out", out, *C.sets(*LONG)), **env)
    try:
        started = live.wait_for(lambda: any(ln.startswith("  step") for ln in live.out), HANG_GUARD)
        assert started, f"no progress line within {HANG_GUARD} s: {live.finish(1)[0]}"
        send(live)
        res, timed_out = live.finish(HANG_GUARD)
        assert not timed_out, f"still running {HANG_GUARD} s after the signal (killed):\n{res}"
        return res
    finally:
        live.kill()


def check_stopped(res, out, signame=None):
    """One stop line; the final snapshot it names exists, whole, at that step. Returns the step."""
    assert "Traceback" not in res.stderr, res
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("parsph")]
    assert len(lines) == 1, res
    m = STOPPED.match(lines[0])
    assert m, f"unexpected stop message: {lines[0]!r}"
    if signame is not None:
        assert m.group(1) == signame, f"the message names {m.group(1)}, not {signame}: {lines[0]!r}"
    step = int(m.group(2))
    files = C.h5_files(out)
    assert files == [name(0)], f"outputs after the stop: {os.listdir(out)}"
    assert not C.h5_files(out, part=True), os.listdir(out)
    snap = C.read_final(out / name(0))
    assert snap["attrs"]["step"] == step, (snap["attrs"]["step"], step)
    assert snap["attrs"]["time"] == pytest.approx(step * C.DT, rel=1e-12)
    assert np.array_equal(snap["id"], np.arange(C.N_SHORT))
    assert 0 < step < round(LONG_T_END / C.DT), f"stopped at step {step}: the run was not stopped early"
    return step


def resume(ranks, out, reference, step):
    """--restart from the stopped run's directory, RESUME_STEPS on; equal to the uninterrupted run."""
    r = C.run(C.run_cmd(ranks, "--restart", out, "--quiet", *resume_sets(step)), timeout=HANG_GUARD)
    assert r.returncode == 0, r
    assert C.h5_files(out) == [name(0), name(1)], os.listdir(out)
    C.assert_same_particles(C.read_final(out / name(1)), reference(step), "stopped run continued with --restart")


# ---- SIGINT / SIGTERM ------------------------------------------------------------------------

@launches
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_signal_to_a_one_rank_run(tmp_path, reference, signame):
    """Without mpirun: exit 130 / 143, one line naming the signal, a final snapshot; then restart."""
    out = tmp_path / "run"
    res = interrupted_run(0, out, lambda live: live.p.send_signal(getattr(C.signal, signame)))
    assert res.returncode == CODE[signame], res
    step = check_stopped(res, out, signame)
    assert C.stderr_lines(res.stderr) == C.parsph_lines(res.stderr), res
    resume(0, out, reference, step)


@launches
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_signal_to_mpirun(tmp_path, reference, signame):
    """SIGINT / SIGTERM to ``mpirun -n 2``: every rank finishes its step and writes the final snapshot.

    mpirun turns the signal into SIGTERM to the ranks MPIRUN_GRACE later and
    SIGKILLs them MPIRUN_GRACE after that: the snapshot must be written within
    that grace. mpirun's exit code is its own (1 with Open MPI 4.1): only
    non-zero is asserted.
    """
    out = tmp_path / "run"
    res = interrupted_run(2, out, lambda live: live.p.send_signal(getattr(C.signal, signame)),
                          OMPI_MCA_odls_base_sigkill_timeout=MPIRUN_GRACE)
    assert res.returncode != 0, res
    step = check_stopped(res, out)  # the ranks got SIGTERM from mpirun, whatever mpirun got
    resume(2, out, reference, step)


@launches
def test_sigterm_to_every_rank(tmp_path, reference):
    """SIGTERM to each rank (as a batch system does): exit 143 through mpirun, one line, restart works."""
    out = tmp_path / "run"

    def send(live):
        pids = C.rank_pids(live.p.pid)
        assert sorted(pids) == [0, 1], pids
        for p in pids.values():
            os.kill(p, C.signal.SIGTERM)

    res = interrupted_run(2, out, send)
    assert res.returncode == 143, res
    step = check_stopped(res, out, "SIGTERM")
    resume(1, out, reference, step)


@launches
def test_sigint_to_one_rank_stops_every_rank_alike(tmp_path, reference):
    """SIGINT to the last rank only: the stop is agreed, so every rank writes, names SIGINT and exits 130.

    The stop flag reaches rank 0 through the per-step all-reduce; rank 0 prints
    the message, so the signal's name (and the exit code) must travel with it.
    """
    out = tmp_path / "run"

    def send(live):
        pids = C.rank_pids(live.p.pid)
        assert sorted(pids) == [0, 1], pids
        os.kill(pids[1], C.signal.SIGINT)

    res = interrupted_run(2, out, send)
    step = check_stopped(res, out, "SIGINT")
    assert res.returncode == 130, res
    resume(2, out, reference, step)


# ---- SIGKILL ------------------------------------------------------------------------------------

KILL_EVERY = 2  # steps between outputs: a write (~25 ms for 672 particles) outlasts the 2 steps between
KILLED = (*C.SHORT, "output.t_end=0.5",
          C.times_list(np.round(np.arange(1, 2001) * KILL_EVERY * C.DT, 10)), "output.progress_interval=0")
KILL_AFTER = 3  # complete outputs before the watch for a .part starts
KILL_TRIES = 3  # runs started until a kill lands inside a write (the first one does, as a rule)


def check_output_file(path, index):
    """A complete output, read with nothing but h5py: attributes, profile and full particle arrays."""
    with h5py.File(path, "r") as f:
        a = f.attrs
        assert int(a["index"]) == index, (path, a["index"])
        step = int(a["step"])
        assert step == (index + 1) * KILL_EVERY, (path, step)
        assert a["time"] == pytest.approx(step * C.DT, rel=1e-12)
        assert int(a["n_particles"]) == C.N_SHORT
        assert f["profile/vy"].shape == (50,) and np.isfinite(f["profile/vy"][()]).all()
        g = f["particles"]
        ids = g["id"][()]
        assert np.array_equal(np.sort(ids), np.arange(C.N_SHORT)), f"{path}: particle ids are not 0..N-1"
        for key, shape in (("kind", ()), ("mass", ()), ("position", (2,)), ("velocity", (2,)), ("theta", ())):
            arr = g[key][()]
            assert arr.shape == (C.N_SHORT, *shape), (path, key, arr.shape)
            if arr.dtype.kind == "f":
                assert np.isfinite(arr).all(), f"{path}: non-finite /particles/{key}"
        assert (g["mass"][()] > 0).all() and (g["theta"][()] > 0).all(), f"{path}: unwritten (zero) particles"
        assert g["mass"].attrs["units"] == "kg/m"  # 2-D: per metre of z


@launches
@pytest.mark.parametrize("restart_ranks", [1, 2])
def test_sigkill_mid_write_leaves_only_whole_outputs(tmp_path, restart_ranks):
    """SIGKILL to mpirun and both ranks while the ranks write an output file.

    The test polls the output directory and kills the moment a ``.part`` file
    appears after KILL_AFTER complete outputs, then checks that the kill did
    land in the write (the ``.part`` is still there; if the write won the race,
    a fresh run is tried, at most KILL_TRIES). Every <stem>_NNNN.h5 left opens
    and reads whole; the unfinished write is one .part file, which
    output_files / read_profile / last_snapshot ignore; --restart from the
    directory continues from the last complete output, on 1 or 2 ranks (into a
    fresh --out: restarting in place over a .part is test_restart.py's
    test_restart_in_place_ignores_an_unfinished_part_file).
    """
    from parsph.output import last_snapshot, output_files, read_profile
    for attempt in range(1, KILL_TRIES + 1):
        out = tmp_path / f"run{attempt}"
        live = C.Live(C.run_cmd(2, "--out", out, "--quiet", *C.sets(*KILLED)))
        try:
            # a few complete outputs first, so that several earlier snapshots are checked
            assert live.wait_for(lambda: out.is_dir() and len(C.h5_files(out)) >= KILL_AFTER, HANG_GUARD), \
                f"no {KILL_AFTER} outputs within {HANG_GUARD} s: {live.finish(1)[0]}"
            pids = C.descendants(live.p.pid) + [live.p.pid]  # mpirun and the ranks, found before the race
            seen, end = [], time.monotonic() + HANG_GUARD
            while not seen and time.monotonic() < end and live.p.poll() is None:
                seen = [f for f in os.listdir(out) if f.endswith(".h5.part")]
                if not seen:
                    time.sleep(0.001)
            for p in pids:  # at once, by id: no /proc scan between seeing the .part and the kill
                try:
                    os.kill(p, C.signal.SIGKILL)
                except ProcessLookupError:
                    pass
            assert seen, f"no .part file seen within {HANG_GUARD} s (run ended: {live.p.poll() is not None})"
            live.finish(HANG_GUARD)
            end = time.monotonic() + HANG_GUARD
            while C.alive(pids) and time.monotonic() < end:
                time.sleep(0.05)
            assert not C.alive(pids), f"processes alive after SIGKILL: {C.alive(pids)}"
        finally:
            live.kill()
        parts = C.h5_files(out, part=True)
        if parts:  # the kill landed inside a write
            break
    else:
        pytest.fail(f"{KILL_TRIES} runs: every write finished before the kill")

    files = C.h5_files(out)
    parts = C.h5_files(out, part=True)
    assert files, os.listdir(out)
    assert [int(f[-7:-3]) for f in files] == list(range(len(files))), f"a gap in the outputs: {files}"
    for k, f in enumerate(files):
        check_output_file(out / f, k)
    assert len(parts) == 1 and int(parts[0][-12:-8]) == len(files), \
        f"unfinished files other than the next output: {parts}"

    # the readers see the complete outputs only
    assert [os.path.basename(f) for f in output_files(out)] == files
    assert len(read_profile(out)["time"]) == len(files)
    assert os.path.basename(last_snapshot(out)) == files[-1]

    # and a restart from the directory continues
    last = C.read_final(out / files[-1])
    t_end = round((int(last["attrs"]["step"]) + 20) * C.DT, 10)
    fresh = tmp_path / "continued"
    r = C.run(C.run_cmd(restart_ranks, "--restart", out, "--out", fresh, "--quiet",
                        *C.sets(*C.SHORT, f"output.t_end={t_end!r}", f"output.times=[{t_end!r}]")), timeout=HANG_GUARD)
    assert r.returncode == 0, r
    new = f"{C.STEM}_{len(files):04d}.h5"
    assert C.h5_files(fresh) == [new], os.listdir(fresh)
    with h5py.File(fresh / new, "r") as f:
        assert int(f.attrs["step"]) == int(last["attrs"]["step"]) + 20


# ---- in process on COMM_WORLD (pytest-mpi) -------------------------------------------------

@pytest.mark.mpi
def test_stop_requested_on_one_rank_in_process(mpi_tmp_path):
    """A stop seen by the last rank only: every rank writes the final snapshot and raises Interrupted."""
    from parsph.output import Output, read_snapshot, read_state
    from parsph.errors import Interrupted
    from parsph.simulation.solver import Simulation
    comm, cfg, (a, b) = C.comm_world_case(mpi_tmp_path, ("stopped", "uninterrupted"),
                                          "output.t_end=0.0003", "output.times=[0.0003]")

    sim = Simulation(cfg, comm)
    seen = []  # the step at which the last rank's poll first saw the stop (polled between compiled blocks)

    def stop_requested():
        if comm.rank == comm.size - 1 and sim.step >= 7:
            seen.append(sim.step)
            return 1
        return 0
    with pytest.raises(Interrupted, match=r"stopped at step \d+,") as e:
        sim.run(output=Output(comm, str(a), C.STEM, cfg, sim.n_total), stop_requested=stop_requested)
    stopped = int(e.value.args[0].split()[3].rstrip(","))
    first_seen = comm.bcast(seen[0] if seen else None, root=comm.size - 1)
    assert first_seen is not None and first_seen <= stopped <= first_seen + 1, (first_seen, stopped)
    comm.Barrier()
    assert sorted(os.listdir(a)) == [f"{C.STEM}.cells.h5", f"{C.STEM}.xdmf", name(0)]
    state = read_state(str(a / name(0)))
    assert int(state["attrs"]["step"]) == stopped

    sim2 = Simulation(cfg, comm, state=state)
    sim2.run(output=Output(comm, str(a), C.STEM, cfg, sim2.n_total, first_index=1))
    ref = Simulation(cfg, comm)
    ref.run(output=Output(comm, str(b), C.STEM, cfg, ref.n_total))
    comm.Barrier()
    C.assert_same_particles(read_snapshot(str(a / name(1))), read_snapshot(str(b / name(0))),
                            f"stopped and continued on {comm.size} rank(s)")
