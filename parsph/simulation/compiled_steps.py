"""The compiled steps' side of :class:`parsph.simulation.solver.Simulation`: the block's state and arguments,
the blocks up to the next event, and what Python does when a block returns in the middle of a step
(a list build, a blow-up) or needs a new linear limit (auto dt).
"""
import time

import numba
import numpy as np

from parsph.parallel import native_mpi
from parsph.physics import limits
from parsph.sph import pass_data
from parsph.sph.dispatch import compiled, kinds
from . import block
from .block import Modes, Motion, Rule

BLOCK_SECONDS = 0.1  # a compiled block's length: the stop signal is polled (and progress shown) between blocks


class CompiledSteps:
    """Mixed into Simulation: the steps between events in compiled blocks."""

    def _init_blocks(self, native):
        """The compiled step's state: where MPI can be called from compiled code (else the Python path)."""
        cfg = self.cfg
        self.native, self.native_why = native_mpi.available()
        if native is False:
            self.native, self.native_why = False, "native=False"
        self.ring.native = self.native  # the list build's messages take the same route
        self._control = np.zeros(1, block.CONTROL)  # the block's clock and its exchanges with Python
        self._scratch = np.zeros(block.N_SCRATCH)
        self._timers_block = np.zeros(len(block.TIMER_PHASES))
        self._req, self._stat = native_mpi.requests(1)  # the sync's all-reduce in flight
        nbuckets = int(round(0.999 / limits.THETA_STEP)) + 1  # limits.limits: theta at most 0.999
        self._rule = Rule(float(cfg.dt), float(cfg.get("numerics.dt_safety")), float(cfg.h), float(cfg.theta0),
                          float(limits.THETA_STEP), float(self.skin), np.full(nbuckets, np.nan))
        self._block_steps = 1
        self.block_calls = 0  # returns from compiled code to Python (blocks run)
        self._block_args = None
        self._block_fn = None
        self._block_versions = {}
        dim = cfg.dim
        self._no_gather = pass_data.Gather(np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(0), np.zeros(0),
                                           np.zeros(0))
        self._no_state = np.zeros((0, dim))

    def _block(self):
        """The compiled block for this build's argument types (compiled or loaded from the cache once)."""
        if self._block_args is None:
            ps, R, N, cfg = self.ps, self.rates, self.neighbours, self.cfg
            threaded = numba.get_num_threads() > 1
            mid = cfg.integrator == "midpoint"
            motion = Motion(ps.disp, ps.ref, ps.jump, ps.pos0 if mid else self._no_state,
                            ps.vel0 if mid else self._no_state)
            sw = pass_data.switch
            modes = Modes(sw(mid), sw(cfg.dt_auto), sw(threaded), self._implicit, sw(self.explicit_drag))
            self._block_modes = modes
            self._block_args = (self.ring.plan(ps.dim), R.list, pass_data.particle_arrays(ps), motion, N.cells,
                                N.local, N.box, N.work, R.consts, R.switches,
                                R.gather_arrays() if threaded else self._no_gather, self._rule, self.limits, *modes,
                                self._control, self._timers_block, self._scratch, self._req,
                                self._stat)
            self._block_fn = None
        if self._block_fn is None:
            # the arguments' types are those of the first build with these modes (every array is made anew
            # alike, C-contiguous, at each build): their kinds are read once per modes, not at every build
            modes = self._block_modes
            fn = self._block_versions.get(modes)
            if fn is None:
                fn = self._block_versions.get(kinds(self._block_args))
                if fn is None:
                    fn = compiled(block.run_block, *self._block_args)
                    self._block_versions[kinds(self._block_args)] = fn
                self._block_versions[modes] = fn
            self._block_fn = fn
        return self._block_fn

    def _to_next_event(self, pending, most=None, stop_requested=None):
        """At least one step, up to the next output or the end (``most`` steps at most, else about
        BLOCK_SECONDS of them), in compiled blocks that run the checks too where the messages can be sent
        from compiled code, else one step."""
        cfg = self.cfg
        target = min(pending[0], cfg.t_end) if pending else cfg.t_end
        if not self.native:
            self.python_step(stop_requested, target)
            return
        stop_step = self.step + (most or self._block_steps)
        if not cfg.dt_auto:
            stop_step = min(stop_step, cfg.nsteps)
            if pending:
                stop_step = min(stop_step, max(round(pending[0] / cfg.dt), self.step + 1))
        self._stop_local = stop_requested() if stop_requested is not None else 0
        self._run_compiled(stop_step, target)

    def _run_compiled(self, stop_step, target):
        """Compiled blocks to ``stop_step`` (or the landing on ``target``): the codes of :mod:`.block`."""
        ctl = self._control
        t0 = time.perf_counter()
        steps0 = self.step
        while True:
            ctl["t"], ctl["dt"], ctl["step"] = self.t, self.dt, self.step
            ctl["t_target"], ctl["stop_step"] = target, stop_step
            ctl["stop_in"], ctl["force_in"], ctl["stop_out"] = self._stop_local, self.force_rebuild, 0.0
            code = self._block()(*self._block_args)
            self.block_calls += 1
            self.t, self.dt, self.step = float(ctl["t"][0]), float(ctl["dt"][0]), int(ctl["step"][0])
            self._bad = self._stop_local = 0
            self.force_rebuild = False
            if ctl["stop_out"][0]:
                self.stop = int(ctl["stop_out"][0])
            self._checked = int(ctl["checked"][0])
            self._add_block_timers()
            if code == block.CHECK:
                self.check()  # raises GuardError on every rank (it passes only where a sum's last bit differs)
                break
            if code == block.NEED_LIMIT:
                self._new_limit()
                continue
            if code == block.MPI_ERROR:
                raise RuntimeError("an MPI call of the compiled step failed")
            if code in (block.REBUILD, block.BAD, block.REBUILD_MID, block.BAD_MID):
                self._finish_step(code)
            self._fresh = True
            break
        took = time.perf_counter() - t0
        if self.step > steps0 and took > 0:  # the next block's length: about BLOCK_SECONDS of steps
            per_step = took / (self.step - steps0)
            self._block_steps = max(1, min(100_000, int(BLOCK_SECONDS / per_step)))

    def _finish_step(self, code):
        """The rest of a step a block returned in: act on the agreed flags (checks, rebuild), the rates
        (a compiled evaluation of the new list); at the midpoint, the second half and the step's last
        sync too."""
        self._act(self._scratch[block.FLAGS_ALL].copy())
        self._evaluate_compiled()
        if code in (block.REBUILD_MID, block.BAD_MID):
            self._count_step(self.dt, self._correct(self.dt))
            if self._control["land"][0]:
                self.t = float(self._control["t_target"][0])
            self.compute_rates()

    def _evaluate_compiled(self):
        """Eq. (3), the ghosts' rho, Eq. (5) of the current state, in the compiled block (no step)."""
        ctl = self._control
        ctl["eval_first"] = True
        ctl["t"], ctl["dt"], ctl["step"] = self.t, self.dt, self.step
        ctl["t_target"], ctl["stop_step"] = self.t, self.step
        ctl["stop_in"], ctl["force_in"], ctl["stop_out"] = 0.0, False, 0.0
        if self._block()(*self._block_args) == block.MPI_ERROR:
            raise RuntimeError("an MPI call of the compiled step failed")
        self._add_block_timers()

    def _new_limit(self):
        """The linear limit of the bucket the agreed largest theta is in, into the rule's table (the auto
        rule, Python's side)."""
        theta_max = min(float(self._scratch[block.THETA_MAX_ALL]), 0.999)
        table = self._rule.linear
        lim = limits.run_limits(self.cfg, theta_max, 0.0, 0.0)  # limits rounds theta up to its bucket
        table[block.bucket_index(theta_max, limits.THETA_STEP, len(table))] = min(lim.values())

    def _add_block_timers(self):
        tb = self._timers_block
        for k, name in enumerate(block.TIMER_PHASES):
            self.timers[name] += float(tb[k])
        tb[:] = 0.0
