"""The gas's drag on the solids (PHYSICS.md, "The solid phase in a gas"): the interphase coefficient beta.

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
(a zero divisor gives inf or nan, as in the loops, instead of raising).
"""
import math

from numba import njit

STOKES, WEN_YU, GIDASPOW = 0, 1, 2
MODELS = {"stokes": STOKES, "wen_yu": WEN_YU, "gidaspow": GIDASPOW}


@njit(cache=True, inline="always", error_model="numpy")
def _power(x, a):
    """x^a for x > 0 (0 at x = 0, a > 0) as exp(a ln x): a fifth cheaper than pow in the step's loop."""
    return math.exp(a * math.log(x)) if x > 0.0 else 0.0


@njit(cache=True, inline="always", error_model="numpy")
def wen_yu(theta, slip, rho_g, mu_g, d):
    """Wen & Yu's beta [kg/(m^3 s)]."""
    eps = 1.0 - theta
    re = eps * rho_g * slip * d / mu_g
    if re < 1000.0:
        return 18.0 * mu_g * theta * _power(eps, -2.65) / (d * d) * (1.0 + 0.15 * _power(re, 0.687))
    return 0.33 * rho_g * theta * _power(eps, -1.65) * slip / d


@njit(cache=True, inline="always", error_model="numpy")
def beta(model, theta, slip, rho_g, mu_g, d):
    """beta [kg/(m^3 s)] of closure ``model`` (:data:`MODELS`)."""
    eps = 1.0 - theta
    if model == STOKES:
        return 18.0 * mu_g * theta * _power(eps, -2.65) / (d * d)
    wy = wen_yu(theta, slip, rho_g, mu_g, d)
    if model == WEN_YU:
        return wy
    ergun = 150.0 * theta * theta * mu_g / (eps * d * d) + 1.75 * theta * rho_g * slip / d
    phi = math.atan(150.0 * 1.75 * (eps - 0.8)) / math.pi + 0.5
    return (1.0 - phi) * ergun + phi * wy


@njit(cache=True, inline="always", error_model="numpy")
def rate(model, theta, slip, rho_s, rho_g, mu_g, d):
    """K = beta / (rho_s theta eps) [1/s]: the drag per unit mass and unit slip (1/tau in a stream). For
    Stokes written as 18 mu_g eps^-3.65 / (rho_s d^2): no slip and one power, the step's cheapest case."""
    eps = 1.0 - theta
    if model == STOKES:
        return 18.0 * mu_g / (rho_s * d * d) * _power(eps, -3.65)
    return beta(model, theta, slip, rho_g, mu_g, d) / (rho_s * theta * eps)


def terminal_velocity(rho_s, rho_g, g, d, mu_g):
    """u_t = (rho_s - rho_g) |g| d^2 / (18 mu_g) [m/s]: Stokes's terminal velocity of one grain."""
    return (rho_s - rho_g) * abs(g) * d * d / (18.0 * mu_g)


def relaxation_time(model, theta, slip, rho_s, rho_g, mu_g, d, along_column=False):
    """tau [s] with which drag relaxes the slip: 1 / K = rho_s theta eps / beta (a stream, or across a
    column), eps / K = rho_s theta eps^2 / beta along a column's axis."""
    return (1.0 - theta if along_column else 1.0) / rate(model, theta, slip, rho_s, rho_g, mu_g, d)
