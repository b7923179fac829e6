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


_LN_1000 = math.log(1000.0)


@njit(cache=True, inline="always", error_model="numpy")
def rate(model, theta, slip2, rho_s, rho_g, mu_g, d):
    """K = beta / (rho_s theta eps) [1/s] at slip^2 = |u_g - v|^2: the drag per unit mass and unit slip (1/tau
    in a stream), the quantity the step needs. Written in the log domain, one log of eps and (slip-dependent
    closures) one of slip^2 shared by every power, no sqrt below Re = 1000, no division by theta or eps:

        Stokes     K = A eps^-3.65,                         A = 18 mu_g / (rho_s d^2)
        Wen & Yu   K = A eps^-3.65 (1 + 0.15 Re^0.687),     ln Re = ln eps + ln(rho_g d / mu_g) + ln(slip^2) / 2
                   K = 0.33 rho_g eps^-2.65 slip / (rho_s d)              (Re >= 1000)
        Gidaspow   K = (1 - phi) K_Ergun + phi K_Wen&Yu,
                   K_Ergun = 150 theta mu_g / (rho_s eps^2 d^2) + 1.75 rho_g slip / (rho_s eps d)

    The Wen & Yu branch costs 2 logs and 2 exps per particle (24 -> 18 ns against powers of eps and Re)."""
    eps = 1.0 - theta
    le = math.log(eps)
    a = 18.0 * mu_g / (rho_s * d * d)
    if model == STOKES:
        return a * math.exp(-3.65 * le)
    lre = le + math.log(rho_g * d / mu_g) + 0.5 * math.log(slip2)
    if lre < _LN_1000:
        wy = a * math.exp(-3.65 * le) * (1.0 + 0.15 * math.exp(0.687 * lre))
    else:
        wy = 0.33 * rho_g / (rho_s * d) * math.exp(-2.65 * le) * math.sqrt(slip2)
    if model == WEN_YU:
        return wy
    ergun = (150.0 * theta * mu_g / (eps * d) + 1.75 * rho_g * math.sqrt(slip2)) / (rho_s * eps * d)
    phi = math.atan(150.0 * 1.75 * (eps - 0.8)) / math.pi + 0.5
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
