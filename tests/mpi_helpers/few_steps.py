"""Build the paper case on COMM_WORLD (a short box) and take a few steps; print one line per rank.

    [mpirun -n P] python tests/mpi_helpers/few_steps.py [STEPS]

Used to count what each process adds to the numba cache.
"""
import sys
from pathlib import Path

from mpi4py import MPI

from parsph import config
from parsph.solver import Simulation

PAPER = Path(__file__).resolve().parents[2] / "run" / "couette_paper.toml"


def main(argv):
    steps = int(argv[0]) if argv else 3
    comm = MPI.COMM_WORLD
    cfg = config.load(PAPER, [f"domain.Ly={max(8, 3 * comm.size) * 2e-4!r}", "output.times=[]"])
    sim = Simulation(cfg, comm)
    for _ in range(steps):
        sim.compute_rates()
        sim.advance(sim.dt)
    sim.check()
    # one write per line: mpirun forwards the ranks' output in chunks, and print() with
    # PYTHONUNBUFFERED writes the text and its newline separately (lines could interleave)
    sys.stdout.write(f"few_steps: rank {comm.rank} ok after {sim.step} steps\n")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
