"""Reference 3 of docs/physics.md ("The solid phase in a gas"): a bed fluidised by a gas fed through its floor at
superficial velocity U. :func:`steady_column` (the steady profile theta(x) with the bed's mass and a free top,
integrated from the top down), :func:`uniform_bed_fraction` (theta*), :func:`richardson_zaki_fraction`,
:func:`fluidization_velocity`, :func:`minimum_fluidization_velocity` (Ergun), :func:`compression_length`;
the phases are :class:`parsph.physics.gas_references.Phases`.

The columns' effective pressure p_s(theta) is that of the pressure form in use
(:func:`parsph.physics.limits.pressure`: "paper" p = G theta, "consistent" p = G / (G_a ln 10), with
G = 10^(G_a theta + G_b)); only p_s' enters the profiles. :func:`parsph.physics.analytic.settling_equilibrium`
solves the walled column (a lid, no free top) by shooting from the floor; the free-top columns here are
integrated from the top down instead (below), and the tests use that function as an independent check.
"""
import math

import numpy as np
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq

from . import limits
from .closures import G_A, G_B
from .gas_references import RZ_N, balance_root, check_fraction


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
    return balance_root(theta, ph)


def minimum_fluidization_velocity(theta_mf, ph):
    """U_mf [m/s] from Ergun (the Gidaspow closure's dense branch, eps < 0.8) at the packed fraction theta_mf:
    the bed's buoyant weight carried by the Ergun pressure drop,

        150 mu_g theta^2 U / (eps^3 d^2) + 1.75 rho_g theta U^2 / (eps^3 d) = theta (rho_s - rho_g) |g|,

    i.e. beta_Ergun(theta, U/eps) U = theta eps^2 (rho_s - rho_g) |g|; the positive root of the quadratic,
    U = 2C / (B + sqrt(B^2 + 4AC)). Independent of ``ph.model``; the Gidaspow closure with MFiX's blend
    differs by the Wen & Yu share phi(eps) (0.3% of beta at eps = 0.4): :func:`fluidization_velocity`."""
    check_fraction(theta_mf, "theta_mf")
    eps = 1.0 - theta_mf
    A = 1.75 * ph.rho_g * theta_mf / (eps ** 3 * ph.d)
    B = 150.0 * ph.mu_g * theta_mf ** 2 / (eps ** 3 * ph.d ** 2)
    C = theta_mf * ph.buoyant
    return 2.0 * C / (B + math.sqrt(B * B + 4.0 * A * C))


def check_form(form):
    if form not in limits.FORMS:
        raise ValueError(f"pressure form {form!r}: one of {limits.FORMS}")


def compression_length(U, ph, G_a=G_A, G_b=G_B, form="paper", packing=()):
    """Ref. 3: l = p_s'(theta*) / f'(theta*) [m], f of :func:`column_rhs`: the length over which the profile
    relaxes to theta* (theta* - theta ~ exp(-(x_top - x)/l) away from the top); a bed much taller than l has a
    uniform interior. f' by a central difference (step 1e-6 theta*)."""
    check_form(form)
    th = uniform_bed_fraction(U, ph)
    h = 1e-6 * min(th, 1.0 - th)
    fp = (column_rhs(th + h, U, ph) - column_rhs(th - h, U, ph)) / (2.0 * h)
    return limits.dpressure(th, G_a, G_b, form, packing) / fp


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


def steady_column(mass, U, ph, G_a=G_A, G_b=G_B, form="paper", rtol=1e-12, packing=()):
    """Ref. 3 (U > 0) and the final sediment of ref. 4 (U = 0): the steady theta(x) of a column at rest on the
    floor with ``mass`` [kg/m^2] = int rho_s theta dx and a free top, from

        p_s'(theta) dtheta/dx = f(theta) = beta(theta, U/eps) U / eps^2 - theta (rho_s - rho_g) |g|

    (p_s of the pressure form ``form``, with the frictional p_f of a packing limit ``packing`` = (theta_min,
    theta_max) where given; x up from the floor). Returns a :class:`Column`.

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
    check_form(form)
    if not mass > 0:
        raise ValueError("the column needs a mass > 0")
    if U < 0:
        raise ValueError("U must be >= 0")
    if ph.rho_s <= ph.rho_g:
        raise ValueError("the solids must be denser than the gas")
    theta_star = uniform_bed_fraction(U, ph) if U > 0 else math.nan
    target = mass / ph.rho_s                                      # int theta dx [m]

    def dp(th):
        return limits.dpressure(th, G_a, G_b, form, packing)

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
