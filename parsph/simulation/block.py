"""The steps between events in compiled code: integrate, sync, Eq. (3), ghosts' rho, Eq. (5), again and again.

:func:`run_block` advances the state by whole steps of the stages of
:mod:`.stages`, which the Python path of :class:`parsph.simulation.solver.Simulation`
takes too (the messages through :mod:`parsph.parallel.native_mpi` instead of
mpi4py), and returns to Python when something happens there:

- ``EVENT``: the step ``stop_step`` was reached, or (auto dt) the step landed
  on the target time: an output, a check, the end, a progress line or a
  signal poll is due;
- ``REBUILD`` / ``REBUILD_MID``: the all-reduce after a sync (at the end of a
  step, or at the midpoint integrator's middle evaluation) says the
  neighbour list must be rebuilt; the particles are synced, the step's rates
  are not computed yet;
- ``BAD`` / ``BAD_MID``: the last integration left a non-finite state or a
  jump beyond h on some rank (Python runs the checks, which raise);
- ``CHECK``: the run-time checks of :mod:`.guards`, run every ``checks.every``
  steps once the step's rates are computed, failed on some rank (Python runs
  them again to name the particle and raises);
- ``STOP``: a signal's stop, agreed at a sync in this block (rates computed);
- ``NEED_LIMIT``: (auto dt) the largest theta is in a bucket whose linear
  limit Python has not computed yet (``Rule.linear``); nothing of the step
  is done yet;
- ``MPI_ERROR``: an MPI call failed;
- ``GAS``: (the solved gas, ``gas`` on) an evaluation stands between Eq. (3) and Eq. (5), the particles'
  theta known: Python runs the gas stage (its solve is scipy's and LAPACK's) and calls the block again,
  which resumes where it returned (``control``'s ``resume``: after a step's last evaluation, after the
  midpoint's middle one, or after the evaluation of a new list's state), with Eq. (5).

Every decision is taken from all-reduced values or from the step count, so
every rank returns at the same step with the same code.
"""
import math
from typing import NamedTuple

import numpy as np
from numba import njit, uintp

from parsph.parallel import native_halo
from parsph.parallel.native_mpi import OP_MAX, OP_SUM, allreduce, iallreduce, wait, wtime
from parsph.sph import walls
from parsph.sph.integrators import integrate_first, integrate_second
from parsph.sph.cells import patch_spread
from parsph.sph.particles import drag_maximum, state_maxima
from parsph.physics.limits import landing, state_limit
from .guards import N_FASTEST, N_REPORT, check_report
from . import stages
# the codes of the module doc (the driver reads them here) and the phase timers
from .stages import (BAD, BAD_MID, CHECK, CHECKS, DENSITY, DONE, EVENT, FORCES_ONLY, GAS,  # noqa: F401
                     INTEGRATE, MPI_ERROR, NEED_LIMIT, REBUILD, REBUILD_MID, START, STOP, SYNC, TIMER_PHASES)

# where a block resumes after GAS (control's resume): nowhere (a fresh start), after a step's last evaluation,
# after the midpoint's middle evaluation, after the evaluation of the state as it is (eval_first)
FRESH, AFTER_END, AFTER_MID, AFTER_FIRST = range(4)
_STEP = -2  # run_block's phase: a step from its start
# the block's clock and its exchanges with Python: one record (``control``, an array of one element of
# this type, read and written by field name on both sides)
CONTROL = np.dtype([
    ("t", np.float64), ("dt", np.float64), ("step", np.int64),  # the clock
    ("t_target", np.float64),   # (auto dt) the time to land on: the next output or the end
    ("stop_step", np.int64),    # the step to stop at
    ("eval_first", np.bool_),   # evaluate the rates of the state first (a list was just built)
    ("stop_in", np.float64),    # a signal this rank saw since the last sync (0: none)
    ("force_in", np.bool_),     # rebuild the list at the next sync
    ("stop_out", np.float64),   # a stop agreed at a sync of the block (the signal's number)
    ("land", np.bool_),         # the last step landed on t_target
    ("checked", np.int64),      # the last step whose checks the block ran
    ("reflected", np.int64),    # grains this rank's walls.reflect put back on a plate
    ("resume", np.int64),       # where the block resumes after GAS (FRESH: it does not)
])
# scratch (float64): the all-reduces' buffers of run_block, by name
FLAGS, FLAGS_ALL = slice(0, 3), slice(3, 6)        # a sync's (bad, stop, rebuild), and their agreed values
MAXIMA, MAXIMA_ALL = slice(6, 10), slice(10, 14)   # the auto rule's (|v|, theta, |a|, drag C) maxima
THETA_MAX_ALL = 11                                 # the agreed largest theta (maxima_all[1])
N_SCRATCH = 14 + N_REPORT + N_FASTEST + 4


