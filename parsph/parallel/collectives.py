"""The collective reductions the solver issues, through one object that owns the communicator.

The solver's own agreements (the per-step flags, the stable time step, the
profile's bin sums, the run-time checks) go through :class:`Collectives`, as
Dedalus's distributor owns the communicator of its transforms; the slab ring
(:mod:`parsph.parallel.slab_ring`) keeps its own point-to-point messages. Buffers
are numpy arrays: nothing is pickled.
"""
import numpy as np
from mpi4py import MPI


def any_rank(comm, flag):
    """Whether ``flag`` holds on any rank: one all-reduce of a one-element buffer (nothing pickled; none on
    one rank), for the agreements made at every solve."""
    if comm.size == 1:
        return bool(flag)
    buf = np.array([1 if flag else 0], np.int64)
    comm.Allreduce(MPI.IN_PLACE, buf, op=MPI.MAX)
    return bool(buf[0])


class Collectives:
    def __init__(self, comm):
        self.comm = comm
        self.rank, self.size = comm.rank, comm.size

    def max(self, values):
        """Element-wise maximum over ranks of a float64 vector."""
        values = np.ascontiguousarray(values, dtype=float)
        out = np.empty_like(values)
        self.comm.Allreduce(values, out, op=MPI.MAX)
        return out

    def sum(self, values):
        """Element-wise sum over ranks of a float64 array."""
        values = np.ascontiguousarray(values, dtype=float)
        out = np.empty_like(values)
        self.comm.Allreduce(values, out, op=MPI.SUM)
        return out

    def gather(self, row):
        """Every rank's float64 row, stacked in rank order, on every rank."""
        row = np.ascontiguousarray(row, dtype=float)
        out = np.zeros((self.size,) + row.shape)
        self.comm.Allgather(row, out)
        return out

    def total(self, count):
        """The sum of an integer over ranks."""
        return int(self.comm.allreduce(int(count), op=MPI.SUM))
