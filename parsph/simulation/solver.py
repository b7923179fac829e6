"""The time loop over one slab: the events (outputs, checks, the end, a stop) in Python, the steps between
them in compiled blocks (:mod:`.compiled_steps`, :mod:`.block`) or, where MPI cannot be called from
compiled code, step by step from Python with the same numba stages.

One step (state at t_n -> t_{n+1}), paper integrator:

  sync:      ghosts' positions from their owners -> validity test of the
             neighbour list -> one all-reduce (blow-up, stop signal,
             rebuild) -> [rebuild: wrap, migrate, ghosts, images, list]
  rates:     density Eq. (3) -> ghosts' rho -> momentum Eq. (5)
  [output, checks]
  integrate: Eqs. (6)-(7) for the owned particles

The neighbour list (:mod:`parsph.sph.cells`) is rebuilt only when the
test says it may miss a pair (and at the first step: a snapshot keeps the
positions of the last build, so a restart builds the same list and continues
bit for bit). Every rank takes the same decision (an all-reduce of a
quantity that does not depend on the decomposition), so every rank count
rebuilds on the same steps and the results do not depend on it, bit for bit.

The communicator is passed in; one rank is the same code path (the rank is
its own neighbour across the periodic boundary).
"""
import math
import time
from collections import defaultdict

import numpy as np

from parsph.sph import integrators
from parsph.physics import limits
from parsph.parallel.collectives import Collectives
from parsph.parallel.slab_ring import SlabRing
from parsph.errors import Interrupted
from .guards import limits_of, run_checks
from parsph.physics.kernels import get_kernel
from parsph.physics.lattice_sums import lattice_sum
from parsph.sph.cells import grid_for
from parsph.output import Frame, read_particles
from parsph.sph.particles import FLUID, Particles, drag_maximum, state_maxima
from parsph.sph.profiles import bin_centres, bin_sums, errors
from parsph.sph.rates import Rates
from parsph.sph.neighbour_list import NeighbourList
from parsph.physics.kernels import kernel_w_f
from parsph.sph import pass_data
from .compiled_steps import CompiledSteps

PHASES = ("sync", "rebuild", "density", "halo", "forces", "integrate", "output", "checks")


