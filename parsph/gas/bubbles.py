"""Bubbles on the solved gas's grid (docs/physics.md, reference 8): the connected sets of cells whose theta
lies below a threshold (:func:`find`), and their motion between two grids (:func:`match`). Serial numpy and
scipy.ndimage on a grid an output holds; no MPI.

A bubble is a set of cells with theta < threshold connected through their faces (4-connected in 2-D,
6-connected in 3-D), joined across a periodic axis (y, and z in 3-D; x in a box periodic along gravity), of at
least :data:`MIN_CELLS` cells (2 x 2; 2 x 2 x 2 in 3-D: a smaller set is below what the grid resolves), not
touching the grid's top row where that is open (a set that does is the clear gas above the bed, or a bubble
that has erupted). Its size is the cells' area (2-D, per unit depth) or volume (3-D), its equivalent diameter
D = sqrt(4 area / pi) or (6 volume / pi)^(1/3), its centroid the cells' mean centre (unwrapped across a
periodic axis at the widest gap between its cells).
"""
from dataclasses import dataclass
import math

import numpy as np

MIN_CELLS = {2: 4, 3: 8}  # a bubble smaller than 2 x 2 (x 2) cells is not resolved by the grid
MATCH_AREA = 1.5       # a pair whose areas differ by more than this factor split or merged: no rise velocity


@dataclass(frozen=True)
class Bubble:
    area: float        # [m^2] per unit depth in 2-D; in 3-D its volume [m^3]
    x: float           # centroid along gravity's axis (height above the floor) [m]
    y: float           # centroid across [m], in [0, Ly)
    cells: tuple       # the cells' indices per axis (numpy arrays)
    z: float = None    # centroid across z [m], in [0, Lz) (3-D)

    @property
    def dim(self):
        return len(self.cells)

    @property
    def diameter(self):
        """The equivalent diameter [m]: D = sqrt(4 area / pi) in 2-D, (6 volume / pi)^(1/3) in 3-D."""
        if self.dim == 3:
            return (6.0 * self.area / math.pi) ** (1.0 / 3.0)
        return math.sqrt(4.0 * self.area / math.pi)


def _unwrapped_mean(index, n):
    """The mean of cell indices on a ring of n cells, cut at the widest gap between the indices present."""
    present = np.unique(index)
    if present.size == n:  # the set spans the ring (a slug across the bed): no unique centre, take the plain mean
        return float(index.mean())
    gaps = np.diff(np.concatenate([present, [present[0] + n]]))
    start = present[(int(np.argmax(gaps)) + 1) % present.size]   # the first index after the widest gap
    return float(np.mean((index - start) % n + start)) % n


