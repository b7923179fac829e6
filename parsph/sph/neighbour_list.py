"""The neighbour list of one rank as an object: the particles sorted into cells, the unique pairs within
2h + skin of their reference positions, and the test of whether it still holds (the numba loops and
the proof are in :mod:`parsph.sph.cells`). In LAMMPS's terms, the Neighbor; the passes over it
are :class:`parsph.sph.rates.Rates`.
"""
import numpy as np

from . import cells, walls
from .dispatch import Calls


class NeighbourList:
    """Built at each list build (:meth:`build`); :meth:`spread` tests it every step."""

    def __init__(self, grid):
        self.grid = grid
        self.npairs = 0
        self.n = 0
        self.pi = np.zeros(0, np.int32)
        self.pj = np.zeros(0, np.int32)
        self._cap = 0
        self.start = np.zeros(0, np.int64)
        self._entries = None
        self._wall_pairs = None
        self._calls = Calls({"patch_spread": cells.patch_spread})

    def _room(self, n, ncells):
        if self._cap < n:
            self._cap = max(n, int(1.3 * self._cap))
            self.cell = np.zeros(self._cap, np.int64)
            self.order = np.zeros(self._cap, np.int64)
            self.need = np.zeros(self._cap, np.bool_)
            self.pstart = np.zeros(self._cap + 1, np.int64)
        if len(self.start) < ncells + 1:
            self.start = np.zeros(ncells + 1, np.int64)
            self.box = np.zeros((6, ncells))   # patch_spread's scratch: rows of minima and maxima
            self.work = np.zeros((6, ncells))

    def sort_owned(self, ps, coords, local, grid_params):
        """Cell coordinates of the owned particles from ``ps.ref`` into ``coords``, and the order of the
        owned particles by cell and gid (indices into 0..n_own-1; ``coords`` already in that order)."""
        n = ps.n_own
        self._room(n, int(np.prod(local.size)))
        cells.order_owned(ps.ref, ps.gid, n, *grid_params, local, coords, self.cell, self.order, self.start)
        return self.order[:n]

    def build(self, ps, coords, local):
        """Sort the n local particles into cells and list their unique pairs within 2h + skin of their
        reference positions ``ps.ref`` (the positions at this build).

        ``coords``: integer cell coordinates per particle; ``local``: the
        rank's :class:`parsph.sph.cells.CellBox` (SlabRing.local_box).
        """
        n = ps.n
        self.local = local
        self.size = local.size
        self._room(n, int(np.prod(local.size)))
        if len(self.pi) < 1:  # build_pairs needs room for one store beyond its pairs
            self.pi = np.zeros(16 * n + 64, np.int32)
            self.pj = np.zeros(16 * n + 64, np.int32)
        while True:
            count = cells.build_list(ps.ref, ps.gid, ps.kind, n, ps.n_own, coords, local, self.grid.cutoff,
                                          self.cell, self.order, self.start, self.need, self.pstart, self.pi,
                                          self.pj)
            if count >= 0:
                break
            cap = int(1.2 * -count) + 64
            self.pi = np.zeros(cap, np.int32)
            self.pj = np.zeros(cap, np.int32)
        self.cells = cells.CellOrder(self.cell, self.order, self.start, n)
        self.npairs = count
        self.n = n
        self._kind = ps.kind
        self._entries = None
        self._wall_pairs = None
        self._calls.forget()

    def spread(self, disp):
        """The largest displacement spread over the patches of cells of this rank (the list holds while below the skin)."""
        return self._calls("patch_spread", disp, self.cells, self.local, self.box, self.work)

    def wall_pairs(self):
        """The indices of the pairs of a wall and a fluid particle, in list order (once per build;
        :mod:`parsph.sph.walls`)."""
        if self._wall_pairs is None:
            self._wall_pairs = walls.wall_pairs(self.pi, self.pj, self.npairs, self._kind)
        return self._wall_pairs

    def entries(self):
        """(offset, entry): each particle's pairs in pair order, for the threaded passes (once per build)."""
        if self._entries is None:
            offset = np.zeros(self.n + 1, np.int64)
            entry = np.zeros(2 * self.npairs + 1, np.int64)
            cells.build_entries(self.pi, self.pj, self.npairs, self.need, self.n, offset, entry)
            self._entries = (offset, entry)
        return self._entries
