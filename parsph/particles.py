"""Particle storage: flat numpy arrays, owned particles first, then halo copies.

Indices ``0 .. n_own-1`` are the particles this rank owns; ``n_own .. n-1``
are halo copies received from the neighbouring slabs for the current step.
Arrays have spare capacity so that halo exchange and migration rarely
allocate.
"""
import numpy as np
from numba import njit

FLUID, WALL, MOVING_WALL = 0, 1, 2


class Particles:
    def __init__(self, dim, capacity=16):
        self.dim = dim
        self.n_own = 0
        self.n = 0
        self._alloc(max(16, capacity))

    def _alloc(self, cap, old=None, keep=0):
        dim = self.dim
        new = {
            "gid": np.zeros(cap, np.int64),
            "kind": np.zeros(cap, np.int64),
            "mass": np.zeros(cap),
            "pos": np.zeros((cap, dim)),
            "vel": np.zeros((cap, dim)),
            "acc": np.zeros((cap, dim)),
            "rho": np.zeros(cap),
            "theta": np.zeros(cap),
        }
        if old is not None:
            for name, arr in new.items():
                arr[:keep] = old[name][:keep]
        for name, arr in new.items():
            setattr(self, name, arr)
        self.capacity = cap

    def ensure(self, n, keep=None):
        """Grow every array to hold at least n particles, keeping the first ``keep``."""
        if n > self.capacity:
            old = {name: getattr(self, name) for name in
                   ("gid", "kind", "mass", "pos", "vel", "acc", "rho", "theta")}
            self._alloc(max(n, int(1.5 * self.capacity)), old, self.n if keep is None else keep)

    @classmethod
    def from_arrays(cls, gid, kind, mass, pos, vel):
        n = len(gid)
        p = cls(pos.shape[1], capacity=int(1.3 * n) + 16)
        p.gid[:n], p.kind[:n], p.mass[:n], p.pos[:n], p.vel[:n] = gid, kind, mass, pos, vel
        p.n_own = p.n = n
        return p

    # ---- packing of whole particles into float64 rows (halo, migration) ----
    @property
    def row_width(self):
        return 4 + 2 * self.dim

    ycol = 4  # column of the y coordinate in a packed row

    def pack(self, idx, k, out):
        """Write particles ``idx[:k]`` as rows [gid, kind, mass, pos, vel, rho] into ``out``.

        rho travels because wall particles hold theirs (fluid densities are
        recomputed every step).
        """
        _pack(self.gid, self.kind, self.mass, self.pos, self.vel, self.rho, idx, k, out)

    def unpack(self, rows, start):
        """Store ``rows`` as particles ``start .. start+len(rows)-1``."""
        _unpack(rows, start, self.gid, self.kind, self.mass, self.pos, self.vel, self.rho)

    def keep_owned(self, gone, k):
        """Drop the owned particles ``gone[:k]`` (ascending indices), keeping the others' order."""
        self.n_own = self.n = _compact(gone, k, self.n_own, self.gid, self.kind, self.mass, self.pos, self.vel,
                                       self.rho)


@njit(cache=True)
def _pack(gid, kind, mass, pos, vel, rho, idx, k, out):
    d = pos.shape[1]
    for r in range(k):
        i = idx[r]
        out[r, 0] = gid[i]
        out[r, 1] = kind[i]
        out[r, 2] = mass[i]
        for c in range(d):
            out[r, 3 + c] = pos[i, c]
            out[r, 3 + d + c] = vel[i, c]
        out[r, 3 + 2 * d] = rho[i]


@njit(cache=True)
def _unpack(rows, start, gid, kind, mass, pos, vel, rho):
    d = pos.shape[1]
    for r in range(rows.shape[0]):
        i = start + r
        gid[i] = np.int64(rows[r, 0])
        kind[i] = np.int64(rows[r, 1])
        mass[i] = rows[r, 2]
        for c in range(d):
            pos[i, c] = rows[r, 3 + c]
            vel[i, c] = rows[r, 3 + d + c]
        rho[i] = rows[r, 3 + 2 * d]


@njit(cache=True, inline="always")
def _copy(i, j, gid, kind, mass, pos, vel, rho):
    """Particle i's fields into place j."""
    gid[j] = gid[i]
    kind[j] = kind[i]
    mass[j] = mass[i]
    rho[j] = rho[i]
    for c in range(pos.shape[1]):
        pos[j, c] = pos[i, c]
        vel[j, c] = vel[i, c]


@njit(cache=True)
def _compact(gone, k, n, gid, kind, mass, pos, vel, rho):
    """Remove indices gone[:k] (ascending) from 0..n-1 in place; return the new count."""
    w = 0
    g = 0
    for i in range(n):
        if g < k and gone[g] == i:
            g += 1
            continue
        if w != i:
            _copy(i, w, gid, kind, mass, pos, vel, rho)
        w += 1
    return w


@njit(cache=True)
def add_images(gid, kind, mass, pos, vel, rho, n, axis, period, width, src):
    """Append periodic copies of particles 0..n-1 lying within ``width`` of either end of [0, period).

    Copies are shifted by +period (near 0) or -period (near the top); ``src``
    receives each copy's original index. Returns the number of copies (the
    arrays must have room for them: see :func:`count_images`).
    """
    k = 0
    for i in range(n):
        x = pos[i, axis]
        for shift in (period, -period):
            if (shift > 0.0 and x < width) or (shift < 0.0 and x >= period - width):
                j = n + k
                _copy(i, j, gid, kind, mass, pos, vel, rho)
                pos[j, axis] = x + shift
                src[k] = i
                k += 1
    return k


@njit(cache=True)
def count_images(pos, n, axis, period, width):
    k = 0
    for i in range(n):
        x = pos[i, axis]
        if x < width:
            k += 1
        if x >= period - width:
            k += 1
    return k


@njit(cache=True)
def copy_from_sources(arr, start, src, k):
    """arr[start + m] = arr[src[m]] for m < k (refresh periodic copies)."""
    for m in range(k):
        arr[start + m] = arr[src[m]]
