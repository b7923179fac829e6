"""Slabs along the periodic y direction: migration, ghosts and periodic images, over MPI.

Rank r owns y in [bounds[r], bounds[r+1]) with equal widths at each rebuild
of the neighbour list; every slab spans the whole channel in x. The ring is
periodic: rank P-1's upper neighbour is rank 0, and copies that cross y = Ly
are shifted by -Ly (going up) or +Ly (going down) on arrival. With one rank
the rank is its own neighbour and the same code runs.

At a rebuild (:meth:`SlabRing.wrap`, :meth:`~SlabRing.migrate`, :meth:`~SlabRing.exchange_ghosts`,
:meth:`~SlabRing.add_images`): positions are wrapped into the box,
particles migrate to the rank that owns their y (several slabs away if they
must), and each rank receives as ghosts the whole rows of cells of the
neighbour list's grid that it needs (the rows within M cells of its own:
every patch of the validity test centred on its rows is then complete, and
every particle within r_c of it is there). Periodic images of the directions
a rank holds whole (x without walls, z in 3-D) are appended as copies.
Between rebuilds particles stay where they are, even outside their slab:
:meth:`SlabRing.forward` refreshes the same ghosts' positions, velocities
and displacements, and :meth:`SlabRing.refresh` one scalar (rho), each in
one round of messages of sizes known in advance.

Messages are float64 rows (no pickling), packed and unpacked by the loops of
:mod:`parsph.parallel.halo_rows`, :mod:`parsph.parallel.build_loops` and
:mod:`parsph.sph.particles`; they are sent from compiled code
(:mod:`parsph.parallel.native_mpi`) where it can call MPI, else with
mpi4py's buffer methods. A ghost round is written once, in
:mod:`parsph.parallel.native_halo` on this build's plan (:meth:`SlabRing.plan`):
the compiled step and :meth:`SlabRing.forward` / :meth:`SlabRing.refresh`
call it, and without native MPI the ring sends its packed rows through
mpi4py. A build's rounds of unknown size send their row counts first, in a
round of their own. The slab arithmetic (edges, rows,
whether a rank count fits) is :mod:`parsph.parallel.slabs`.
This module knows nothing of the equations, only of particle arrays and the
cell grid.
"""
import time
from collections import defaultdict

import numpy as np
from mpi4py import MPI

from . import native_mpi
from .build_loops import ghost_places, sort_strays, wrap_fields
from . import native_halo
from .halo_rows import copy_images, pack_ghosts, unpack_ghosts
from .native_halo import TAG_DOWN, TAG_UP, HaloPlan
from parsph.sph.cells import CellBox
from parsph.sph.particles import pack_rows
from parsph.errors import DecompositionError
from .slabs import cell_rows, fits, max_ranks, min_length, slab_bounds

TAG_MOVE_UP, TAG_MOVE_DOWN = 13, 14
# the fields a ghost or image carries (halo_rows.pack_ghosts, copy_images)
GHOST_FIELDS = ("gid", "kind", "mass", "pos", "vel", "rho", "ref")


