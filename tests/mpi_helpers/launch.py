"""Launching parsph under mpirun from a serial pytest process (shared by the test_mpi_* modules).

Not a test module: pytest collects nothing here. The subprocess environment is
always passed explicitly (a copy of ``os.environ``): a Python process that has
initialised MPI as a singleton may carry C-level Open MPI variables that make
a nested ``mpirun`` fail silently.

Launched processes get a numba cache directory of their own (one per test
session, removed at exit) unless NUMBA_CACHE_DIR is set: these tests are about
MPI behaviour and must not add to the shared ``parsph/__pycache__``
(test_mpi_numba_cache.py tests the cache itself). It starts as a copy of the
entries there (scripts/setup.sh compiles the loops into it), so that a
session compiles only what the set-up did not; the copy saves time and
nothing else, since numba checks every entry against the source's content and
the machine.
"""
import atexit
import os
import shutil
import tempfile
import signal
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
HELPERS = Path(__file__).resolve().parent
PAPER = REPO / "run" / "couette_paper.toml"
PYTHON = sys.executable

MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           # quiet, shared-memory only: the tests run on one small machine
           "OMPI_MCA_btl": "self,vader", "OMPI_MCA_rmaps_base_oversubscribe": "1"}


def under_mpirun():
    """True inside a process started by mpirun (where launching mpirun again fails)."""
    if any(k in os.environ for k in ("OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE")):
        return True
    if "mpi4py.MPI" in sys.modules:
        return sys.modules["mpi4py.MPI"].COMM_WORLD.size > 1
    return False


_CACHE_DIR = None


def seed_cache(dest, skip=()):
    """Copy the entries of parsph's ``__pycache__`` folders into ``dest`` as numba lays out a
    NUMBA_CACHE_DIR (a folder per source folder); entries whose file name starts with one of
    ``skip`` stay out. Without numba's layout function (another numba) nothing is copied."""
    try:
        from numba.core.caching import _CacheLocator
        for src in (REPO / "parsph").rglob("__pycache__"):
            module = src.parent / "__init__.py"  # any source file of that folder names its cache subpath
            dst = Path(dest) / _CacheLocator.get_suitable_cache_subpath(str(module))
            dst.mkdir(parents=True, exist_ok=True)
            for f in src.glob("*.nb[ic]"):
                if not f.name.startswith(tuple(skip)):
                    shutil.copy2(f, dst / f.name)
    except Exception:  # noqa: BLE001 - an optimisation only
        pass


def private_cache_dir():
    """The session's numba cache for launched processes, seeded from parsph's own (seed_cache)."""
    global _CACHE_DIR
    if _CACHE_DIR is None:
        _CACHE_DIR = tempfile.mkdtemp(prefix="parsph-test-numba-")
        os.chmod(_CACHE_DIR, 0o755)
        atexit.register(shutil.rmtree, _CACHE_DIR, True)
        seed_cache(_CACHE_DIR)
    return _CACHE_DIR


def env(**extra):
    e = dict(os.environ)
    e.update(MPI_ENV)
    if "NUMBA_CACHE_DIR" not in e:
        e["NUMBA_CACHE_DIR"] = private_cache_dir()
    e["PYTHONUNBUFFERED"] = "1"
    e.setdefault("NUMBA_NUM_THREADS", "1")  # ranks share the cores: no extra threads per rank
    e.update({k: str(v) for k, v in extra.items()})
    return e


def parsph_cmd(*args):
    return [PYTHON, "-m", "parsph", *map(str, args)]


def mpirun_cmd(n, *argv):
    return ["mpirun", "--oversubscribe", "-n", str(n), *map(str, argv)]


class Result:
    def __init__(self, rc, stdout, stderr, elapsed):
        self.returncode, self.stdout, self.stderr, self.elapsed = rc, stdout, stderr, elapsed

    @property
    def output(self):
        return self.stdout + self.stderr

    def __repr__(self):
        return (f"rc={self.returncode} after {self.elapsed:.1f} s\n--- stdout ---\n{self.stdout}"
                f"\n--- stderr ---\n{self.stderr}")


def run(cmd, timeout=90, cwd=REPO, shared_cache=False, **extra_env):
    """Run ``cmd`` in its own session; on timeout kill that whole process group and fail.

    ``shared_cache``: the package's own numba cache instead of the private one (no recompiling;
    for tests of behaviour that the cache cannot affect), with the repository on PYTHONPATH."""
    t0 = time.monotonic()
    e = env(**extra_env)
    if shared_cache:
        del e["NUMBA_CACHE_DIR"]
        e["PYTHONPATH"] = str(REPO) + (os.pathsep + e["PYTHONPATH"] if e.get("PYTHONPATH") else "")
    p = subprocess.Popen(cmd, cwd=cwd, env=e, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        out, err = p.communicate()
        raise AssertionError(f"{' '.join(map(str, cmd))} did not finish within {timeout} s\n"
                             f"--- stdout ---\n{out}\n--- stderr ---\n{err}") from None
    return Result(p.returncode, out, err, time.monotonic() - t0)


_WARM = False


def warm_cache(timeout=300):
    """Fill the launched processes' numba cache once per test session (a 2-step 1-rank run with output).

    A cold cache costs each process 20+ s of CPU for compilation (more on a loaded machine), which
    would count against the tests' hang guards; they are about MPI behaviour, not about the
    compiler. Later processes load the compiled functions from the cache (after the set-up, which
    compiles them into the cache this one is seeded from, the run only loads them).
    """
    global _WARM
    if _WARM:
        return
    out = tempfile.mkdtemp(prefix="parsph-test-warm-")
    try:
        r = run(parsph_cmd("run", PAPER, "--set", "domain.Ly=0.002", "--set", "output.t_end=2e-5",
                           "--set", "output.times=[2e-5]", "--out", out, "--quiet"), timeout=timeout)
    finally:
        shutil.rmtree(out, True)
    assert r.returncode == 0, f"warming the numba cache failed: {r}"
    _WARM = True


def count_lines(text, needle):
    return sum(needle in line for line in text.splitlines())
