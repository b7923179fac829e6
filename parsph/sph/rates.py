"""The right-hand side on one rank: the neighbour list and the passes of Eq. (3) and Eq. (5) over it.

:meth:`Rates.build` makes the list from the local particles (owned, ghosts,
images) at a rebuild; :meth:`Rates.spread` tests whether it still holds;
calling the object evaluates density, theta and accelerations. Between the
two passes the densities of the ghosts come from their owners through the
``halo`` object it is handed (:class:`parsph.parallel.slab_ring.SlabRing`); this
module knows nothing of MPI.
"""
import time

import numba
import numpy as np

from . import equations, neighbours, pass_data
from parsph.physics.kernels import kernel_w_f
from .particles import FLUID


# the passes as compiled here (scripts/bench.py wraps the module's names to time them: these stay as they are)
PASSES = {name: getattr(equations, name) for name in ("density_serial", "density_threaded", "particle_factors",
                                                      "momentum_serial", "momentum_threaded")}
PASSES["block_spread"] = neighbours.block_spread  # the list's validity test, every step


def compiled(dispatcher, *args):
    """The version of a numba pass compiled for the types of ``args`` (compiled, or loaded from the cache, now).

    The dispatcher types named-tuple arguments at every call (6 to 10 us a
    pass more than the same arrays as positional arguments:
    docs/performance.md); the compiled version takes them as they are. The
    dispatcher must have run once (it starts numba's threads, which the
    compiled version expects). Typing the arguments here costs some 100 us
    a named tuple, so :class:`Rates` does it once per kind of arguments
    (:func:`kinds`). Without the JIT (``NUMBA_DISABLE_JIT``) the function is
    returned as it is.
    """
    if not hasattr(dispatcher, "compile"):
        return dispatcher
    return dispatcher.compile(tuple(numba.typeof(a) for a in args))


def kinds(value):
    """What decides a value's numba type, read cheaply: an array's dtype, dimensions, contiguity and
    writeability, a tuple's class and elements, another value's Python type."""
    if isinstance(value, np.ndarray):
        return (value.dtype.char, value.ndim, value.flags.c_contiguous, value.flags.writeable)
    if isinstance(value, tuple):
        return (type(value),) + tuple(kinds(v) for v in value)
    return type(value)