class Simulation(CompiledSteps):
    def __init__(self, cfg, comm, state=None, native=None, clock=time.perf_counter):
        """Set up the run on ``comm``; ``state`` (output.read_state: attrs and path) continues a run.

        ``native``: send the step's messages from compiled code (:mod:`parsph.parallel.native_mpi`);
        None (default) where the bindings load, False for the mpi4py path (the same arithmetic).
        ``clock``: the seconds of the phase timers Python keeps (list builds, outputs, checks, the
        Python path's phases; e.g. time.process_time for CPU time); the compiled blocks' phases are
        wall seconds (MPI_Wtime)."""
        self.cfg = cfg
        self.clock = clock
        self._fresh = False      # the rates are those of the current state
        self.comm = comm
        self._restore = False  # the first build takes the list's reference positions from a snapshot
        self.scene = cfg.scene
        self.kernel = get_kernel(cfg.kernel, cfg.dim)
        self.skin = cfg.get("numerics.skin") * cfg.h
        self.grid = grid_for(cfg, self.kernel)
        walls = self.scene.walls
        self._grid_params = self.grid.params()
        self.ring = SlabRing(comm, cfg.Ly, self.grid, clock)
        self.ps = self._particles(state)
        ps = self.ps
        ps.add_field("ref")  # positions at the last build of the neighbour list
        self.position_fields = ("pos",)
        if cfg.integrator == "midpoint":
            ps.add_field("pos0")
            ps.add_field("vel0")
            self.position_fields = ("pos", "pos0")
        self._hold_wall_density()
        self.gas = cfg.gas
        self.g = np.zeros(3)  # every scene honours body_force.g; in a gas, with buoyancy (PHYSICS.md)
        self.g[:cfg.dim] = cfg.g
        if self.gas is not None:
            self.g *= 1.0 - self.gas.rho / cfg.rho_s
            ps.add_field("drag")
            ps.add_field("drag_rate", vector=False)
        self._implicit = pass_data.switch(self.gas is not None and self.gas.implicit)
        self.period_x = 0.0 if walls else cfg.L
        self.step = 0 if state is None else int(state["attrs"]["step"])
        self.t = 0.0 if state is None else float(state["attrs"]["time"])
        self.dt = cfg.dt if state is None else float(state["attrs"]["dt"])
        self.timers = defaultdict(float)
        self.neighbours = NeighbourList(self.grid)
        self.collect = Collectives(comm)
        self.rates = Rates(*self._pass_groups())
        self.n_total = self.collect.total(ps.n_own)
        fluid = ps.kind[:ps.n_own] == FLUID
        self.limits = limits_of(cfg, float(self.collect.sum(np.array([ps.mass[:ps.n_own][fluid].sum()]))[0]))
        self._checked = -1       # the last step whose checks a compiled block ran
        self.nbins = cfg.Nx
        self._sums = np.zeros((4, self.nbins))
        self._flags = np.zeros(3)
        self._flags_all = np.zeros(3)
        self._built = False      # no list yet: the first evaluation builds one
        self._bad = 0            # non-finite or jumping particles left by the last integration (this rank)
        self._stop_local = 0     # signal seen by this rank since the last sync
        self.force_rebuild = False
        self.stop = 0
        self.rebuilds = 0
        self._coords = np.zeros((0, 3), np.int64)  # cell coordinates per local particle at a build
        self._init_blocks(native)

    def _pass_groups(self):
        """The run's numbers and terms as the passes take them (pass_data.Constants, pass_data.Switches)."""
        cfg, kernel, sw = self.cfg, self.kernel, pass_data.switch
        inv_h = 1.0 / cfg.h
        norm = kernel.norm(cfg.h, cfg.dim)
        w0 = kernel_w_f(kernel.kid, 0.0, inv_h, norm)[0]
        mass = self._the_one_mass()
        consts = pass_data.Constants(kernel.kid, inv_h, norm, w0, cfg.rho_s, cfg.G_a, cfg.G_b, cfg.k, cfg.L,
                                     cfg.beta_max, np.asarray(self.g, float), mass, self._gas_constants())
        switches = pass_data.Switches(sw(cfg.pressure), sw(cfg.viscosity),
                                      sw(cfg.get("numerics.viscosity_form") == "symmetric"), sw(self.scene.walls),
                                      sw(cfg.get("numerics.pressure_form") == "consistent"), sw(cfg.dim == 3),
                                      sw(mass > 0.0), sw(self.gas is not None))
        return consts, switches

    def _gas_constants(self):
        """The gas as the loops take it (pass_data.GasConstants; zeros without a gas)."""
        gas = self.gas
        if gas is None:
            return pass_data.GasConstants(0, 0.0, 0.0, 0.0, 0, 0, 0.0, 0.0, np.zeros(3))
        u = np.zeros(3)
        u[:len(gas.velocity)] = gas.velocity
        return pass_data.GasConstants(gas.model, gas.rho, gas.mu, gas.d, int(gas.column), max(gas.axis, 0),
                                      gas.sign, gas.U, u)

    def _the_one_mass(self):
        """The mass every particle of the run has, or 0.0 where they differ (over all ranks; a run neither
        creates nor changes particles, so it holds to the end)."""
        m = self.ps.mass[:self.ps.n_own]
        lo_hi = np.array([-m.min(), m.max()]) if m.size else np.array([-np.inf, -np.inf])
        neg_lo, hi = self.collect.max(lo_hi)
        return float(hi) if -neg_lo == hi else 0.0

    def _particles(self, state):
        """This slab's particles: from the scene, from a snapshot (``state["path"]``) or from arrays."""
        cfg = self.cfg
        if state is None:
            return Particles.from_arrays(*self.scene.particles(cfg, self.ring.lo, self.ring.hi))
        if "path" in state:  # a snapshot: only this slab's particles, read collectively (O(N/P) memory)
            p = read_particles(state["path"], self.comm, self.ring.lo, self.ring.hi)
            exact = "ref" in p  # the solver's state as it held it: continue from the same neighbour list
            ps = Particles.from_arrays(p["id"], p["kind"].astype(np.int64), p["mass"],
                                       p["position_raw"] if exact else p["position"], p["velocity"])
            if exact:
                ps.add_field("ref")
                ps.ref[:ps.n_own] = p["ref"]
                self._restore = True
            return ps
        # a state given as arrays (id, kind, mass, position, velocity): this slab's rows
        y = state["position"][:, 1]
        mine = (y >= self.ring.lo) & (y < self.ring.hi)
        return Particles.from_arrays(state["id"][mine], state["kind"][mine].astype(np.int64),
                                     state["mass"][mine], state["position"][mine], state["velocity"][mine])

    def _hold_wall_density(self):
        """Walls hold the density that Eq. (3) gives inside the initial lattice, so that the undisturbed
        lattice is in equilibrium next to a wall; scaled by the scene's wall_theta(x) / theta_0 where it
        has one (a function of x, which walls keep: a restart finds the same values)."""
        cfg, ps = self.cfg, self.ps
        self.rho_wall = cfg.mass * lattice_sum(self.kernel, cfg.h, cfg.spacing)
        ps.rho[:ps.n] = self.rho_wall
        if self.scene.wall_theta is not None:
            wall = ps.kind[:ps.n] != FLUID
            ps.rho[:ps.n][wall] *= self.scene.wall_theta(cfg, ps.pos[:ps.n][wall, 0]) / cfg.theta0

    # ---- the neighbour list ---------------------------------------------------------
    def _sync(self):
        """Refresh the ghosts, test the list, agree (one all-reduce) on blow-up, stop and rebuild."""
        if not self._built:
            self._rebuild(restore=self._restore)
            self._restore = False
        t0 = self.clock()
        ps = self.ps
        n = ps.n_own
        np.subtract(ps.pos[:n], ps.ref[:n], out=ps.disp[:n])  # positions may have changed (a step, a caller)
        self.ring.forward(ps)
        spread = self.neighbours.spread(ps.disp)
        f = self._flags
        f[0] = self._bad
        f[1] = self._stop_local
        f[2] = 1.0 if (self.force_rebuild or not spread < self.skin) else 0.0
        self._flags_all = self.collect.max(f)
        self.timers["sync"] += self.clock() - t0
        self._act(self._flags_all)

    def _act(self, flags):
        """What the agreed flags of a sync (bad, stop, rebuild) ask: the checks, the stop, a rebuild."""
        self._bad = 0
        self._stop_local = 0
        self.force_rebuild = False
        bad, stop, rebuild = flags
        if bad:
            self.check()  # raises GuardError on every rank
        if stop:
            self.stop = int(stop)
        if rebuild:
            self._rebuild()

    def _rebuild(self, restore=False):
        """Wrap, migrate, choose the ghosts and images, build the list (collective).

        The list is built from the reference positions ``ref``: the current
        ones, wrapped into the box, except on ``restore``, where ``ref`` came
        from a snapshot with the positions as the writing run held them, so
        that the same list is built again and the run continues bit for bit.
        """
        t0 = self.clock()
        ps, ring = self.ps, self.ring
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
        self.rates.attach(self.neighbours)
        self._block_args = None  # the compiled block's arguments are this build's arrays
        self._built = True
        self.rebuilds += 1
        self.timers["rebuild"] += self.clock() - t0

    # ---- one evaluation of the right-hand side -------------------------------
    def compute_rates(self):
        """Density, theta and accelerations of the owned particles at the current state."""
        self._sync()
        self.rates(self.ps, self.ring, self.timers, self.clock)
        self._fresh = True

    def integrate(self, dt, stop_requested=None):
        """One step of the chosen integrator; the particles stay on this rank until the next rebuild.

        ``stop_requested()`` (a signal number, 0 for none) is polled once;
        the next evaluation agrees on it over all ranks (``self.stop``).
        """
        ps, T, cfg = self.ps, self.timers, self.cfg
        t0 = self.clock()
        n = ps.n_own
        drag = self._drag_field()
        if cfg.integrator == "paper":
            bad = integrators.step_paper(ps.pos, ps.vel, ps.acc, ps.kind, n, dt, ps.jump, cfg.h, drag, self._implicit)
            T["integrate"] += self.clock() - t0
        else:
            bad = integrators.midpoint_predict(ps.pos, ps.vel, ps.acc, ps.kind, n, dt, ps.pos0, ps.vel0, ps.jump, cfg.h,
                                               drag, self._implicit)
            T["integrate"] += self.clock() - t0
            self._bad = bad
            self.compute_rates()
            bad = self._correct(dt)
        self._count_step(dt, bad)
        self._fresh = False
        self._stop_local = stop_requested() if stop_requested is not None else 0

    def _correct(self, dt):
        """The midpoint integrator's second half (the rates at the midpoint are computed)."""
        ps, cfg = self.ps, self.cfg
        t0 = self.clock()
        bad = integrators.midpoint_correct(ps.pos, ps.vel, ps.acc, ps.kind, ps.n_own, dt, ps.pos0, ps.vel0,
                                           ps.jump, cfg.h, self._drag_field(), self._implicit)
        self.timers["integrate"] += self.clock() - t0
        return bad

    def _count_step(self, dt, bad):
        self.step += 1
        self.t = self.step * self.cfg.dt if not self.cfg.dt_auto else self.t + dt
        self._bad = bad

    def stable_dt(self):
        """The largest stable step for the current state (global minimum over ranks)."""
        ps, cfg = self.ps, self.cfg
        cmax = drag_maximum(ps.drag, ps.kind, ps.n_own) if self.explicit_drag else 0.0
        local = np.array([*state_maxima(ps.vel, ps.acc, ps.theta, ps.kind, ps.n_own, cfg.theta0), cmax])
        vmax, theta_max, amax, cmax = self.collect.max(local)
        theta_max = min(theta_max, 0.999)
        return limits.stable_dt(cfg, theta_max, vmax, amax, cmax)[0]   # config.build's limits, at the current state

    def _drag_field(self):
        """The particles' drag coefficients as the integrators take them (an empty array without a gas; read
        anew each step, as the field is reallocated when the particles grow)."""
        return self.ps.drag if self.gas is not None else self._no_state

    @property
    def explicit_drag(self):
        """A gas whose drag the step takes explicitly: the auto rule's drag limit applies."""
        return self.gas is not None and not self.gas.implicit

    # ---- reductions ------------------------------------------------------------
    def profile(self):
        """Global v_y(x), theta(x) and v_x(x): per-bin sums and counts all-reduced over ranks.

        Returns a dict: x, vy, theta, count, vx, the scene's reference profiles
        (vy_exact, theta_exact, vx_exact; NaN where it has none) and (err_max, err_rms)
        of its error field, relative to ``cfg.error_scale(t)``.
        """
        ps, cfg = self.ps, self.cfg
        bin_sums(ps.pos, ps.vel, ps.theta, ps.kind, ps.n_own, cfg.L / self.nbins, self.nbins, self.period_x,
                 self._sums)
        # v_x's row reduced on its own: the other rows' all-reduce (its size, hence MPI's choice of algorithm
        # and order of additions) is what it was before v_x was profiled
        sums, vx = self.collect.sum(self._sums[:3]), self.collect.sum(self._sums[3])
        count = sums[2]
        with np.errstate(invalid="ignore", divide="ignore"):
            out = {"x": bin_centres(cfg.L, self.nbins), "vy": sums[0] / count, "theta": sums[1] / count,
                   "count": count, "vx": vx / count}
        ref = self.scene.reference(cfg, out["x"], self.t) if self.scene.reference else {}
        for key in ("vy", "theta", "vx"):
            out[key + "_exact"] = ref.get(key, np.full(self.nbins, np.nan))
        field = self.scene.error_field
        scale = cfg.error_scale(self.t)
        out["err"] = errors(out[field], out[field + "_exact"], scale) if field in ref else (math.nan, math.nan)
        return out

    def check(self):
        """Collective run-time checks (:mod:`parsph.simulation.guards`); on failure every rank raises GuardError."""
        t0 = self.clock()
        try:
            run_checks(self.collect, self.ps, self.cfg, self.step, self.t, self.limits)
        finally:
            self.timers["checks"] += self.clock() - t0

    def particles(self):
        """The owned particles as an output writes them (read-only views; ``position`` wrapped into the
        box, a copy; ``position_raw`` and ``ref`` as the solver holds them, for a restart)."""
        ps, n = self.ps, self.ps.n_own
        pos = ps.pos[:n].copy()
        for axis in range(ps.dim):
            a = self.grid.axes[axis]
            if a.periodic:
                pos[:, axis] %= a.period
        fields = {"id": ps.gid[:n], "kind": ps.kind[:n], "mass": ps.mass[:n], "position": pos,
                  "velocity": ps.vel[:n], "theta": ps.theta[:n], "position_raw": ps.pos[:n], "ref": ps.ref[:n]}
        for v in fields.values():
            if v is not pos:
                v.flags.writeable = False  # views of the solver's arrays
        return fields

    def frame(self, snapshot=True):
        """What an output writes: time, step, dt, the profile and (``snapshot``) the owned particles."""
        return Frame(self.t, self.step, self.dt, self.profile(), self.particles() if snapshot else None)

    # ---- the loop ----------------------------------------------------------------
    def _output_due(self, t_out):
        if not self.cfg.dt_auto:
            return self.step == round(t_out / self.cfg.dt)
        return self.t >= t_out * (1 - 1e-12) - 1e-300

    def run(self, output=None, progress=None, stop_requested=None, observe=None):
        """Advance to t_end; ``output(frame, snapshot)`` at each output time, ``progress(sim, rate, eta)``.

        ``observe(sim)`` is called at every step once the rates are evaluated, before the checks
        (reading ``sim.step``, ``sim.t``, ``sim.particles()``, ``sim.profile()``); it must not change
        the state, and may raise to end the run.

        ``stop_requested()`` (a signal number, 0 for none) is polled between
        blocks of steps (at most about ``compiled_steps.BLOCK_SECONDS`` apart); when it is set
        on any rank the run writes a final output with particles and raises
        Interrupted on every rank with the same number.
        """
        return self._run_loop(output, progress, stop_requested, observe)

    def take_steps(self, n, stop_requested=None):
        """``n`` steps (fewer where t_end comes first) exactly as :meth:`run` takes them: compiled blocks,
        the auto rule landing on the output times, the run-time checks; no outputs. For benchmarks and
        studies that step a run themselves."""
        return self._run_loop(None, None, stop_requested, None, last_step=self.step + n)

    def _run_loop(self, output, progress, stop_requested, observe, last_step=None):
        """The events between the steps, in their order: the outputs due, the observer, the checks, the end,
        a stop (with a restart point), then steps to the next event and a progress line."""
        pending = self._pending_outputs()
        ticker = _Ticker(self, progress)
        if not self._fresh:
            self.compute_rates()
        while True:
            stop = self.stop
            self._write_due(pending, output)
            done = self._at_end()
            if observe is not None:
                observe(self)
            if done or (self.step % self.limits.every == 0 and self._checked != self.step):
                self.check()
            if done or (last_step is not None and self.step >= last_step):
                break
            if stop:
                self._stop_at_restart_point(output, stop)
            self._to_next_event(pending, self._most_steps(observe, last_step), stop_requested)
            ticker.tick()
        self.wall_time = time.perf_counter() - self.loop_started
        return self

    def _pending_outputs(self):
        """The output times still to write (a restart's own state was written already)."""
        pending = [t for t in self.cfg.output_times if t >= self.t * (1 + 1e-12) or (self.step == 0 and t == 0)]
        if self.step > 0:
            pending = [t for t in pending if not self._output_due(t)]
        return pending

    def _write_due(self, pending, output):
        """Every output whose time the state has reached, taken off ``pending``."""
        snapshots = self.cfg.get("output.snapshots")
        while pending and self._output_due(pending[0]):
            if output is not None:
                t0 = self.clock()
                output(self.frame(snapshots), snapshot=snapshots)
                self.timers["output"] += self.clock() - t0
            pending.pop(0)

    def _at_end(self):
        cfg = self.cfg
        return self.t >= cfg.t_end * (1 - 1e-12) if cfg.dt_auto else self.step >= cfg.nsteps

    def _stop_at_restart_point(self, output, stop):
        """A stop agreed by every rank: a final output with particles, then Interrupted on every rank."""
        if output is not None:
            output(self.frame(True), snapshot=True)
        raise Interrupted(f"stopped at step {self.step}, t = {self.t:.6g} s; the last output is a restart point",
                          stop)

    def _most_steps(self, observe, last_step):
        """The most steps before Python sees the state again: one for an observer, up to ``last_step``."""
        most = 1 if observe is not None else None
        if last_step is not None:
            most = min(most or last_step, last_step - self.step)
        return most

    # ---- whole steps -------------------------------------------------------------------
    def python_step(self, stop_requested=None, target=None):
        """One step on the Python path (mpi4py messages), from a state whose rates are computed:
        the auto rule's dt (landing on ``target``, default t_end), Eqs. (6)-(7), the next rates."""
        cfg = self.cfg
        if cfg.dt_auto:
            dt = cfg.get("numerics.dt_safety") * self.stable_dt()
            target = cfg.t_end if target is None else target
            dt, land = limits.landing(dt, target - self.t)
            self.dt = dt
            self.integrate(dt, stop_requested)
            if land:
                self.t = target
        else:
            self.integrate(self.dt, stop_requested)
        self.compute_rates()


class _Ticker:
    """The loop's clock for progress (parsph.cli.progress): ``sim.loop_started``, ``sim.steady`` (step, t,
    clock) once the run's first step, which loads or compiles the loops and builds the first list, is done
    (steps after it are steady), and ``progress(sim, rate, eta)`` every ``output.progress_interval`` s."""

    def __init__(self, sim, progress):
        self.sim, self.progress = sim, progress
        self.interval = sim.cfg.get("output.progress_interval")
        self.step0, self.t0 = sim.step, sim.t
        sim.loop_started = self.last = time.perf_counter()
        sim.steady = None

    def tick(self):
        sim, now = self.sim, time.perf_counter()
        if sim.steady is None:
            sim.steady = (sim.step, sim.t, now)
        if self.progress is not None and self.interval > 0 and now - self.last >= self.interval:
            self.last = now
            rate = sim.n_total * (sim.step - self.step0) / (now - sim.loop_started)
            eta = (sim.cfg.t_end - sim.t) * (now - sim.loop_started) / max(sim.t - self.t0, 1e-300)
            self.progress(sim, rate, eta)
