"""The compiled blocks of one run (:mod:`.block`) as a part of the driver: the record that crosses
between Python and the block (``block.CONTROL``), the scratch of its all-reduces, its phase timers, its
arguments (this build's arrays, made anew after each build) and the block compiled for their types.
The driver (:class:`parsph.simulation.solver.Simulation`) decides what a returned code asks."""

import numpy as np

from parsph.parallel import native_mpi
from parsph.physics import limits
from parsph.sph import dispatch, pass_data
from parsph.sph.dispatch import compiled, kinds
from . import block
from .block import Modes, Motion, Rule

BLOCK_SECONDS = 0.1  # a compiled block's length: the stop signal is polled (and progress shown) between blocks


class CompiledSteps:
    """Runs blocks on the parts it is given: the particles, the slab ring, the list, the passes, the
    integrator and the run-time checks' bounds; adds its phase seconds into ``timers``."""

    def __init__(self, cfg, ps, ring, neighbours, rates, integrator, bounds, skin, timers, gas=None):
        """``gas(step, t, middle)``: the solved gas's stage, run where a block returns GAS (None: no solved gas);
        ``middle``: at the midpoint integrator's middle evaluation."""
        self.cfg, self.ps, self.ring, self.neighbours, self.rates = cfg, ps, ring, neighbours, rates
        self.gas = gas
        self.integrator, self.bounds, self.timers = integrator, bounds, timers
        self.control = np.zeros(1, block.CONTROL)  # the block's clock and its exchanges with Python
        self.scratch = np.zeros(block.N_SCRATCH)
        self._timers = np.zeros(len(block.TIMER_PHASES))
        self._req, self._stat = native_mpi.requests(1)  # the sync's all-reduce in flight
        nbuckets = int(round(0.999 / limits.THETA_STEP)) + 1  # limits.limits: theta at most 0.999
        self.rule = Rule(float(cfg.dt), float(cfg.get("numerics.dt_safety")), float(cfg.h), float(cfg.theta0),
                         float(limits.THETA_STEP), float(skin), np.full(nbuckets, np.nan))
        self.steps = 1   # the next block's length in steps
        self.calls = 0   # returns from compiled code to Python (blocks run)
        self._args = None
        self._fn = None
        self._versions = {}

    def forget(self):
        """A list was built: the next block's arguments are its arrays."""
        self._args = None

    def _block(self):
        """The compiled block for this build's argument types (compiled or loaded from the cache once)."""
        if self._args is None:
            ps, R, N, cfg, integ = self.ps, self.rates, self.neighbours, self.cfg, self.integrator
            threaded = dispatch.threaded()
            sw = pass_data.switch
            modes = Modes(sw(integ.midpoint), bool(cfg.dt_auto), sw(threaded), integ.implicit,
                          bool(integ.explicit_drag), self.gas is not None)
            self._modes = modes
            self._args = (self.ring.plan(ps.dim), R.list, pass_data.particle_arrays(ps), Motion(*integ.motion(ps)),
                          N.cells, N.local, N.box, N.work, R.consts, R.switches,
                          R.gather_for(threaded), self.rule, self.bounds, *modes,
                          self.control, self._timers, self.scratch, self._req, self._stat)
            self._fn = None
        if self._fn is None:
            # the arguments' types are those of the first build with these modes (every array is made anew
            # alike, C-contiguous, at each build): their kinds are read once per modes, not at every build
            fn = self._versions.get(self._modes)
            if fn is None:
                fn = self._versions.get(kinds(self._args))
                if fn is None:
                    fn = compiled(block.run_block, *self._args)
                    self._versions[kinds(self._args)] = fn
                self._versions[self._modes] = fn
            self._fn = fn
        return self._fn

    def run(self, timeline, target, stop_step, stop_in, force_in):
        """Blocks from ``timeline``'s state to ``stop_step`` (or the landing on ``target``) until one returns
        a code of :mod:`.block`; ``timeline`` is advanced to where it returned."""
        ctl = self.control
        ctl["t"], ctl["dt"], ctl["step"] = timeline.t, timeline.dt, timeline.step
        ctl["t_target"], ctl["stop_step"] = target, stop_step
        ctl["stop_in"], ctl["force_in"], ctl["stop_out"] = stop_in, force_in, 0.0
        return self._call(timeline)

    def _call(self, timeline):
        """The block, and again after each GAS it returns once the gas stage has run at the state it stopped
        at (``timeline`` advanced to it first: a failed solve writes that state; the block resumes where it
        returned); ``timeline`` is advanced to where the last call returned."""
        fn = self._block()
        ctl = self.control
        code = fn(*self._args)
        self.calls += 1
        while code == block.GAS:
            self._add_timers()
            self._clock_to(timeline)
            self.gas(timeline.step, timeline.t, int(ctl["resume"][0]) == block.AFTER_MID)
            code = fn(*self._args)
            self.calls += 1
        self._add_timers()
        self._clock_to(timeline)
        return code

    def _clock_to(self, timeline):
        ctl = self.control
        timeline.t, timeline.dt, timeline.step = float(ctl["t"][0]), float(ctl["dt"][0]), int(ctl["step"][0])

    def evaluate(self, timeline):
        """Eq. (3), the ghosts' rho, Eq. (5) of the current state, in the compiled block (no step: the record's
        landing, ``land`` and ``t_target``, stays as the last step left it, for the driver to finish that step)."""
        ctl = self.control
        ctl["eval_first"] = True
        ctl["t"], ctl["dt"], ctl["step"] = timeline.t, timeline.dt, timeline.step
        ctl["stop_step"] = timeline.step
        ctl["stop_in"], ctl["force_in"], ctl["stop_out"] = 0.0, False, 0.0
        if self._call(timeline) == block.MPI_ERROR:
            raise RuntimeError("an MPI call of the compiled step failed")

    def field(self, name):
        """A field of the record as Python reads it (``stop_out``, ``checked``, ``land``, ``t_target``)."""
        return self.control[name][0]

    def agreed_flags(self):
        """The flags (bad, stop, rebuild) the last sync of the block agreed."""
        return self.scratch[block.FLAGS_ALL].copy()

    def new_limit(self):
        """The linear limit of the bucket the agreed largest theta is in, into the rule's table (the auto
        rule, Python's side)."""
        theta_max = min(float(self.scratch[block.THETA_MAX_ALL]), 0.999)
        table = self.rule.linear
        lim = limits.run_limits(self.cfg, theta_max, 0.0, 0.0)  # limits rounds theta up to its bucket
        table[block.bucket_index(theta_max, limits.THETA_STEP, len(table))] = min(lim.values())

    def pace(self, steps, seconds):
        """The next block's length from the last run's: about BLOCK_SECONDS of steps."""
        if steps > 0 and seconds > 0:
            self.steps = max(1, min(100_000, int(BLOCK_SECONDS / (seconds / steps))))

    def _add_timers(self):
        tb = self._timers
        for k, name in enumerate(block.TIMER_PHASES):
            self.timers[name] += float(tb[k])
        tb[:] = 0.0


def native_route(native):
    """(whether the step's messages are sent from compiled code, why not): ``native`` None takes it where
    the bindings load (:mod:`parsph.parallel.native_mpi`), False never."""
    if native is False:
        return False, "native=False"
    return native_mpi.available()
