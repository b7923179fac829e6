"""Particle storage: flat numpy arrays, owned particles first, then halo copies.

Indices ``0 .. n_own-1`` are the particles this rank owns; ``n_own .. n-1``
are copies of other ranks' particles (ghosts) and periodic images, made at
the last neighbour-list build and refreshed every step. Arrays have spare
capacity so that rebuilds rarely allocate.

Every field is a per-particle array of float64 (or int64) with an optional
trailing shape. Whole particles travel between ranks only at a rebuild
(migration), as float64 rows holding every field that is not recomputed
after a rebuild (:meth:`Particles.rows`; ``DERIVED`` are not carried), so a
field added with :meth:`Particles.add_field` (the midpoint integrator's
saved state, say) migrates without further code.

Fields:
    gid, kind, mass      identity, FLUID/WALL/MOVING_WALL, mass [kg/m in 2-D]
    pos, vel, acc        position (not wrapped between rebuilds), velocity, acceleration
    rho, theta           summation density Eq. (3), volume fraction
    disp                 displacement since the last rebuild (the list's validity test)
    jump                 length of the last step's displacement (run-time check 5)
"""
import math

import numpy as np
from numba import njit

FLUID, WALL, MOVING_WALL = 0, 1, 2
# recomputed by the evaluation that follows every rebuild: neither migrated nor reordered
DERIVED = ("acc", "theta", "disp")


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
    def rows(self, idx):
        """Particles ``idx`` as float64 rows holding every field (ids are exact below 2^53)."""
        k = len(idx)
        cols = [getattr(self, name)[idx].reshape(k, int(np.prod(shape, dtype=np.int64))).astype(float)
                for name, (_, shape) in self._carried()]
        return np.concatenate(cols, axis=1)

    def put_rows(self, rows, start):
        """Store ``rows`` (from :meth:`rows`) as particles ``start .. start+len(rows)-1``."""
        c = 0
        k = len(rows)
        for name, (dtype, shape) in self._carried():
            w = int(np.prod(shape, dtype=np.int64))
            getattr(self, name)[start:start + k] = rows[:, c:c + w].reshape((k,) + shape).astype(dtype)
            c += w

    def remove_owned(self, gone):
        """Drop the owned particles ``gone`` (a boolean mask over 0..n_own-1), keeping the others' order."""
        keep = np.flatnonzero(~gone)
        self.reorder_owned(keep)

    def reorder_owned(self, order):
        """Owned particles become ``order`` (indices into 0..n_own-1, each at most once); halo copies are dropped.

        The DERIVED fields are left as they are (the next evaluation recomputes them)."""
        k = len(order)
        for name, _ in self._carried():
            _take_rows(getattr(self, name), order)
        self.n_own = self.n = k


@njit(cache=True)
def _take_rows(arr, order):
    """arr[:len(order)] = arr[order] (rows; ``order`` holds each index at most once)."""
    tmp = arr[order]
    arr[:order.shape[0]] = tmp


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
        if kind[i] == FLUID and not theta[i] <= th:
            th = theta[i]
    return math.sqrt(v2), th, math.sqrt(a2)
