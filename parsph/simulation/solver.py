"""The driver of the time loop over one slab, composed of parts that own their data (after LAMMPS's
Neighbor, Comm, Pair and Fix): the slab ring (:class:`parsph.parallel.slab_ring.SlabRing`), the list
kept over it (:class:`.list_keeper.ListKeeper`), the passes (:class:`parsph.sph.rates.Rates`), the
integrator (:class:`.integrator.Integrator`), the clock (:class:`.timeline.Timeline`), what an output
writes (:class:`.frames.Frames`) and the compiled blocks (:class:`.compiled_steps.CompiledSteps`).
The driver holds the events: the outputs, the checks, the end, a stop, and what a block's return asks.

One step (state at t_n -> t_{n+1}), paper integrator:

  sync:      ghosts' positions from their owners -> validity test of the
             neighbour list -> one all-reduce (blow-up, stop signal,
             rebuild) -> [rebuild: wrap, migrate, ghosts, images, list]
  rates:     density Eq. (3) -> ghosts' rho -> momentum Eq. (5)
  [output, checks]
  integrate: Eqs. (6)-(7) for the owned particles

Between events the steps run in compiled blocks (:mod:`.block`); where MPI cannot be called from compiled
code, step by step from Python with the same numba stages (:meth:`Simulation.python_step`). The list is
built at the first step and whenever the sync's test says it may miss a pair. The communicator is passed
in; one rank is the same code path (the rank is its own neighbour across the periodic boundary).
"""
import time
from collections import defaultdict

import numpy as np

from parsph.errors import Interrupted, SolveError
from parsph.output import read_grid
from parsph.parallel.collectives import Collectives
from parsph.parallel.slab_ring import SlabRing
from parsph.physics import limits
from parsph.physics.kernels import get_kernel
from parsph.sph.cells import grid_for
from parsph.sph.particles import GRAIN, drag_maximum, state_maxima
from parsph.sph.rates import Rates
from . import block, start
from .compiled_steps import CompiledSteps, native_route
from .evaluation import Evaluation
from .frames import Frames
from .guards import bounds_of, run_checks
from .integrator import Integrator
from .list_keeper import ListKeeper
from .timeline import Ticker, Timeline

PHASES = ("sync", "rebuild", "gas", "density", "halo", "forces", "integrate", "output", "checks")


