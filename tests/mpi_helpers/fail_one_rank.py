"""Run ``parsph run`` with an exception injected on one rank at a given step.

    mpirun -n 2 python tests/mpi_helpers/fail_one_rank.py RANK STEP -- parsph-run-args...

On rank RANK, ``Simulation.advance`` raises RuntimeError("injected failure")
when it is called at step STEP; the other ranks run on normally and must not
hang. The exit status is that of ``parsph.cli.main``.
"""
import sys

from mpi4py import MPI

import parsph.solver
from parsph import cli


def main(argv):
    rank, step = int(argv[0]), int(argv[1])
    rest = argv[3:] if argv[2:3] == ["--"] else argv[2:]
    if MPI.COMM_WORLD.rank == rank:
        original = parsph.solver.Simulation.advance

        def advance(self, dt, stop_requested=None):
            if self.step == step:
                raise RuntimeError("injected failure")
            return original(self, dt, stop_requested)

        parsph.solver.Simulation.advance = advance
    return cli.main(["run", *rest])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
