"""Run ``parsph run`` with a fault injected on one rank at a given step.

    mpirun -n 2 python tests/mpi_helpers/inject_one_rank.py raise|nan RANK STEP -- parsph-run-args...

``raise``: on rank RANK, the solver's step driver (``Simulation._to_next_event``)
raises RuntimeError("injected failure") when it is called at step STEP; the other ranks run on normally and
must not hang.

``nan``: on rank RANK, right after the steps that reach step STEP (the
driver is held to end its compiled block there, after the block's checks of
that step), the y velocity of its first owned fluid particle becomes NaN. The
per-step collective flag raised by the next integration (non-finite
positions) must then stop every rank with exit code 3 and one message; on
the Python path (``PARSPH_NATIVE_MPI=0``) the run-time checks of step STEP,
which run after the driver returns, see it first.

The exit status is that of ``parsph.cli.command.main``.
"""
import sys

import numpy as np
from mpi4py import MPI

import parsph.simulation.solver
from parsph import cli
from parsph.sph.particles import GRAIN


def put_nan(sim, rank, step):
    ps = sim.ps
    k = int(np.flatnonzero(ps.kind[:ps.n_own] == GRAIN)[0])
    ps.vel[k, 1] = np.nan
    # one write (with its newline), so that mpirun cannot join it with another line
    sys.stderr.write(f"nan_one_rank: NaN put into particle {ps.gid[k]} on rank {rank} at step {step}\n")
    sys.stderr.flush()


def main(argv):
    mode, rank, step = argv[0], int(argv[1]), int(argv[2])
    rest = argv[4:] if argv[3:4] == ["--"] else argv[3:]
    if MPI.COMM_WORLD.rank == rank:
        # the solver's step driver (compiled blocks, or the Python path step by step), held to end a
        # block at STEP so that the fault lands at that step exactly
        original = parsph.simulation.solver.Simulation._to_next_event

        def advance(self, pending, most=None, stop_requested=None):
            if mode == "raise" and self.step == step:
                raise RuntimeError("injected failure")
            if self.step < step:
                most = min(most or step, step - self.step)
            original(self, pending, most, stop_requested)
            if mode == "nan" and self.step == step:
                put_nan(self, rank, step)

        parsph.simulation.solver.Simulation._to_next_event = advance
    return cli.main(["run", *rest])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