class SlabRing:
    """The slab of this rank, its two neighbours, its ghosts and images, and the exchange buffers."""

    def __init__(self, comm, Ly, grid, clock=time.perf_counter, native=True):
        """``clock``: the seconds of :attr:`stats` (e.g. time.process_time for CPU time); ``native``: False
        sends every message through mpi4py even where compiled code can call MPI."""
        self.comm = comm
        self.native = native
        self.clock = clock
        # what the Python-side messages cost, by method: seconds in the method, seconds waiting in MPI,
        # (sends, bytes) and all-reduces; the compiled step's messages are counted by their plan's sizes
        self.stats = {"seconds": defaultdict(float), "waiting": defaultdict(float),
                      "sends": defaultdict(lambda: [0, 0]), "allreduces": defaultdict(int)}
        self.rank, self.size = comm.rank, comm.size
        self.Ly = Ly
        self.grid = grid
        P = self.size
        ay = grid.axes[1]
        self.side, self.ny, self.m = ay.side, ay.n, grid.m
        if not fits(Ly, P, self.side, self.ny, self.m):
            most = max_ranks(Ly, grid.cutoff, self.m)
            raise DecompositionError(
                f"{P} slabs of Ly = {Ly:g} m are {Ly / P:g} m wide, too thin for their ghost rows "
                f"(about {(self.m + 1) * self.side:.3g} m: the neighbour-list cutoff 2h + skin = {grid.cutoff:.3g} m "
                f"and half of it again): use at most {most} ranks or Ly >= {min_length(P, grid.cutoff, self.m):g} m")
        self.bounds = slab_bounds(Ly, P)
        self.lo, self.hi = self.bounds[self.rank], self.bounds[self.rank + 1]
        self.left = (self.rank - 1) % P
        self.right = (self.rank + 1) % P
        first, last = cell_rows(self.bounds, self.side, self.ny)
        self.first_row, self.last_row = int(first[self.rank]), int(last[self.rank])
        self._rows_of = (first, last)
        # ghosts: counts from below and above, the owned places sent down and up, y shifts on arrival
        self.n_below = self.n_above = 0
        self.send_down = np.zeros(0, np.int64)
        self.send_up = np.zeros(0, np.int64)
        self.shift_below = -Ly if self.rank == 0 else 0.0   # rows from the left neighbour
        self.shift_above = Ly if self.rank == P - 1 else 0.0
        self.img_src = np.zeros(0, np.int64)
        self.img_axis = np.zeros(0, np.int64)
        self.img_shift = np.zeros(0)
        self.n_images = 0
        self._bufs = {}
        self._handles = None  # native_mpi.handles of comm, made with the first plan
        self._flag = np.zeros(1, np.int64)
        self._flag_all = np.zeros(1, np.int64)
        self._places = np.zeros(0, np.int64)
        self._periodic = self._period = None
        self._local = None  # (dim, the local CellBox)
        self._plan = None   # this build's ghost rounds (plan)

    # -- buffers --------------------------------------------------------------------
    def _buf(self, key, rows, width):
        """A preallocated float64 buffer of at least (rows, width), grown only when too small."""
        buf = self._bufs.get(key)
        if buf is None or buf.shape[0] < rows or buf.shape[1] != width:
            old = 0 if buf is None else buf.shape[0]
            buf = np.zeros((max(rows, 64, int(1.5 * old) if rows > old else old), width))
            self._bufs[key] = buf
        return buf

    def _native(self):
        """The communicator's handles and 4 requests for :mod:`native_mpi`, or None where it is unavailable."""
        if not (self.native and native_mpi.available()[0]):
            return None
        if self._handles is None:
            self._handles = native_mpi.handles(self.comm)
            self._reqs = native_mpi.requests(4)
        return self._handles

    def _rounds(self, up, n_up, down, n_down, below, n_below, above, n_above, tags, method):
        """One round of known sizes: n_up rows of ``up`` to the right, n_down of ``down`` to the left,
        n_below rows from the left into ``below``, n_above from the right into ``above``; from compiled
        code where it can call MPI, else through mpi4py."""
        tag_up, tag_down = tags
        t0 = self.clock()
        h = self._native()
        if h is not None:
            err = native_mpi.exchange_rows(h, self.left, self.right, tag_up, tag_down, up, n_up, down, n_down,
                                           below, n_below, above, n_above, *self._reqs)
            if err:
                raise RuntimeError(f"an MPI call of the slab ring's {method} failed (error {err})")
        else:
            c = self.comm
            MPI.Request.Waitall([c.Irecv([below[:n_below], MPI.DOUBLE], source=self.left, tag=tag_up),
                                 c.Irecv([above[:n_above], MPI.DOUBLE], source=self.right, tag=tag_down),
                                 c.Isend([up[:n_up], MPI.DOUBLE], dest=self.right, tag=tag_up),
                                 c.Isend([down[:n_down], MPI.DOUBLE], dest=self.left, tag=tag_down)])
        self.stats["waiting"][method] += self.clock() - t0

    def _send_receive(self, up, n_up, down, n_down, tags, method):
        """Send the first n_up rows of ``up`` to the right neighbour and n_down of ``down`` to the left;
        receive rows of a number each learns first from a header (one round of counts, then the rows).
        Returns (rows from the left, rows from the right): views of this ring's buffers, valid until the
        next call with the same ``method``."""
        width = up.shape[1]
        counts = self._buf(("counts", method), 4, 1)
        counts[0, 0], counts[1, 0] = n_up, n_down
        tag_up, tag_down = tags
        self._rounds(counts[0:1], 1, counts[1:2], 1, counts[2:3], 1, counts[3:4], 1,
                     (tag_up + 100, tag_down + 100), method)
        nb, na = int(counts[2, 0]), int(counts[3, 0])
        below = self._buf(("from left", method), nb, width)
        above = self._buf(("from right", method), na, width)
        self._rounds(up, n_up, down, n_down, below, nb, above, na, tags, method)
        self._count(method, counts[0:1], counts[1:2], up[:n_up], down[:n_down])
        return below[:nb], above[:na]

    def _count(self, method, *bufs):
        e = self.stats["sends"][method]
        e[0] += len(bufs)
        e[1] += sum(b.nbytes for b in bufs)

    # -- every step -------------------------------------------------------------------
    def forward(self, ps):
        """Positions, velocities and displacements of the ghosts (one round) and of the images."""
        plan = self.plan(ps.dim)
        if self._native() is not None:
            self._compiled_round(native_halo.forward, "forward", plan, plan.f_up, plan.f_down, ps.pos, ps.vel,
                                 ps.disp, ps.n_own)
        else:
            native_halo.pack_forward_rows(plan, ps.pos, ps.vel, ps.disp)
            self._mpi4py_round(plan.f_up, plan.f_down, plan.f_below, plan.f_above, "forward")
            native_halo.unpack_forward_rows(plan, ps.pos, ps.vel, ps.disp, ps.n_own)

    def refresh(self, ps, arr):
        """One scalar per particle (``arr``, e.g. ps.rho) of the ghosts and images from their originals."""
        plan = self.plan(ps.dim)
        if self._native() is not None:
            self._compiled_round(native_halo.refresh, "refresh", plan, plan.s_up, plan.s_down, arr, ps.n_own)
        else:
            native_halo.pack_scalar_rows(plan, arr)
            self._mpi4py_round(plan.s_up, plan.s_down, plan.s_below, plan.s_above, "refresh")
            native_halo.unpack_scalar_rows(plan, arr, ps.n_own)

    def _compiled_round(self, round_, method, plan, up, down, *args):
        """A ghost round of :mod:`native_halo` called from Python, its messages sent from compiled code."""
        t0 = self.clock()
        err = round_(plan, *args)
        self.stats["waiting"][method] += self.clock() - t0
        if err:
            raise RuntimeError(f"an MPI call of the slab ring's {method} failed (error {err})")
        self._count(method, up[:len(self.send_up)], down[:len(self.send_down)])

    def _mpi4py_round(self, up, down, below, above, method):
        """A ghost round's packed rows through mpi4py (the sizes of this build)."""
        nu, nd = len(self.send_up), len(self.send_down)
        self._rounds(up, nu, down, nd, below, self.n_below, above, self.n_above, (TAG_UP, TAG_DOWN), method)
        self._count(method, up[:nu], down[:nd])

    def plan(self, dim):
        """This build's ghost rounds (:class:`native_halo.HaloPlan`, made once a build): the places sent, the
        shifts, the images and the buffers every route packs into; MPI's handles where compiled code can call
        it (zeros where it cannot, and the rounds go through mpi4py)."""
        if self._plan is not None:
            return self._plan
        nu, nd, nb, na = len(self.send_up), len(self.send_down), self.n_below, self.n_above
        w = 3 * dim
        f = [self._buf((side, "fwd"), k, w) for side, k in (("send up", nu), ("send down", nd),
                                                             ("recv below", nb), ("recv above", na))]
        s = [self._buf((side, "scalar"), k, 1) for side, k in (("send up", nu), ("send down", nd),
                                                                ("recv below", nb), ("recv above", na))]
        h = self._native()
        handles, reqs = (h, self._reqs) if h is not None else (np.zeros(4, np.int64), native_mpi.requests(4))
        self._plan = HaloPlan(handles, self.left, self.right, self.send_up, self.send_down, nb, na,
                              float(self.shift_below), float(self.shift_above), self.img_src, self.img_axis,
                              self.img_shift, *f, *s, *reqs)
        return self._plan

    # -- at a rebuild -------------------------------------------------------------------
    def wrap(self, ps, position_fields):
        """Wrap the owned positions into the box along its periodic directions (the same shift for every
        field in ``position_fields``, e.g. the midpoint integrator's saved positions)."""
        if self._periodic is None:
            axes = self.grid.axes
            self._periodic = np.array([axes[k].periodic for k in range(ps.dim)], np.bool_)
            self._period = np.array([axes[k].period if axes[k].periodic else 0.0 for k in range(ps.dim)])
        wrap_fields(tuple(getattr(ps, name) for name in position_fields), ps.n_own, self._periodic,
                    self._period)

    def migrate(self, ps, key="pos"):
        """Hand every owned particle whose y (of field ``key``) is outside the slab to its owner, through
        the ring, one slab a round, the shorter way round.

        One all-reduce gives the most slabs any particle is from its owner,
        and as many rounds follow; a round's sizes travel in a header.
        """
        if self.size == 1:
            return
        t_in = self.clock()
        try:
            self._migrate(ps, key)
        finally:
            self.stats["seconds"]["migrate"] += self.clock() - t_in

    def _migrate(self, ps, key):
        hops = None
        while True:
            n = ps.n_own
            if len(self._places) < n:
                self._places = np.zeros(int(1.3 * n) + 16, np.int64)
            idx = self._places
            stay, n_up, n_down, far = sort_strays(getattr(ps, key), n, self.bounds, self.rank, self.size, idx)
            if hops is None:
                self._flag[0] = far
                t0 = self.clock()
                self.comm.Allreduce(self._flag, self._flag_all, op=MPI.MAX)
                self.stats["waiting"]["migrate"] += self.clock() - t0
                self.stats["allreduces"]["migrate"] += 1
                hops = int(self._flag_all[0])
            if hops == 0:
                return
            hops -= 1
            groups = ps.groups()
            width = ps.row_width()
            up = self._buf(("move", "up"), n_up, width)
            down = self._buf(("move", "down"), n_down, width)
            pack_rows(idx[stay:], n_up, *groups, up)
            pack_rows(idx[stay + n_up:], n_down, *groups, down)
            from_left, from_right = self._send_receive(up, n_up, down, n_down, (TAG_MOVE_UP, TAG_MOVE_DOWN),
                                                       "migrate")
            ps.reorder_owned(idx[:stay])
            k = len(from_left) + len(from_right)
            ps.ensure(stay + k, keep=stay)
            ps.put_rows(from_left, stay)
            ps.put_rows(from_right, stay + len(from_left))
            ps.n_own = ps.n = stay + k

    def exchange_ghosts(self, ps, coords):
        """Receive as ghosts the neighbours' particles in the cell rows this slab needs; returns the coords array.

        ``coords`` (int64, (capacity, 3)): integer cell coordinates of the owned
        particles; the ghosts' are appended (their row shifted by -+ny across
        y = Ly). A ghost carries :data:`GHOST_FIELDS` (halo_rows.pack_ghosts).
        """
        t_in = self.clock()
        self._plan = None
        P, r, m, ny = self.size, self.rank, self.m, self.ny
        first, last = self._rows_of
        n = ps.n_own
        # rows as the receiver numbers them: +ny for rank 0 sending down across y = 0, -ny for P-1 up
        down, up = np.zeros(n, np.int64), np.zeros(n, np.int64)
        nd, nu = ghost_places(coords, n, ny if r == 0 else 0, int(last[self.left]) + m,
                              -ny if r == P - 1 else 0, int(first[self.right]) - m, down, up)
        self.send_down, self.send_up = down[:nd], up[:nu]
        width = 7 + 3 * ps.dim

        def rows(idx, key):
            out = self._buf(("ghost rows", key), len(idx), width)
            pack_ghosts(idx, ps.gid, ps.kind, ps.mass, ps.pos, ps.vel, ps.rho, ps.ref, coords, out)
            return out

        below, above = self._send_receive(rows(self.send_up, "up"), nu, rows(self.send_down, "down"), nd,
                                          (TAG_UP, TAG_DOWN), "exchange_ghosts")
        self.n_below, self.n_above = nb, na = len(below), len(above)
        ps.n = n
        ps.ensure(n + nb + na, keep=n)
        coords = self._room(coords, ps.capacity)
        for part, start, shift, row_shift in ((below, n, self.shift_below, -ny if r == 0 else 0),
                                              (above, n + nb, self.shift_above, ny if r == P - 1 else 0)):
            unpack_ghosts(part, start, float(shift), row_shift, ps.gid, ps.kind, ps.mass, ps.pos, ps.vel, ps.rho,
                          ps.ref, coords)
        ps.n = n + nb + na
        self.stats["seconds"]["exchange_ghosts"] += self.clock() - t_in
        return coords

    @staticmethod
    def _room(coords, capacity):
        """``coords`` with at least ``capacity`` rows."""
        if len(coords) < capacity:
            coords = np.concatenate([coords, np.zeros((capacity - len(coords), 3), np.int64)])
        return coords

    def add_images(self, ps, coords):
        """Periodic copies along x (without walls) and z (3-D) of the M rows of cells at each end.

        Copies of the rows 0..M-1 go to n..n+M-1 (shift +period), of the rows
        n-M..n-1 to -M..-1; directions in turn, so corners are copied too.
        Records the sources for :meth:`forward` and :meth:`refresh`.
        """
        self._plan = None
        src_all, axis_all, shift_all = [], [], []
        start = ps.n
        for axis in (0, 2):
            a = self.grid.axes[axis]
            if axis >= ps.dim or not a.periodic:
                continue
            n = ps.n
            c = coords[:n, axis]
            lo = np.flatnonzero(c < self.m)
            hi = np.flatnonzero(c >= a.n - self.m)
            src = np.concatenate([lo, hi])
            shift = np.concatenate([np.full(len(lo), a.period), np.full(len(hi), -a.period)])
            k = len(src)
            ps.ensure(n + k, keep=n)
            coords = self._room(coords, ps.capacity)
            copy_images(src, n, axis, shift, a.n, ps.gid, ps.kind, ps.mass, ps.pos, ps.vel, ps.rho, ps.ref, coords)
            ps.n = n + k
            src_all.append(src)
            axis_all.append(np.full(k, axis, np.int64))
            shift_all.append(shift)
        if src_all:
            self.img_src = np.concatenate(src_all).astype(np.int64)
            self.img_axis = np.concatenate(axis_all)
            self.img_shift = np.concatenate(shift_all)
        self.n_images = ps.n - start
        return coords

    def local_box(self, ps_dim):
        """This rank's local cell box (a :class:`parsph.sph.cells.CellBox`) in global integer cell coordinates.

        Rows: this slab's own rows and M more on each side; x and z: the whole
        grid, plus M image rows at each periodic end. Block centres: the slab's
        own rows, every x and z cell. The same at every build (the slab edges are fixed).
        """
        if self._local is not None and self._local[0] == ps_dim:
            return self._local[1]
        m = self.m
        lo, size, c_lo, c_hi = [], [], [], []
        for axis in range(3):
            a = self.grid.axes[axis]
            if axis == 1:
                lo.append(self.first_row - m)
                size.append(self.last_row - self.first_row + 1 + 2 * m)
                c_lo.append(m)
                c_hi.append(m + self.last_row - self.first_row)
            elif a.periodic and axis < ps_dim:
                lo.append(-m)
                size.append(a.n + 2 * m)
                c_lo.append(m)
                c_hi.append(m + a.n - 1)
            else:
                lo.append(0)
                size.append(a.n)
                c_lo.append(0)
                c_hi.append(a.n - 1)
        as_int = lambda v: np.array(v, np.int64)  # noqa: E731
        box = CellBox(as_int(lo), as_int(size), as_int(c_lo), as_int(c_hi))
        self._local = (ps_dim, box)
        return box
