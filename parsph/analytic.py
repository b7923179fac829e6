"""Analytic references.

Transient plane Couette flow, Eq. (8) with the sum starting at n = 1
(PHYSICS.md fixes the paper's n = 0 typo):

    v_y(x, t) = V_w x/L + sum_{n>=1} (2 V_w/(n pi)) (-1)^n sin(n pi x/L) exp(-n^2 pi^2 nu t/L^2)

The series is truncated where the factor exp(-n^2 pi^2 nu t / L^2) (times the
2/(n pi) amplitude) falls below ``tol`` relative to V_w, so the cut-off grows
as t -> 0 (about 150 terms at t = 1e-4 s for Table 1, 46,000 at 1e-9 s).
"""
import math

import numpy as np


def couette_terms(t, nu, L, tol=1e-17):
    """Number of series terms needed at time t for a truncation error below tol*V_w."""
    if t <= 0:
        raise ValueError("the series needs t > 0")
    a = math.pi ** 2 * nu * t / L ** 2
    # tail sum_{n>N} (2/(n pi)) e^{-n^2 a} < (2/(N pi)) e^{-N^2 a} / (1 - e^{-a})
    n = max(1, int(math.ceil(math.sqrt(max(0.0, -math.log(tol)) / a))))
    while True:
        tail = 2.0 / (n * math.pi) * math.exp(-n * n * a) / -math.expm1(-a)
        if tail < tol:
            return n
        n = int(n * 1.2) + 1


def couette_velocity(x, t, nu, L, V_w, tol=1e-17, chunk=4096):
    """Eq. (8): v_y at positions x (array) and time t > 0; t = 0 gives the initial state."""
    x = np.asarray(x, dtype=float)
    if t == 0:
        return np.where(x >= L, V_w, 0.0)
    nmax = couette_terms(t, nu, L, tol)
    a = math.pi ** 2 * nu * t / L ** 2
    v = V_w * x / L
    for n0 in range(1, nmax + 1, chunk):
        n = np.arange(n0, min(nmax, n0 + chunk - 1) + 1, dtype=float)
        amp = 2.0 * V_w / (n * math.pi) * np.where(n % 2 == 0, 1.0, -1.0) * np.exp(-n * n * a)
        v = v + np.sin(np.multiply.outer(x, n) * (math.pi / L)) @ amp
    return v


def couette_velocity_images(x, t, nu, L, V_w, nimg=50):
    """The same solution by the method of images (erfc sum): an independent check, best at small t."""
    x = np.asarray(x, dtype=float)
    s = 2.0 * math.sqrt(nu * t)
    erfc = np.vectorize(math.erfc)
    v = np.zeros_like(x)
    for k in range(nimg):
        v += erfc(((2 * k + 1) * L - x) / s) - erfc(((2 * k + 1) * L + x) / s)
    return V_w * v
