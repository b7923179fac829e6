"""The neighbour list: unique pairs within r_c = 2h + skin, kept for as many steps as it stays valid.

Cells. A global grid of cells of side at least r_c / M per direction (M =
``CELLS_PER_CUTOFF``) tiles the periodic directions exactly (y always; x
without walls; z in 3-D). A particle's integer cell coordinates are taken
from its position in its owner's frame (wrapped into the box) plus a whole
number of periods for a periodic copy, so every copy of a particle lies in
the same cell on any rank count, bit for bit. Without walls in x the grid
spans the wall particles' lattice columns; a particle beyond them is
clamped into the edge cell, so a runaway particle cannot make the grid grow.

Order. The local particles (owned, ghosts, images) are sorted by cell (z,
y, x, lexicographic) and by global id inside a cell. The pair list holds
every unique pair (a, b), a before b in that order, within r_c of each
other, of which at least one member is an owned fluid particle, in that
order: a particle's pairs therefore come in the order of its neighbours'
places. That order is the same on any rank count, and the loops of
:mod:`parsph.sph.density` and :mod:`parsph.sph.momentum` add each particle's contributions in it, so results
do not depend on the rank or thread count, bit for bit.

Validity. The list built at step n holds every pair within 2h at step m > n
if no two particles whose cells are at most 2M apart along every direction
moved by more than the skin relative to each other since n. The test
(:func:`patch_spread`): the bounding box of the displacements of the
particles in each patch of (2M+1)^d cells, an empty cell counting as
displacement 0, has a diagonal below the skin. Proof: a pair whose cells
are at most 2M apart in every direction lies in the patch centred between
them, so its distance changed by less than the skin, and one that was
farther than r_c apart came no closer than 2h. A pair whose cells are more
than 2M apart along some direction was at least 2 r_c apart; a chain of
patches joins them, each adding less than one skin of relative displacement
per 2M cells crossed, which is never enough to close the gap to 2h.
Relative, not absolute, displacement is what counts: a plate that carries
its neighbours along at V_w does not force a rebuild.
"""
import math
from typing import NamedTuple

import numpy as np
from numba import njit, uintp

from .particles import GRAIN

CELLS_PER_CUTOFF = 2  # M: cells of side r_c / 2; patches of 5^d cells span 2.5 r_c


class Axis:
    """The cells along one direction: ``n`` cells of side ``side`` from ``origin``; periodic or clamped."""

    def __init__(self, periodic, length, origin, extent, cutoff):
        m = CELLS_PER_CUTOFF
        self.periodic = periodic
        if periodic:
            self.n = max(1, int(math.floor(m * length / cutoff * (1 + 1e-12))))
            self.side = length / self.n
            self.origin = 0.0
            self.period = length
        else:
            self.side = cutoff / m
            self.origin = origin
            # the last cell holds the outermost lattice column: no empty cell at the edge
            self.n = int(math.floor(extent / self.side)) + 1
            self.period = 0.0


class Grid:
    """The global cell grid of a run: one :class:`Axis` per direction (x, y, z; z = one cell in 2-D)."""

    def __init__(self, cutoff, dim, walls, L, Ly, Lz, x_lo, x_hi):
        self.cutoff = cutoff
        self.dim = dim
        self.m = CELLS_PER_CUTOFF
        self.axes = [Axis(not walls, L, x_lo, x_hi - x_lo, cutoff), Axis(True, Ly, 0.0, Ly, cutoff),
                     Axis(True, Lz, 0.0, Lz, cutoff) if dim == 3 else None]
        if dim == 2:
            z = Axis(False, 1.0, 0.0, 0.0, cutoff)
            z.n, z.side = 1, 1.0
            self.axes[2] = z

    def params(self):
        """(origin, side, n, periodic) per direction as arrays for the numba functions."""
        a = self.axes
        return (np.array([x.origin for x in a]), np.array([x.side for x in a]),
                np.array([x.n for x in a], np.int64), np.array([int(x.periodic) for x in a], np.int64))


class CellBox(NamedTuple):
    """A rank's local cell box, in global integer cell coordinates (``SlabRing.local_box``)."""
    lo: np.ndarray         # the first cell per direction
    size: np.ndarray       # cells per direction
    centre_lo: np.ndarray  # the patch centres of the validity test: local cells centre_lo .. centre_hi
    centre_hi: np.ndarray


