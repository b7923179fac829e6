"""Threads inside a rank (``parsph run --threads N``): the same numbers bit for bit on any thread count.

Each particle's sums run over its own neighbour list in a fixed order, so the
prange loops must give identical results with 1 and 2 threads; checked on one
rank for the scenes' combinations of terms (2-D and 3-D, walls, body force,
consistent pressure).
"""
import numba
import numpy as np
import pytest
from mpi4py import MPI

from parsph.setup import config
from parsph.simulation.solver import Simulation

from conftest import ROOT, run_cli

CASES = {
    "couette_paper": ["domain.Ly=0.001"],
    "couette_3d": [],
    "settling": [],
    "periodic_box": ["domain.Ly=0.001"],
}


def state_after(name, over, threads, steps=25):
    numba.set_num_threads(threads)
    try:
        cfg = config.load(ROOT / "run" / f"{name}.toml", [*over, "output.times=[]"])
        sim = Simulation(cfg, MPI.COMM_SELF)
        for _ in range(steps):
            sim.compute_rates()
            sim.integrate(sim.dt)
        sim.compute_rates()
    finally:
        numba.set_num_threads(1)
    ps, n = sim.ps, sim.ps.n_own
    order = np.argsort(ps.gid[:n])
    return {k: getattr(ps, k)[:n][order].copy() for k in ("pos", "vel", "rho", "theta", "acc")}


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba allows one thread here")
@pytest.mark.parametrize("name", sorted(CASES))
def test_two_threads_bit_for_bit(name):
    one = state_after(name, CASES[name], 1)
    two = state_after(name, CASES[name], 2)
    assert np.abs(one["vel"]).max() > 0
    for key in one:
        assert np.array_equal(one[key], two[key]), f"{name}: {key} differs between 1 and 2 threads"


@pytest.mark.parametrize("n", ["0", "100000"])
def test_bad_thread_count_is_refused(n, tmp_path):
    rc, out, err = run_cli("run", ROOT / "run" / "couette_paper.toml", "--threads", n, "--out", tmp_path)
    assert rc == 2, (rc, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "--threads" in lines[0], err


def test_thread_limit_says_where_it_comes_from():
    """The refusal names its cause in one line: NUMBA_NUM_THREADS in the environment, the launcher's binding
    (fewer usable cores than the machine has: mpirun -n 2 binds each rank to one core) with its remedy, or
    the cores themselves."""
    from parsph.simulation.case import thread_limit
    bound = thread_limit(2, 1, env="", usable=1, cores=2)
    assert bound.startswith("--threads 2: must be between 1 and 1: ")
    assert "1 of the machine's 2 cores" in bound and "mpirun --bind-to none" in bound and "\n" not in bound
    assert "NUMBA_NUM_THREADS=1 in the environment" in thread_limit(2, 1, env="1", usable=1, cores=2)
    free = thread_limit(5, 2, env="", usable=2, cores=2)
    assert "bind" not in free and "cores this process may run on" in free
    assert "bind" not in thread_limit(0, 1, env="", usable=1, cores=2)   # below 1: no binding to blame
