"""The solved gas's grid summed over the slabs: each rank deposits its particles on the whole grid
(:func:`parsph.gas.deposit.deposit`, fixed point) and one all-reduce of int64 adds the ranks' arrays, exactly
and in any order, so every rank holds the same bits as one rank would. The grid is small against the
particles (a cell holds several), so the whole of it travels: a slab's columns and their neighbours' would do,
and are the way to a grid that outgrows one rank's memory."""
from mpi4py import MPI

from .collectives import any_rank


class GridSum:
    def __init__(self, comm):
        self.comm = comm

    def __call__(self, sums):
        """``sums`` (int64) replaced by its sum over the ranks."""
        if self.comm.size > 1:
            self.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        return sums

    def agree_failed(self, failed):
        """Whether the solve failed on any rank (each solves the same grid; they fail alike, but no rank may
        be left waiting should one differ)."""
        return any_rank(self.comm, failed)
