"""Exact references for the solid phase in a gas (docs/physics.md, "The solid phase in a gas", references 1-4).

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
3. Bed expansion: :func:`steady_column` (the steady profile theta(x) with the bed's mass and a free top,
   integrated from the top down), :func:`uniform_bed_fraction` (theta*), :func:`richardson_zaki_fraction`,
   :func:`minimum_fluidization_velocity` (Ergun), :func:`compression_length`.
4. Batch sedimentation (Kynch 1952): :func:`batch_sedimentation` (the interface line, the sediment
   front, their meeting, the final sediment), :func:`kynch_flux`, :func:`final_sediment`.

The columns' effective pressure p_s(theta) is that of the pressure form in use
(:func:`parsph.physics.limits.pressure`: "paper" p = G theta, "consistent" p = G / (G_a ln 10), with
G = 10^(G_a theta + G_b)); only p_s' enters the profiles. :func:`parsph.physics.analytic.settling_equilibrium`
solves the walled column (a lid, no free top) by shooting from the floor; the free-top columns here are
integrated from the top down instead (below), and the tests use that function as an independent check.
"""
import math
from typing import NamedTuple

import numpy as np
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq

from . import drag, limits
from .closures import G_A, G_B

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


def _check_fraction(theta, name="theta0"):
    if not 0.0 < theta < 1.0:
        raise ValueError(f"{name} = {theta!r} must lie in (0, 1)")


# ---- 1. drag relaxation in a stream (reference 1) ----------------------------------------------------------
def stokes_stream_time(theta0, ph):
    """tau = rho_s d^2 eps0^3.65 / (18 mu_g) [s]: the Stokes closure's relaxation time in a stream (ref. 1),
    = rho_s theta0 eps0 / beta."""
    _check_fraction(theta0)
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
    _check_fraction(theta0)
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
    _check_fraction(theta0)
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
def _balance_root(theta, ph):
    """The slip speed s > 0 [m/s] with beta(theta, s/eps) s = theta eps^2 (rho_s - rho_g) |g|.

    beta s rises monotonically from 0 (beta does not fall with the slip in any closure), so the root is
    bracketed by [0, hi], hi doubled from the Stokes value u_t eps^4.65 until the balance is passed."""
    _check_fraction(theta)
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
    return -_balance_root(theta0, ph)


def richardson_zaki_velocity(theta0, ph):
    """Ref. 2 with the Stokes closure, closed form: v.e = -u_t eps0^4.65 [m/s] (Richardson & Zaki, n = 4.65)."""
    _check_fraction(theta0)
    return -ph.u_t * (1.0 - theta0) ** RZ_N


def settling_relaxation_time(theta0, ph):
    """Ref. 2: tau = rho_s theta0 eps0^2 / beta [s] along the column, beta at the steady slip |v| / eps0
    (Stokes: rho_s d^2 eps0^4.65 / (18 mu_g)). For a closure whose beta grows with the slip this is the drag
    coefficient's time; a small departure from the steady state decays faster, by d ln(beta s) / d ln s."""
    v = hindered_settling_velocity(theta0, ph)
    return drag.relaxation_time(ph.model_id, theta0, abs(v) / (1.0 - theta0), ph.rho_s, ph.rho_g, ph.mu_g, ph.d,
                                along_column=True)


# ---- 3. bed expansion (reference 3) ----------------------------------------------------------------------
def column_rhs(theta, U, ph):
    """f(theta) = beta(theta, U/eps) U / eps^2 - theta (rho_s - rho_g) |g| [Pa/m]: dp_s/dx of a column at rest
    (x up from the floor) fed at superficial velocity U [m/s] (ref. 3). U = 0: hydrostatic,
    -theta (rho_s - rho_g)|g|."""
    eps = 1.0 - theta
    drag_part = ph.beta(theta, U / eps) * U / (eps * eps) if U != 0.0 else 0.0
    return drag_part - theta * ph.buoyant


def _balance(theta, U, ph):
    """eps^2 f(theta) = beta(theta, U/eps) U - theta eps^2 (rho_s - rho_g) |g| (finite as eps -> 0 for Ergun)."""
    eps = 1.0 - theta
    return ph.beta(theta, U / eps) * U - theta * eps * eps * ph.buoyant


