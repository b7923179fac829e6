"""Particle storage: flat numpy arrays, owned particles first, then halo copies.

Indices ``0 .. n_own-1`` are the particles this rank owns; ``n_own .. n-1``
are copies of other ranks' particles (ghosts) and periodic images, made at
the last neighbour-list build and refreshed every step. Arrays have spare
capacity so that rebuilds rarely allocate.

Every field is a per-particle array of float64 (or int64) with an optional
trailing shape. Whole particles travel between ranks only at a rebuild
(migration), as float64 rows holding every field that is not recomputed
after a rebuild (:func:`pack_rows`; ``DERIVED`` are not carried), so a
field added with :meth:`Particles.add_field` (the midpoint integrator's
saved state, say) migrates without further code.

Fields:
    gid, kind, mass      identity, GRAIN/WALL/MOVING_WALL, mass [kg/m in 2-D]
    pos, vel, acc        position (not wrapped between rebuilds), velocity, acceleration
    rho, theta           summation density Eq. (3), volume fraction
    disp                 displacement since the last rebuild (the list's validity test)
    jump                 length of the last step's displacement (run-time check 5)
    drag_coef            with a gas: the drag coefficient C per component (pass_data.ParticleArrays.drag_coef)
    drag_rate            with a gas: the closure's K per particle, the drag loops' scratch (ParticleArrays.drag_rate)
    flux                 the solved gas: the mixture's flux j at the particle, from the grid (ParticleArrays.flux)
"""
import math

import numpy as np
from numba import njit

# particle kinds: the solid phase's particles (each a volume of the granular continuum, "grains" beside the
# gas), fixed wall particles, wall particles moving with a plate
GRAIN, WALL, MOVING_WALL = 0, 1, 2
# recomputed by the evaluation that follows every rebuild: neither migrated nor reordered
DERIVED = ("acc", "theta", "disp", "drag_coef", "drag_rate", "flux")


class Particles:
    def __init__(self, dim, capacity=16):
        self.dim = dim
        self.n_own = 0
        self.n = 0
        self.capacity = 0
        self._spec = {}  # name -> (dtype, trailing shape)
        for name, dtype, vector in (("gid", np.int64, False), ("kind", np.int64, False), ("mass", float, False),
                                    ("pos", float, True), ("vel", float, True), ("acc", float, True),
                                    ("rho", float, False), ("theta", float, False), ("disp", float, True),
                                    ("jump", float, False)):
            self._spec[name] = (dtype, (dim,) if vector else ())
        self._alloc(max(16, capacity), keep=0)

    def add_field(self, name, vector=True):
        """A further float64 field (``(n, dim)`` if ``vector``) that migrates with the particles."""
        if name not in self._spec:
            self._spec[name] = (float, (self.dim,) if vector else ())
            setattr(self, name, np.zeros((self.capacity,) + self._spec[name][1]))

    def _carried(self):
        return [(name, spec) for name, spec in self._spec.items() if name not in DERIVED]

    def _alloc(self, cap, keep):
        for name, (dtype, shape) in self._spec.items():
            new = np.zeros((cap,) + shape, dtype)
            if keep:
                new[:keep] = getattr(self, name)[:keep]
            setattr(self, name, new)
        self.capacity = cap

    def ensure(self, n, keep=None):
        """Grow every array to hold at least n particles, keeping the first ``keep`` (default n)."""
        if n > self.capacity:
            self._alloc(max(n, int(1.5 * self.capacity)), self.n if keep is None else keep)

    @classmethod
    def from_arrays(cls, gid, kind, mass, pos, vel):
        n = len(gid)
        p = cls(pos.shape[1], capacity=int(1.3 * n) + 16)
        p.gid[:n], p.kind[:n], p.mass[:n], p.pos[:n], p.vel[:n] = gid, kind, mass, pos, vel
        p.n_own = p.n = n
        return p

    # ---- whole particles as float64 rows (migration) ----------------------------
    def groups(self):
        """The carried fields for the compiled row loops: (int64 fields, float64 scalars, float64 vectors),
        three tuples of arrays (made anew after :meth:`ensure` grows them)."""
        ints, scalars, vectors = [], [], []
        for name, (dtype, shape) in self._carried():
            arr = getattr(self, name)
            (vectors if shape else ints if dtype is np.int64 else scalars).append(arr)
        return tuple(ints), tuple(scalars), tuple(vectors)

    def row_width(self):
        """float64 numbers per particle row (:func:`pack_rows`)."""
        ints, scalars, vectors = self.groups()
        return len(ints) + len(scalars) + self.dim * len(vectors)

    def put_rows(self, rows, start):
        """Store ``rows`` (from :func:`pack_rows`) as particles ``start .. start+len(rows)-1`` (within capacity)."""
        unpack_rows(rows, start, *self.groups())

    def reorder_owned(self, order):
        """Owned particles become ``order`` (indices into 0..n_own-1, each at most once); halo copies are dropped.

        The DERIVED fields are left as they are (the next evaluation recomputes them)."""
        order = np.asarray(order, np.int64)
        take_rows(order, len(order), *self.groups())
        self.n_own = self.n = len(order)