class Rates:
    """Evaluates rho, theta and the accelerations of the owned particles of a ``Particles`` set.

    ``switches`` are :func:`pass_data.switch` values for (pressure,
    viscosity, symmetric viscosity, walls, consistent pressure); ``g`` the
    body force as a 3-vector.
    """

    def __init__(self, kernel, h, dim, rho_s, G_a, G_b, k, L, beta_max, g, switches, grid, skin):
        inv_h = 1.0 / h
        norm = kernel.norm(h, dim)
        w0 = kernel_w_f(kernel.kid, 0.0, inv_h, norm)[0]
        self.consts = pass_data.Constants(kernel.kid, inv_h, norm, w0, rho_s, G_a, G_b, k, L, beta_max,
                                          np.asarray(g, float))
        self.switches = pass_data.Switches(*switches, pass_data.switch(dim == 3))
        self.grid = grid
        self.skin = skin
        self.npairs = 0
        self.pi = np.zeros(0, np.int32)
        self.pj = np.zeros(0, np.int32)
        self.fp = np.zeros(0)
        self.list = None      # pass_data.PairList of the last build
        self._gather = None   # pass_data.Gather, made when threads are in use
        self._passes = {}     # name -> the pass compiled for this build's argument types (compiled())
        self._versions = {}   # (name, kinds(args)) -> the compiled version, kept across builds
        self.wrap = None      # if set, wraps each pass as it is looked up (scripts/bench.py times them)
        self._cap = 0
        self.n = 0

    # ---- the list ------------------------------------------------------------------
    def sort_owned(self, coords, gid, n, local):
        """The order of particles 0..n-1 by cell and gid (a counting sort on the local cell box)."""
        ncells = int(np.prod(local.size))
        cell = np.zeros(n, np.int64)
        order = np.zeros(n, np.int64)
        start = np.zeros(ncells + 1, np.int64)
        neighbours.local_cells(coords, n, local, cell)
        neighbours.sort_by_cell(cell, gid, n, ncells, order, start)
        return order

    def build(self, ps, coords, local):
        """Sort the n local particles into cells and list their unique pairs within 2h + skin of their
        reference positions ``ps.ref`` (the positions at this build).

        ``coords``: integer cell coordinates per particle; ``local``: the
        rank's :class:`parsph.sph.neighbours.CellBox` (SlabRing.local_box).
        """
        n = ps.n
        self.local = local
        self.size = local.size
        ncells = int(np.prod(local.size))
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
        neighbours.local_cells(coords, n, local, self.cell)
        neighbours.sort_by_cell(self.cell, ps.gid, n, ncells, self.order, self.start)
        self.cells = neighbours.CellOrder(self.cell, self.order, self.start, n)
        self.need[:n] = False
        self.need[:ps.n_own] = ps.kind[:ps.n_own] == FLUID
        if len(self.pi) < 1:  # build_pairs needs room for one store beyond its pairs
            self.pi = np.zeros(16 * n + 64, np.int32)
            self.pj = np.zeros(16 * n + 64, np.int32)
        while True:
            count = neighbours.build_pairs(ps.ref, self.need, self.cells, local, self.grid.cutoff, self.pstart,
                                           self.pi, self.pj)
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
        self.list = pass_data.PairList(self.order, self.pstart, self.pi, self.pj, self.need, n, count, self.fp,
                                       self.rho_sum, self.fields)
        self._gather = None
        self._passes = {}

    def spread(self, ps):
        """The largest displacement spread over the blocks of this rank (the list holds while below the skin)."""
        return self._run("block_spread", ps.disp, self.cells, self.local, self.box, self.work)

    def gather_arrays(self):
        """The threaded passes' scratch of this build (made once per build)."""
        if self._gather is None:
            n, npairs = self.n, self.npairs
            offset = np.zeros(n + 1, np.int64)
            entry = np.zeros(2 * npairs + 1, np.int64)
            neighbours.build_entries(self.pi, self.pj, npairs, self.need, n, offset, entry)
            self._gather = pass_data.Gather(offset, entry, np.zeros(npairs), np.zeros(npairs), np.zeros(npairs))
        return self._gather

    # ---- the passes ------------------------------------------------------------------
    def _run(self, name, *args):
        """Call pass ``name`` (of PASSES) through its compiled version, looked up once per list build.

        The first call with arguments of a new kind goes through numba's
        dispatcher (which compiles or loads the pass and starts numba's
        threads); the compiled version for that kind is kept across builds.
        """
        fn = self._passes.get(name)
        if fn is not None:
            return fn(*args)
        wrap = self.wrap or (lambda f: f)
        key = (name, kinds(args))
        version = self._versions.get(key)
        if version is None:
            dispatcher = PASSES[name]
            out = wrap(dispatcher)(*args)
            self._versions[key] = compiled(dispatcher, *args)
            self._passes[name] = wrap(self._versions[key])
            return out
        fn = self._passes[name] = wrap(version)
        return fn(*args)

    def __call__(self, ps, halo, timers=None, clock=time.perf_counter):
        """Fill ps.rho, ps.theta and ps.acc of the owned particles; ``halo.refresh(ps, ps.rho)`` updates the copies.

        Wall particles keep the rho they hold. ``timers`` (a dict) gets the
        seconds of "density", "halo" and "forces" added, read from ``clock``.
        """
        lst, c, sw = self.list, self.consts, self.switches  # the particles of the last build
        parts = pass_data.particle_arrays(ps)
        n, n_own = lst.n, ps.n_own
        gather = self.gather_arrays() if numba.get_num_threads() > 1 else None
        t0 = clock()
        if gather is not None:
            self._run("density_threaded", lst, parts, c, sw, gather)
        else:
            self._run("density_serial", lst, parts, c, sw)
        self._run("particle_factors", lst, parts, c, sw, 0, n_own)
        t1 = clock()
        halo.refresh(ps, ps.rho)
        t2 = clock()
        self._run("particle_factors", lst, parts, c, sw, n_own, n)
        if gather is not None:
            self._run("momentum_threaded", lst, parts, c, sw, gather)
        else:
            self._run("momentum_serial", lst, parts, c, sw)
        t3 = clock()
        if timers is not None:
            timers["density"] += t1 - t0
            timers["halo"] += t2 - t1
            timers["forces"] += t3 - t2
