"""Compile parsph's loops into numba's disk cache ahead of the first run (``scripts/setup.sh`` calls it).

    python -m parsph.cli.warm [RUN_DIR] [--suite] [--jobs N]

numba compiles a loop for each set of argument types the first time a
process needs it and keeps it in ``__pycache__`` beside the source (keyed by
the source's content, the CPU and numba's version), which later processes
load in well under a second. A run file's scene, dimension and terms decide
the types (the compile-time switches of :mod:`parsph.sph.pass_data` and
:mod:`parsph.simulation.block`), so this runs cases for a few steps on a tiny
box, one rank each:

- by default what ``scripts/main.sh`` runs: the paper case (RUN_DIR's
  couette_paper.toml, default the repository's ``run/``) on one thread;
- with ``--suite`` also what the test suite (``scripts/test.sh``) runs in
  launched processes and under mpirun, where each process or rank would
  compile it again: every run file of RUN_DIR with one thread and with two,
  the paper case with the midpoint integrator, and the variants of
  :data:`SUITE_EXTRA`.

Any other combination compiles at its first run, which says so and for how
long (:mod:`.progress`). What the cache holds already is loaded, not compiled
again; no result depends on any of it. Prints one line: what it ran, and the
seconds it compiled.

With several cases the runs go to ``--jobs`` processes (default: one per core,
at most 4) that take the cases one by one from a shared queue. numba writes a
compiled version as a read-modify-write of the function's index file followed
by the data file the index names, each replaced atomically but not the two
together: two processes saving versions of one function at the same time can
both take the same data file number (numba.core.caching.IndexDataCacheFile.save),
leaving the index pointing at the other version's code. The processes here
therefore hold one lock (``fcntl.flock``) from the index's read to the data
file's write; loading needs no lock (an index entry whose data file is not
written yet reads as a miss, and the version compiles).
"""
import argparse
import contextlib
import io
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "2")  # the threaded passes compile even on one core

# (run file, overrides): tiny boxes that every scene accepts, a few steps, one output with particles
TINY = ["domain.Ly=0.003", "output.t_end=3e-5", "output.times=[3e-5]", "output.progress_interval=0"]
TINY_3D = ["domain.Lz=0.0006"]
RUN_DIR = Path(__file__).resolve().parents[2] / "run"
MAIN = [("couette_paper.toml", [], 1)]  # scripts/main.sh: the paper case, one thread per rank
EXTRA = {"couette_paper.toml": [["numerics.integrator=midpoint"]]}
# (run file, overrides, threads) that the suite runs in launched processes or under mpirun beyond the above:
# tests/test_mpi_parallel.py (midpoint, auto dt, symmetric viscosity), tests/mpi_helpers/scene_ranks.py
# (the settling column with a fixed dt; the periodic box with the pressure term, 2 threads and 1)
SUITE_EXTRA = [
    ("couette_paper.toml", ["numerics.integrator=midpoint", 'numerics.dt="auto"', "numerics.viscosity_form=symmetric"],
     1),
    ("settling.toml", ["numerics.dt=5e-5"], 1),
    ("periodic_box.toml", ["terms.pressure=true"], 1),
    ("periodic_box.toml", ["terms.pressure=true"], 2),
]
QUEUE = "PARSPH_WARM_QUEUE"  # a worker's shared folder: the lock, the next case, the results


def _tiny(path):
    return TINY + (TINY_3D if "dim = 3" in Path(path).read_text() else [])


def variants(run_dir, suite=False):
    """(run file, overrides, threads) of every case to run: main.sh's, and with ``suite`` the suite's."""
    run_dir = Path(run_dir)
    picked = [(run_dir / name, sets, threads) for name, sets, threads in MAIN]
    if suite:
        for path in sorted(run_dir.glob("*.toml")):
            for more in [[]] + EXTRA.get(path.name, []):
                picked += [(path, more, threads) for threads in (1, 2)]
        picked += [(run_dir / name, sets, threads) for name, sets, threads in SUITE_EXTRA]
    out = []
    for path, sets, threads in picked:
        case = (path, _tiny(path) + list(sets), threads)
        if path.exists() and case not in out:
            out.append(case)
    return out