class Motion(NamedTuple):
    """The particle fields the step moves besides ParticleArrays'."""
    disp: np.ndarray  # displacement since the last list build
    ref: np.ndarray   # positions at the last build
    jump: np.ndarray  # the last step's displacement length
    pos0: np.ndarray  # midpoint integrator: r^n, v^n (else empty)
    vel0: np.ndarray


class Rule(NamedTuple):
    """The numbers of the step rule: fixed dt or the auto rule (parsph.physics.limits.stable_dt)."""
    dt: float          # the fixed step (the first step with auto dt)
    safety: float      # numerics.dt_safety
    h: float           # the jump limit (check 5) and the advection/force limits' length
    theta0: float      # the floor of the largest theta (state_maxima)
    theta_step: float  # limits.THETA_STEP: the bucket of the cached linear limit
    skin: float
    linear: np.ndarray  # the linear limit of bucket k (theta k theta_step, bucket_index); NaN until Python
                        # computes it (a table, so that a theta going back and forth between buckets costs
                        # one return to Python per bucket, not one per crossing)


class Modes(NamedTuple):
    """The block's choices, passed to :func:`run_block` as arguments of their own (``*modes``).

    ``midpoint``, ``threaded``, ``implicit`` are compile-time (pass_data.switch values): numba prunes a branch
    on an empty tuple's ``len`` before typing only for an argument, so that a serial block compiles no
    ``parallel=True`` pass and no midpoint integrator. ``dt_auto``, ``drag_limit`` and ``gas`` are run-time
    flags: a branch an evaluation or a step, and one version serves both values (each a switch compiled a
    block of its own, about 5 s)."""
    midpoint: tuple
    dt_auto: bool
    threaded: tuple
    implicit: tuple   # the gas's drag implicit in v (numerics.drag_update; integrators)
    drag_limit: bool  # the auto rule's drag limit dt <= 1/C_max (explicit drag)
    gas: bool         # the solved gas: each evaluation returns GAS between Eq. (3) and Eq. (5)


@njit(cache=True)
def _sync(plan, parts, motion, cells, local, box, work, control, flags, flags_all, bad, skin, timers, req):
    """Displacements, the ghosts' refresh, the list's validity test, and the all-reduce of (bad, stop,
    rebuild) started: ``flags_all`` holds the agreed values once ``native_mpi.wait(req)`` returned.
    Returns MPI's error code."""
    t0 = wtime()
    pos, ref, d = parts.pos.reshape(-1), motion.ref.reshape(-1), motion.disp.reshape(-1)
    for k in range(uintp(parts.n_own * parts.pos.shape[1])):  # flat: a vector loop
        d[k] = pos[k] - ref[k]
    err = native_halo.forward(plan, parts.pos, parts.vel, motion.disp, parts.n_own)
    spread = patch_spread(motion.disp, cells, local, box, work)
    flags[0] = bad
    ctl = control[0]
    flags[1] = ctl.stop_in
    flags[2] = 1.0 if (ctl.force_in or not spread < skin) else 0.0
    ctl.stop_in = 0.0
    ctl.force_in = False
    err |= iallreduce(plan.h, OP_MAX, flags, flags_all, req)
    timers[SYNC] += wtime() - t0
    return err


@njit(cache=True, inline="always")
def evaluate(plan, lst, parts, c, sw, gather, threaded, gas, timers):
    """Eq. (3), the ghosts' rho, Eq. (5): the rates of the owned particles (:mod:`.stages`); DONE, GAS or
    MPI_ERROR (:func:`.stages.after_density`)."""
    t0 = wtime()
    stages.density(lst, parts, c, sw, gather, threaded)
    timers[DENSITY] += wtime() - t0
    return stages.after_density(plan, lst, parts, c, sw, gather, threaded, sw.mirror, gas, np.int64(START), timers)


@njit(cache=True)
def bucket_index(theta_max, theta_step, nbuckets):
    """The index k of theta_max's bucket in ``Rule.linear`` (of ``nbuckets`` entries): theta_max rounded up
    to k theta_step, as parsph.physics.limits.limits rounds it; the last entry holds theta = 0.999 and above."""
    k = math.ceil(theta_max / theta_step - 1e-9)
    return min(max(k, 0), nbuckets - 1)


