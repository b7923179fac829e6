"""The time loop: Python orchestration of the numba stages over one slab.

One step (state at t_n -> t_{n+1}):
  halo exchange -> cell list -> density Eq. (3) -> halo rho -> theta
  -> momentum Eq. (5) -> [output, checks] -> integrate Eqs. (6)-(7) -> migrate

The communicator is passed in; one rank is the same code path (the rank is
its own neighbour across the periodic boundary).
"""
import math
import time
from collections import defaultdict

import numpy as np
from mpi4py import MPI

from . import equations, integrate, neighbours
from .decomposition import SlabRing
from .kernels import get_kernel
from .particles import FLUID, Particles
from .profile import bin_centres, bin_sums, errors
from .scenes import get_scene

PHASES = ("halo", "neighbours", "density", "forces", "integrate", "migrate", "output", "checks")


class GuardError(RuntimeError):
    """A run-time check failed on some rank; raised on every rank alike."""


class Simulation:
    def __init__(self, cfg, comm):
        self.cfg = cfg
        self.comm = comm
        self.scene = get_scene(cfg.values["scene"]["name"])
        self.terms = self.scene.terms
        self.kernel = get_kernel(cfg.kernel, cfg.dim)
        self.norm = self.kernel.norm(cfg.h, cfg.dim)
        self.support = self.kernel.support * cfg.h
        self.ring = SlabRing(comm, cfg.Ly, self.support)
        self.ps = Particles.from_arrays(*self.scene.particles(cfg, self.ring.lo, self.ring.hi))
        self.rho_wall = cfg.rho_s * cfg.theta0
        self.ps.rho[:self.ps.n] = self.rho_wall
        self.x0 = -cfg.layers * cfg.dx - self.support
        self.g = np.array(cfg.g if self.terms.body_force else (0.0,) * cfg.dim, dtype=float)
        self.step = 0
        self.timers = defaultdict(float)
        self._cell_xy = np.zeros((0, 3), np.int64)
        self._order = np.zeros(0, np.int64)
        self.n_total = comm.allreduce(self.ps.n_own)
        self.nbins = cfg.Nx
        self._sums = np.zeros(self.nbins)
        self._counts = np.zeros(self.nbins)

    @property
    def t(self):
        return self.step * self.cfg.dt

    # ---- one evaluation of the right-hand side -------------------------------
    def compute_rates(self):
        """Density, theta and accelerations of the owned particles at the current state."""
        cfg, ps, T = self.cfg, self.ps, self.timers
        t0 = time.perf_counter()
        self.ring.exchange_halo(ps)
        t1 = time.perf_counter()
        n = ps.n
        if self._order.shape[0] < n:
            self._order = np.zeros(ps.capacity, np.int64)
            self._cell_xy = np.zeros((ps.capacity, 3), np.int64)
        start, ncx, ncy, ncz = neighbours.build_cells(ps.pos, ps.gid, n, self.x0, self.support,
                                                      self._cell_xy, self._order)
        cells = (self._cell_xy, start, self._order, ncx, ncy, ncz)
        t2 = time.perf_counter()
        equations.density(ps.pos, ps.mass, ps.kind, ps.n_own, *cells, cfg.h, self.norm,
                          self.kernel.w, self.rho_wall, ps.rho)
        self.ring.exchange_halo_field(ps, "rho")
        equations.volume_fraction(ps.rho, n, cfg.rho_s, cfg.G_a, ps.theta, ps.half_G)
        t3 = time.perf_counter()
        equations.momentum(ps.pos, ps.vel, ps.mass, ps.kind, ps.rho, ps.theta, ps.half_G, ps.n_own,
                           *cells, cfg.h, self.norm, self.kernel.dwdr, cfg.rho_s, cfg.G_b, cfg.k,
                           cfg.L, cfg.beta_max, self.g, self.terms.pressure, self.terms.viscosity,
                           ps.acc)
        t4 = time.perf_counter()
        T["halo"] += t1 - t0
        T["neighbours"] += t2 - t1
        T["density"] += t3 - t2
        T["forces"] += t4 - t3

    def advance(self):
        """Eqs. (6)-(7), then hand particles that left the slab to their new owner."""
        ps, T = self.ps, self.timers
        t0 = time.perf_counter()
        integrate.step_paper(ps.pos, ps.vel, ps.acc, ps.kind, ps.n_own, self.cfg.dt, self.cfg.Ly)
        t1 = time.perf_counter()
        self.ring.migrate(ps)
        T["integrate"] += t1 - t0
        T["migrate"] += time.perf_counter() - t1
        self.step += 1

    # ---- reductions ------------------------------------------------------------
    def profile(self):
        """Global v_y(x): per-bin sums and counts all-reduced over ranks."""
        ps = self.ps
        bin_sums(ps.pos, ps.vel, ps.kind, ps.n_own, self.cfg.L / self.nbins, self.nbins,
                 self._sums, self._counts)
        sums = np.empty_like(self._sums)
        counts = np.empty_like(self._counts)
        self.comm.Allreduce(self._sums, sums, op=MPI.SUM)
        self.comm.Allreduce(self._counts, counts, op=MPI.SUM)
        with np.errstate(invalid="ignore", divide="ignore"):
            vy = sums / counts
        x = bin_centres(self.cfg.L, self.nbins)
        exact = None
        err = (math.nan, math.nan)
        if self.scene.exact_profile is not None:
            exact = self.scene.exact_profile(self.cfg, x, self.t)
            err = errors(vy, exact, self.scene.velocity_scale(self.cfg))
        return x, vy, counts, exact, err

    def check(self):
        """Collective run-time checks: non-finite state, fluid particles through a wall."""
        ps, cfg = self.ps, self.cfg
        t0 = time.perf_counter()
        n = ps.n_own
        report = np.zeros(4)  # code, gid, x, y
        bad = ~np.isfinite(ps.pos[:n]).all(axis=1) | ~np.isfinite(ps.vel[:n]).all(axis=1)
        fluid = ps.kind[:n] == FLUID
        through = fluid & ((ps.pos[:n, 0] < 0.0) | (ps.pos[:n, 0] > cfg.L))
        for code, mask in ((1, bad), (2, through)):
            if mask.any():
                k = int(np.argmax(mask))
                report[:] = code, ps.gid[k], ps.pos[k, 0], ps.pos[k, 1]
                break
        reports = np.zeros((self.comm.size, 4))
        self.comm.Allgather(report, reports)
        self.timers["checks"] += time.perf_counter() - t0
        failed = reports[reports[:, 0] > 0]
        if len(failed):
            code, gid, x, y = failed[0]
            what = {1: "non-finite position or velocity", 2: "fluid particle crossed a wall plane"}[int(code)]
            raise GuardError(f"check failed: {what} at step {self.step}, t = {self.t:.6g} s: "
                             f"particle {int(gid)} at x = {x:.6g} m, y = {y:.6g} m")

    # ---- the loop ----------------------------------------------------------------
    def run(self, output=None, progress=None):
        """Advance to t_end; ``output(sim, k)`` at output step k, ``progress(sim, rate, eta)``."""
        cfg = self.cfg
        outs = {s: k for k, s in enumerate(cfg.output_steps)}
        check_every = cfg.values["output"]["check_every"]
        interval = cfg.values["output"]["progress_interval"]
        t_start = last = time.perf_counter()
        step0 = self.step
        while True:
            self.compute_rates()
            if self.step in outs and output is not None:
                t0 = time.perf_counter()
                output(self, outs[self.step])
                self.timers["output"] += time.perf_counter() - t0
            if self.step % check_every == 0 or self.step == cfg.nsteps:
                self.check()
            if self.step >= cfg.nsteps:
                break
            self.advance()
            now = time.perf_counter()
            if progress is not None and interval > 0 and now - last >= interval:
                last = now
                done = self.step - step0
                rate = self.n_total * done / (now - t_start)
                eta = (cfg.nsteps - self.step) * (now - t_start) / done
                progress(self, rate, eta)
        self.wall_time = time.perf_counter() - t_start
        return self