def uniform_bed_fraction(U, ph):
    """Ref. 3: theta*, the uniform interior of a bed fed at U > 0 [m/s]: the smallest root in (0, 1) of

        beta(theta*, U/eps*) U = theta* eps*^2 (rho_s - rho_g) |g|.

    The smallest: integrated from the free top down, the profile climbs from 0 to the first zero of f.
    Found by scanning theta for the first sign change, then brentq. ValueError where U blows the bed out
    (the balance is already positive at theta -> 0: U at or above one grain's terminal velocity)."""
    if not U > 0:
        raise ValueError("a bed needs U > 0 (U = 0 is the hydrostatic sediment)")
    grid = np.concatenate([np.geomspace(1e-12, 1e-2, 41), np.linspace(1e-2, 1.0 - 1e-9, 1001)[1:]])
    prev_t, prev = grid[0], _balance(grid[0], U, ph)
    if prev >= 0.0:
        raise ValueError(f"U = {U:g} m/s carries the grains away (at or above one grain's terminal velocity)")
    for th in grid[1:]:
        val = _balance(th, U, ph)
        if val >= 0.0:
            if val == 0.0:
                return float(th)
            return brentq(_balance, prev_t, th, args=(U, ph), xtol=1e-15, rtol=4.0 * np.finfo(float).eps)
        prev_t, prev = th, val
    raise ValueError(f"no uniform bed at U = {U:g} m/s below theta = 1")


def richardson_zaki_fraction(U, ph):
    """Ref. 3 with the Stokes closure, closed form: U = u_t eps*^4.65 (Richardson & Zaki),
    theta* = 1 - (U/u_t)^(1/4.65)."""
    if not 0.0 < U < ph.u_t:
        raise ValueError(f"U = {U:g} m/s must lie in (0, u_t = {ph.u_t:g} m/s)")
    return 1.0 - (U / ph.u_t) ** (1.0 / RZ_N)


def fluidization_velocity(theta, ph):
    """The superficial velocity U [m/s] that holds a uniform bed at theta at rest, for the closure of ``ph``: the
    inverse of :func:`uniform_bed_fraction` (the same balance; = |hindered settling velocity(theta)|: in a column
    only U - v enters the drag)."""
    return _balance_root(theta, ph)


def minimum_fluidization_velocity(theta_mf, ph):
    """U_mf [m/s] from Ergun (the Gidaspow closure's dense branch, eps < 0.8) at the packed fraction theta_mf:
    the bed's buoyant weight carried by the Ergun pressure drop,

        150 mu_g theta^2 U / (eps^3 d^2) + 1.75 rho_g theta U^2 / (eps^3 d) = theta (rho_s - rho_g) |g|,

    i.e. beta_Ergun(theta, U/eps) U = theta eps^2 (rho_s - rho_g) |g|; the positive root of the quadratic,
    U = 2C / (B + sqrt(B^2 + 4AC)). Independent of ``ph.model``; the Gidaspow closure with MFiX's blend
    differs by the Wen & Yu share phi(eps) (0.3% of beta at eps = 0.4): :func:`fluidization_velocity`."""
    _check_fraction(theta_mf, "theta_mf")
    eps = 1.0 - theta_mf
    A = 1.75 * ph.rho_g * theta_mf / (eps ** 3 * ph.d)
    B = 150.0 * ph.mu_g * theta_mf ** 2 / (eps ** 3 * ph.d ** 2)
    C = theta_mf * ph.buoyant
    return 2.0 * C / (B + math.sqrt(B * B + 4.0 * A * C))


def _check_form(form):
    if form not in limits.FORMS:
        raise ValueError(f"pressure form {form!r}: one of {limits.FORMS}")


def compression_length(U, ph, G_a=G_A, G_b=G_B, form="paper"):
    """Ref. 3: l = p_s'(theta*) / f'(theta*) [m], f of :func:`column_rhs`: the length over which the profile
    relaxes to theta* (theta* - theta ~ exp(-(x_top - x)/l) away from the top); a bed much taller than l has a
    uniform interior. f' by a central difference (step 1e-6 theta*)."""
    _check_form(form)
    th = uniform_bed_fraction(U, ph)
    h = 1e-6 * min(th, 1.0 - th)
    fp = (column_rhs(th + h, U, ph) - column_rhs(th - h, U, ph)) / (2.0 * h)
    return limits.dpressure(th, G_a, G_b, form) / fp