@njit(cache=True)
def _auto_dt(plan, parts, rule, maxima, maxima_all, drag_limit):
    """The auto rule's dt (safety x the smallest of the linear, advection, force and, with ``drag_limit``,
    drag limits: :func:`parsph.physics.limits.state_limits`), or -1 when the linear limit of the largest
    theta's bucket is not in ``rule.linear`` yet; -2 on an MPI error."""
    v, th, a = state_maxima(parts.vel, parts.acc, parts.theta, parts.kind, parts.n_own, rule.theta0)
    maxima[0] = v
    maxima[1] = th
    maxima[2] = a
    maxima[3] = drag_maximum(parts.drag_coef, parts.kind, parts.n_own) if drag_limit else 0.0
    if allreduce(plan.h, OP_MAX, maxima, maxima_all) != 0:
        return -2.0
    vmax, theta_max, amax = maxima_all[0], min(maxima_all[1], 0.999), maxima_all[2]
    linear = rule.linear[bucket_index(theta_max, rule.theta_step, len(rule.linear))]
    if linear != linear:  # NaN: not computed yet
        return -1.0
    return rule.safety * min(linear, state_limit(rule.h, vmax, amax, maxima_all[3]))


@njit(cache=True)
def _checks_fail(plan, parts, motion, lim, report, fastest, sums, sums_all):
    """The run-time checks on every rank (one all-reduce): 1 where one failed somewhere, 0 where none
    did, -1 on an MPI error."""
    ke = check_report(parts.pos, parts.vel, parts.acc, parts.theta, motion.jump, parts.kind, parts.mass,
                      parts.n_own, lim, report, fastest)
    sums[0] = 1.0 if report[0] > 0 else 0.0
    sums[1] = ke
    if allreduce(plan.h, OP_SUM, sums, sums_all) != 0:
        return -1
    return 1 if sums_all[0] > 0 or not sums_all[1] <= lim.ke_bound else 0


@njit(cache=True, inline="always")
def _sync_evaluate(plan, lst, parts, motion, cells, local, box, work, c, sw, gather, threaded, gas, control, flags,
                   flags_all, bad, skin, timers, req, stat):
    """A sync, then the rates unless the agreed flags say otherwise: DONE when the rates are computed, else
    the block's code (BAD, REBUILD; :func:`run_block` makes them BAD_MID, REBUILD_MID at the midpoint
    integrator's middle evaluation; GAS before Eq. (5) with the solved gas). A stop agreed here is kept in
    ``control``'s stop_out.

    Eq. (3) runs while the flags' all-reduce is in flight (it writes only the list's sums, which a
    rebuild or a bad state discards): the wait for the all-reduce comes after the pass, so a rank that
    reaches it first computes its densities instead of waiting, and its latency hides behind them."""
    if _sync(plan, parts, motion, cells, local, box, work, control, flags, flags_all, bad, skin, timers, req):
        return MPI_ERROR
    t0 = wtime()
    stages.density(lst, parts, c, sw, gather, threaded)
    t1 = wtime()
    err = wait(req, stat)
    timers[DENSITY] += t1 - t0
    timers[SYNC] += wtime() - t1
    if err:
        return MPI_ERROR
    if flags_all[0] != 0.0:
        return BAD
    if flags_all[1] != 0.0:
        control[0].stop_out = flags_all[1]
    if flags_all[2] != 0.0:
        return REBUILD
    return stages.after_density(plan, lst, parts, c, sw, gather, threaded, sw.mirror, gas, np.int64(START), timers)


