"""The gas solve's blocks over the ranks (:mod:`parsph.gas.split_band`): block b is rank b's (modulo the ranks:
one rank does both), its results sent to every rank by a broadcast from its owner, and a failure agreed before
any broadcast, so that no rank waits on one that raised."""
from .collectives import any_rank


class BlockShare:
    def __init__(self, comm):
        self.comm = comm

    def mine(self, block):
        return block % self.comm.size == self.comm.rank

    def share(self, block, array):
        """``array`` (float64, contiguous, the same shape on every rank) as block's owner computed it."""
        if self.comm.size > 1:
            self.comm.Bcast(array, root=block % self.comm.size)
        return array

    def agree_failed(self, failed):
        return any_rank(self.comm, failed)
