"""Particle storage: flat numpy arrays, owned particles first, then halo copies.

Indices ``0 .. n_own-1`` are the particles this rank owns; ``n_own .. n-1``
are halo copies received from the neighbouring slabs for the current step.
Arrays have spare capacity so that halo exchange and migration rarely
allocate.
"""
import numpy as np

FLUID, WALL, MOVING_WALL = 0, 1, 2
KIND_NAMES = {FLUID: "fluid", WALL: "fixed wall", MOVING_WALL: "moving wall"}

# Fields that travel with a particle (migration, halo, output); acc and rho
# are recomputed every step.
STATE_FIELDS = ("gid", "kind", "mass", "pos", "vel")


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
            "half_G": np.zeros(cap),
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
                   ("gid", "kind", "mass", "pos", "vel", "acc", "rho", "theta", "half_G")}
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
        return 3 + 2 * self.dim

    ycol = 4  # column of the y coordinate in a packed row

    def pack(self, idx, out):
        """Write particles ``idx`` as rows [gid, kind, mass, pos, vel] into ``out``."""
        d = self.dim
        k = len(idx)
        out[:k, 0] = self.gid[idx]
        out[:k, 1] = self.kind[idx]
        out[:k, 2] = self.mass[idx]
        out[:k, 3:3 + d] = self.pos[idx]
        out[:k, 3 + d:3 + 2 * d] = self.vel[idx]

    def unpack(self, rows, start):
        """Store ``rows`` as particles ``start .. start+len(rows)-1``."""
        d = self.dim
        stop = start + len(rows)
        self.gid[start:stop] = rows[:, 0]
        self.kind[start:stop] = rows[:, 1]
        self.mass[start:stop] = rows[:, 2]
        self.pos[start:stop] = rows[:, 3:3 + d]
        self.vel[start:stop] = rows[:, 3 + d:3 + 2 * d]

    def keep_owned(self, mask):
        """Drop the owned particles where ``mask`` is False (order kept)."""
        keep = np.flatnonzero(mask)
        k = len(keep)
        for name in STATE_FIELDS:
            arr = getattr(self, name)
            arr[:k] = arr[keep]
        self.n_own = self.n = k
