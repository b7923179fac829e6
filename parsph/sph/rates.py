"""The right-hand side on one rank: the passes of Eq. (3) and Eq. (5) over a neighbour list.

:meth:`Rates.attach` takes the list of a build (:class:`parsph.sph.neighbour_list.NeighbourList`)
and sizes the passes' scratch to it; calling the object evaluates density, theta and accelerations.
Between the two passes the densities of the ghosts come from their owners through the ``halo``
object it is handed (:class:`parsph.parallel.slab_ring.SlabRing`); this module knows nothing of MPI.
In LAMMPS's terms, the Pair.
"""
import time

import numpy as np

from . import density, momentum, pass_data, walls
from .dispatch import Calls, threaded

PASSES = {"density_serial": density.density_serial, "density_threaded": density.density_threaded,
          "particle_factors": momentum.particle_factors, "particle_factors_serial": momentum.particle_factors_serial,
          "momentum_serial": momentum.momentum_serial, "momentum_threaded": momentum.momentum_threaded,
          "renormalise": walls.renormalise, "forces": walls.forces}


class Rates:
    """Evaluates rho, theta and the accelerations of the owned particles of a ``Particles`` set, with the
    run's numbers ``consts`` (:class:`pass_data.Constants`) and terms ``switches`` (:class:`pass_data.Switches`)."""

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
        self._calls = Calls(PASSES)

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
        self._calls.forget()

    def gather_arrays(self):
        """The threaded passes' scratch of this build (made once per build)."""
        if self._gather is None:
            offset, entry = self.neighbours.entries()
            npairs = self.neighbours.npairs
            self._gather = pass_data.Gather(offset, entry, np.zeros(npairs), np.zeros(npairs), np.zeros(npairs))
        return self._gather

    def __call__(self, ps, halo, timers=None, clock=time.perf_counter, between=None):
        """Fill ps.rho, ps.theta and ps.acc of the owned particles; ``halo.refresh(ps, ps.rho)`` updates the copies.

        Wall particles keep the rho they hold; mirrored walls (:mod:`.walls`) act through their passes. ``timers`` (a dict) gets the
        seconds of "density", "halo" and "forces" added, read from ``clock``.
        ``between(ps)``: a stage between Eq. (3) and Eq. (5), the particles' theta known (the solved gas:
        :class:`parsph.simulation.gas_stage.GasStage`); its seconds are its own to count.
        """
        lst, c, sw, run = self.list, self.consts, self.switches, self._calls
        parts = pass_data.particle_arrays(ps)
        n, n_own = lst.n, ps.n_own
        gather = self.gather_arrays() if threaded() else None
        t0 = clock()
        # one thread: the serial factors, as the compiled block takes them (no parallel=True code compiled)
        factors = "particle_factors" if gather is not None else "particle_factors_serial"
        if gather is not None:
            run("density_threaded", lst, parts, c, sw, gather)
        else:
            run("density_serial", lst, parts, c, sw)
        if len(sw.mirror):
            run("renormalise", lst, parts, c, sw)
        run(factors, lst, parts, c, sw, 0, n_own)
        t1 = clock()
        halo.refresh(ps, ps.rho)
        t2 = clock()
        run(factors, lst, parts, c, sw, n_own, n)
        if between is not None:
            t_b = clock()
            between(ps)
            t2 += clock() - t_b
        if gather is not None:
            run("momentum_threaded", lst, parts, c, sw, gather)
        else:
            run("momentum_serial", lst, parts, c, sw)
        if len(sw.mirror):
            run("forces", lst, parts, c, sw)
        t3 = clock()
        if timers is not None:
            timers["density"] += t1 - t0
            timers["halo"] += t2 - t1
            timers["forces"] += t3 - t2
