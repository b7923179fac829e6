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
