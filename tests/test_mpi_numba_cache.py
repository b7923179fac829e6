"""Every rank is a process that loads the numba cache: repeated (and concurrent) runs must keep working.

Serial pytest launching the processes itself (skipped inside an mpirun job):

    .venv/bin/python -m pytest -q tests/test_mpi_numba_cache.py

The module compiles once, on 3 ranks at once, into a fresh NUMBA_CACHE_DIR of its own. numba keeps at most
NUMBA_FUNCTION_CACHE_SIZE (default 128) unpickled dispatchers alive; setting it
low reproduces in three runs what the shared cache reaches after ~128 runs.
"""
import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "mpi_helpers"))
import launch  # noqa: E402

pytestmark = pytest.mark.skipif(launch.under_mpirun(), reason="launches mpirun itself (nested mpirun fails)")

FEW_STEPS = str(launch.HELPERS / "few_steps.py")


def data_files(cache, function):
    return sorted(p.name for p in Path(cache).rglob(f"equations.{function}-*.nbc"))


def job(cache, n=3, **env):
    return launch.run(launch.mpirun_cmd(n, launch.PYTHON, FEW_STEPS), timeout=300, NUMBA_CACHE_DIR=cache, **env)


@pytest.fixture(scope="module")
def first_job(tmp_path_factory):
    """A 3-rank job on a fresh cache: all ranks compile and write the same entries at once.

    Compiling everything takes most of a minute, so the module compiles once and every test
    below starts from this cache (the limit only catches a hang)."""
    cache = tmp_path_factory.mktemp("numba_cache") / "numba"
    return cache, job(cache, NUMBA_FUNCTION_CACHE_SIZE=2)


def ranks_ok(r, n=3):
    # every rank reports once (counted as occurrences: mpirun may join the ranks' lines)
    return (r.returncode == 0 and r.stdout.count("ok after 3 steps") == n
            and sorted(int(m) for m in re.findall(r"rank (\d+) ok after 3 steps", r.stdout)) == list(range(n)))


def test_ranks_share_one_cache_under_mpirun(first_job):
    """Two successive 3-rank jobs on one fresh cache: every rank of both jobs runs."""
    cache, first = first_job
    assert ranks_ok(first), f"job 1: {first}"
    second = job(cache, NUMBA_FUNCTION_CACHE_SIZE=2)
    assert ranks_ok(second), f"job 2: {second}"


def test_compiled_equations_are_reused_by_the_next_process(first_job):
    """A later process finds density and momentum in the cache instead of adding new entries."""
    cache, first = first_job
    assert first.returncode == 0, first
    before = {f: data_files(cache, f) for f in ("density_serial", "momentum_serial")}
    assert all(before.values()), before
    r = launch.run([launch.PYTHON, FEW_STEPS], timeout=120, NUMBA_CACHE_DIR=cache)
    assert r.returncode == 0, r
    after = {f: data_files(cache, f) for f in ("density_serial", "momentum_serial")}
    assert after == before, "every process adds a new cache entry (the cache never hits)"


def test_runs_keep_working_once_the_cache_index_is_long(first_job):
    """Three runs sharing one cache, as the 128th+ run would see it (NUMBA_FUNCTION_CACHE_SIZE=1)."""
    cache, first = first_job
    assert first.returncode == 0, first
    for k in range(3):
        r = launch.run([launch.PYTHON, FEW_STEPS], timeout=300, NUMBA_CACHE_DIR=cache,
                       NUMBA_FUNCTION_CACHE_SIZE=1)
        assert r.returncode == 0 and "ReferenceError" not in r.output, f"run {k + 1}: {r}"
