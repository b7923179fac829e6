"""Exact references for the solid phase in a gas (docs/physics.md, "The solid phase in a gas", references 1 and
2), and what every reference shares: the two phases.

One place each; SI units throughout. The two phases are given as :class:`Phases` (rho_s, rho_g [kg/m^3],
mu_g [Pa s], the grain diameter d [m], |g| [m/s^2] and the drag closure of :mod:`parsph.physics.drag`).
eps = 1 - theta is the gas fraction, u_t = (rho_s - rho_g) |g| d^2 / (18 mu_g) Stokes's terminal velocity.
The solids feel beta (u_g - v) / (rho_s theta eps) per unit mass besides gravity with buoyancy and the
stress; in a column fed at superficial velocity U along e (opposite to gravity) the slip along e is
(U - v.e) / eps (docs/physics.md, "The gas velocity").

1. Drag relaxation in a stream u_g (no gravity): :func:`relaxation_velocity` (Stokes, exact),
   :func:`relaxation_discrete` (Eq. (7) and the midpoint scheme, explicit or implicit drag, exact for a
   constant beta), :func:`relaxation_ode` (any closure: the scalar ODE), :func:`relaxation_steps` (the
   solver's recursion with beta frozen over each stage, any closure).
2. Hindered settling: :func:`hindered_settling_velocity` (any closure, a root),
   :func:`richardson_zaki_velocity` (Stokes, closed form), :func:`settling_relaxation_time`.

Reference 3, bed expansion, is :mod:`parsph.physics.bed_expansion`; reference 4, batch sedimentation
(Kynch), :mod:`parsph.physics.kynch`.
"""
from typing import NamedTuple

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from . import drag

RZ_N = 4.65           # Richardson & Zaki's exponent that the Stokes closure gives exactly
INTEGRATORS = ("paper", "midpoint")
DRAG_UPDATES = ("explicit", "implicit")


def _model_id(model):
    if isinstance(model, str):
        try:
            return drag.MODELS[model]
        except KeyError:
            raise ValueError(f"unknown drag closure {model!r} (one of {', '.join(drag.MODELS)})") from None
    if int(model) not in drag.MODELS.values():
        raise ValueError(f"unknown drag closure id {model!r}")
    return int(model)


class Phases(NamedTuple):
    """The solids and the gas: rho_s, rho_g [kg/m^3], mu_g [Pa s], grain diameter d [m], |g| [m/s^2], and
    the drag closure (a name of :data:`parsph.physics.drag.MODELS` or its id)."""
    rho_s: float
    rho_g: float
    mu_g: float
    d: float
    g: float = 9.81
    model: object = "stokes"

    @property
    def model_id(self):
        return _model_id(self.model)

    @property
    def buoyant(self):
        """(rho_s - rho_g) |g| [N/m^3]: the buoyant weight of the solid per unit volume of grains."""
        return (self.rho_s - self.rho_g) * abs(self.g)

    @property
    def u_t(self):
        """Stokes's terminal velocity of one grain [m/s]."""
        return drag.terminal_velocity(self.rho_s, self.rho_g, self.g, self.d, self.mu_g)

    def beta(self, theta, slip):
        """beta [kg/(m^3 s)] of the closure at (theta, |u_g - v|)."""
        return drag.beta(self.model_id, float(theta), float(slip), float(self.rho_g), float(self.mu_g),
                         float(self.d))

    def rate(self, theta, slip):
        """K = beta / (rho_s theta eps) [1/s]: the drag per unit mass and unit slip in a stream."""
        return self.beta(theta, slip) / (self.rho_s * theta * (1.0 - theta))


def check_fraction(theta, name="theta0"):
    if not 0.0 < theta < 1.0:
        raise ValueError(f"{name} = {theta!r} must lie in (0, 1)")


# ---- 1. drag relaxation in a stream (reference 1) ----------------------------------------------------------
def stokes_stream_time(theta0, ph):
    """tau = rho_s d^2 eps0^3.65 / (18 mu_g) [s]: the Stokes closure's relaxation time in a stream (ref. 1),
    = rho_s theta0 eps0 / beta."""
    check_fraction(theta0)
    return ph.rho_s * ph.d ** 2 * (1.0 - theta0) ** (RZ_N - 1.0) / (18.0 * ph.mu_g)


