"""Constitutive closures of the solid phase (docs/physics.md, "The model: the solid phase, without drag").

- elastic modulus G(theta) = 10^(a theta + b) Pa (Jayaswal 1991), with
  grad p_s = G(theta) grad theta;
- solids viscosity mu_s = k theta.

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
