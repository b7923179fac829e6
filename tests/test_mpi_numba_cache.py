"""Every rank is a process that loads the numba cache: repeated (and concurrent) runs must keep working.

Serial pytest launching the processes itself (skipped inside an mpirun job):

    .venv/bin/python -m pytest -q tests/test_mpi_numba_cache.py

The module's first job is a 3-rank ``parsph run`` on a NUMBA_CACHE_DIR of its own
that lacks the evaluation's stages (``simulation/stages.py``: Eq. (3), and the factors, the ghosts' rho and
Eq. (5)), which a run's first evaluation calls: every rank compiles them and writes
the same entries at once (the rest of the cache is a copy of parsph's own, which
the set-up fills, so that the module compiles only what it tests; without a
set-up the job compiles everything, as before). That run also shows what a run
that compiles prints. numba keeps at most NUMBA_FUNCTION_CACHE_SIZE (default
128) unpickled dispatchers alive; setting it low reproduces in three runs what
the shared cache reaches after ~128 runs.
"""
import re
from pathlib import Path

import pytest

from mpi_helpers import launch  # noqa: E402

from parsph.cli.progress import COMPILING  # noqa: E402

pytestmark = pytest.mark.skipif(launch.under_mpirun(), reason="launches mpirun itself (nested mpirun fails)")

FEW_STEPS = str(launch.HELPERS / "few_steps.py")
FRESH = ("stages.density-", "stages.after_density-")  # compiled by the first job, on 3 ranks at once
FUNCTIONS = tuple(f[:-1] for f in FRESH)


def data_files(cache, function):
    """The cache's data files of ``function`` (``module.name``)."""
    return sorted(p.name for p in Path(cache).rglob(f"{function}-*.nbc"))


def job(cache, n=3, **env):
    return launch.run(launch.mpirun_cmd(n, launch.PYTHON, FEW_STEPS), timeout=300, NUMBA_CACHE_DIR=cache, **env)


@pytest.fixture(scope="module")
def first_job(tmp_path_factory):
    """A 3-rank run of 3 steps, a progress line after each compiled block, on a cache without the passes of FRESH.

    The module compiles once and every test below starts from this cache (the limit only catches a hang)."""
    cache = tmp_path_factory.mktemp("numba_cache") / "numba"
    launch.seed_cache(cache, skip=FRESH)
    assert not any(data_files(cache, f) for f in FUNCTIONS)
    out = tmp_path_factory.mktemp("first_run")
    sets = ["domain.Ly=0.0024", "output.t_end=3e-5", "output.times=[3e-5]", "output.progress_interval=1e-6"]
    cmd = launch.parsph_cmd("run", launch.PAPER, "--out", out, *[a for s in sets for a in ("--set", s)])
    return cache, launch.run(launch.mpirun_cmd(3, *cmd), timeout=300, NUMBA_CACHE_DIR=cache,
                             NUMBA_FUNCTION_CACHE_SIZE=2)


def ranks_ok(r, n=3):
    # every rank reports once (counted as occurrences: mpirun may join the ranks' lines)
    return (r.returncode == 0 and r.stdout.count("ok after 3 steps") == n
            and sorted(int(m) for m in re.findall(r"rank (\d+) ok after 3 steps", r.stdout)) == list(range(n)))


def test_ranks_share_one_cache_under_mpirun(first_job):
    """Two successive 3-rank jobs on one fresh cache: both run to the end on every rank."""
    cache, first = first_job
    assert first.returncode == 0 and "done: 3 steps in" in first.stdout, f"job 1: {first}"
    second = job(cache, NUMBA_FUNCTION_CACHE_SIZE=2)
    assert ranks_ok(second), f"job 2: {second}"


def test_a_run_that_compiles_says_so_and_gives_no_rate_for_its_first_step(first_job):
    """One 'compiling the loops' line, after the banner and before the first progress line; the
    line after the first step has no rate and no time left, those after it have both."""
    _, first = first_job
    assert first.returncode == 0, first
    lines = first.stdout.splitlines()
    assert lines.count(f"  {COMPILING}") == 1, first
    steps = [k for k, ln in enumerate(lines) if ln.startswith("  step")]
    banner = next(k for k, ln in enumerate(lines) if ln.startswith("parsph couette:"))
    assert banner < lines.index(f"  {COMPILING}") < steps[0], first
    # a line per compiled block: the first step is a block of its own; steps 2 and 3 share one where the
    # first block ran fast (its compile done before it), as numba's cache decides
    shown = [lines[k].split()[1] for k in steps]
    assert shown in (["1/3", "2/3", "3/3"], ["1/3", "3/3"]), first
    assert "first step (compiling took" in lines[steps[0]] and "left" not in lines[steps[0]], lines[steps[0]]
    for k in steps[1:]:
        assert re.search(r"particle-steps/s  left \d+m\d\ds$", lines[k]), lines[k]


def test_compiled_equations_are_reused_by_the_next_process(first_job):
    """A later process finds the evaluation's stages in the cache instead of adding new entries."""
    cache, first = first_job
    assert first.returncode == 0, first
    before = {f: data_files(cache, f) for f in FUNCTIONS}
    assert all(before.values()), before
    r = launch.run([launch.PYTHON, FEW_STEPS], timeout=120, NUMBA_CACHE_DIR=cache)
    assert r.returncode == 0, r
    after = {f: data_files(cache, f) for f in FUNCTIONS}
    assert after == before, "every process adds a new cache entry (the cache never hits)"


def test_runs_keep_working_once_the_cache_index_is_long(first_job):
    """Three runs sharing one cache, as the 128th+ run would see it (NUMBA_FUNCTION_CACHE_SIZE=1)."""
    cache, first = first_job
    assert first.returncode == 0, first
    for k in range(3):
        r = launch.run([launch.PYTHON, FEW_STEPS], timeout=300, NUMBA_CACHE_DIR=cache,
                       NUMBA_FUNCTION_CACHE_SIZE=1)
        assert r.returncode == 0 and "ReferenceError" not in r.output, f"run {k + 1}: {r}"



def test_the_main_job_on_two_ranks_compiles_nothing_after_the_set_up(tmp_path):
    """scripts/main.sh's run (the paper case on 2 ranks) after the set-up's compile (``parsph.cli.warm``, its
    default cases, into a copy of parsph's cache: a few seconds where the set-up filled it): 100 steps (the list
    is rebuilt, particles migrate between the slabs), no 'compiling the loops' line, no compile time."""
    cache = tmp_path / "numba"
    launch.seed_cache(cache)
    warm = launch.run([launch.PYTHON, "-m", "parsph.cli.warm"], timeout=600, NUMBA_CACHE_DIR=cache)
    assert warm.returncode == 0 and "skipped" not in warm.stderr, warm
    sets = ["domain.Ly=0.0024", "output.t_end=1e-3", "output.times=[1e-3]", "output.progress_interval=1e-4"]
    cmd = launch.parsph_cmd("run", launch.PAPER, "--out", tmp_path / "out", *[a for s in sets for a in ("--set", s)])
    r = launch.run(launch.mpirun_cmd(2, *cmd), timeout=300, NUMBA_CACHE_DIR=cache)
    assert r.returncode == 0 and "done: 100 steps in" in r.stdout, r
    assert COMPILING not in r.stdout and "compile 0.0 s" in r.stdout, r
