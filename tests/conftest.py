"""Shared fixtures of the serial suite.

Paths are absolute (derived from this file), so the suite runs from any cwd.
"""
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numba
import pytest

# Each worker's in-process runs on one numba thread, as `parsph run` without --threads and as the set-up
# compiled them (numba's default is one thread a core: every in-process Simulation would compile and run the
# threaded passes, three workers' threads on two cores); results are the same bits on any thread count
# (test_threads.py), and the tests of threads set their own count and come back to one
numba.set_num_threads(1)

ROOT = Path(__file__).resolve().parent.parent
PAPER_TOML = ROOT / "run" / "couette_paper.toml"

# Open MPI refuses to start as root unless told; harmless otherwise.
MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}
for _k, _v in MPI_ENV.items():
    os.environ.setdefault(_k, _v)


def cli_env():
    env = dict(os.environ)
    env.update(MPI_ENV)
    # make the package importable whatever the cwd and whether it is installed
    env["PYTHONPATH"] = str(ROOT) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


def cli_command(*args):
    return [sys.executable, "-m", "parsph", *map(str, args)]


def run_cli(*args, timeout=60):
    """Run ``python -m parsph ARGS`` in the repository root; return (returncode, stdout, stderr)."""
    p = subprocess.run(cli_command(*args), cwd=ROOT, env=cli_env(), capture_output=True,
                       text=True, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def paper_raw():
    """The paper run file as a raw dict (to edit before :func:`parsph.setup.config.build` of a RunFile of it)."""
    with open(PAPER_TOML, "rb") as f:
        return tomllib.load(f)


@pytest.fixture
def paper_cfg():
    """Factory: ``paper_cfg("numerics.dt=2e-5", ...)`` loads the paper case with overrides."""
    from parsph.setup import config

    def make(*overrides):
        return config.load(str(PAPER_TOML), list(overrides))
    return make


@pytest.fixture
def cli():
    """The CLI runner as a fixture: ``cli("run", path, "--out", d)``."""
    return run_cli
