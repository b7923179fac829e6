"""Time integrators (``numerics.integrator``).

"paper", Eqs. (6)-(7), first order in v:
    r^{n+1} = r^n + dt v^n + dt^2 R^n / 2,    v^{n+1} = v^n + dt R^n.

"midpoint", second order (explicit midpoint / RK2, two evaluations of R):
    r* = r^n + dt/2 v^n,  v* = v^n + dt/2 R(r^n, v^n)
    r^{n+1} = r^n + dt v*,  v^{n+1} = v^n + dt R(r*, v*).

Wall particles move with their prescribed velocity (r += dt v). Positions
are not wrapped into the periodic box here: particles stay where they are
until the next rebuild of the neighbour list, which wraps them. Each function
updates ``jump`` (how far a particle moved in the step) and returns the number of
owned particles whose new state is not finite or that jumped further than
``limit`` (h: run-time check 5), so that a blow-up is caught before the next
pass. Particles are independent: the loops are threaded
(prange), with the count as a reduction.
"""
import math

from numba import njit, prange

from .particles import FLUID

INTEGRATORS = ("paper", "midpoint")


@njit(cache=True, inline="always")
def _finish(pos, vel, jump, i, old, limit):
    """The jump of particle i (``old``: its position before the step); 1 if its state is finite and
    it moved no further than ``limit``."""
    ok = 1
    moved = 0.0
    for d in range(pos.shape[1]):
        moved += (pos[i, d] - old[d]) ** 2
        if not (math.isfinite(pos[i, d]) and math.isfinite(vel[i, d])):
            ok = 0
    jump[i] = math.sqrt(moved)
    if not jump[i] <= limit:
        ok = 0
    return ok


@njit(cache=True, inline="always")
def _paper_one(pos, vel, acc, kind, i, dt, half_dt2, jump, limit):
    """Eqs. (6)-(7) for particle i; 1 if it left a bad state (see _finish)."""
    dim = pos.shape[1]
    old = (pos[i, 0], pos[i, 1], pos[i, dim - 1])
    if kind[i] == FLUID:
        for d in range(dim):
            pos[i, d] += dt * vel[i, d] + half_dt2 * acc[i, d]
            vel[i, d] += dt * acc[i, d]
    else:
        for d in range(dim):
            pos[i, d] += dt * vel[i, d]
    return 1 - _finish(pos, vel, jump, i, old, limit)


@njit(cache=True, inline="always")
def _predict_one(pos, vel, acc, kind, i, dt, pos0, vel0, jump, limit):
    """Save (r^n, v^n) of particle i and move it to the midpoint state."""
    dim = pos.shape[1]
    old = (pos[i, 0], pos[i, 1], pos[i, dim - 1])
    for d in range(dim):
        pos0[i, d] = pos[i, d]
        vel0[i, d] = vel[i, d]
        pos[i, d] += 0.5 * dt * vel[i, d]
        if kind[i] == FLUID:
            vel[i, d] += 0.5 * dt * acc[i, d]
    return 1 - _finish(pos, vel, jump, i, old, limit)


@njit(cache=True, inline="always")
def _correct_one(pos, vel, acc, kind, i, dt, pos0, vel0, jump, limit):
    """r^{n+1} = r^n + dt v*, v^{n+1} = v^n + dt R(r*, v*) for particle i."""
    dim = pos.shape[1]
    old = (pos0[i, 0], pos0[i, 1], pos0[i, dim - 1])
    for d in range(dim):
        pos[i, d] = pos0[i, d] + dt * vel[i, d]
        if kind[i] == FLUID:
            vel[i, d] = vel0[i, d] + dt * acc[i, d]
    return 1 - _finish(pos, vel, jump, i, old, limit)


# Each integrator threaded (prange) and serial: the same arithmetic per particle; the serial one saves the
# parallel region's start (about 1 us a call on one thread) in the compiled step.
@njit(cache=True, parallel=True)
def step_paper(pos, vel, acc, kind, n_own, dt, jump, limit):
    """Eqs. (6)-(7)."""
    half_dt2 = 0.5 * dt * dt
    bad = 0
    for i in prange(n_own):
        bad += _paper_one(pos, vel, acc, kind, i, dt, half_dt2, jump, limit)
    return bad


@njit(cache=True)
def step_paper_serial(pos, vel, acc, kind, n_own, dt, jump, limit):
    """:func:`step_paper` on one thread."""
    half_dt2 = 0.5 * dt * dt
    bad = 0
    for i in range(n_own):
        bad += _paper_one(pos, vel, acc, kind, i, dt, half_dt2, jump, limit)
    return bad


@njit(cache=True, parallel=True)
def midpoint_predict(pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit):
    """Save (r^n, v^n) and move to the midpoint state (r*, v*)."""
    bad = 0
    for i in prange(n_own):
        bad += _predict_one(pos, vel, acc, kind, i, dt, pos0, vel0, jump, limit)
    return bad


@njit(cache=True)
def midpoint_predict_serial(pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit):
    """:func:`midpoint_predict` on one thread."""
    bad = 0
    for i in range(n_own):
        bad += _predict_one(pos, vel, acc, kind, i, dt, pos0, vel0, jump, limit)
    return bad


@njit(cache=True, parallel=True)
def midpoint_correct(pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit):
    """r^{n+1} = r^n + dt v*, v^{n+1} = v^n + dt R(r*, v*)."""
    bad = 0
    for i in prange(n_own):
        bad += _correct_one(pos, vel, acc, kind, i, dt, pos0, vel0, jump, limit)
    return bad


@njit(cache=True)
def midpoint_correct_serial(pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit):
    """:func:`midpoint_correct` on one thread."""
    bad = 0
    for i in range(n_own):
        bad += _correct_one(pos, vel, acc, kind, i, dt, pos0, vel0, jump, limit)
    return bad
