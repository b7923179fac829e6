"""The neighbour list kept valid over the slab ring (LAMMPS's Neighbor deciding and building, with Comm's
exchange and borders): every step a sync refreshes the ghosts, tests the list and agrees over all ranks
on three flags; a build wraps, migrates, chooses the ghosts and images and lists the pairs.

The decision is an all-reduce of quantities that do not depend on the decomposition, so every rank
count rebuilds on the same steps and the results do not depend on it, bit for bit. The first build
of a restart takes the list's reference positions from the snapshot, so that the same list is built
again.
"""
import numpy as np

from parsph.sph.neighbour_list import NeighbourList


class ListKeeper:
    """The list of this rank (:attr:`neighbours`), the ring it is kept over and this rank's flags since
    the last sync: ``bad`` (the last integration left a non-finite or jumping particle), ``stop`` (a
    signal's number), ``force`` (rebuild at the next sync)."""

    def __init__(self, ring, grid, skin, collect, position_fields, timers, clock):
        self.ring, self.skin, self.collect = ring, skin, collect
        self.position_fields = position_fields
        self.timers, self.clock = timers, clock
        self.neighbours = NeighbourList(grid)
        self._grid_params = grid.params()
        self._coords = np.zeros((0, 3), np.int64)  # cell coordinates per local particle at a build
        self._flags = np.zeros(3)
        self.built = False     # no list yet: the first sync builds one
        self.restore = False   # the first build takes ``ref`` from a snapshot
        self.rebuilds = 0
        self.clear()

    def clear(self):
        self.bad = 0
        self.stop = 0
        self.force = False

    def sync(self, ps):
        """Refresh the ghosts, test the list; returns the flags (bad, stop, rebuild) agreed over all ranks
        (one all-reduce) and clears this rank's."""
        t0 = self.clock()
        n = ps.n_own
        np.subtract(ps.pos[:n], ps.ref[:n], out=ps.disp[:n])  # positions may have changed (a step, a caller)
        self.ring.forward(ps)
        spread = self.neighbours.spread(ps.disp)
        f = self._flags
        f[0] = self.bad
        f[1] = self.stop
        f[2] = 1.0 if (self.force or not spread < self.skin) else 0.0
        agreed = self.collect.max(f)
        self.timers["sync"] += self.clock() - t0
        self.clear()
        return agreed

    def build(self, ps, restore=False):
        """Wrap, migrate, choose the ghosts and images, build the list (collective).

        The list is built from the reference positions ``ref``: the current
        ones, wrapped into the box, except on ``restore``, where ``ref`` came
        from a snapshot with the positions as the writing run held them.
        """
        ring = self.ring
        ps.n = ps.n_own
        if not restore:
            ring.wrap(ps, self.position_fields)
            ps.ref[:ps.n_own] = ps.pos[:ps.n_own]
        ring.migrate(ps, "ref")
        if len(self._coords) < ps.capacity:
            self._coords = np.zeros((ps.capacity, 3), np.int64)
        coords = self._coords
        # owned particles in cell order (z, y, x), by gid inside a cell: neighbours sit close in memory
        local = ring.local_box(ps.dim)
        ps.reorder_owned(self.neighbours.sort_owned(ps, coords, local, self._grid_params))
        coords = ring.exchange_ghosts(ps, coords)
        coords = ring.add_images(ps, coords)
        self._coords = coords
        ps.disp[:ps.n] = 0.0  # the next forward sends the owners' displacements
        self.neighbours.build(ps, coords, local)
        self.built = True
        self.rebuilds += 1
