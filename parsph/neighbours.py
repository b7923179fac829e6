"""Cell linked list (cells of side >= 2h) for neighbour candidates.

Cell coordinates are global: ``floor((x - x0) / cs)`` and ``floor(y / cs)``
(``y`` including the periodic shift of halo copies), so a particle falls into
the same cell whatever the number of ranks. Inside a cell particles are ordered
by global id. Loops that visit the 3^dim neighbour cells in a fixed order
therefore add up contributions in the same order on any rank count, which is
what makes results independent of P bit for bit.
"""
import numpy as np
from numba import njit


@njit(cache=True)
def build_cells(pos, gid, n, x0, cs, cell_xy, order):
    """Sort particles 0..n-1 into cells.

    Fills ``cell_xy[i] = (cx, cy, cz)`` local cell coordinates and ``order``
    (particle indices grouped by cell, by gid inside a cell). Returns
    ``(start, ncx, ncy, ncz)``: particles of cell c are
    ``order[start[c]:start[c+1]]``, with ``c = (cz * ncy + cy) * ncx + cx``.
    """
    dim = pos.shape[1]
    big = 1 << 60
    lo = np.array([big, big, big])
    hi = np.array([-big, -big, -big])
    for i in range(n):
        for d in range(dim):
            if d == 0:
                c = int(np.floor((pos[i, 0] - x0) / cs))
            else:
                c = int(np.floor(pos[i, d] / cs))
            cell_xy[i, d] = c
            if c < lo[d]:
                lo[d] = c
            if c > hi[d]:
                hi[d] = c
    if dim == 2:
        lo[2] = 0
        hi[2] = 0
    ncx = hi[0] - lo[0] + 1
    ncy = hi[1] - lo[1] + 1
    ncz = hi[2] - lo[2] + 1
    start = np.zeros(ncx * ncy * ncz + 1, np.int64)
    for i in range(n):
        cx = cell_xy[i, 0] - lo[0]
        cy = cell_xy[i, 1] - lo[1]
        cz = (cell_xy[i, 2] - lo[2]) if dim == 3 else 0
        cell_xy[i, 0] = cx
        cell_xy[i, 1] = cy
        cell_xy[i, 2] = cz
        start[(cz * ncy + cy) * ncx + cx + 1] += 1
    for c in range(ncx * ncy * ncz):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    for i in range(n):
        c = (cell_xy[i, 2] * ncy + cell_xy[i, 1]) * ncx + cell_xy[i, 0]
        # insertion by gid keeps each cell sorted
        k = fill[c]
        while k > start[c] and gid[order[k - 1]] > gid[i]:
            order[k] = order[k - 1]
            k -= 1
        order[k] = i
        fill[c] += 1
    return start, ncx, ncy, ncz