class CellOrder(NamedTuple):
    """The local particles sorted by cell (:func:`sort_by_cell`)."""
    cell: np.ndarray   # local cell id per particle
    order: np.ndarray  # order[a]: the particle at sorted place a
    start: np.ndarray  # the places of cell c: start[c] .. start[c+1]-1
    n: int             # particles sorted


def grid_for(cfg, kernel):
    """The cell grid of a run: cutoff 2h + skin; without walls x spans [0, L), with walls the lattice columns."""
    cutoff = kernel.support * cfg.h + cfg.get("numerics.skin") * cfg.h
    edge = (cfg.layers - 0.5) * cfg.dx  # the outermost wall particles' distance beyond the plates
    x_lo, x_hi = (-edge, cfg.L + edge) if cfg.scene.walls else (0.0, cfg.L)
    return Grid(cutoff, cfg.dim, cfg.scene.walls, cfg.L, cfg.Ly_ring, cfg.Lz if cfg.dim == 3 else 0.0, x_lo, x_hi)


@njit(cache=True)
def cell_coords(pos, start, stop, origin, side, ncell, periodic, out):
    """Integer cell coordinates of particles start..stop-1 (positions in the owner's frame, wrapped)."""
    dim = pos.shape[1]
    for i in range(start, stop):
        for d in range(3):
            if d >= dim:
                out[i, d] = 0
                continue
            c = int(math.floor((pos[i, d] - origin[d]) / side[d]))
            if c < 0:
                c = 0
            elif c >= ncell[d]:
                c = ncell[d] - 1
            out[i, d] = c


@njit(cache=True)
def local_cells(coords, n, local, cell):
    """Local cell ids ((cz - lo_z) size_y + cy - lo_y) size_x + cx - lo_x, clamped into the :class:`CellBox`."""
    lo, size = local.lo, local.size
    for i in range(n):
        c = 0
        for d in (2, 1, 0):
            k = coords[i, d] - lo[d]
            if k < 0:
                k = 0
            elif k >= size[d]:
                k = size[d] - 1
            c = c * size[d] + k
        cell[i] = c


@njit(cache=True, inline="always")
def _starts(count, m):
    """The counts of m buckets in ``count[1..m]`` become their first places (``count[b]``, in place, a prefix
    sum); returns a copy of the first places, to be advanced as the buckets are filled."""
    for b in range(m):
        count[b + 1] += count[b]
    return count[:m].copy()


@njit(cache=True)
def sort_by_cell(cell, gid, n, ncells, order, start):
    """Counting sort of particles 0..n-1 by cell, by gid inside a cell: ``order[a]`` is the a-th particle.

    ``start[c] .. start[c+1]-1`` are the places of cell c.
    """
    start[:ncells + 1] = 0
    for i in range(n):
        start[cell[i] + 1] += 1
    fill = _starts(start, ncells)
    for i in range(n):
        c = cell[i]
        k = fill[c]
        while k > start[c] and gid[order[k - 1]] > gid[i]:  # insertion by gid: cells hold a few particles
            order[k] = order[k - 1]
            k -= 1
        order[k] = i
        fill[c] += 1


