"""Every rank is a process that loads the numba cache: repeated (and concurrent) runs must keep working.

Serial pytest launching the processes itself (skipped inside an mpirun job):

    .venv/bin/python -m pytest -q tests/test_mpi_numba_cache.py

Each test uses a fresh NUMBA_CACHE_DIR of its own. numba keeps at most
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


def test_compiled_equations_are_reused_by_the_next_process(tmp_path):
    """A second process finds density and momentum in the cache instead of adding new entries."""
    cache = tmp_path / "numba"
    first = launch.run([launch.PYTHON, FEW_STEPS], timeout=300, NUMBA_CACHE_DIR=cache)
    assert first.returncode == 0, first
    after_first = {f: data_files(cache, f) for f in ("density", "momentum")}
    assert all(after_first.values()), after_first
    second = launch.run([launch.PYTHON, FEW_STEPS], timeout=120, NUMBA_CACHE_DIR=cache)
    assert second.returncode == 0, second
    after_second = {f: data_files(cache, f) for f in ("density", "momentum")}
    assert after_second == after_first, "every process adds a new cache entry (the cache never hits)"


def test_runs_keep_working_once_the_cache_index_is_long(tmp_path):
    """Three runs sharing one cache, as the 128th+ run would see it (NUMBA_FUNCTION_CACHE_SIZE=1)."""
    cache = tmp_path / "numba"
    for k in range(3):
        r = launch.run([launch.PYTHON, FEW_STEPS], timeout=300, NUMBA_CACHE_DIR=cache,
                       NUMBA_FUNCTION_CACHE_SIZE=1)
        assert r.returncode == 0 and "ReferenceError" not in r.output, f"run {k + 1}: {r}"


def test_ranks_share_one_cache_under_mpirun(tmp_path):
    """Two successive 3-rank jobs on one fresh cache: every rank of both jobs runs."""
    cache = tmp_path / "numba"
    for k in range(2):
        # the first job compiles everything on 3 ranks sharing the cores (about 75 s on a busy
        # 2-core machine): the limit only catches a hang
        r = launch.run(launch.mpirun_cmd(3, launch.PYTHON, FEW_STEPS), timeout=300, NUMBA_CACHE_DIR=cache,
                       NUMBA_FUNCTION_CACHE_SIZE=2)
        assert r.returncode == 0, f"job {k + 1}: {r}"
        # every rank reports once (counted as occurrences: mpirun may join the ranks' lines)
        assert r.stdout.count("ok after 3 steps") == 3, f"job {k + 1}: {r}"
        assert sorted(int(m) for m in re.findall(r"rank (\d+) ok after 3 steps", r.stdout)) == [0, 1, 2], r
