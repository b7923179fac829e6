"""The passes' data on one rank: the list of a build, its scratch, the run's numbers and terms.

:meth:`Rates.attach` takes the list of a build (:class:`parsph.sph.neighbour_list.NeighbourList`)
and sizes the passes' scratch to it; the stages of :mod:`parsph.simulation.stages` evaluate density,
theta and accelerations over it (both routes, the compiled block's and the Python path's). This
module knows nothing of MPI. In LAMMPS's terms, the Pair's data.
"""
import numpy as np

from . import pass_data


class Rates:
    """What the passes over the particles of a ``Particles`` set read: the list, its scratch, the run's numbers
    ``consts`` (:class:`pass_data.Constants`) and terms ``switches`` (:class:`pass_data.Switches`)."""

    def __init__(self, consts, switches):
        self.consts = consts
        self.switches = switches
        self.fp = np.zeros(0)
        self.cj = np.zeros(0, np.uint32)
        self.cf = np.zeros(0)
        self.cstart = np.zeros(0, np.int64)
        self.wall_share = np.zeros(0)
        self.list = None      # pass_data.PairList of the attached build
        self.neighbours = None
        self._gather = None   # pass_data.Gather, made when threads are in use
        self._cap = 0
        self._no_gather = pass_data.Gather(np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(0), np.zeros(0),
                                           np.zeros(0))

    def attach(self, nlist):
        """The passes' view of a new build's list, with scratch per particle and per pair sized to it."""
        n = nlist.n
        if self._cap < n:
            self._cap = max(n, int(1.3 * self._cap))
            self.rho_sum = np.zeros(self._cap)
            self.fields = np.zeros((self._cap, 8))
        if len(self.fp) < nlist.npairs:
            self.fp = np.zeros(len(nlist.pi))
            self.cj = np.zeros(len(nlist.pi), np.uint32)
            self.cf = np.zeros(len(nlist.pi))
        if len(self.cstart) < n + 1:
            self.cstart = np.zeros(self._cap + 1, np.int64)
        self.neighbours = nlist
        mirror = len(self.switches.mirror) > 0
        wall_pairs = nlist.wall_pairs() if mirror else np.zeros(0, np.int64)
        if mirror and len(self.wall_share) < n:
            self.wall_share = np.zeros(self._cap)
        self.list = pass_data.PairList(nlist.order, nlist.pstart, nlist.pi, nlist.pj, nlist.need, n, nlist.npairs,
                                       self.fp, self.rho_sum, self.fields, self.cstart, self.cj, self.cf,
                                       wall_pairs, self.wall_share)
        self._gather = None

    def gather_arrays(self):
        """The threaded passes' scratch of this build (made once per build)."""
        if self._gather is None:
            offset, entry = self.neighbours.entries()
            npairs = self.neighbours.npairs
            self._gather = pass_data.Gather(offset, entry, np.zeros(npairs), np.zeros(npairs), np.zeros(npairs))
        return self._gather

    def gather_for(self, threaded):
        """What the passes take as their gather: this build's (:meth:`gather_arrays`) with threads, else an empty
        one of the same types (the serial passes do not read it)."""
        return self.gather_arrays() if threaded else self._no_gather
