"""The gas solve's blocks over the ranks (:mod:`parsph.gas.split_band`): block b is rank b's (modulo the ranks:
one rank does both), its results sent to every rank by its owner (all the blocks at once:
:meth:`BlockShare.share_all`), and a failure agreed before any exchange, so that no rank waits on one that
raised."""
import numpy as np
from mpi4py import MPI

from .collectives import any_rank


class BlockShare:
    def __init__(self, comm):
        self.comm = comm

    def mine(self, block):
        return block % self.comm.size == self.comm.rank

    def share_all(self, arrays):
        """Every block's array (float64; ``arrays[b]`` the same shape on every rank, its owner's computed) as its
        owner computed it, in one collective (an all-gather of each rank's blocks): one wait for the slowest
        rank where a broadcast per block waited once per block."""
        size = self.comm.size
        if size == 1:
            return list(arrays)
        owner = [b % size for b in range(len(arrays))]
        counts = [sum(a.size for b, a in enumerate(arrays) if owner[b] == r) for r in range(size)]
        displs = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int)
        mine = [np.ravel(a) for b, a in enumerate(arrays) if owner[b] == self.comm.rank]
        send = np.concatenate(mine) if mine else np.zeros(0)
        recv = np.empty(sum(counts))
        self.comm.Allgatherv(send, [recv, counts, displs, MPI.DOUBLE])
        out, at = [], list(displs)
        for b, a in enumerate(arrays):
            r = owner[b]
            out.append(recv[at[r]:at[r] + a.size].reshape(a.shape))
            at[r] += a.size
        return out

    def agree_failed(self, failed):
        return any_rank(self.comm, failed)
