"""The stages of an evaluation of the rates (Eq. (3), the ghosts' rho, Eq. (5)), in the order both routes take
them: the compiled block (:func:`.block.evaluate`) and the Python path (:class:`.evaluation.Evaluation`) call
these functions and not the passes below them, so that an evaluation is composed once and its
serial/threaded choice is made here alone (``threaded``: a ``pass_data.switch`` of
:func:`parsph.sph.dispatch.threaded`).

1. :func:`density`: Eq. (3) into the list's sums;
2. :func:`after_density` from ``START``: [walls' renormalisation], the owned particles' rho and factors, the
   ghosts' rho from their owners (one round; where compiled code cannot call MPI it returns ``HALO`` and the
   caller sends the round through mpi4py, then calls it again from ``AFTER_HALO``), the ghosts' factors;
   with the solved gas it returns ``GAS`` (the caller runs the gas stage, then calls it from ``FORCES_ONLY``);
   then Eq. (5) and the body force, [the walls' forces].

Each function takes its modes as arguments of their own (``threaded``, ``mirror``: empty tuple or ``(1,)``):
numba prunes the branch on an argument's length before typing, so a one-thread version compiles no
``parallel=True`` loop and a scene without mirrored walls none of their passes.

The integration's serial/threaded choice is :func:`parsph.sph.integrators.steps_for`'s alone: the
:class:`.integrator.Integrator` and the block both call :func:`parsph.sph.integrators.integrate_first` and
``integrate_second``, which in the block resolve to its functions as numba types it, inlined (as calls of
a stage function of their own the block's step took 8% longer: docs/performance.md, "What was tried and
lost").
"""
import numpy as np
from numba import njit

from parsph.parallel import native_halo
from parsph.parallel.native_mpi import COMM, wtime
from parsph.sph import density as eq3
from parsph.sph import momentum, walls

# what a compiled block returns (:mod:`.block`'s doc), and HALO: an evaluation on the Python path waits for
# the ghosts' rho from mpi4py
EVENT, REBUILD, REBUILD_MID, BAD, BAD_MID, STOP, NEED_LIMIT, MPI_ERROR, CHECK, GAS, HALO = range(11)
DONE = -1  # the rates are computed
START, AFTER_HALO, FORCES_ONLY = range(3)  # where after_density starts
# the phase timers (float64 seconds), in the solver's phase names
TIMER_PHASES = ("sync", "density", "halo", "forces", "integrate", "checks")
SYNC, DENSITY, HALO_T, FORCES, INTEGRATE, CHECKS = range(6)


@njit(cache=True)
def density(lst, parts, c, sw, gather, threaded):
    """Eq. (3) into the list's sums (``lst.rho_sum``, the pairs' (dW/dr)/r): the particles' fields are
    not touched, so that the pass can run while the sync's all-reduce is in flight."""
    if len(threaded):
        eq3.density_threaded(lst, parts, c, sw, gather)
    else:
        eq3.density_serial(lst, parts, c, sw)


@njit(cache=True)
def after_density(plan, lst, parts, c, sw, gather, threaded, mirror, gas, start, timers):
    """After Eq. (3), from ``start`` (np.int64: one version for every start): the owned particles' rho and
    factors, the ghosts' rho (one round), their factors, then Eq. (5) and the body force, or GAS before
    them (``gas``: the solved gas's stage reads the factors). Returns DONE, HALO (``plan`` holds no MPI
    handles: the round goes through Python), GAS or MPI_ERROR. ``mirror`` (``sw.mirror``) as an argument
    of its own: a block without such walls compiles none of their passes (a field of ``sw`` would type
    them). One function for every part: each part a function of its own cost a tenth more compiling a
    block."""
    n, n_own = lst.n, parts.n_own
    if start == START:
        t0 = wtime()
        first = np.int64(0)  # not the literal 0: one version of the passes for both calls
        if len(mirror):
            walls.renormalise(lst, parts, c, sw)
        if len(threaded):
            momentum.particle_factors(lst, parts, c, sw, first, n_own)
        else:
            momentum.particle_factors_serial(lst, parts, c, sw, first, n_own)
        timers[DENSITY] += wtime() - t0
        if plan.h[COMM] == 0:
            return HALO
        t1 = wtime()
        err = native_halo.refresh(plan, parts.rho, n_own)
        timers[HALO_T] += wtime() - t1
        if err:
            return MPI_ERROR
    if start != FORCES_ONLY:
        t2 = wtime()
        if len(threaded):
            momentum.particle_factors(lst, parts, c, sw, n_own, n)
        else:
            momentum.particle_factors_serial(lst, parts, c, sw, n_own, n)
        timers[FORCES] += wtime() - t2
        if gas:
            return GAS
    t0 = wtime()
    if len(threaded):
        momentum.momentum_threaded(lst, parts, c, sw, gather)
    else:
        momentum.momentum_serial(lst, parts, c, sw)
    if len(mirror):
        walls.forces(lst, parts, c, sw)
    timers[FORCES] += wtime() - t0
    return DONE
