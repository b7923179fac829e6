"""Cell linked list and the cell-ordered copies the loops read.

Cell coordinates are global: ``floor((x - x0) / cs)``, ``floor(y / cs)`` and
``floor(z / cs)`` (``y`` including the periodic shift of halo copies), so a
particle falls into the same cell whatever the number of ranks. Particles are
copied into cell order (x fastest), by global id inside a cell. Loops that
visit the cells around a particle in a fixed order therefore add up
contributions in the same order on any rank count: results do not depend on
P, bit for bit. Cell order also puts neighbours next to each other in memory,
and makes the cells of one row along x a contiguous run.
"""
import numpy as np
from numba import njit


class Workspace:
    """Preallocated cell-ordered arrays, grown only when the particle count or the neighbour count grows.

    The neighbour list has a fixed width per particle (``nbr_j[i, :nbr_n[i]]``),
    so that each particle's list is written independently (threads).
    """

    FIELDS_F = ("sx", "sy", "sz", "svx", "svy", "svz", "sm", "stheta", "spress")
    FIELDS_I = ("order", "cell_of", "skind", "tmp")
    MARGIN = 4  # list slots beyond the largest count seen

    def __init__(self):
        self.capacity = 0
        self.width = 1  # the loops need one slot to write into; the first pass widens it
        self.ensure(1)

    def ensure(self, n):
        if n > self.capacity:
            cap = max(n, int(1.3 * self.capacity), 64)
            for name in self.FIELDS_F:
                setattr(self, name, np.zeros(cap))
            for name in self.FIELDS_I:
                setattr(self, name, np.zeros(cap, np.int64))
            self.owned = np.zeros(cap, np.bool_)
            self.sinv = np.zeros((cap, 2))
            self.nbr_n = np.zeros(cap, np.int64)
            self.capacity = cap
            self._list(self.width)

    def ensure_width(self, count):
        """Widen the neighbour list to hold ``count`` neighbours per particle (plus a margin)."""
        if count > self.width:
            self._list(count + self.MARGIN)

    def _list(self, width):
        self.width = width
        self.nbr_j = np.zeros((self.capacity, width), np.int32)
        self.nbr_f = np.zeros((self.capacity, width))

    def pairs(self, n):
        """Neighbour-list entries (i sees j) of the last density pass over n sorted places."""
        return int(self.nbr_n[:n].sum())


@njit(cache=True)
def sort_into_cells(pos, vel, mass, kind, gid, n, n_own, x0, cs,
                    order, cell_of, tmp, sx, sy, sz, svx, svy, svz, sm, skind, owned):
    """Sort particles 0..n-1 into cells and copy their fields in that order.

    ``order[k]`` is the particle at sorted place k; ``cell_of[k]`` its cell
    ``(cz * ncy + cy) * ncx + cx``. Returns ``(start, ncx, ncy, ncz, lox,
    loy, loz)``: the particles of cell c are sorted places ``start[c] ..
    start[c+1]-1``; cell (cx, cy, cz) spans x - x0 in [(cx + lox) cs, (cx +
    lox + 1) cs), and likewise y and z from 0.
    """
    dim = pos.shape[1]
    big = 1 << 60
    lox = loy = loz = big
    hix = hiy = hiz = -big
    for i in range(n):
        cx = int(np.floor((pos[i, 0] - x0) / cs))
        cy = int(np.floor(pos[i, 1] / cs))
        cz = int(np.floor(pos[i, 2] / cs)) if dim == 3 else 0
        lox = min(lox, cx)
        hix = max(hix, cx)
        loy = min(loy, cy)
        hiy = max(hiy, cy)
        loz = min(loz, cz)
        hiz = max(hiz, cz)
    if n == 0:
        lox = loy = loz = hix = hiy = hiz = 0
    ncx = hix - lox + 1
    ncy = hiy - loy + 1
    ncz = hiz - loz + 1
    start = np.zeros(ncx * ncy * ncz + 1, np.int64)
    for i in range(n):
        cx = int(np.floor((pos[i, 0] - x0) / cs)) - lox
        cy = int(np.floor(pos[i, 1] / cs)) - loy
        cz = (int(np.floor(pos[i, 2] / cs)) - loz) if dim == 3 else 0
        c = (cz * ncy + cy) * ncx + cx
        tmp[i] = c
        start[c + 1] += 1
    for c in range(ncx * ncy * ncz):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    for i in range(n):
        c = tmp[i]
        # insertion by gid keeps each cell sorted
        k = fill[c]
        while k > start[c] and gid[order[k - 1]] > gid[i]:
            order[k] = order[k - 1]
            k -= 1
        order[k] = i
        fill[c] += 1
    for k in range(n):
        i = order[k]
        cell_of[k] = tmp[i]
        sx[k] = pos[i, 0]
        sy[k] = pos[i, 1]
        svx[k] = vel[i, 0]
        svy[k] = vel[i, 1]
        if dim == 3:
            sz[k] = pos[i, 2]
            svz[k] = vel[i, 2]
        else:
            sz[k] = 0.0
            svz[k] = 0.0
        sm[k] = mass[i]
        skind[k] = kind[i]
        owned[k] = i < n_own
    return start, ncx, ncy, ncz, lox, loy, loz