@njit(cache=True)
def pack_rows(idx, k, ints, scalars, vectors, out):
    """Particles idx[:k] as rows of ``out``: the int64 fields, the scalars, then each vector's components."""
    for r in range(k):
        i = idx[r]
        c = 0
        for a in ints:
            out[r, c] = a[i]
            c += 1
        for a in scalars:
            out[r, c] = a[i]
            c += 1
        for a in vectors:
            for d in range(a.shape[1]):
                out[r, c] = a[i, d]
                c += 1


@njit(cache=True)
def unpack_rows(rows, start, ints, scalars, vectors):
    """Rows of :func:`pack_rows` as particles start, start + 1, ..."""
    for r in range(rows.shape[0]):
        i = start + r
        c = 0
        for a in ints:
            a[i] = np.int64(rows[r, c])
            c += 1
        for a in scalars:
            a[i] = rows[r, c]
            c += 1
        for a in vectors:
            for d in range(a.shape[1]):
                a[i, d] = rows[r, c]
                c += 1


@njit(cache=True)
def take_rows(order, k, ints, scalars, vectors):
    """Every field's first k rows become its rows order[:k] (each index at most once)."""
    tmp_i = np.empty(k, np.int64)
    tmp = np.empty(k)
    for a in ints:
        for r in range(k):
            tmp_i[r] = a[order[r]]
        a[:k] = tmp_i
    for a in scalars:
        for r in range(k):
            tmp[r] = a[order[r]]
        a[:k] = tmp
    for a in vectors:
        for d in range(a.shape[1]):
            for r in range(k):
                tmp[r] = a[order[r], d]
            for r in range(k):
                a[r, d] = tmp[r]


@njit(cache=True)
def state_maxima(vel, acc, theta, kind, n, theta_floor):
    """(|v|_max, largest fluid theta (at least ``theta_floor``), |a|_max) of particles 0..n-1, one pass."""
    v2 = 0.0
    a2 = 0.0
    th = theta_floor
    dim = vel.shape[1]
    for i in range(n):
        sv = 0.0
        sa = 0.0
        for d in range(dim):
            sv += vel[i, d] * vel[i, d]
            sa += acc[i, d] * acc[i, d]
        if not sv <= v2:  # NaN propagates: a blow-up is not hidden
            v2 = sv
        if not sa <= a2:
            a2 = sa
        if kind[i] == GRAIN and not theta[i] <= th:
            th = theta[i]
    return math.sqrt(v2), th, math.sqrt(a2)


@njit(cache=True)
def drag_maximum(drag, kind, n):
    """The largest drag coefficient C [1/s] of fluid particles 0..n-1 (NaN propagates)."""
    c = 0.0
    for i in range(n):
        if kind[i] == GRAIN:
            for d in range(drag.shape[1]):
                if not drag[i, d] <= c:
                    c = drag[i, d]
    return c