@njit(cache=True)
def run_block(plan, lst, parts, motion, cells, local, box, work, c, sw, gather, rule, lim, midpoint, dt_auto,
              threaded, implicit, drag_limit, gas, control, timers, scratch, req, stat):
    """Whole steps from a state whose rates are computed, until a code of the module doc; returns it.

    ``control`` (one record of :data:`CONTROL`) holds the clock (t, dt, step) and the exchanges with
    Python (the target time, the step to stop at, stop and forced-rebuild flags in, a stop out, whether
    to evaluate the rates of the state first, the last step checked, where to resume after GAS); ``lim``
    the checks' bounds (guards.Bounds); ``midpoint`` .. ``gas`` the fields of :class:`Modes`; ``timers``
    gets the phases' seconds; ``scratch`` (N_SCRATCH float64) the all-reduces' buffers, by the named slices
    above; ``req``, ``stat`` (native_mpi.requests(1)) the sync's all-reduce in flight.

    A step runs as phases, so that a block can return for the gas stage in the middle of one and resume
    there: from its start (dt, the integration or the midpoint's prediction and middle evaluation), after
    the middle evaluation (the correction), after the integration (the sync and the last evaluation), and
    its tail (the checks, a stop, the landing).
    """
    flags, flags_all = scratch[FLAGS], scratch[FLAGS_ALL]
    maxima, maxima_all = scratch[MAXIMA], scratch[MAXIMA_ALL]
    report = scratch[14:14 + N_REPORT]
    fastest = scratch[14 + N_REPORT:14 + N_REPORT + N_FASTEST]
    sums = scratch[14 + N_REPORT + N_FASTEST:16 + N_REPORT + N_FASTEST]
    sums_all = scratch[16 + N_REPORT + N_FASTEST:18 + N_REPORT + N_FASTEST]
    pos, vel, acc, kind, drag = parts.pos, parts.vel, parts.acc, parts.kind, parts.drag_coef
    n_own = parts.n_own
    ctl = control[0]
    phase = _STEP
    if ctl.resume != FRESH:  # the gas stage of the evaluation the block returned in is done: Eq. (5)
        stages.after_density(plan, lst, parts, c, sw, gather, threaded, sw.mirror, gas, np.int64(FORCES_ONLY),
                             timers)
        phase = _STEP if ctl.resume == AFTER_FIRST else ctl.resume
        ctl.resume = FRESH
    elif ctl.eval_first:  # the rates of the state as it is (a list was just built)
        ctl.eval_first = False
        code = evaluate(plan, lst, parts, c, sw, gather, threaded, gas, timers)
        if code == GAS:
            ctl.resume = AFTER_FIRST
            return GAS
        if code >= 0:
            return MPI_ERROR
    bad = False
    t0 = 0.0
    while True:
        if phase == _STEP:
            if not ctl.step < ctl.stop_step:
                return EVENT
            # -- the step's dt
            land = False
            if dt_auto:
                dt = _auto_dt(plan, parts, rule, maxima, maxima_all, drag_limit)
                if dt == -2.0:
                    return MPI_ERROR
                if dt < 0.0:
                    return NEED_LIMIT
                dt, land = landing(dt, ctl.t_target - ctl.t)
            else:
                dt = rule.dt
            ctl.dt = dt
            ctl.land = land
            # -- integrate (midpoint: predict, evaluate at the midpoint, correct)
            t0 = wtime()
            bad = integrate_first(threaded, midpoint, pos, vel, acc, kind, n_own, dt, motion.pos0, motion.vel0,
                                  motion.jump, rule.h, drag, implicit)
            if len(midpoint):
                if len(sw.mirror):
                    ctl.reflected += walls.reflect(pos, vel, kind, n_own, c.L, c.side, c.ring)
                timers[INTEGRATE] += wtime() - t0
                code = _sync_evaluate(plan, lst, parts, motion, cells, local, box, work, c, sw, gather, threaded,
                                      gas, control, flags, flags_all, bad, rule.skin, timers, req, stat)
                if code == GAS:
                    ctl.resume = AFTER_MID
                    return GAS
                if code >= 0:
                    return BAD_MID if code == BAD else REBUILD_MID if code == REBUILD else code
                phase = AFTER_MID
        if phase == AFTER_MID:
            t0 = wtime()
            bad = integrate_second(threaded, pos, vel, acc, kind, n_own, ctl.dt, motion.pos0, motion.vel0, motion.jump,
                                   rule.h, drag, implicit)
        if phase != AFTER_END:
            if len(sw.mirror):
                ctl.reflected += walls.reflect(pos, vel, kind, n_own, c.L, c.side, c.ring)
            ctl.step += 1
            if dt_auto:
                ctl.t = ctl.t_target if ctl.land else ctl.t + ctl.dt
            else:
                ctl.t = ctl.step * rule.dt
            timers[INTEGRATE] += wtime() - t0
            # -- sync, and the rates of the new state
            code = _sync_evaluate(plan, lst, parts, motion, cells, local, box, work, c, sw, gather, threaded, gas,
                                  control, flags, flags_all, bad, rule.skin, timers, req, stat)
            if code == GAS:
                ctl.resume = AFTER_END
                return GAS
            if code >= 0:
                return code
        # -- the step's tail
        if ctl.step % lim.every == 0:  # the run-time checks, before a stop as Python's loop orders them
            t0 = wtime()
            failed = _checks_fail(plan, parts, motion, lim, report, fastest, sums, sums_all)
            ctl.checked = ctl.step
            timers[CHECKS] += wtime() - t0
            if failed < 0:
                return MPI_ERROR
            if failed:
                return CHECK
        if ctl.stop_out != 0.0:  # agreed at this step's syncs: the step is done, its rates computed
            return STOP
        if ctl.land:
            return EVENT
        phase = _STEP