class Column:
    """A steady column at rest on the floor x = 0 with a free top (:func:`steady_column`).

    Attributes: ``mass`` [kg/m^2], ``U`` [m/s], ``theta_star`` (nan for U = 0), ``theta_floor``, ``x`` and
    ``theta`` (the solver's points, x ascending from 0 to ``top``), ``top`` [m] (where the integration started:
    theta = ``theta_top``), ``tail_length`` [m] (above ``top`` theta ~ theta_top exp(-(x - top)/tail_length)).
    theta -> 0 only as x -> infinity: the free top is an exponential tail, not a height."""

    def __init__(self, mass, U, theta_star, sol, top, theta_top, tail_length, rho_s):
        self.mass, self.U, self.theta_star, self._rho_s = mass, U, theta_star, rho_s
        self._sol, self.top, self.theta_top, self.tail_length = sol, top, theta_top, tail_length
        s = sol.t
        self.x = np.ascontiguousarray((top - s)[::-1])
        self.theta = np.ascontiguousarray(sol.y[0][::-1])
        self.x[0] = 0.0
        self.theta_floor = float(self.theta[0])

    def theta_at(self, x):
        """theta at heights x [m] >= 0 (the dense solution; the tail above ``top``)."""
        x = np.asarray(x, dtype=float)
        if np.any(x < 0):
            raise ValueError("x below the floor")
        s = np.clip(self.top - x, 0.0, self.top)
        inside = np.asarray(self._sol.sol(s.ravel())[0]).reshape(x.shape)
        tail = self.theta_top * np.exp(-np.maximum(x - self.top, 0.0) / self.tail_length)
        return np.where(x <= self.top, inside, tail)

    def quantiles(self, fractions):
        """The heights [m] below which each of ``fractions`` (in (0, 1)) of the column's mass lies: where the
        integration's int theta dx from the top (its second component) leaves (1 - fraction) of the mass above
        (brentq on the dense solution). ValueError for a fraction whose height is in the tail above ``top``."""
        target = self.mass / self._rho_s
        out = []
        for q in np.atleast_1d(np.asarray(fractions, dtype=float)):
            above = (1.0 - q) * target
            if not 0.0 < q < 1.0 or above < self._sol.y[1][0]:
                raise ValueError(f"fraction {q!r}: not in (0, 1), or its height is in the tail above the top")
            s = brentq(lambda s: self._sol.sol(s)[1] - above, 0.0, self.top, xtol=1e-15 * self.top, rtol=1e-14)
            out.append(self.top - s)
        return np.array(out)

    def height_of(self, level):
        """The height [m] where theta = level (theta falls monotonically upward), 0 < level <= theta_floor."""
        if not 0.0 < level <= self.theta_floor:
            raise ValueError(f"theta = {level!r} is not in the column (floor {self.theta_floor:g})")
        if level <= self.theta_top:
            return self.top + self.tail_length * math.log(self.theta_top / level)
        if level == self.theta_floor:
            return 0.0
        s = brentq(lambda s: self._sol.sol(s)[0] - level, 0.0, self.top, xtol=1e-15 * self.top, rtol=1e-14)
        return self.top - s


