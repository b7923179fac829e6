"""The time loop: Python orchestration of the numba stages over one slab.

One step (state at t_n -> t_{n+1}):
  halo exchange -> cell list -> density Eq. (3) -> halo rho -> theta
  -> momentum Eq. (5) -> [output, checks] -> integrate -> migrate

The communicator is passed in; one rank is the same code path (the rank is
its own neighbour across the periodic boundary).
"""
import math
import time
from collections import defaultdict

import numpy as np
from mpi4py import MPI

from . import equations, integrate
from .config import dt_limits
from .decomposition import SlabRing
from .kernels import get_kernel, lattice_sum
from .output import Frame, read_particles
from .particles import FLUID, Particles, add_images, copy_from_sources, count_images
from .profile import bin_centres, bin_sums, errors
from .rates import Rates

PHASES = ("halo", "neighbours", "density", "forces", "integrate", "migrate", "output", "checks")
CHECKS = {1: "non-finite position, velocity or acceleration", 2: "fluid particle crossed a wall plane",
          3: "volume fraction out of range", 4: "kinetic energy above what the walls can inject",
          5: "particle moved more than one slab in one step"}


class GuardError(RuntimeError):
    """A run-time check failed on some rank; raised on every rank alike."""


class Interrupted(RuntimeError):
    """A stop was requested (signal); raised on every rank alike after the last output."""

    def __init__(self, message, signum):
        super().__init__(message)
        self.signum = signum


