"""The gas's drag on the solids (docs/physics.md, "Drag closures"): the interphase coefficient beta.

The solids feel ``+beta (u_g - v)`` per unit volume; ``slip`` below is |u_g - v| [m/s],
``theta`` the solids' volume fraction, eps = 1 - theta, ``d`` the grain diameter:

- Stokes limit of Wen & Yu (Re -> 0): ``beta = 18 mu_g theta eps^-2.65 / d^2``, independent of the slip;
- Wen & Yu (1966), Re = eps rho_g slip d / mu_g:
  ``18 mu_g theta eps^-2.65 / d^2 (1 + 0.15 Re^0.687)`` for Re < 1000,
  ``0.33 rho_g theta eps^-1.65 slip / d`` above (C_D = 0.44);
- Gidaspow (1994) with MFiX's blend of its two branches at eps = 0.8:
  Ergun ``150 theta^2 mu_g / (eps d^2) + 1.75 theta rho_g slip / d``,
  phi = atan(150 * 1.75 (eps - 0.8)) / pi + 0.5, beta = (1 - phi) Ergun + phi Wen & Yu.
  The blend is used (not the jump) so that beta is continuous in theta: the hindered settling root
  and an implicit update see no step.

numba functions (the step's loops call them per particle) that work from Python too; numpy's error model
(a zero divisor gives inf or nan, as in the loops, instead of raising). The transcendentals are
:mod:`parsph.physics.fastmath`'s, so that the loops run on vector registers.
"""
import math

from numba import njit

from parsph.physics import fastmath as fm

STOKES, WEN_YU, GIDASPOW = 0, 1, 2
MODELS = {"stokes": STOKES, "wen_yu": WEN_YU, "gidaspow": GIDASPOW}


_LN_1000 = math.log(1000.0)
_INV_PI = 1.0 / math.pi


@njit(cache=True, inline="always", error_model="numpy")
def rate(model, theta, slip2, rho_s, rho_g, mu_g, d):
    """K = beta / (rho_s theta eps) [1/s] at slip^2 = |u_g - v|^2: the drag per unit mass and unit slip (1/tau
    in a stream), the quantity the step needs. Written in the log domain, one log of eps and (slip-dependent
    closures) one of slip^2 shared by every power, no division by theta (Gidaspow's one by eps):

        Stokes     K = A eps^-3.65,                         A = 18 mu_g / (rho_s d^2)
        Wen & Yu   K = A eps^-3.65 (1 + 0.15 Re^0.687),     ln Re = ln eps + ln(rho_g d / mu_g) + ln(slip^2) / 2
                   K = 0.33 rho_g eps^-3.65 eps slip / (rho_s d)              (Re >= 1000)
        Gidaspow   K = (1 - phi) K_Ergun + phi K_Wen&Yu,
                   K_Ergun = (150 mu_g / (rho_s d^2) theta / eps + 1.75 rho_g / (rho_s d) slip) / eps

    Branch-free (both Wen & Yu branches, then a select) on :mod:`parsph.physics.fastmath`'s log, exp and
    atan, so that a loop over particles calling it with a constant ``model`` runs on vector registers
    (:func:`parsph.sph.body_force.drag_rates`); slip2 = 0 gives Re^0.687 = exp(-inf) = 0. Within 1e-15 of
    docs/physics.md's formulas written with powers (tests/test_drag.py asks 1e-13)."""
    eps = 1.0 - theta
    le = fm.log(eps)
    a = 18.0 * mu_g / (rho_s * d * d)
    e365 = fm.exp(-3.65 * le)
    if model == STOKES:
        return a * e365
    lre = le + fm.log(rho_g * d / mu_g) + 0.5 * fm.log(slip2)
    slip = math.sqrt(slip2)
    low = a * e365 * (1.0 + 0.15 * fm.exp(0.687 * lre))
    high = 0.33 * rho_g / (rho_s * d) * (e365 * eps) * slip
    wy = low if lre < _LN_1000 else high
    if model == WEN_YU:
        return wy
    ie = 1.0 / eps
    ergun = (150.0 * mu_g / (rho_s * d * d) * theta * ie + 1.75 * rho_g / (rho_s * d) * slip) * ie
    phi = fm.atan(150.0 * 1.75 * (eps - 0.8)) * _INV_PI + 0.5
    return (1.0 - phi) * ergun + phi * wy


@njit(cache=True, error_model="numpy")
def beta(model, theta, slip, rho_g, mu_g, d):
    """beta [kg/(m^3 s)] of closure ``model`` (:data:`MODELS`) at slip = |u_g - v|: rho_s theta eps K."""
    return theta * (1.0 - theta) * rate(model, theta, slip * slip, 1.0, rho_g, mu_g, d)


def terminal_velocity(rho_s, rho_g, g, d, mu_g):
    """u_t = (rho_s - rho_g) |g| d^2 / (18 mu_g) [m/s]: Stokes's terminal velocity of one grain."""
    return (rho_s - rho_g) * abs(g) * d * d / (18.0 * mu_g)


def relaxation_time(model, theta, slip, rho_s, rho_g, mu_g, d, along_column=False):
    """tau [s] with which drag relaxes the slip: 1 / K = rho_s theta eps / beta (a stream, or across a
    column), eps / K = rho_s theta eps^2 / beta along a column's axis."""
    return (1.0 - theta if along_column else 1.0) / rate(model, theta, slip * slip, rho_s, rho_g, mu_g, d)
