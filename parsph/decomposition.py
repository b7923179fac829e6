"""Slabs along the periodic y direction: halo exchange and migration over MPI.

Rank r owns y in [bounds[r], bounds[r+1]) with equal widths; every slab spans
the whole channel in x. The ring is periodic: rank P-1's upper neighbour is
rank 0, and copies that cross y = Ly are shifted by -Ly (going up) or +Ly
(going down) on arrival. With one rank the rank is its own neighbour and the
same code runs. Messages are float64 rows sent with mpi4py's buffer methods;
this module knows nothing of the equations, only of particle arrays.
"""
import math

import numpy as np
from mpi4py import MPI
from numba import njit

TAG_UP, TAG_DOWN = 11, 12


def slab_bounds(Ly, P):
    """Edges of P equal slabs on [0, Ly): a pure function, checked serially."""
    b = np.array([r * Ly / P for r in range(P + 1)])
    b[-1] = Ly
    return b


def max_ranks(Ly, min_width):
    """The largest rank count whose slabs are at least ``min_width`` wide."""
    return max(1, int(math.floor(Ly / min_width * (1 + 1e-12))))


@njit(cache=True)
def _select_bands(y, n, lo, hi, up, down):
    """Indices with y >= hi (into ``up``) and y < lo (into ``down``); returns both counts."""
    nu = 0
    nd = 0
    for i in range(n):
        if y[i] >= hi:
            up[nu] = i
            nu += 1
        if y[i] < lo:
            down[nd] = i
            nd += 1
    return nu, nd


class DecompositionError(Exception):
    """A decomposition that cannot work (slabs too thin)."""


