"""Shared by test_restart.py, test_interrupt.py and test_input_fuzz.py (not a test module).

Launching ``parsph`` (optionally under ``mpirun``) as a subprocess with a hard
timeout, watching a live run's output, killing a run's whole process tree, and
comparing snapshots.

Notes on the environment:

* The subprocess environment is always passed explicitly (a copy of
  ``os.environ``): a Python process that has initialised MPI as a singleton
  carries C-level Open MPI variables that would make a nested ``mpirun`` fail.
* Launched processes share one private numba cache directory per test session
  (removed at exit, the same as launch.py's) unless NUMBA_CACHE_DIR is set, so
  these tests do not add to ``parsph/__pycache__``; it starts as a copy of the
  entries there, so that only what the set-up did not compile is compiled.
* Open MPI puts every rank in a process group of its own, so killing
  ``mpirun``'s process group does not reach the ranks (they linger for about a
  second, then exit). :func:`kill_tree` kills mpirun and every descendant by
  process id instead.
"""
import os
import signal
import subprocess
import threading
import time

import numpy as np

from mpi_helpers.launch import MPI_ENV as _LAUNCH_ENV, PAPER, PYTHON, REPO, private_cache_dir, under_mpirun  # noqa: E402,F401

STEM = "couette_paper"
DT = 1e-5  # the paper's time step
SHORT = ("domain.Ly=0.0024",)  # 12 rows: 672 particles (3 slabs fit their ghost rows), a few hundred steps per second on 1 core
N_SHORT = 672
FIELDS = ("id", "kind", "mass", "position", "velocity", "theta")

