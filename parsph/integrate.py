"""Time integrators (``numerics.integrator``).

"paper", Eqs. (6)-(7), first order in v:
    r^{n+1} = r^n + dt v^n + dt^2 R^n / 2,    v^{n+1} = v^n + dt R^n.

"midpoint", second order (explicit midpoint / RK2, two evaluations of R):
    r* = r^n + dt/2 v^n,  v* = v^n + dt/2 R(r^n, v^n)
    r^{n+1} = r^n + dt v*,  v^{n+1} = v^n + dt R(r*, v*).

Wall particles move with their prescribed velocity (r += dt v). Positions are
wrapped into the periodic box at the end of a step (``box[d]`` is the period
of direction d, 0 where it is not periodic; y always is). Each function returns
the number of owned particles whose new state is not finite, so that a blow-up
is caught before the next neighbour search. Particles are independent: the
loops are threaded (prange), with the count as a reduction.
"""
import math

from numba import njit, prange

from .particles import FLUID

INTEGRATORS = ("paper", "midpoint")
EVALUATIONS = {"paper": 1, "midpoint": 2}  # right-hand sides per step


@njit(cache=True, inline="always")
def _finite(pos, vel, i):
    for d in range(pos.shape[1]):
        if not (math.isfinite(pos[i, d]) and math.isfinite(vel[i, d])):
            return 0
    return 1


@njit(cache=True, inline="always")
def _wrap(pos, i, box):
    for d in range(pos.shape[1]):
        period = box[d]
        if period > 0.0:
            y = pos[i, d]
            if y >= period:
                y -= period
            elif y < 0.0:
                y += period
                if y >= period:
                    y = 0.0
            pos[i, d] = y


@njit(cache=True, parallel=True)
def step_paper(pos, vel, acc, kind, n_own, dt, box):
    """Eqs. (6)-(7)."""
    dim = pos.shape[1]
    half_dt2 = 0.5 * dt * dt
    bad = 0
    for i in prange(n_own):
        if kind[i] == FLUID:
            for d in range(dim):
                pos[i, d] += dt * vel[i, d] + half_dt2 * acc[i, d]
                vel[i, d] += dt * acc[i, d]
        else:
            for d in range(dim):
                pos[i, d] += dt * vel[i, d]
        _wrap(pos, i, box)
        bad += 1 - _finite(pos, vel, i)
    return bad


@njit(cache=True, parallel=True)
def midpoint_predict(pos, vel, acc, kind, n_own, dt, pos0, vel0):
    """Save (r^n, v^n) and move to the midpoint state (r*, v*); no wrap."""
    dim = pos.shape[1]
    bad = 0
    for i in prange(n_own):
        for d in range(dim):
            pos0[i, d] = pos[i, d]
            vel0[i, d] = vel[i, d]
            pos[i, d] += 0.5 * dt * vel[i, d]
            if kind[i] == FLUID:
                vel[i, d] += 0.5 * dt * acc[i, d]
        bad += 1 - _finite(pos, vel, i)
    return bad


@njit(cache=True, parallel=True)
def midpoint_correct(pos, vel, acc, kind, n_own, dt, pos0, vel0, box):
    """r^{n+1} = r^n + dt v*, v^{n+1} = v^n + dt R(r*, v*)."""
    dim = pos.shape[1]
    bad = 0
    for i in prange(n_own):
        for d in range(dim):
            pos[i, d] = pos0[i, d] + dt * vel[i, d]
            if kind[i] == FLUID:
                vel[i, d] = vel0[i, d] + dt * acc[i, d]
        _wrap(pos, i, box)
        bad += 1 - _finite(pos, vel, i)
    return bad
