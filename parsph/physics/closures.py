"""Constitutive closures of the solid phase (docs/physics.md, "The model: the solid phase, without drag").

- elastic modulus G(theta) = 10^(a theta + b) Pa (Jayaswal 1991), with
  grad p_s = G(theta) grad theta;
- solids viscosity mu_s = k theta;
- where a run sets a packing limit (``material.theta_max``), a frictional pressure p_f(theta) that
  diverges there (Johnson & Jackson 1987, Johnson, Jackson & Pfeffer's constants as MFiX's defaults),
  added to the consistent form's p = G / (G_a ln 10): :func:`packing_pressure`.

In the pair loop G is needed at the pair-mean theta; it factorises exactly:
G((theta_i + theta_j)/2) = 10^b * 10^(a theta_i / 2) * 10^(a theta_j / 2),
so each particle carries ``half_modulus = 10^(a theta / 2)`` and the loop
multiplies.
"""
import math

import numpy as np
from numba import njit

LN10 = math.log(10.0)
G_A, G_B = 8.76, -1.183  # G = 10^(G_A theta + G_B) Pa (Jayaswal 1991; docs/physics.md)


@njit(cache=True)
def modulus_unchecked(theta, a, b):
    """G(theta) = 10^(a theta + b) for numba code, without :func:`modulus`'s overflow check."""
    return math.exp((a * theta + b) * LN10)  # 10^x as exp(x ln 10): a third of pow's cost in the loops


@njit(cache=True)
def half_modulus(theta, a):
    """10^(a theta / 2): the per-particle factor of G at the pair mean (the pair loops call it)."""
    return math.exp(0.5 * a * LN10 * theta)


# p_f = FR (theta - theta_min)^2 / (theta_max - theta)^5 [Pa] (Johnson & Jackson 1987; FR, n = 2, p = 5 of
# Johnson, Jackson & Pfeffer 1990, MFiX's defaults). Past theta_c = theta_max - PACKING_TANGENT (theta_max -
# theta_min) p_f continues on its tangent: a grain pressed past theta_c within one step meets a steep, finite
# pressure instead of a pole (and a sign change) at theta_max.
FRICTION_FR = 0.05
PACKING_TANGENT = 0.1
THETA_MIN = 0.5  # material.theta_min's default: p_f = 0 below it


@njit(cache=True)
def packing_limit(theta_min, theta_max):
    """theta_c: where p_f leaves its closed form for its tangent (a run's grains should stay below it)."""
    return theta_max - PACKING_TANGENT * (theta_max - theta_min)


@njit(cache=True)
def packing_pressure(theta, theta_min, theta_max):
    """(p_f, dp_f/dtheta) [Pa] of the frictional pressure at theta (zero at or below theta_min)."""
    if not theta > theta_min:
        return 0.0, 0.0
    tc = packing_limit(theta_min, theta_max)
    t = min(theta, tc)
    a = t - theta_min
    b = theta_max - t
    p = FRICTION_FR * a * a / (b * b * b * b * b)
    dp = p * (2.0 / a + 5.0 / b)
    if theta > tc:
        p += dp * (theta - tc)
    return p, dp


def modulus(theta, a=G_A, b=G_B):
    """G(theta) [Pa], for a number or an array; the one definition of G (numba code calls :func:`modulus_unchecked`).

    Raises OverflowError where G does not fit a float (as Python's own power does)."""
    if np.ndim(theta):
        return np.array([modulus(float(t), a, b) for t in np.ravel(theta)]).reshape(np.shape(theta))
    g = modulus_unchecked(float(theta), float(a), float(b))
    if not math.isfinite(g) and math.isfinite(theta) and math.isfinite(a) and math.isfinite(b):
        raise OverflowError(f"G = 10^({a:g} * {theta:g} + {b:g}) does not fit a float")
    return g


def viscosity(theta, k):
    """mu_s = k theta [Pa s]."""
    return k * theta