def describe(case):
    """A case as one line: the run file, the overrides beyond the tiny box's, the threads."""
    path, sets, threads = case
    more = [s for s in sets if s not in TINY + TINY_3D]
    return " ".join([Path(path).name] + more + [f"--threads {threads}"])


def run_case(parsph, case, out):
    """Run one case with ``parsph`` (the command's main) into the directory ``out``, quietly: (exit code,
    what it wrote on stderr)."""
    path, sets, threads = case
    args = ["run", str(path), "--out", str(out), "--quiet", "--threads", str(threads)]
    for s in sets:
        args += ["--set", s]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
        code = parsph(args)
    return code, err.getvalue()


@contextlib.contextmanager
def _locked(folder):
    import fcntl
    with open(os.path.join(folder, "lock"), "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def serialise_cache_saves(folder):
    """From now on this process saves numba's cache entries under the lock of ``folder`` (module doc)."""
    from numba.core import caching
    save = caching.IndexDataCacheFile.save

    def locked_save(self, key, data):
        with _locked(folder):
            return save(self, key, data)
    caching.IndexDataCacheFile.save = locked_save


def _next_case(folder):
    """The index of the next case nobody took (a counter in ``folder``, under its lock)."""
    with _locked(folder):
        counter = Path(folder) / "next"
        k = int(counter.read_text()) if counter.exists() else 0
        counter.write_text(str(k + 1))
    return k


def run_cases(cases, take=None):
    """Run the cases (those ``take()`` hands out, until it returns an index past the end): (compile
    seconds, [failures])."""
    from .command import main as parsph
    from .progress import CompileWatch
    failed = []
    with CompileWatch() as watch, tempfile.TemporaryDirectory(prefix="parsph-warm-") as tmp:
        for k in iter(take, None) if take else range(len(cases)):
            if k >= len(cases):
                break
            code, err = run_case(parsph, cases[k], os.path.join(tmp, str(k)))
            if code != 0:
                failed.append(f"{describe(cases[k])}: exit {code}: {err.strip()[-300:]}")
    return watch.seconds(), failed


def default_jobs():
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count() or 1
    return max(1, min(cores, 4))


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m parsph.cli.warm", description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", nargs="?", default=str(RUN_DIR))
    ap.add_argument("--suite", action="store_true", help="also what the test suite runs in launched processes")
    ap.add_argument("--jobs", type=int, default=int(os.environ.get("PARSPH_WARM_JOBS", 0)) or default_jobs())
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    cases = variants(a.run_dir, a.suite)
    if a.worker:  # one of main()'s processes: cases from the queue, the result into it
        folder = os.environ[QUEUE]
        serialise_cache_saves(folder)
        seconds, failed = run_cases(cases, lambda: _next_case(folder))
        Path(folder, f"result.{os.getpid()}").write_text(json.dumps([seconds, failed]))
        return 0
    t0 = time.perf_counter()
    jobs = max(1, min(a.jobs, len(cases)))
    if jobs == 1:
        seconds, failed = run_cases(cases)
    else:
        with tempfile.TemporaryDirectory(prefix="parsph-warm-queue-") as folder:
            cmd = [sys.executable, "-m", "parsph.cli.warm", a.run_dir, "--worker"] + (["--suite"] if a.suite else [])
            procs = [subprocess.Popen(cmd, env={**os.environ, QUEUE: folder}) for _ in range(jobs)]
            codes = [proc.wait() for proc in procs]
            results = [json.loads(f.read_text()) for f in Path(folder).glob("result.*")]
        seconds = sum(r[0] for r in results)
        failed = [f for r in results for f in r[1]]
        failed += [f"a worker process: exit {c}" for c in codes if c != 0]
    what = "the cases of main.sh and the test suite" if a.suite else "the case of main.sh"
    runs = f"{len(cases)} tiny run{'s' if len(cases) > 1 else ''}"
    print(f"warm: {runs} ({what}) of {a.run_dir} in {time.perf_counter() - t0:.0f} s"
          f"{f' ({jobs} processes)' if jobs > 1 else ''}, {seconds:.0f} s of compiling", file=sys.stderr)
    for f in failed:  # a case that cannot run here only leaves its loops to compile at its first run
        print(f"warm: skipped {f}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