def _stream(u_g):
    """(speed |u_g|, unit vector, or a sign for a scalar u_g)."""
    u = np.asarray(u_g, dtype=float)
    speed = float(np.sqrt(np.sum(u * u)))
    return speed, (u / speed if speed > 0 else np.zeros_like(u))


def relaxation_velocity(t, u_g, tau):
    """Ref. 1, Stokes (beta independent of the slip), exact: v(t) = u_g (1 - exp(-t/tau)) [m/s].

    t [s]: a number or an array; u_g [m/s]: a number or a vector. Returns shape t.shape + u_g.shape."""
    return np.multiply.outer(-np.expm1(-np.asarray(t, dtype=float) / tau), np.asarray(u_g, dtype=float))


def relaxation_factor(z, integrator="paper", drag_update="explicit"):
    """r(z), z = dt / tau: the slip's factor per step of a constant-beta drag (ref. 1, Eq. (7)):

    - paper, explicit (Eq. (7)):            r = 1 - z
    - paper, implicit (backward Euler):     r = 1 / (1 + z)
    - midpoint, explicit (RK2):             r = 1 - z + z^2 / 2
    - midpoint, implicit (Crank-Nicolson):  r = (1 - z/2) / (1 + z/2)
    (:mod:`parsph.sph.integrators`). |r| < 1 is stability: explicit needs z < 2, the implicit ones hold for
    every z; r < 0 (z > 1 paper explicit, z > 2 Crank-Nicolson) is a slip that alternates in sign."""
    z = np.asarray(z, dtype=float)
    if integrator not in INTEGRATORS or drag_update not in DRAG_UPDATES:
        raise ValueError(f"integrator {integrator!r} / drag_update {drag_update!r}: "
                         f"one of {INTEGRATORS} / {DRAG_UPDATES}")
    if integrator == "paper":
        return 1.0 - z if drag_update == "explicit" else 1.0 / (1.0 + z)
    if drag_update == "explicit":
        return 1.0 - z + 0.5 * z * z
    return (1.0 - 0.5 * z) / (1.0 + 0.5 * z)


def relaxation_discrete(n, dt, u_g, tau, integrator="paper", drag_update="explicit"):
    """Ref. 1's discrete solution after n steps of dt [s] from rest: v_n = u_g (1 - r^n) [m/s], r of
    :func:`relaxation_factor` at z = dt / tau (exact for a constant beta: the Stokes closure).

    n: an integer or an integer array; returns shape n.shape + u_g.shape."""
    n = np.asarray(n)
    if not np.issubdtype(n.dtype, np.integer):
        raise ValueError("n must be an integer (a number of steps)")
    r = float(relaxation_factor(dt / tau, integrator, drag_update))
    return np.multiply.outer(1.0 - np.power(r, n.astype(float)), np.asarray(u_g, dtype=float))


def relaxation_ode(t, u_g, theta0, ph, rtol=1e-12):
    """Ref. 1 for any closure: v(t) [m/s] of a uniform suspension at theta0, at rest at t = 0 in a stream u_g.

    v stays parallel to u_g; its component v along u_g solves the scalar ODE

        rho_s theta0 eps0 dv/dt = beta(theta0, |u_g| - v) (|u_g| - v),

    integrated (in the slip fraction s = 1 - v/|u_g|, ds/dt = -K(theta0, |u_g| s) s) with
    scipy.integrate.solve_ivp, DOP853, rtol ``rtol``, atol 1e-16. t >= 0: a number or an array (any
    order); returns shape t.shape + u_g.shape."""
    check_fraction(theta0)
    speed, unit = _stream(u_g)
    t = np.asarray(t, dtype=float)
    if np.any(t < 0):
        raise ValueError("t must be >= 0")
    frac = np.zeros(t.shape)
    if speed > 0 and t.size and t.max() > 0:
        ts = np.unique(t.ravel())

        def rhs(_, y):
            return [-ph.rate(theta0, speed * abs(y[0])) * y[0]]

        sol = solve_ivp(rhs, (0.0, ts[-1]), [1.0], method="DOP853", t_eval=ts, rtol=rtol, atol=1e-16)
        if not sol.success:
            raise RuntimeError(f"relaxation ODE: {sol.message}")
        frac = np.interp(t, ts, 1.0 - sol.y[0])  # exact look-up: t's values are the t_eval points
    return np.multiply.outer(speed * frac, unit)