def _join(labels, periodic):
    """Labels of components that touch across a periodic axis, joined (union-find over the edge pairs)."""
    parent = np.arange(labels.max() + 1)

    def root(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for axis, wraps in enumerate(periodic):
        if not wraps:
            continue
        first, last = np.take(labels, 0, axis=axis), np.take(labels, -1, axis=axis)
        for a, b in zip(first[(first > 0) & (last > 0)], last[(first > 0) & (last > 0)]):
            ra, rb = root(a), root(b)
            if ra != rb:
                parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([root(a) for a in range(parent.size)])
    return roots[labels]


def find(theta, hx, hy, threshold, periodic=(False, True), open_top=None, hz=None):
    """The bubbles of a grid: theta (nx, ny) of cells hx x hy [m], or (nx, ny, nz) of hx x hy x ``hz`` (x along
    gravity's axis, from the floor), ``periodic`` per axis (z: periodic unless said); ``open_top`` (default: x
    not periodic) leaves out the sets that touch the top row. Returns a list of :class:`Bubble`, largest
    first."""
    theta = np.asarray(theta)
    dim = theta.ndim
    h = (hx, hy, hz)[:dim]
    periodic = tuple(periodic) + (True,) * (dim - len(periodic))
    from scipy import ndimage  # on first use: bed_report imports this module in every run's closing check
    labels, n = ndimage.label(theta < threshold)
    if n == 0:
        return []
    labels = _join(labels, periodic)
    if (not periodic[0]) if open_top is None else open_top:
        labels[np.isin(labels, np.unique(labels[-1]))] = 0
    out = []
    for lab in np.unique(labels[labels > 0]):
        idx = np.nonzero(labels == lab)
        if idx[0].size < MIN_CELLS[dim]:
            continue
        centre = [((_unwrapped_mean(i, m) if wraps else float(i.mean())) + 0.5) * ha
                  for i, m, wraps, ha in zip(idx, theta.shape, periodic, h)]
        out.append(Bubble(idx[0].size * math.prod(h), centre[0], centre[1] % (theta.shape[1] * hy), idx,
                          None if dim == 2 else centre[2] % (theta.shape[2] * hz)))
    out.sort(key=lambda b: -b.area)
    return out


@dataclass(frozen=True)
class Pair:
    """A bubble seen on two grids dt apart: its rise velocity and its mean diameter."""
    before: Bubble
    after: Bubble
    velocity: float    # the centroid's displacement along x over dt [m/s] (up: > 0)

    @property
    def diameter(self):
        return 0.5 * (self.before.diameter + self.after.diameter)

    @property
    def detached(self):
        """Clear of the floor on both grids (none of its cells in the first row): rising, not still forming
        over the floor."""
        return self.before.cells[0].min() > 0 and self.after.cells[0].min() > 0


def match(before, after, dt, shape):
    """Pairs of bubbles of two grids dt [s] apart (``shape`` the grids'): each bubble of ``after``
    with the bubble of ``before`` it overlaps most, where that one overlaps it most too and their areas
    differ by less than :data:`MATCH_AREA` (else it split or merged). Needs outputs close enough that a
    bubble moves less than its size between them."""
    lab = np.zeros(shape, np.int64)
    for k, b in enumerate(before):
        lab[b.cells] = k + 1
    best_of_after = []
    for b in after:
        hits = np.bincount(lab[b.cells], minlength=len(before) + 1)[1:]
        best_of_after.append(int(np.argmax(hits)) if hits.size and hits.max() > 0 else -1)
    pairs = []
    for ka, kb in enumerate(best_of_after):
        if kb < 0:
            continue
        # mutual: of the bubbles of ``after`` that overlap ``before[kb]``, ``after[ka]`` overlaps it most
        theirs = [a for a, c in enumerate(best_of_after) if c == kb]
        if len(theirs) > 1:
            overlap = [np.count_nonzero(lab[after[a].cells] == kb + 1) for a in theirs]
            if theirs[int(np.argmax(overlap))] != ka:
                continue
        b0, b1 = before[kb], after[ka]
        if max(b0.area, b1.area) > MATCH_AREA * min(b0.area, b1.area):
            continue
        pairs.append(Pair(b0, b1, (b1.x - b0.x) / dt))
    return pairs


def throughflow(bubble, u_gx, hy, u_b, hz=1.0):
    """The gas through a bubble in its own frame [m^2/s per unit depth in 2-D; m^3/s in 3-D]: the sum over
    the bubble's cells in its widest layer across x (its equator) of (u_g,x - u_b) times the cell's face (hy;
    hy hz in 3-D). In the bubble eps = 1, so that is the gas crossing the equator relative to the bubble:
    Davidson's 4 U_mf r_b in 2-D, 3 pi U_mf r_b^2 in 3-D (:func:`parsph.physics.bubbling.throughflow`).
    u_gx: the grid's gas velocity along x [m/s]; u_b the bubble's rise velocity [m/s]."""
    rows = bubble.cells[0]
    row = int(np.bincount(rows).argmax())
    sel = rows == row
    at = (np.full(int(sel.sum()), row),) + tuple(c[sel] for c in bubble.cells[1:])
    return float(np.sum(u_gx[at] - u_b) * hy * (hz if bubble.dim == 3 else 1.0))
