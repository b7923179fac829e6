"""Time integrators (``numerics.integrator``).

"paper", Eqs. (6)-(7), first order in v:
    r^{n+1} = r^n + dt v^n + dt^2 R^n / 2,    v^{n+1} = v^n + dt R^n.

"midpoint", second order (explicit midpoint / RK2, two evaluations of R):
    r* = r^n + dt/2 v^n,  v* = v^n + dt/2 R(r^n, v^n)
    r^{n+1} = r^n + dt v*,  v^{n+1} = v^n + dt R(r*, v*).

With a gas and ``numerics.drag_update = "implicit"`` (the switch ``implicit``), the drag is implicit in v
with beta frozen over the step: the acceleration ``acc`` holds the explicit rate R + C (w - v) of
:func:`parsph.sph.body_force.drag_plain`, and ``drag`` its coefficient C per component, so that

    paper:     v^{n+1} = v^n + dt (R^n + C^n (w - v^{n+1}))         -> a = acc / (1 + dt C)
    midpoint:  v*      = v^n + dt/2 (R^n + C^n (w - v*))            -> a = acc / (1 + dt/2 C)
               v^{n+1} = v^n + dt (R* + C* (w - (v^n + v^{n+1})/2))  -> a = (acc* + C* (v* - v^n)) / (1 + dt/2 C*)

and the update uses a in place of acc (positions too). Backward Euler in the drag keeps "paper" first
order and damps a stiff slip in one step (L-stable); the trapezoidal rule keeps "midpoint" second
order (A-stable: a slip with dt >> tau alternates in sign as it decays, by (1 - dt/2tau)/(1 + dt/2tau)
a step). Explicit drag needs no change here: it is in acc.

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
from typing import NamedTuple

from numba import njit, prange, uintp
from numba.extending import overload

from .particles import GRAIN

INTEGRATORS = ("paper", "midpoint")


@njit(cache=True, inline="always")
def _paper_one(pos, vel, acc, kind, i, dt, half_dt2, jump, limit, drag, implicit):
    """Eqs. (6)-(7) for particle i; 1 if it left a bad state (non-finite, or a jump beyond ``limit``).

    (One loop over the components with an integer flag: a tuple of the old position, a further call
    or a chain of ``and`` made the serial loop 3 to 10 times slower than the prange one.)"""
    fluid = kind[i] == GRAIN
    moved = 0.0
    ok = 1
    for d in range(pos.shape[1]):
        old = pos[i, d]
        if fluid:
            a = acc[i, d]
            if len(implicit):
                a = a / (1.0 + dt * drag[i, d])
            pos[i, d] += dt * vel[i, d] + half_dt2 * a
            vel[i, d] += dt * a
        else:
            pos[i, d] += dt * vel[i, d]
        moved += (pos[i, d] - old) ** 2
        if not (math.isfinite(pos[i, d]) and math.isfinite(vel[i, d])):
            ok = 0
    jump[i] = math.sqrt(moved)
    if not jump[i] <= limit:
        ok = 0
    return 1 - ok


@njit(cache=True, inline="always")
def _predict_one(pos, vel, acc, kind, i, dt, pos0, vel0, jump, limit, drag, implicit):
    """Save (r^n, v^n) of particle i and move it to the midpoint state."""
    fluid = kind[i] == GRAIN
    moved = 0.0
    ok = 1
    for d in range(pos.shape[1]):
        old = pos[i, d]
        pos0[i, d] = pos[i, d]
        vel0[i, d] = vel[i, d]
        pos[i, d] += 0.5 * dt * vel[i, d]
        if fluid:
            a = acc[i, d]
            if len(implicit):
                a = a / (1.0 + 0.5 * dt * drag[i, d])
            vel[i, d] += 0.5 * dt * a
        moved += (pos[i, d] - old) ** 2
        if not (math.isfinite(pos[i, d]) and math.isfinite(vel[i, d])):
            ok = 0
    jump[i] = math.sqrt(moved)
    if not jump[i] <= limit:
        ok = 0
    return 1 - ok


@njit(cache=True, inline="always")
def _correct_one(pos, vel, acc, kind, i, dt, pos0, vel0, jump, limit, drag, implicit):
    """r^{n+1} = r^n + dt v*, v^{n+1} = v^n + dt R(r*, v*) for particle i (its jump from r^n)."""
    fluid = kind[i] == GRAIN
    moved = 0.0
    ok = 1
    for d in range(pos.shape[1]):
        pos[i, d] = pos0[i, d] + dt * vel[i, d]
        if fluid:
            a = acc[i, d]
            if len(implicit):
                a = (a + drag[i, d] * (vel[i, d] - vel0[i, d])) / (1.0 + 0.5 * dt * drag[i, d])
            vel[i, d] = vel0[i, d] + dt * a
        moved += (pos[i, d] - pos0[i, d]) ** 2
        if not (math.isfinite(pos[i, d]) and math.isfinite(vel[i, d])):
            ok = 0
    jump[i] = math.sqrt(moved)
    if not jump[i] <= limit:
        ok = 0
    return 1 - ok


# Each integrator threaded (prange) and serial: the same arithmetic per particle; the serial one saves the
# parallel region's start (about 1 us a call on one thread) in the compiled step.
@njit(cache=True, parallel=True)
def step_paper(pos, vel, acc, kind, n_own, dt, jump, limit, drag, implicit):
    """Eqs. (6)-(7)."""
    half_dt2 = 0.5 * dt * dt
    bad = 0
    for i in prange(n_own):
        bad += _paper_one(pos, vel, acc, kind, i, dt, half_dt2, jump, limit, drag, implicit)
    return bad


@njit(cache=True)
def step_paper_serial(pos, vel, acc, kind, n_own, dt, jump, limit, drag, implicit):
    """:func:`step_paper` on one thread."""
    if pos.shape[1] == 2:
        return _paper_2d(pos, vel, acc, kind, n_own, dt, jump, limit, drag, implicit)
    half_dt2 = 0.5 * dt * dt
    bad = 0
    for i in range(n_own):
        bad += _paper_one(pos, vel, acc, kind, i, dt, half_dt2, jump, limit, drag, implicit)
    return bad


@njit(cache=True, error_model="numpy")
def _paper_2d(pos, vel, acc, kind, n_own, dt, jump, limit, drag, implicit):
    """:func:`_paper_one`'s arithmetic for 2-D, bit for bit, without a branch: both components written out
    (no loop over a run-time dimension), the wall's update a select, the flags combined with ``&``;
    twice as fast as the loop over the components."""
    half_dt2 = 0.5 * dt * dt
    bad = 0
    for k in range(uintp(n_own)):
        fluid = kind[k] == GRAIN
        x0 = pos[k, 0]
        y0 = pos[k, 1]
        vx = vel[k, 0]
        vy = vel[k, 1]
        ax = acc[k, 0]
        ay = acc[k, 1]
        if len(implicit):
            ax = ax / (1.0 + dt * drag[k, 0])
            ay = ay / (1.0 + dt * drag[k, 1])
        x1 = x0 + (dt * vx + half_dt2 * ax) if fluid else x0 + dt * vx
        y1 = y0 + (dt * vy + half_dt2 * ay) if fluid else y0 + dt * vy
        vx1 = vx + dt * ax if fluid else vx
        vy1 = vy + dt * ay if fluid else vy
        pos[k, 0] = x1
        pos[k, 1] = y1
        vel[k, 0] = vx1
        vel[k, 1] = vy1
        moved = (x1 - x0) ** 2 + (y1 - y0) ** 2
        j = math.sqrt(moved)
        jump[k] = j
        ok = math.isfinite(x1) & math.isfinite(y1) & math.isfinite(vx1) & math.isfinite(vy1) & (j <= limit)
        bad += 1 - int(ok)
    return bad


@njit(cache=True, parallel=True)
def midpoint_predict(pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit):
    """Save (r^n, v^n) and move to the midpoint state (r*, v*)."""
    bad = 0
    for i in prange(n_own):
        bad += _predict_one(pos, vel, acc, kind, i, dt, pos0, vel0, jump, limit, drag, implicit)
    return bad


@njit(cache=True)
def midpoint_predict_serial(pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit):
    """:func:`midpoint_predict` on one thread."""
    bad = 0
    for i in range(n_own):
        bad += _predict_one(pos, vel, acc, kind, i, dt, pos0, vel0, jump, limit, drag, implicit)
    return bad


@njit(cache=True, parallel=True)
def midpoint_correct(pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit):
    """r^{n+1} = r^n + dt v*, v^{n+1} = v^n + dt R(r*, v*)."""
    bad = 0
    for i in prange(n_own):
        bad += _correct_one(pos, vel, acc, kind, i, dt, pos0, vel0, jump, limit, drag, implicit)
    return bad


@njit(cache=True)
def midpoint_correct_serial(pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit):
    """:func:`midpoint_correct` on one thread."""
    bad = 0
    for i in range(n_own):
        bad += _correct_one(pos, vel, acc, kind, i, dt, pos0, vel0, jump, limit, drag, implicit)
    return bad


class Steps(NamedTuple):
    """The integration's two calls: ``first`` the paper's whole step or the midpoint's prediction, ``second``
    the midpoint's correction."""
    first: object
    second: object


