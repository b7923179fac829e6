"""Run ``parsph run`` with a NaN put into one rank's velocities at a given step.

    mpirun -n 2 python tests/mpi_helpers/nan_one_rank.py RANK STEP -- parsph-run-args...

On rank RANK, right after the ``Simulation.advance`` that reaches step STEP,
the y velocity of its first owned fluid particle becomes NaN. Either the
run-time checks (every ``checks.every`` steps, on the state before the next
step) or, between two checks, the per-step collective flag raised by the next
integration (non-finite positions) must then stop every rank with exit code 3
and one message.
"""
import sys

import numpy as np
from mpi4py import MPI

import parsph.solver
from parsph import cli
from parsph.particles import FLUID


def main(argv):
    rank, step = int(argv[0]), int(argv[1])
    rest = argv[3:] if argv[2:3] == ["--"] else argv[2:]
    if MPI.COMM_WORLD.rank == rank:
        original = parsph.solver.Simulation.advance

        def advance(self, dt, stop_requested=None):
            stop = original(self, dt, stop_requested)
            if self.step == step:
                ps = self.ps
                k = int(np.flatnonzero(ps.kind[:ps.n_own] == FLUID)[0])
                ps.vel[k, 1] = np.nan
                # one write (with its newline), so that mpirun cannot join it with another line
                sys.stderr.write(f"nan_one_rank: NaN put into particle {ps.gid[k]} on rank {rank} "
                                 f"at step {step}\n")
                sys.stderr.flush()
            return stop

        parsph.solver.Simulation.advance = advance
    return cli.main(["run", *rest])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