class Simulation:
    def __init__(self, cfg, comm, state=None, native=None, clock=time.perf_counter):
        """Set up the run on ``comm``; ``state`` (output.read_state: attrs and path) continues a run.

        ``native``: send the step's messages from compiled code (:mod:`parsph.parallel.native_mpi`);
        None (default) where the bindings load, False for the mpi4py path (the same arithmetic).
        ``clock``: the seconds of the phase timers Python keeps (list builds, outputs, checks, the
        Python path's phases; e.g. time.process_time for CPU time); the compiled blocks' phases are
        wall seconds (MPI_Wtime)."""
        self.cfg, self.comm, self.clock = cfg, comm, clock
        self.timers = defaultdict(float)
        self.kernel = get_kernel(cfg.kernel, cfg.dim)
        self.skin = cfg.get("numerics.skin") * cfg.h
        self.grid = grid_for(cfg, self.kernel)
        self.native, self.native_why = native_route(native)
        self.ring = SlabRing(comm, cfg.Ly_ring, self.grid, clock, native=self.native)
        self.collect = Collectives(comm)
        self.ps, restore = start.slab_particles(cfg, self.ring, comm, state)
        ps = self.ps
        ps.add_field("ref")  # positions at the last build of the neighbour list
        self.integrator = Integrator(cfg, ps)
        self.rho_wall = start.hold_wall_density(cfg, self.kernel, ps)
        if cfg.gas is not None:
            ps.add_field("drag_coef")
            ps.add_field("drag_rate", vector=False)
        self.gas = None
        if cfg.gas is not None and cfg.gas.solved:
            from .gas_stage import GasStage  # with scipy's solvers: only where the gas is solved
            self.gas = GasStage(cfg, comm, ps)
        if self.gas is not None and state is not None and "path" in state:
            grid = read_grid(state["path"])
            if grid is not None:  # a file without /grid: the first solve factorises
                self.gas.restore(grid)
        self.timeline = Timeline(cfg, None if state is None else state["attrs"])
        self.keeper = ListKeeper(self.ring, self.grid, self.skin, self.collect, self.integrator.position_fields,
                                 self.timers, clock)
        self.keeper.restore = restore
        self.neighbours = self.keeper.neighbours
        self.rates = Rates(*start.pass_groups(cfg, self.kernel, start.the_one_mass(self.collect, ps)))
        self.evaluation = Evaluation(self.rates, self.ring, clock, None if self.gas is None else self._gas_stage)
        self.n_total = self.collect.total(ps.n_own)
        fluid = ps.kind[:ps.n_own] == GRAIN
        self.bounds = bounds_of(cfg, float(self.collect.sum(np.array([ps.mass[:ps.n_own][fluid].sum()]))[0]))
        self.frames = Frames(cfg, self.grid, self.collect)
        self.blocks = CompiledSteps(cfg, ps, self.ring, self.neighbours, self.rates, self.integrator, self.bounds,
                                    self.skin, self.timers, None if self.gas is None else self._gas_stage_at)
        self.stop = 0            # a stop signal agreed by every rank
        self._checked = -1       # the last step whose checks a compiled block ran
        self._fresh = False      # the rates are those of the current state

    # ---- the clock and the list, as the callers read them ----------------------------
    t = property(lambda self: self.timeline.t, lambda self, v: setattr(self.timeline, "t", v))
    dt = property(lambda self: self.timeline.dt, lambda self, v: setattr(self.timeline, "dt", v))
    step = property(lambda self: self.timeline.step, lambda self, v: setattr(self.timeline, "step", v))
    rebuilds = property(lambda self: self.keeper.rebuilds)
    block_calls = property(lambda self: self.blocks.calls)

    @property
    def force_rebuild(self):
        """Rebuild the list at the next sync (whatever its test says)."""
        return self.keeper.force

    @force_rebuild.setter
    def force_rebuild(self, value):
        self.keeper.force = value

    # ---- one evaluation of the right-hand side -------------------------------
    def compute_rates(self):
        """Density, theta and accelerations of the owned particles at the current state."""
        self._sync()
        self.evaluation(self.ps, self.timers)
        self._fresh = True

    def _gas_stage(self, ps):
        """The solved gas between Eq. (3) and Eq. (5): the particles' theta of this state is known."""
        self._gas_stage_at(self.step, self.t)

    def _gas_stage_at(self, step, t, middle=False):
        """The same where a compiled block returned for it, at its state's ``step`` and ``t``; ``middle``: at
        the midpoint's middle evaluation, where a failed solve puts the particles back at the step's start."""
        t0 = self.clock()
        try:
            self.gas(self.ps, step, t)
        except SolveError:
            if middle:
                self._back_to_step_start()
            raise
        self.timers["gas"] += self.clock() - t0

    def _sync(self):
        """The list's sync (building it first where there is none) and what its agreed flags ask."""
        if not self.keeper.built:
            self._build(restore=self.keeper.restore)
            self.keeper.restore = False
        self._act(self.keeper.sync(self.ps))

    def _act(self, flags):
        """What the agreed flags of a sync (bad, stop, rebuild) ask: the checks, the stop, a build."""
        bad, stop, rebuild = flags
        if bad:
            self.check()  # raises GuardError on every rank
        if stop:
            self.stop = int(stop)
        if rebuild:
            self._build()

    def _build(self, restore=False):
        """A new list (collective); the passes and the blocks take its arrays (the phase "rebuild")."""
        t0 = self.clock()
        self.keeper.build(self.ps, restore)
        self.rates.attach(self.neighbours)
        self.evaluation.forget()
        self.blocks.forget()
        self.timers["rebuild"] += self.clock() - t0

    def integrate(self, dt, stop_requested=None):
        """One step of the chosen integrator; the particles stay on this rank until the next rebuild.

        ``stop_requested()`` (a signal number, 0 for none) is polled once;
        the next evaluation agrees on it over all ranks (``self.stop``).
        """
        t0 = self.clock()
        bad = self.integrator.first(self.ps, dt)
        self.timers["integrate"] += self.clock() - t0
        if self.integrator.midpoint:
            self.keeper.bad = bad
            try:
                self.compute_rates()
            except SolveError:
                self._back_to_step_start()
                raise
            bad = self._correct(dt)
        self._count_step(dt, bad)
        self._fresh = False
        self.keeper.stop = stop_requested() if stop_requested is not None else 0

    def _back_to_step_start(self):
        """The midpoint evaluation's gas solve failed: the owned particles back at the step's start (the
        predictor kept it), the gas stage at its start's call, so that what is written is that whole state."""
        ps, n = self.ps, self.ps.n_own
        ps.pos[:n] = ps.pos0[:n]
        ps.vel[:n] = ps.vel0[:n]
        self.gas.step_back()

    def _correct(self, dt):
        """The midpoint integrator's second half (the rates at the midpoint are computed)."""
        t0 = self.clock()
        bad = self.integrator.second(self.ps, dt)
        self.timers["integrate"] += self.clock() - t0
        return bad

    def _count_step(self, dt, bad):
        self.timeline.count(dt)
        self.keeper.bad = bad

    def stable_dt(self):
        """The largest stable step for the current state (global minimum over ranks)."""
        ps, cfg = self.ps, self.cfg
        cmax = drag_maximum(ps.drag_coef, ps.kind, ps.n_own) if self.integrator.explicit_drag else 0.0
        local = np.array([*state_maxima(ps.vel, ps.acc, ps.theta, ps.kind, ps.n_own, cfg.theta0), cmax])
        vmax, theta_max, amax, cmax = self.collect.max(local)
        theta_max = min(theta_max, 0.999)
        return limits.stable_dt(cfg, theta_max, vmax, amax, cmax)[0]   # config.build's limits, at the current state

    # ---- what the outputs and observers read -----------------------------------------
    def profile(self):
        """Global v_y(x), theta(x) and v_x(x) with the scene's reference and error (:meth:`Frames.profile`)."""
        return self.frames.profile(self.ps, self.t)

    def particles(self):
        """The owned particles as an output writes them (:meth:`Frames.particles`)."""
        return self.frames.particles(self.ps)

    def frame(self, snapshot=True):
        """What an output writes: time, step, dt, the profile and (``snapshot``) the owned particles."""
        frame = self.frames.frame(self.ps, self.timeline, snapshot)
        if self.gas is not None:
            frame.grid = self.gas.fields()
        return frame

    def reflections(self):
        """Collective: how many times a grain was put back on a plate (``walls.reflect``, the layers' backstop
        where the walls' pressure did not stop it within a step), over all ranks, since this run started."""
        return self.collect.total(int(self.blocks.field("reflected")) + self.integrator.reflected)

    def check(self):
        """Collective run-time checks (:mod:`parsph.simulation.guards`); on failure every rank raises GuardError."""
        t0 = self.clock()
        try:
            run_checks(self.collect, self.ps, self.cfg, self.step, self.t, self.bounds)
        finally:
            self.timers["checks"] += self.clock() - t0

    # ---- the loop ----------------------------------------------------------------
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
        timeline = self.timeline
        pending = timeline.pending_outputs()
        ticker = Ticker(self, progress)
        try:
            if not self._fresh:
                self.compute_rates()
            self._steps_and_events(timeline, pending, ticker, output, stop_requested, observe, last_step)
        except SolveError as e:  # raised on every rank alike
            raise self._restart_point_at(e, output) from None
        self.wall_time = time.perf_counter() - self.loop_started
        return self

    def _restart_point_at(self, error, output):
        """A failed gas solve: the whole state it failed on (a step's end, or the start of the step whose
        midpoint it was) written as a restart point, and the error saying so."""
        if output is None:
            return SolveError(f"{error}; the last output is the restart point")
        output(self.frame(True), snapshot=True)
        return SolveError(f"{error}; a restart point written at step {self.step}, t = {self.t:.6g} s")

    def _steps_and_events(self, timeline, pending, ticker, output, stop_requested, observe, last_step):
        """The loop of :meth:`_run_loop` from a state whose rates are computed."""
        while True:
            stop = self.stop
            self._write_due(pending, output)
            done = timeline.at_end()
            if observe is not None:
                observe(self)
            if done or (self.step % self.bounds.every == 0 and self._checked != self.step):
                self.check()
            if done or (last_step is not None and self.step >= last_step):
                break
            if stop:
                self._stop_at_restart_point(output, stop)
            self._to_next_event(pending, timeline.most_steps(observe, last_step), stop_requested)
            ticker.tick()

    def _write_due(self, pending, output):
        """Every output whose time the state has reached, taken off ``pending``."""
        snapshots = self.cfg.get("output.snapshots")
        while pending and self.timeline.output_due(pending[0]):
            if output is not None:
                t0 = self.clock()
                output(self.frame(snapshots), snapshot=snapshots)
                self.timers["output"] += self.clock() - t0
            pending.pop(0)

    def _stop_at_restart_point(self, output, stop):
        """A stop agreed by every rank: a final output with particles, then Interrupted on every rank."""
        if output is not None:
            output(self.frame(True), snapshot=True)
        raise Interrupted(f"stopped at step {self.step}, t = {self.t:.6g} s; the last output is a restart point",
                          stop)

    # ---- steps to the next event -------------------------------------------------------
    def _to_next_event(self, pending, most=None, stop_requested=None):
        """At least one step, up to the next output or the end (``most`` steps at most, else about
        BLOCK_SECONDS of them), in compiled blocks that run the checks too where the messages can be sent
        from compiled code, else one step."""
        target = self.timeline.target(pending)
        if not self.native:
            self.python_step(stop_requested, target)
            return
        stop_step = self.timeline.stop_step(pending, most or self.blocks.steps)
        self.keeper.stop = stop_requested() if stop_requested is not None else 0
        self._run_compiled(stop_step, target)

    def _run_compiled(self, stop_step, target):
        """Compiled blocks to ``stop_step`` (or the landing on ``target``), and what each return asks."""
        blocks, keeper = self.blocks, self.keeper
        t0 = time.perf_counter()
        steps0 = self.step
        while True:
            code = blocks.run(self.timeline, target, stop_step, keeper.stop, keeper.force)
            keeper.clear()
            if blocks.field("stop_out"):
                self.stop = int(blocks.field("stop_out"))
            self._checked = int(blocks.field("checked"))
            if code == block.CHECK:
                self.check()  # raises GuardError on every rank (it passes only where a sum's last bit differs)
                break
            if code == block.NEED_LIMIT:
                blocks.new_limit()
                continue
            if code == block.MPI_ERROR:
                raise RuntimeError("an MPI call of the compiled step failed")
            if code in (block.REBUILD, block.BAD, block.REBUILD_MID, block.BAD_MID):
                self._finish_step(code)
            self._fresh = True
            break
        blocks.pace(self.step - steps0, time.perf_counter() - t0)

    def _finish_step(self, code):
        """The rest of a step a block returned in: act on the agreed flags (checks, build), the rates
        (a compiled evaluation of the new list); at the midpoint, the second half and the step's last
        sync too."""
        self._act(self.blocks.agreed_flags())
        self.blocks.evaluate(self.timeline)
        if code in (block.REBUILD_MID, block.BAD_MID):
            self._count_step(self.dt, self._correct(self.dt))
            if self.blocks.field("land"):
                self.t = float(self.blocks.field("t_target"))
            self.compute_rates()

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