def relaxation_steps(n, dt, u_g, theta0, ph, integrator="paper", drag_update="explicit"):
    """Ref. 1, the solver's discrete recursion for any closure: v after 0, 1, ..., n steps of dt [s] from rest
    (shape (n + 1,) + u_g.shape) [m/s].

    With C = K(theta0, |u_g - v|) at the stage's own v (beta frozen over the stage) and w = |u_g| along u_g,
    as :mod:`parsph.sph.integrators` writes it:

    - paper:    a = C (w - v)  [/ (1 + dt C), implicit],  v += dt a;
    - midpoint: a = C (w - v)  [/ (1 + dt/2 C)],  v* = v + dt/2 a;
                explicit: v += dt C* (w - v*);  implicit: v += dt (C* (w - v*) + C* (v* - v)) / (1 + dt/2 C*).

    For the Stokes closure this is :func:`relaxation_discrete`; for the others it converges to
    :func:`relaxation_ode` at first (paper) or second (midpoint) order in dt."""
    check_fraction(theta0)
    relaxation_factor(0.0, integrator, drag_update)  # checks the names
    speed, unit = _stream(u_g)
    implicit = drag_update == "implicit"
    v = 0.0
    out = np.empty(int(n) + 1)
    out[0] = v
    for k in range(int(n)):
        C = ph.rate(theta0, abs(speed - v))
        a = C * (speed - v)
        if integrator == "paper":
            if implicit:
                a = a / (1.0 + dt * C)
            v = v + dt * a
        else:
            if implicit:
                a = a / (1.0 + 0.5 * dt * C)
            vs = v + 0.5 * dt * a
            Cs = ph.rate(theta0, abs(speed - vs))
            acc = Cs * (speed - vs)
            if implicit:
                acc = (acc + Cs * (vs - v)) / (1.0 + 0.5 * dt * Cs)
            v = v + dt * acc
        out[k + 1] = v
    return np.multiply.outer(out, unit)


# ---- 2. hindered settling (reference 2) ------------------------------------------------------------------
def balance_root(theta, ph):
    """The slip speed s > 0 [m/s] with beta(theta, s/eps) s = theta eps^2 (rho_s - rho_g) |g|.

    beta s rises monotonically from 0 (beta does not fall with the slip in any closure), so the root is
    bracketed by [0, hi], hi doubled from the Stokes value u_t eps^4.65 until the balance is passed."""
    check_fraction(theta)
    eps = 1.0 - theta
    weight = theta * eps * eps * ph.buoyant

    def h(s):
        return ph.beta(theta, s / eps) * s - weight

    hi = ph.u_t * eps ** RZ_N
    for _ in range(200):
        if h(hi) >= 0.0:
            break
        hi *= 2.0
    else:
        raise ValueError("no balance of drag and weight found")
    if h(hi) == 0.0:
        return hi
    return brentq(h, 0.0, hi, xtol=1e-300, rtol=4.0 * np.finfo(float).eps, maxiter=500)


def hindered_settling_velocity(theta0, ph):
    """Ref. 2: the steady settling velocity v.e [m/s] (negative: downward) of a uniform suspension at theta0 in a
    closed column (U = 0): |v| is the root of

        beta(theta0, |v| / eps0) |v| = theta0 eps0^2 (rho_s - rho_g) |g|        (scipy.optimize.brentq)."""
    if ph.rho_s <= ph.rho_g:
        raise ValueError("the solids must be denser than the gas")
    return -balance_root(theta0, ph)


def richardson_zaki_velocity(theta0, ph):
    """Ref. 2 with the Stokes closure, closed form: v.e = -u_t eps0^4.65 [m/s] (Richardson & Zaki, n = 4.65)."""
    check_fraction(theta0)
    return -ph.u_t * (1.0 - theta0) ** RZ_N


def settling_relaxation_time(theta0, ph):
    """Ref. 2: tau = rho_s theta0 eps0^2 / beta [s] along the column, beta at the steady slip |v| / eps0
    (Stokes: rho_s d^2 eps0^4.65 / (18 mu_g)). For a closure whose beta grows with the slip this is the drag
    coefficient's time; a small departure from the steady state decays faster, by d ln(beta s) / d ln s."""
    v = hindered_settling_velocity(theta0, ph)
    return drag.relaxation_time(ph.model_id, theta0, abs(v) / (1.0 - theta0), ph.rho_s, ph.rho_g, ph.mu_g, ph.d,
                                along_column=True)