@njit(cache=True)
def build_pairs(pos, need, cells, local, cutoff, pstart, pi, pj):
    """Unique pairs within ``cutoff`` of the particles sorted into ``cells`` (:class:`CellOrder`) in the
    :class:`CellBox` ``local``, in sorted order (see the module docstring); returns their count.

    The pairs of the particle at sorted place a (with the particles after it)
    are ``pstart[a] .. pstart[a+1]-1``; ``pi``/``pj`` hold their members.
    ``pi``/``pj`` must hold every pair and one more; if they are too short, the
    count is returned negative (minus the pairs found) and the caller grows them.
    """
    cell, order, start, n, size = cells.cell, cells.order, cells.start, cells.n, local.size
    m = 2  # CELLS_PER_CUTOFF
    dim = pos.shape[1]
    cut2 = cutoff * cutoff
    cap = uintp(pi.shape[0])
    one = uintp(1)
    npairs = uintp(0)  # unsigned, as the indices below: no test for a negative index in the loop
    nx, ny, nz = size[0], size[1], size[2]
    # positions and needs in sorted order: the candidates of a cell row are contiguous in memory
    xs = np.empty(n)
    ys = np.empty(n)
    zs = np.zeros(n)
    ns = np.empty(n, np.bool_)
    for b in range(n):
        j = order[b]
        xs[b] = pos[j, 0]
        ys[b] = pos[j, 1]
        if dim == 3:
            zs[b] = pos[j, 2]
        ns[b] = need[j]
    for a in range(n):
        pstart[a] = min(npairs, cap)
        i = order[a]
        c = cell[i]
        cx = c % nx
        cy = (c // nx) % ny
        cz = c // (nx * ny)
        xi = xs[a]
        yi = ys[a]
        zi = zs[a]
        need_i = ns[a]
        for z in range(cz, min(cz + m, nz - 1) + 1):  # rows before particle a's hold only earlier places
            for y in range(cy if z == cz else max(cy - m, 0), min(cy + m, ny - 1) + 1):
                row = (z * ny + y) * nx
                lo = max(start[row + max(cx - m, 0)], a + 1)
                hi = start[row + min(cx + m, nx - 1) + 1]
                if hi <= lo:  # (an unsigned range must not start past its end)
                    continue
                for b in range(uintp(lo), uintp(hi)):
                    dx = xi - xs[b]
                    dy = yi - ys[b]
                    r2 = dx * dx + dy * dy
                    if dim == 3:
                        dz = zi - zs[b]
                        r2 += dz * dz
                    # branch-free compaction: always store, advance only for a pair (about half the candidates)
                    k = npairs if npairs < cap else cap - one
                    pi[k] = i
                    pj[k] = order[b]
                    npairs += uintp((r2 < cut2) & (need_i | ns[b]))
    pstart[n] = min(npairs, cap)
    count = np.int64(npairs)
    return count if npairs < cap else -count


@njit(cache=True)
def order_owned(ref, gid, n, origin, side, ncell, periodic, local, coords, cell, order, start):
    """At a build, the owned particles 0..n-1: their cell coordinates (from ``ref``) into ``coords``, their
    order by cell and gid into ``order`` (:func:`sort_by_cell`), and ``coords`` put in that order."""
    cell_coords(ref, 0, n, origin, side, ncell, periodic, coords)
    local_cells(coords, n, local, cell)
    ncells = local.size[0] * local.size[1] * local.size[2]
    sort_by_cell(cell, gid, n, ncells, order, start)
    tmp = coords[:n].copy()
    for a in range(n):
        for d in range(3):
            coords[a, d] = tmp[order[a], d]


@njit(cache=True)
def build_list(ref, gid, kind, n, n_own, coords, local, cutoff, cell, order, start, need, pstart, pi, pj):
    """The list of the n local particles in one call: their cells, the sort by cell and gid, which need
    sums (the owned fluid particles), and the pairs (:func:`build_pairs`; its return)."""
    local_cells(coords, n, local, cell)
    ncells = local.size[0] * local.size[1] * local.size[2]
    sort_by_cell(cell, gid, n, ncells, order, start)
    for i in range(n):
        need[i] = i < n_own and kind[i] == GRAIN
    return build_pairs(ref, need, CellOrder(cell, order, start, n), local, cutoff, pstart, pi, pj)


@njit(cache=True)
def build_entries(pi, pj, npairs, need, n, offset, entry):
    """Per particle that needs sums, its pairs in ascending order: ``entry = 2 p + side`` (side 1: it is pj[p]).

    For the threaded loops, which sum each particle's pair values in this
    order (the same order in which the serial loops add them).
    """
    offset[:n + 1] = 0
    for p in range(npairs):
        if need[pi[p]]:
            offset[pi[p] + 1] += 1
        if need[pj[p]]:
            offset[pj[p] + 1] += 1
    fill = _starts(offset, n)
    for p in range(npairs):
        i = pi[p]
        j = pj[p]
        if need[i]:
            entry[fill[i]] = 2 * p
            fill[i] += 1
        if need[j]:
            entry[fill[j]] = 2 * p + 1
            fill[j] += 1


def _window3(larger):
    """A numba loop: d = the minimum (``larger``: maximum) of s over cells k-1, k, k+1 along one axis of
    ``length`` cells ``stride`` apart, clipped at the axis' ends; m of them in turn give the window of
    2m+1 cells. Unsigned indices and a select without a flag: a loop LLVM puts on vector registers."""
    if larger:
        @njit(cache=True, inline="always")
        def pick(a, b):
            return a if a > b else b
    else:
        @njit(cache=True, inline="always")
        def pick(a, b):
            return a if a < b else b

    @njit(cache=True)
    def window3(s, d, ncells, stride, length):
        one = uintp(1)
        st = uintp(stride)
        ln = uintp(length)
        last = (ln - one) * st
        for o in range(uintp(ncells // (stride * length))):
            b = o * st * ln
            if stride == 1:  # along the row: the loop over k is the long one
                d[b] = pick(s[b], s[b + one])
                for c in range(b + one, b + last):
                    d[c] = pick(pick(s[c - one], s[c]), s[c + one])
                d[b + last] = pick(s[b + last - one], s[b + last])
                continue
            for t in range(b, b + st):
                d[t] = pick(s[t], s[t + st])
            for k in range(one, ln - one):
                c0 = b + k * st
                for c in range(c0, c0 + st):
                    d[c] = pick(pick(s[c - st], s[c]), s[c + st])
            for t in range(b + last, b + last + st):
                d[t] = pick(s[t - st], s[t])
    return window3


_min3 = _window3(False)
_max3 = _window3(True)


@njit(cache=True)
def patch_spread(disp, cells, local, box, work):
    """The largest diagonal of the displacement box of any patch of (2M+1)^d cells centred in ``local``'s
    centre range, for the particles sorted into ``cells``.

    ``box`` and ``work`` ((6, ncells)) are scratch space: rows 0..dim-1
    hold the minima, 3..3+dim-1 the maxima. Empty cells count as
    displacement 0. Blocks are clipped at the local grid's edges; centres
    run over ``centre_lo[d] .. centre_hi[d]`` (local cells whose
    (2M+1)-wide neighbourhood is complete on this rank). The window is M
    windows of 3 cells along each axis in turn (min and max are exact, so
    any grouping gives the same numbers). An infinite displacement makes
    the result infinite; a NaN one is not seen here (the step's non-finite
    flag stops the run first).
    """
    size, centre_lo, centre_hi = local.size, local.centre_lo, local.centre_hi
    dim = disp.shape[1]
    nx, ny, nz = size[0], size[1], size[2]
    ncells = uintp(nx * ny * nz)
    order, start = cells.order, cells.start
    for c in range(ncells):  # each cell's box from its sorted places: no store-to-load chains
        lo = uintp(start[c])
        hi = uintp(start[c + 1])
        for q in range(dim):
            mn = np.inf
            mx = -np.inf
            for k in range(lo, hi):
                v = disp[uintp(order[k]), q]
                mn = v if v < mn else mn
                mx = v if v > mx else mx
            box[q, c] = mn if hi > lo else 0.0
            box[3 + q, c] = mx if hi > lo else 0.0
    src = box
    dst = work
    stride = 1
    for axis in range(3):
        length = size[axis]
        if length > 1:
            for _ in range(CELLS_PER_CUTOFF):
                for q in range(dim):
                    _min3(src[q], dst[q], ncells, stride, length)
                    _max3(src[3 + q], dst[3 + q], ncells, stride, length)
                src, dst = dst, src
        stride *= length
    worst2 = 0.0
    for z in range(centre_lo[2], centre_hi[2] + 1):
        for y in range(centre_lo[1], centre_hi[1] + 1):
            row = uintp((z * ny + y) * nx)
            for x in range(uintp(centre_lo[0]), uintp(centre_hi[0] + 1)):
                c = row + x
                d2 = 0.0
                for q in range(dim):
                    e = src[3 + q, c] - src[q, c]
                    d2 += e * e
                if not d2 <= worst2:  # also NaN (inf - inf): the worst
                    worst2 = d2 if d2 == d2 else np.inf
    return math.sqrt(worst2)
