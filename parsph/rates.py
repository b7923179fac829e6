"""The right-hand side on one rank: the neighbour list and the passes of Eq. (3) and Eq. (5) over it.

:meth:`Rates.build` makes the list from the local particles (owned, ghosts,
images) at a rebuild; :meth:`Rates.spread` tests whether it still holds;
calling the object evaluates density, theta and accelerations. Between the
two passes the densities of the ghosts come from their owners through the
``halo`` object it is handed (:class:`parsph.decomposition.SlabRing`); this
module knows nothing of MPI.
"""
import time

import numba
import numpy as np

from . import equations, neighbours
from .kernels import kernel_w_f
from .particles import FLUID


class Rates:
    """Evaluates rho, theta and the accelerations of the owned particles of a ``Particles`` set.

    ``switches`` are :func:`equations.switch` values for (pressure,
    viscosity, symmetric viscosity, walls, consistent pressure); ``g`` the
    body force as a 3-vector.
    """

    def __init__(self, kernel, h, dim, rho_s, G_a, G_b, k, L, beta_max, g, switches, grid, skin):
        pressure, viscosity, symmetric_mu, walls, consistent = switches
        self.three_d = equations.switch(dim == 3)
        self.grid = grid
        self.skin = skin
        self.kid = kernel.kid
        self.inv_h = 1.0 / h
        self.norm = kernel.norm(h, dim)
        self.w0 = kernel_w_f(kernel.kid, 0.0, self.inv_h, self.norm)[0]
        self.rho_s, self.G_a, self.G_b = rho_s, G_a, G_b
        self.pressure, self.consistent = pressure, consistent
        self.momentum_consts = (rho_s, G_b, k, L, beta_max, np.asarray(g, float), pressure, viscosity,
                                symmetric_mu, walls, consistent, self.three_d)
        self.npairs = 0
        self.pi = np.zeros(0, np.int32)
        self.pj = np.zeros(0, np.int32)
        self.fp = np.zeros(0)
        self._threaded = None  # (wp, Pp, Vp, offset, entry), made when threads are in use
        self._cap = 0
        self.n = 0

    # ---- the list ------------------------------------------------------------------
    def sort_owned(self, coords, gid, n, box):
        """The order of particles 0..n-1 by cell and gid (a counting sort on the local cell box)."""
        lo, size = box[:2]
        ncells = int(np.prod(size))
        cell = np.zeros(n, np.int64)
        order = np.zeros(n, np.int64)
        start = np.zeros(ncells + 1, np.int64)
        neighbours.local_cells(coords, n, lo, size, cell)
        neighbours.sort_by_cell(cell, gid, n, ncells, order, start)
        return order

    def build(self, ps, coords, box):
        """Sort the n local particles into cells and list their unique pairs within 2h + skin of their
        reference positions ``ps.ref`` (the positions at this build).

        ``coords``: integer cell coordinates per particle; ``box``: (lo, size,
        centre_lo, centre_hi) of the local cell box (SlabRing.local_box).
        """
        n = ps.n
        lo, size, self.centre_lo, self.centre_hi = box
        self.size = size
        ncells = int(np.prod(size))
        if self._cap < n:
            self._cap = max(n, int(1.3 * self._cap))
            self.cell = np.zeros(self._cap, np.int64)
            self.order = np.zeros(self._cap, np.int64)
            self.need = np.zeros(self._cap, np.bool_)
            self.rho_sum = np.zeros(self._cap)
            self.fields = np.zeros((self._cap, 8))
            self.pstart = np.zeros(self._cap + 1, np.int64)
        if not hasattr(self, "start") or len(self.start) < ncells + 1:
            self.start = np.zeros(ncells + 1, np.int64)
            self.box = np.zeros((ncells, 6))
            self.work = np.zeros((ncells, 6))
        neighbours.local_cells(coords, n, lo, size, self.cell)
        neighbours.sort_by_cell(self.cell, ps.gid, n, ncells, self.order, self.start)
        self.need[:n] = False
        self.need[:ps.n_own] = ps.kind[:ps.n_own] == FLUID
        if len(self.pi) < 1:  # build_pairs needs room for one store beyond its pairs
            self.pi = np.zeros(16 * n + 64, np.int32)
            self.pj = np.zeros(16 * n + 64, np.int32)
        while True:
            count = neighbours.build_pairs(ps.ref, self.need, self.order, self.start, self.cell, n, size,
                                           self.grid.cutoff, self.pstart, self.pi, self.pj)
            if count >= 0:
                break
            cap = int(1.2 * -count) + 64
            self.pi = np.zeros(cap, np.int32)
            self.pj = np.zeros(cap, np.int32)
            self.fp = np.zeros(cap)
        self.npairs = count
        if len(self.fp) < count:
            self.fp = np.zeros(len(self.pi))
        self.n = n
        self._threaded = None

    def spread(self, ps):
        """The largest displacement spread over the blocks of this rank (the list holds while below the skin)."""
        return neighbours.block_spread(ps.disp, self.n, self.cell, self.size, self.centre_lo, self.centre_hi,
                                       self.box, self.work)

    def _threaded_arrays(self):
        if self._threaded is None:
            n, npairs = self.n, self.npairs
            offset = np.zeros(n + 1, np.int64)
            entry = np.zeros(2 * npairs + 1, np.int64)
            neighbours.build_entries(self.pi, self.pj, npairs, self.need, n, offset, entry)
            self._threaded = (np.zeros(npairs), np.zeros(npairs), np.zeros(npairs), offset, entry)
        return self._threaded

    # ---- the passes ------------------------------------------------------------------
    def __call__(self, ps, halo, timers=None):
        """Fill ps.rho, ps.theta and ps.acc of the owned particles; ``halo.refresh(ps, ps.rho)`` updates the copies.

        Wall particles keep the rho they hold. ``timers`` (a dict) gets the
        seconds of "density", "halo" and "forces" added.
        """
        n, n_own, npairs = self.n, ps.n_own, self.npairs  # the particles of the last build
        threaded = numba.get_num_threads() > 1
        t0 = time.perf_counter()
        if threaded:
            wp, Pp, Vp, offset, entry = self._threaded_arrays()
            equations.density_threaded(self.order, self.pstart, self.pi, self.pj, n, npairs, ps.pos, ps.mass,
                                       self.kid, self.inv_h, self.norm, self.w0, self.three_d, self.rho_sum, self.fp,
                                       wp, self.need, offset, entry)
        else:
            equations.density_serial(self.order, self.pstart, self.pj, n, ps.pos, ps.mass, self.kid, self.inv_h,
                                     self.norm, self.w0, self.three_d, self.rho_sum, self.fp)
        equations.particle_factors(ps.rho, self.rho_sum, ps.kind, 0, n_own, n_own, self.rho_s, self.G_a, self.G_b,
                                   self.pressure, self.consistent, ps.vel, ps.theta, self.fields)
        t1 = time.perf_counter()
        halo.refresh(ps, ps.rho)
        t2 = time.perf_counter()
        equations.particle_factors(ps.rho, self.rho_sum, ps.kind, n_own, n, n_own, self.rho_s, self.G_a, self.G_b,
                                   self.pressure, self.consistent, ps.vel, ps.theta, self.fields)
        if threaded:
            equations.momentum_threaded(self.order, self.pstart, self.pi, self.pj, n, npairs, self.fp, ps.pos,
                                        ps.mass, ps.kind, self.fields, self.need, n_own, *self.momentum_consts,
                                        ps.acc, Pp, Vp, offset, entry)
        else:
            equations.momentum_serial(self.order, self.pstart, self.pj, n, self.fp, ps.pos, ps.mass, ps.kind,
                                      self.fields, self.need, n_own, *self.momentum_consts, ps.acc)
        t3 = time.perf_counter()
        if timers is not None:
            timers["density"] += t1 - t0
            timers["halo"] += t2 - t1
            timers["forces"] += t3 - t2