def steady_column(mass, U, ph, G_a=G_A, G_b=G_B, form="paper", rtol=1e-12):
    """Ref. 3 (U > 0) and the final sediment of ref. 4 (U = 0): the steady theta(x) of a column at rest on the
    floor with ``mass`` [kg/m^2] = int rho_s theta dx and a free top, from

        p_s'(theta) dtheta/dx = f(theta) = beta(theta, U/eps) U / eps^2 - theta (rho_s - rho_g) |g|

    (p_s of the pressure form ``form``, x up from the floor). Returns a :class:`Column`.

    Integrated from the top down, in the depth s below a start point: dtheta/ds = -f/p_s', d(int theta)/ds = theta,
    to the depth where int theta dx reaches mass / rho_s (the floor): solve_ivp (DOP853, ``rtol``) with an event.
    Top down is stable: f'(theta*) > 0, so a departure from theta* grows upward as exp(x / l)
    (l: :func:`compression_length`) and decays downward, where this integration goes; shot from the floor up,
    the floor value's error would grow by exp(H / l). The start: theta -> 0 only as x -> infinity (f ~ -a theta:
    an exponential tail), so the integration starts at theta_top = 1e-9 theta_ref (theta_ref = theta* for
    U > 0, 1 for U = 0), with the mass above it exact as a quadrature in theta (dx = p_s' dtheta / f):
    int_0^theta_top theta p_s' / (-f) dtheta (scipy.integrate.quad; < 1e-6 of the mass, else theta_top is
    lowered; for U = 0 it is (p_s(theta_top) - p_s(0)) / ((rho_s - rho_g) |g|), the hydrostatic identity).
    The start's height is irrelevant: x is measured from the floor the event finds.
    """
    _check_form(form)
    if not mass > 0:
        raise ValueError("the column needs a mass > 0")
    if U < 0:
        raise ValueError("U must be >= 0")
    if ph.rho_s <= ph.rho_g:
        raise ValueError("the solids must be denser than the gas")
    theta_star = uniform_bed_fraction(U, ph) if U > 0 else math.nan
    target = mass / ph.rho_s                                      # int theta dx [m]

    def dp(th):
        return limits.dpressure(th, G_a, G_b, form)

    def q(th):                                                    # dtheta/ds = -f / p_s' > 0 below theta*
        return -column_rhs(th, U, ph) / dp(th)

    theta_top = 1e-9 * (theta_star if U > 0 else 1.0)
    while True:
        m_top = quad(lambda th: th / q(th), 0.0, theta_top, epsabs=0.0, epsrel=1e-12)[0]
        if m_top < 1e-6 * target:
            break
        theta_top *= 1e-3

    def rhs(_, y):
        th = y[0]
        return [q(th), th]

    def floor(_, y):
        return y[1] - target
    floor.terminal, floor.direction = True, 1.0

    # theta >= theta_top all the way down, so int theta dx passes the mass before the depth target / theta_top
    span = target / theta_top
    y0 = [theta_top, m_top]
    sol = solve_ivp(rhs, (0.0, span), y0, method="DOP853", events=floor, dense_output=True, rtol=rtol,
                    atol=[1e-6 * theta_top, 1e-12 * target])
    if sol.status != 1:
        raise RuntimeError(f"steady column: the floor was not reached ({sol.message})")
    top = float(sol.t_events[0][0])
    if not sol.y_events[0][0][0] < 1.0:
        raise ValueError("the column would need theta >= 1 at its floor")
    tail = theta_top / q(theta_top)
    return Column(mass, U, theta_star, sol, top, theta_top, tail, ph.rho_s)


# ---- 4. batch sedimentation (reference 4) ------------------------------------------------------------------
def kynch_flux(theta, ph):
    """Kynch's flux F(theta) = theta v(theta) [m/s] (v of :func:`hindered_settling_velocity`; F(0) = 0, < 0
    downward), for a number or an array."""
    th = np.asarray(theta, dtype=float)
    out = np.array([t * hindered_settling_velocity(t, ph) if t > 0 else 0.0 for t in th.ravel()])
    return out.reshape(th.shape) if th.ndim else float(out[0])


def final_sediment(mass, ph, G_a=G_A, G_b=G_B, form="paper"):
    """Ref. 4's end state: the hydrostatic sediment dp_s/dx = -(rho_s - rho_g) theta |g| with ``mass`` [kg/m^2]
    and a free top (:func:`steady_column` with U = 0)."""
    return steady_column(mass, 0.0, ph, G_a, G_b, form)


class Sedimentation(NamedTuple):
    """Ref. 4 (:func:`batch_sedimentation`). Velocities [m/s], times [s], heights [m] above the floor."""
    theta0: float
    H0: float
    settling_velocity: float   # v0 < 0: the interface's (and the suspension's) velocity
    theta_packed: float        # the sediment's fraction in Kynch's jump condition
    front_speed: float         # > 0: the sediment front's rise
    meeting_time: float
    meeting_height: float
    final: Column              # the hydrostatic end state

    def interface(self, t):
        """Kynch's interface line H(t) = H0 + v0 t (the theta = theta0/2 level) for 0 <= t <= meeting_time;
        nan after (the interface then sits on the consolidating sediment, which ends as ``final``)."""
        t = np.asarray(t, dtype=float)
        return np.where((t >= 0) & (t <= self.meeting_time), self.H0 + self.settling_velocity * t, np.nan)

    def sediment_front(self, t):
        """The sediment front's line h(t) = front_speed t, 0 <= t <= meeting_time (nan after)."""
        t = np.asarray(t, dtype=float)
        return np.where((t >= 0) & (t <= self.meeting_time), self.front_speed * t, np.nan)


