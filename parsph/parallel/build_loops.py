"""The slab ring's loops at a list build: wrapping into the box, the migration's sort of the owned
particles (stay, go up, go down) and the choice of the ghosts each neighbour needs, as numba loops
over flat arrays, so that :class:`parsph.parallel.slab_ring.SlabRing` calls each once per build.
"""
import math

import numpy as np
from numba import njit


@njit(cache=True)
def wrap_fields(fields, n, periodic, period):
    """Wrap particles 0..n-1 into [0, period) along each periodic axis, moving every array of ``fields``
    (the first is the position) by the first one's shift: x -= floor(x / L) L, then -L where rounding
    left x == L."""
    pos = fields[0]
    dim = pos.shape[1]
    for axis in range(dim):
        if not periodic[axis]:
            continue
        L = period[axis]
        for i in range(n):
            shift = math.floor(pos[i, axis] / L) * L
            for f in fields:
                f[i, axis] -= shift
            if pos[i, axis] >= L:
                for f in fields:
                    f[i, axis] -= L


@njit(cache=True)
def sort_strays(y, n, bounds, rank, size, idx):
    """Order the owned places 0..n-1 into ``idx``: those staying (in order), those going up (to rank + 1,
    the shorter way round to their owner), those going down. Returns (staying, up, down, hops), hops the
    most slabs any of them is from its owner."""
    nb = bounds.shape[0]
    way = np.empty(n, np.int64)  # 0: stays, 1: up, 2: down
    stay = up = 0
    hops = 0
    half = size // 2
    for i in range(n):
        o = np.searchsorted(bounds, y[i, 1], side="right") - 1  # the rank whose [lo, hi) holds y
        o = min(max(o, 0), nb - 2)
        ahead = (o - rank) % size
        if ahead == 0:
            way[i] = 0
            stay += 1
        elif ahead <= half:
            way[i] = 1
            up += 1
            hops = max(hops, ahead)
        else:
            way[i] = 2
            hops = max(hops, size - ahead)
    place = np.array([0, stay, stay + up])
    for i in range(n):
        w = way[i]
        idx[place[w]] = i
        place[w] += 1
    return stay, up, n - stay - up, hops


@njit(cache=True)
def ghost_places(row, n, down_shift, down_last, up_shift, up_first, send_down, send_up):
    """The owned places whose cell row (``row``, numbered as the receiver numbers it after +-shift) is
    within the left neighbour's rows (at most ``down_last``) or the right one's (at least ``up_first``).
    Returns (down, up), the counts written to ``send_down`` and ``send_up``."""
    nd = nu = 0
    for i in range(n):
        r = row[i, 1]
        if r + down_shift <= down_last:
            send_down[nd] = i
            nd += 1
        if r + up_shift >= up_first:
            send_up[nu] = i
            nu += 1
    return nd, nu