class Simulation:
    def __init__(self, cfg, comm, state=None):
        """Set up the run on ``comm``; ``state`` (output.read_state: attrs and path) continues a run."""
        self.cfg = cfg
        self.comm = comm
        self.scene = cfg.scene
        self.kernel = get_kernel(cfg.kernel, cfg.dim)
        self.support = self.kernel.support * cfg.h
        # The midpoint state is not migrated: a skin covers its half-step drift
        # (the CFL limit keeps that below h/8).
        self.halo = self.support + (0.25 * cfg.h if cfg.integrator == "midpoint" else 0.0)
        self.ring = SlabRing(comm, cfg.Ly, self.halo)
        if state is None:
            self.ps = Particles.from_arrays(*self.scene.particles(cfg, self.ring.lo, self.ring.hi))
        else:  # only this slab's particles, read collectively: O(N/P) memory on any rank count
            p = read_particles(state["path"], comm, self.ring.lo, self.ring.hi)
            self.ps = Particles.from_arrays(p["id"], p["kind"].astype(np.int64), p["mass"], p["position"],
                                            p["velocity"])
            del p
        # Walls hold the density that Eq. (3) gives inside the initial lattice,
        # so that the undisturbed lattice is in equilibrium next to a wall;
        # scaled by the scene's wall_theta(x) / theta_0 where it has one (a
        # function of x, which walls keep: a restart finds the same values).
        self.rho_wall = cfg.mass * lattice_sum(self.kernel, cfg.h, cfg.spacing)
        ps = self.ps
        ps.rho[:ps.n] = self.rho_wall
        if self.scene.wall_theta is not None:
            wall = ps.kind[:ps.n] != FLUID
            ps.rho[:ps.n][wall] *= self.scene.wall_theta(cfg, ps.pos[:ps.n][wall, 0]) / cfg.theta0
        self.x0 = -cfg.layers * cfg.dx - self.halo
        self.g = np.zeros(3)
        if self.scene.terms.body_force:
            self.g[:cfg.dim] = cfg.g
        # periods of the box per direction (0: bounded by walls); y is cut into slabs
        self.box = np.array([0.0 if self.scene.walls else cfg.L, cfg.Ly, cfg.Lz if cfg.dim == 3 else 0.0])
        # directions made periodic on the rank itself, by copies: x without walls, z in 3-D
        self.local_periodic = [(d, self.box[d]) for d in (0, 2) if self.box[d] > 0]
        self._images = []  # (start, src indices, count) per direction, in creation order
        sw = equations.switch
        switches = (sw(cfg.pressure), sw(cfg.viscosity), sw(cfg.get("numerics.viscosity_form") == "symmetric"),
                    sw(self.scene.walls), sw(cfg.get("numerics.pressure_form") == "consistent"))
        self.step = 0 if state is None else int(state["attrs"]["step"])
        self.t = 0.0 if state is None else float(state["attrs"]["time"])
        self.dt = cfg.dt if state is None else float(state["attrs"]["dt"])
        self.timers = defaultdict(float)
        self._flag = np.zeros(2, np.int64)
        self._flag_all = np.zeros(2, np.int64)
        self._saved = (np.zeros((0, cfg.dim)), np.zeros((0, cfg.dim)))
        self.rates = Rates(self.kernel, cfg.h, cfg.dim, self.x0, cfg.rho_s, cfg.G_a, cfg.G_b,
                           cfg.k, cfg.L, cfg.beta_max, self.g, switches)
        self.work = self.rates.work
        self.n_total = comm.allreduce(self.ps.n_own)
        self.nbins = cfg.Nx
        self._sums = np.zeros((3, self.nbins))


    # ---- one evaluation of the right-hand side -------------------------------
    def compute_rates(self):
        """Density, theta and accelerations of the owned particles at the current state."""
        t0 = time.perf_counter()
        self.ring.exchange_halo(self.ps)
        self._add_periodic_images()
        self.timers["halo"] += time.perf_counter() - t0
        self.rates(self.ps, self._refresh_rho, self.timers)

    def _refresh_rho(self, ps):
        """rho of the halo copies from their owners, and of the local periodic images."""
        self.ring.exchange_halo_field(ps, "rho")
        for start_, src, k in self._images:
            copy_from_sources(ps.rho, start_, src, k)

    def _add_periodic_images(self):
        """Copies of the particles near the ends of each locally periodic direction (x, z)."""
        ps = self.ps
        self._images = []
        for axis, period in self.local_periodic:
            n = ps.n
            k = count_images(ps.pos, n, axis, period, self.halo)
            ps.ensure(n + k, keep=n)
            src = np.zeros(k, np.int64)
            add_images(ps.gid, ps.kind, ps.mass, ps.pos, ps.vel, ps.rho, n, axis, period, self.halo, src)
            self._images.append((n, src, k))
            ps.n = n + k

    def advance(self, dt, stop_requested=None):
        """One step of the chosen integrator, then hand particles that left the slab to their owner.

        Returns the largest stop code any rank got from ``stop_requested()``
        (a signal number; 0: go on). One small all-reduce per step carries that
        and the count of particles that are non-finite or jumped past the
        neighbouring slab; a blow-up raises GuardError on every rank before
        migration and the next neighbour search.
        """
        ps, T, cfg = self.ps, self.timers, self.cfg
        t0 = time.perf_counter()
        if cfg.integrator == "paper":
            bad = integrate.step_paper(ps.pos, ps.vel, ps.acc, ps.kind, ps.n_own, dt, self.box)
        else:
            if self._saved[0].shape[0] < ps.n_own:
                self._saved = (np.zeros((ps.capacity, cfg.dim)), np.zeros((ps.capacity, cfg.dim)))
            pos0, vel0 = self._saved
            bad = integrate.midpoint_predict(ps.pos, ps.vel, ps.acc, ps.kind, ps.n_own, dt, pos0, vel0)
            T["integrate"] += time.perf_counter() - t0
            self._agree(bad, False)
            self.compute_rates()
            t0 = time.perf_counter()
            bad = integrate.midpoint_correct(ps.pos, ps.vel, ps.acc, ps.kind, ps.n_own, dt, pos0, vel0, self.box)
        self.step += 1
        self.t = self.step * cfg.dt if not cfg.dt_auto else self.t + dt
        t1 = time.perf_counter()
        leaving = self.ring.leaving(ps)
        bad += self.ring.count_strays(leaving)
        stop = self._agree(bad, stop_requested() if stop_requested is not None else 0)
        self.ring.migrate(ps, leaving)
        T["integrate"] += t1 - t0
        T["migrate"] += time.perf_counter() - t1
        return stop

    def _agree(self, nonfinite, stop):
        """All-reduce (non-finite count, stop code); run the checks everywhere on a blow-up."""
        self._flag[0] = nonfinite
        self._flag[1] = int(stop)
        self.comm.Allreduce(self._flag, self._flag_all, op=MPI.MAX)
        if self._flag_all[0]:
            self.check()  # raises GuardError on every rank
        return int(self._flag_all[1])

    def stable_dt(self):
        """The largest stable step for the current state (global minimum over ranks)."""
        ps, cfg = self.ps, self.cfg
        n = ps.n_own
        fluid = ps.kind[:n] == FLUID
        local = np.array([
            np.sqrt((ps.vel[:n] ** 2).sum(axis=1)).max(initial=0.0),
            ps.theta[:n][fluid].max(initial=cfg.theta0),
            np.sqrt((ps.acc[:n] ** 2).sum(axis=1)).max(initial=0.0),
        ])
        glob = np.empty(3)
        self.comm.Allreduce(local, glob, op=MPI.MAX)
        vmax, theta_max, amax = glob
        theta_max = min(theta_max, 0.999)
        # the same limits as config.build's, at the current state (the damping one at theta_max)
        lim = dt_limits(cfg.h, theta_max, cfg.rho_s, cfg.k, cfg.G_a, cfg.G_b, vmax, amax, cfg.integrator)
        return min(lim.values())

    # ---- reductions ------------------------------------------------------------
    def frame(self):
        """What an output writes (output.Frame): time, profile and views of the owned particles."""
        ps, n = self.ps, self.ps.n_own
        fields = {"id": ps.gid[:n], "kind": ps.kind[:n], "mass": ps.mass[:n], "position": ps.pos[:n],
                  "velocity": ps.vel[:n], "theta": ps.theta[:n]}
        return Frame(self.t, self.step, self.dt, self.profile(), fields)

    def profile(self):
        """Global v_y(x) and theta(x): per-bin sums and counts all-reduced over ranks.

        Returns a dict: x, vy, theta, count, the scene's reference profiles
        (vy_exact, theta_exact; NaN where it has none) and (err_max, err_rms)
        of its error field, normalised by V_w (velocity) or theta_0 (theta).
        """
        ps, cfg = self.ps, self.cfg
        bin_sums(ps.pos, ps.vel, ps.theta, ps.kind, ps.n_own, cfg.L / self.nbins, self.nbins, self._sums)
        sums = np.empty_like(self._sums)
        self.comm.Allreduce(self._sums, sums, op=MPI.SUM)
        count = sums[2]
        with np.errstate(invalid="ignore", divide="ignore"):
            out = {"x": bin_centres(cfg.L, self.nbins), "vy": sums[0] / count, "theta": sums[1] / count,
                   "count": count}
        ref = self.scene.reference(cfg, out["x"], self.t) if self.scene.reference else {}
        for key in ("vy", "theta"):
            out[key + "_exact"] = ref.get(key, np.full(self.nbins, np.nan))
        field = self.scene.error_field
        scale = cfg.velocity_scale if field == "vy" else cfg.theta0
        out["err"] = errors(out[field], out[field + "_exact"], scale) if field in ref else (math.nan, math.nan)
        return out

    def check(self):
        """Collective run-time checks (CHECKS); on failure every rank raises GuardError.

        The message names the worst offender over all ranks: the first check
        in CHECKS order that fails anywhere, and within it the particle that
        fails it most (deepest through a wall, furthest from theta_0, furthest
        away); for the energy bound, the fastest fluid particle.
        """
        ps, cfg = self.ps, self.cfg
        t0 = time.perf_counter()
        n = ps.n_own
        pos, vel = ps.pos[:n], ps.vel[:n]
        fluid = ps.kind[:n] == FLUID
        report = np.zeros(6)  # code, severity, gid, x, y, value
        finite = np.isfinite(pos).all(axis=1) & np.isfinite(vel).all(axis=1) & np.isfinite(ps.acc[:n]).all(axis=1)
        depth = np.where(fluid & finite, np.maximum(-pos[:, 0], pos[:, 0] - cfg.L), -np.inf) \
            if self.scene.walls else np.full(n, -np.inf)
        dev = np.where(fluid & finite, np.abs(ps.theta[:n] - cfg.theta0), 0.0)
        owner = np.searchsorted(self.ring.bounds, np.where(finite, pos[:, 1], 0.0), side="right") - 1
        far = np.where(finite & (owner != self.ring.rank) & (owner != self.ring.left) & (owner != self.ring.right),
                       1.0, 0.0)
        for code, severity in ((1, np.where(finite, 0.0, 1.0)), (2, np.where(depth > 0, depth, 0.0)),
                               (3, np.where(dev > cfg.get("checks.theta_change") * cfg.theta0, dev, 0.0)),
                               (5, far)):
            if n and severity.max() > 0:
                k = int(np.argmax(severity))
                report[:] = code, severity[k], ps.gid[k], pos[k, 0], pos[k, 1], ps.theta[k]
                break
        speed2 = np.where(fluid & finite, (vel ** 2).sum(axis=1), -1.0)
        k = int(np.argmax(speed2)) if n else 0
        fastest = np.array([speed2[k] if n else -1.0, ps.gid[k] if n else -1, pos[k, 0] if n else 0.0,
                            pos[k, 1] if n else 0.0])
        energy = np.array([0.5 * (ps.mass[:n][fluid] * (vel[fluid] ** 2).sum(axis=1)).sum(), ps.mass[:n][fluid].sum()])
        reports = np.zeros((self.comm.size, 6))
        self.comm.Allgather(report, reports)
        fast = np.zeros((self.comm.size, 4))
        self.comm.Allgather(fastest, fast)
        totals = np.zeros(2)
        self.comm.Allreduce(energy, totals, op=MPI.SUM)
        self.timers["checks"] += time.perf_counter() - t0
        failed = reports[reports[:, 0] > 0]
        where = f"at step {self.step}, t = {self.t:.6g} s"
        if len(failed):
            failed = failed[failed[:, 0] == failed[:, 0].min()]
            code, severity, gid, x, y, value = failed[np.argmax(failed[:, 1])]
            extra = {2: f" ({severity:.3g} m beyond the plate)", 3: f" (theta = {value:.4g}, theta0 = {cfg.theta0:g})",
                     5: " (dt too large or the run blew up)"}.get(int(code), "")
            raise GuardError(f"check failed: {CHECKS[int(code)]} {where}: particle {int(gid)} "
                             f"at x = {x:.6g} m, y = {y:.6g} m{extra}")
        bound = self.scene.max_kinetic_energy(cfg, totals[1], self.t)
        if cfg.get("checks.energy") and not totals[0] <= bound:
            s2, gid, x, y = fast[np.argmax(fast[:, 0])]
            raise GuardError(f"check failed: {CHECKS[4]} {where}: {totals[0]:.4g} J/m > {bound:.4g} J/m; "
                             f"fastest particle {int(gid)} at x = {x:.6g} m, y = {y:.6g} m, "
                             f"|v| = {math.sqrt(max(s2, 0.0)):.4g} m/s")

    # ---- the loop ----------------------------------------------------------------
    def _output_due(self, t_out):
        if not self.cfg.dt_auto:
            return self.step == round(t_out / self.cfg.dt)
        return self.t >= t_out * (1 - 1e-12) - 1e-300

    def run(self, output=None, progress=None, stop_requested=None):
        """Advance to t_end; ``output(sim)`` at each output time, ``progress(sim, rate, eta)``.

        ``stop_requested()`` (a signal number, 0 for none) is polled every
        step; when it is set on any rank the run writes a final output with
        particles and raises Interrupted on every rank with the same number.
        """
        cfg = self.cfg
        pending = [t for t in cfg.output_times if t >= self.t * (1 + 1e-12) or (self.step == 0 and t == 0)]
        if self.step > 0:  # restart: the restart state itself was output already
            pending = [t for t in pending if not self._output_due(t)]
        check_every = cfg.get("checks.every")
        interval = cfg.get("output.progress_interval")
        t_start = last = time.perf_counter()
        step0, tsim0 = self.step, self.t
        stop = 0
        while True:
            self.compute_rates()
            while pending and self._output_due(pending[0]) and output is not None:
                t0 = time.perf_counter()
                output(self)
                pending.pop(0)
                self.timers["output"] += time.perf_counter() - t0
            done = self.t >= cfg.t_end * (1 - 1e-12) if cfg.dt_auto else self.step >= cfg.nsteps
            if self.step % check_every == 0 or done:
                self.check()
            if done:
                break
            if stop:
                if output is not None:
                    output(self, snapshot=True)
                raise Interrupted(f"stopped at step {self.step}, t = {self.t:.6g} s; "
                                  f"the last output is a restart point", stop)
            if cfg.dt_auto:
                dt = cfg.get("numerics.dt_safety") * self.stable_dt()
                target = min(pending[0], cfg.t_end) if pending else cfg.t_end
                remaining = target - self.t
                land = remaining <= dt
                if land:
                    dt = remaining
                elif remaining < 2 * dt:  # two equal steps, not a sliver
                    dt = 0.5 * remaining
                self.dt = dt
                stop = self.advance(dt, stop_requested)
                if land:
                    self.t = target
            else:
                stop = self.advance(self.dt, stop_requested)
            now = time.perf_counter()
            if progress is not None and interval > 0 and now - last >= interval:
                last = now
                rate = self.n_total * (self.step - step0) / (now - t_start)
                eta = (cfg.t_end - self.t) * (now - t_start) / max(self.t - tsim0, 1e-300)
                progress(self, rate, eta)
        self.wall_time = time.perf_counter() - t_start
        return self