def steps_for(midpoint, threaded):
    """The integration's functions: threaded (prange) or serial, the one place that choice is made for the
    integration (:func:`parsph.sph.dispatch.threaded` decides ``threaded``), through :func:`integrate_first`
    and :func:`integrate_second`: from Python they call what it returns, and in compiled code numba resolves
    them to the same functions as it types the caller, so that a serial block holds no parallel region."""
    if threaded:
        return Steps(midpoint_predict if midpoint else step_paper, midpoint_correct)
    return Steps(midpoint_predict_serial if midpoint else step_paper_serial, midpoint_correct_serial)


def integrate_first(threaded, midpoint, pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit):
    """:func:`steps_for`'s ``first`` for the modes ``threaded``, ``midpoint`` (pass_data.switch values; the
    paper's step takes no pos0, vel0); returns the count of bad particles. Compiled code calls the function
    numba chose as it typed the caller (:func:`_first`); Python (the Python path's Integrator) runs this body."""
    first = steps_for(len(midpoint) > 0, len(threaded) > 0).first
    if len(midpoint):
        return first(pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit)
    return first(pos, vel, acc, kind, n_own, dt, jump, limit, drag, implicit)


def integrate_second(threaded, pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit):
    """:func:`steps_for`'s ``second``, the midpoint's correction (as :func:`integrate_first`)."""
    return steps_for(True, len(threaded) > 0).second(pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag,
                                                      implicit)


@overload(integrate_first, inline="always")
def _first(threaded, midpoint, pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit):
    first = steps_for(len(midpoint) > 0, len(threaded) > 0).first
    if len(midpoint):
        def impl(threaded, midpoint, pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit):
            return first(pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit)
    else:
        def impl(threaded, midpoint, pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit):
            return first(pos, vel, acc, kind, n_own, dt, jump, limit, drag, implicit)
    return impl


@overload(integrate_second, inline="always")
def _second(threaded, pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit):
    second = steps_for(True, len(threaded) > 0).second

    def impl(threaded, pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit):
        return second(pos, vel, acc, kind, n_own, dt, pos0, vel0, jump, limit, drag, implicit)
    return impl