MPI_ENV = {**_LAUNCH_ENV, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


def comm_world_case(tmp, names, *over):
    """COMM_WORLD, the paper case in a box short enough for tests (slabs >= 2h on any rank count)
    with run-file overrides ``over``, and empty directories ``tmp/<name>`` made by rank 0."""
    from mpi4py import MPI
    from parsph.setup import config
    comm = MPI.COMM_WORLD
    ly = max(10, 4 * comm.size) * 2e-4
    cfg = config.load(PAPER, [f"domain.Ly={ly!r}", *over])
    dirs = [tmp / n for n in names]
    if comm.rank == 0:
        for d in dirs:
            d.mkdir()
    comm.Barrier()
    return comm, cfg, dirs


def cache_dir():
    """The session's private numba cache of launched processes (launch.private_cache_dir: one for
    every helper, seeded with a copy of the entries of parsph's __pycache__ folders)."""
    return private_cache_dir()


def env(**extra):
    e = dict(os.environ)
    e.update(MPI_ENV)
    e.setdefault("NUMBA_CACHE_DIR", cache_dir())
    e["PYTHONUNBUFFERED"] = "1"
    e["PYTHONPATH"] = str(REPO) + (os.pathsep + e["PYTHONPATH"] if e.get("PYTHONPATH") else "")
    e.update({k: str(v) for k, v in extra.items()})
    return e


def parsph(*args):
    return [PYTHON, "-m", "parsph", *map(str, args)]


def mpirun(n, cmd):
    return ["mpirun", "--oversubscribe", "-n", str(n), *map(str, cmd)]


def sets(*items):
    out = []
    for s in items:
        out += ["--set", s]
    return out


def times_list(times):
    return "output.times=[" + ", ".join(repr(float(t)) for t in times) + "]"


def run_cmd(ranks, *args):
    """``parsph run PAPER ARGS`` on ``ranks`` ranks (0: no mpirun)."""
    cmd = parsph("run", PAPER, *args)
    return mpirun(ranks, cmd) if ranks else cmd


class Result:
    def __init__(self, rc, stdout, stderr, elapsed):
        self.returncode, self.stdout, self.stderr, self.elapsed = rc, stdout, stderr, elapsed

    def __repr__(self):
        return (f"rc={self.returncode} after {self.elapsed:.1f} s\n--- stdout ---\n{self.stdout}"
                f"\n--- stderr ---\n{self.stderr}")


def descendants(pid):
    """Process ids of every live descendant of ``pid`` (from /proc)."""
    children = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as f:
                ppid = int(f.read().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        children.setdefault(ppid, []).append(int(d))
    out, todo = [], [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            out.append(c)
            todo.append(c)
    return out


def rank_pids(mpirun_pid):
    """{rank: pid} of the parsph processes under mpirun (from /proc/PID/environ)."""
    out = {}
    for p in descendants(mpirun_pid):
        try:
            with open(f"/proc/{p}/environ", "rb") as f:
                env = dict(kv.split(b"=", 1) for kv in f.read().split(b"\0") if b"=" in kv)
        except OSError:
            continue
        if b"OMPI_COMM_WORLD_RANK" in env:
            out[int(env[b"OMPI_COMM_WORLD_RANK"])] = p
    return out


def kill_tree(pid, sig=signal.SIGKILL):
    """Send ``sig`` to ``pid`` and all its descendants at once (each by id); return the ids."""
    pids = descendants(pid) + [pid]
    for p in pids:
        try:
            os.kill(p, sig)
        except ProcessLookupError:
            pass
    return pids


def alive(pids):
    out = []
    for p in pids:
        try:
            with open(f"/proc/{p}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] != "Z":
                    out.append(p)
        except OSError:
            pass
    return out


def run(cmd, timeout=120, cwd=REPO, prefix=(), **extra_env):
    """Run ``cmd`` in its own session; on timeout kill its process tree and fail."""
    t0 = time.monotonic()
    p = subprocess.Popen([*prefix, *map(str, cmd)], cwd=cwd, env=env(**extra_env), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        kill_tree(p.pid)
        out, err = p.communicate()
        raise AssertionError(f"{' '.join(map(str, cmd))} did not finish within {timeout} s\n"
                             f"--- stdout ---\n{out}\n--- stderr ---\n{err}") from None
    return Result(p.returncode, out, err, time.monotonic() - t0)


class Live:
    """A running command whose stdout/stderr lines are collected by threads."""

    def __init__(self, cmd, cwd=REPO, **extra_env):
        self.cmd = [str(c) for c in cmd]
        self.t0 = time.monotonic()
        self.p = subprocess.Popen(self.cmd, cwd=cwd, env=env(**extra_env), stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True, start_new_session=True)
        self.out, self.err = [], []
        self.cond = threading.Condition()
        self.threads = [threading.Thread(target=self._pump, args=(s, buf), daemon=True)
                        for s, buf in ((self.p.stdout, self.out), (self.p.stderr, self.err))]
        for t in self.threads:
            t.start()

    def _pump(self, stream, buf):
        for line in stream:
            with self.cond:
                buf.append(line)
                self.cond.notify_all()
        with self.cond:
            self.cond.notify_all()

    def wait_for(self, pred, timeout):
        """Wait until ``pred()`` is true (re-checked on every line and every 0.05 s)."""
        end = time.monotonic() + timeout
        with self.cond:
            while not pred():
                if self.p.poll() is not None and not pred():
                    return pred()
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self.cond.wait(min(left, 0.05))
        return True

    def finish(self, timeout):
        """Wait for the end (killing the tree after ``timeout``); return a Result and whether it timed out."""
        timed_out = False
        try:
            self.p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            timed_out = True
            kill_tree(self.p.pid)
            self.p.wait(timeout=30)
        for t in self.threads:
            t.join(timeout=10)
        return Result(self.p.returncode, "".join(self.out), "".join(self.err), time.monotonic() - self.t0), timed_out

    def kill(self):
        if self.p.poll() is None:
            kill_tree(self.p.pid)
        try:
            self.p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            pass


def h5_files(d, part=False):
    """Names of the complete (or, with part=True, unfinished) output files in d."""
    suffix = ".h5.part" if part else ".h5"
    return sorted(f for f in os.listdir(d) if f.startswith(STEM + "_") and f.endswith(suffix))


def read_final(path):
    """The particles of one output file sorted by id, read with plain h5py."""
    import h5py
    with h5py.File(path, "r") as f:
        g = f["particles"]
        order = np.argsort(g["id"][()], kind="stable")
        out = {k: g[k][()][order] for k in FIELDS}
        out["attrs"] = dict(f.attrs)
    return out


def assert_same_particles(a, b, what=""):
    """Bit-for-bit equality of the particle arrays of two snapshots (sorted by id)."""
    for k in FIELDS:
        if not np.array_equal(a[k], b[k]):
            diff = ""
            if a[k].shape == b[k].shape and a[k].dtype.kind == "f":
                diff = f"; max |diff| = {np.nanmax(np.abs(a[k] - b[k])):.3e}"
            raise AssertionError(f"{what}: /particles/{k} differs{diff}")
    for k in ("step", "time"):
        assert a["attrs"][k] == b["attrs"][k], f"{what}: attribute {k}: {a['attrs'][k]} != {b['attrs'][k]}"


def stderr_lines(text):
    return [ln for ln in text.splitlines() if ln.strip()]


def parsph_lines(text):
    return [ln for ln in text.splitlines() if ln.startswith("parsph")]