class SlabRing:
    """The slab of this rank, its two neighbours and the exchange buffers."""

    def __init__(self, comm, Ly, halo_width):
        self.comm = comm
        self.rank, self.size = comm.rank, comm.size
        self.Ly = Ly
        self.halo = halo_width
        P = self.size
        if Ly / P < halo_width * (1 - 1e-12):
            raise DecompositionError(
                f"{P} slabs of Ly = {Ly:g} m are {Ly / P:g} m wide, thinner than the halo "
                f"{halo_width:g} m (the support 2h, plus h/4 with the midpoint integrator): use at most {max_ranks(Ly, halo_width)} ranks or Ly >= {P * halo_width:g} m")
        self.bounds = slab_bounds(Ly, P)
        self.lo, self.hi = self.bounds[self.rank], self.bounds[self.rank + 1]
        self.left = (self.rank - 1) % P
        self.right = (self.rank + 1) % P
        self._bufs = {}
        self._idx = {TAG_UP: np.zeros(64, np.int64), TAG_DOWN: np.zeros(64, np.int64)}
        self._nsend = {TAG_UP: 0, TAG_DOWN: 0}
        self._nrecv = {TAG_UP: 0, TAG_DOWN: 0}
        self._status = MPI.Status()

    # -- buffers ------------------------------------------------------------
    def _buf(self, role, tag, rows, width):
        """A preallocated (rows, width) float64 buffer, grown only when too small."""
        key = (role, tag, width)
        buf = self._bufs.get(key)
        if buf is None or buf.shape[0] < rows:
            buf = np.zeros((max(rows, 64, 0 if buf is None else int(1.5 * buf.shape[0])), width))
            self._bufs[key] = buf
        return buf

    def _send_receive(self, width, n_up, n_down, ycol=None):
        """Send n_up rows up and n_down rows down; receive rows of unknown number from both neighbours.

        The counts travel as message sizes (MPI_Probe, then a receive of that
        size): one round of messages instead of counts first, then rows.
        Returns the rows from below and from above, with ``ycol`` shifted as
        in :meth:`_exchange_rows`.
        """
        c = self.comm
        sends = [c.Isend([self._buf("send", TAG_UP, n_up, width)[:n_up], MPI.DOUBLE], dest=self.right, tag=TAG_UP),
                 c.Isend([self._buf("send", TAG_DOWN, n_down, width)[:n_down], MPI.DOUBLE],
                         dest=self.left, tag=TAG_DOWN)]
        got = []
        for source, tag in ((self.left, TAG_UP), (self.right, TAG_DOWN)):
            c.Probe(source=source, tag=tag, status=self._status)
            rows = self._status.Get_count(MPI.DOUBLE) // width
            buf = self._buf("recv", tag, rows, width)[:rows]
            c.Recv([buf, MPI.DOUBLE], source=source, tag=tag)
            got.append(buf)
        MPI.Request.Waitall(sends)
        return self._shift(got[0], got[1], ycol)

    def _shift(self, up, down, ycol):
        """Rows that crossed y = Ly going up (arriving at rank 0) or down (at rank P-1) get y -+ Ly."""
        if ycol is not None:
            if self.rank == 0:
                up[:, ycol] -= self.Ly
            if self.rank == self.size - 1:
                down[:, ycol] += self.Ly
        return up, down

    def _exchange_rows(self, width, n_up, n_down, n_from_left, n_from_right, ycol=None):
        """Move rows of the send buffers to the neighbours (up: right, down: left).

        With ``ycol``, rows that crossed y = Ly get that column shifted by -+Ly.
        """
        up = self._buf("recv", TAG_UP, n_from_left, width)[:n_from_left]
        down = self._buf("recv", TAG_DOWN, n_from_right, width)[:n_from_right]
        c = self.comm
        reqs = [c.Irecv([up, MPI.DOUBLE], source=self.left, tag=TAG_UP),
                c.Irecv([down, MPI.DOUBLE], source=self.right, tag=TAG_DOWN),
                c.Isend([self._buf("send", TAG_UP, n_up, width)[:n_up], MPI.DOUBLE], dest=self.right, tag=TAG_UP),
                c.Isend([self._buf("send", TAG_DOWN, n_down, width)[:n_down], MPI.DOUBLE],
                        dest=self.left, tag=TAG_DOWN)]
        MPI.Request.Waitall(reqs)
        return self._shift(up, down, ycol)

    # -- halo ---------------------------------------------------------------
    def _select(self, ps, lo, hi):
        """Owned particles with y < lo (sent down) and y >= hi (sent up)."""
        n = ps.n_own
        if self._idx[TAG_UP].shape[0] < n:
            self._idx = {TAG_UP: np.zeros(ps.capacity, np.int64), TAG_DOWN: np.zeros(ps.capacity, np.int64)}
        nu, nd = _select_bands(ps.pos[:, 1], n, lo, hi, self._idx[TAG_UP], self._idx[TAG_DOWN])
        self._nsend[TAG_UP], self._nsend[TAG_DOWN] = nu, nd
        return nu, nd

    def exchange_halo(self, ps):
        """Append copies of the neighbours' particles within ``halo`` of this slab."""
        nu, nd = self._select(ps, self.lo + self.halo, self.hi - self.halo)
        width = ps.row_width
        for tag, k in ((TAG_UP, nu), (TAG_DOWN, nd)):
            ps.pack(self._idx[tag], k, self._buf("send", tag, k, width))
        from_left, from_right = self._send_receive(width, nu, nd, ycol=ps.ycol)
        nl, nr = len(from_left), len(from_right)
        self._nrecv[TAG_UP], self._nrecv[TAG_DOWN] = nl, nr
        ps.n = ps.n_own
        ps.ensure(ps.n_own + nl + nr, keep=ps.n_own)
        ps.unpack(from_left, ps.n_own)
        ps.unpack(from_right, ps.n_own + nl)
        ps.n = ps.n_own + nl + nr

    def exchange_halo_field(self, ps, field):
        """Refresh a per-particle scalar of the halo copies (same copies as the last exchange)."""
        arr = getattr(ps, field)
        nu, nd = self._nsend[TAG_UP], self._nsend[TAG_DOWN]
        for tag, k in ((TAG_UP, nu), (TAG_DOWN, nd)):
            self._buf("send", tag, k, 1)[:k, 0] = arr[self._idx[tag][:k]]
        nl, nr = self._nrecv[TAG_UP], self._nrecv[TAG_DOWN]
        from_left, from_right = self._exchange_rows(1, nu, nd, nl, nr)
        arr[ps.n_own:ps.n_own + nl] = from_left[:, 0]
        arr[ps.n_own + nl:ps.n_own + nl + nr] = from_right[:, 0]

    def leaving(self, ps):
        """``(indices, owners)``: the owned particles now outside this slab, ascending, and their owners.

        Positions are already wrapped into [0, Ly), so the owner, not the sign
        of the motion, decides where a particle goes (rank 0's particles that
        cross y = 0 go to rank P-1). A non-finite y has owner -1.
        """
        nu, nd = self._select(ps, self.lo, self.hi)
        gone = np.sort(np.concatenate([self._idx[TAG_UP][:nu], self._idx[TAG_DOWN][:nd]]))
        y = ps.pos[gone, 1]
        owner = np.where(np.isfinite(y), np.searchsorted(self.bounds, y, side="right") - 1, -1)
        return gone, owner

    def count_strays(self, leaving):
        """How many of ``leaving`` (from :meth:`leaving`) belong to neither neighbour (a blow-up)."""
        _, owner = leaving
        return int(((owner != self.left) & (owner != self.right) & (owner != self.rank)).sum())

    # -- migration ----------------------------------------------------------
    def migrate(self, ps, leaving):
        """Hand the particles ``leaving`` (from :meth:`leaving`) to the neighbour that owns them now.

        Every rank must have found ``count_strays(leaving)`` zero: the others
        go to the left neighbour.
        """
        ps.n = ps.n_own
        gone, owner = leaving
        to_right = owner == self.right
        up, down = gone[to_right], gone[~to_right]
        width = ps.row_width
        for tag, sel in ((TAG_UP, up), (TAG_DOWN, down)):
            ps.pack(sel, len(sel), self._buf("send", tag, len(sel), width))
        from_left, from_right = self._send_receive(width, len(up), len(down))
        nl, nr = len(from_left), len(from_right)
        if len(gone):
            ps.keep_owned(gone, len(gone))
        n0 = ps.n_own
        ps.ensure(n0 + nl + nr, keep=n0)
        ps.unpack(from_left, n0)
        ps.unpack(from_right, n0 + nl)
        ps.n_own = ps.n = n0 + nl + nr