def batch_sedimentation(theta0, H0, ph, G_a=G_A, G_b=G_B, form="paper", theta_packed=None):
    """Ref. 4: a uniform layer theta0 of height H0 [m] on the floor, clear gas above, U = 0 (Kynch 1952).

    Kynch's theory: theta_t + F(theta)_x = 0, F = theta v(theta) (:func:`kynch_flux`); a jump between states a
    and b moves at the chord's slope (F(b) - F(a)) / (b - a).

    - The top (clear gas, F(0) = 0, over theta0): speed F(theta0)/theta0 = v0, the hindered settling velocity;
      H(t) = H0 + v0 t (Stokes: H0 - u_t (1 - theta0)^4.65 t). It is a shock (Oleinik: F below its chord on
      (0, theta0)) exactly where |v| falls with theta on (0, theta0]; checked, ValueError otherwise.
    - The sediment front (theta0 above, the sediment below, held at rest by p_s: flux 0): speed
      -F(theta0) / (theta_packed - theta0) = theta0 |v0| / (theta_packed - theta0), up from the floor.
    - They meet at t_m = H0 (theta_packed - theta0) / (theta_packed |v0|), at h_m = theta0 H0 / theta_packed.

    Which theta_packed (default): p_s is continuous at the front (above it the suspension's p_s(theta0) carries no
    gradient), and a sediment at rest with no gas flow through it (U = 0) is hydrostatic; so the sediment is the
    hydrostatic profile whose top is at theta0. The mass balance of the layer, int_0^h (theta - theta0) dx =
    theta0 |v0| t, is then Kynch's jump condition with theta_packed(t) the sediment's mean fraction; at the
    meeting the sediment holds the whole layer, so theta_packed = theta0 H0 / h_m with h_m the height of the
    hydrostatic sediment of mass rho_s theta0 H0 below its theta0 level (the :func:`final_sediment` holding that
    plus the mass above theta0 in a free top, rho_s (p_s(theta0) - p_s(0)) / ((rho_s - rho_g) |g|)). This makes
    t_m exact where the sediment consolidates as fast as it is fed (the front is then not exactly a line between:
    theta_packed grows as the sediment deepens); a slower consolidation leaves a looser, taller sediment that
    meets the interface earlier, so t_m is the latest meeting. A float ``theta_packed`` overrides the choice (a
    close packing in a kinematic model)."""
    _check_fraction(theta0)
    if not H0 > 0:
        raise ValueError("H0 must be > 0")
    _check_form(form)
    v0 = hindered_settling_velocity(theta0, ph)
    below = np.linspace(0.0, theta0, 41)[1:-1]
    if np.any(np.abs(kynch_flux(below, ph)) / below < abs(v0)):
        raise ValueError("the settling speed does not fall with theta below theta0: the top is not one shock")
    mass = ph.rho_s * theta0 * H0
    final = final_sediment(mass, ph, G_a, G_b, form)
    if theta_packed is None:
        tail = ph.rho_s * (limits.pressure(theta0, G_a, G_b, form) - limits.pressure(0.0, G_a, G_b, form)) \
            / ph.buoyant                                         # mass above the theta0 level [kg/m^2]
        h_m = final_sediment(mass + tail, ph, G_a, G_b, form).height_of(theta0)
        theta_packed = theta0 * H0 / h_m
    else:
        h_m = theta0 * H0 / theta_packed
    if not theta_packed > theta0:
        raise ValueError(f"theta_packed = {theta_packed:g} must exceed theta0 = {theta0:g}")
    speed = theta0 * abs(v0) / (theta_packed - theta0)
    t_m = (H0 - h_m) / abs(v0)
    return Sedimentation(theta0, H0, v0, theta_packed, speed, t_m, h_m, final)
