"""Build the paper case on COMM_WORLD (a short box) and take a few steps; print one line per rank.

    [mpirun -n P] python tests/mpi_helpers/few_steps.py [STEPS]

Used to count what each process adds to the numba cache.
"""
import sys
from pathlib import Path

import math

from mpi4py import MPI

from parsph.setup import config
from parsph.parallel.slabs import min_length
from parsph.sph.cells import CELLS_PER_CUTOFF
from parsph.simulation.solver import Simulation

PAPER = Path(__file__).resolve().parents[2] / "run" / "couette_paper.toml"


def main(argv):
    steps = int(argv[0]) if argv else 3
    comm = MPI.COMM_WORLD
    rows = max(8, math.ceil(min_length(comm.size, 2.4 * 2.5e-4, CELLS_PER_CUTOFF) / 2e-4 - 1e-9))
    cfg = config.load(PAPER, [f"domain.Ly={rows * 2e-4!r}", "output.times=[]"])
    sim = Simulation(cfg, comm)
    for _ in range(steps):
        sim.compute_rates()
        sim.integrate(sim.dt)
    sim.check()
    # one write per line: mpirun forwards the ranks' output in chunks, and print() with
    # PYTHONUNBUFFERED writes the text and its newline separately (lines could interleave)
    sys.stdout.write(f"few_steps: rank {comm.rank} ok after {sim.step} steps\n")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
