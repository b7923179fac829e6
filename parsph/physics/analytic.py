"""Analytic references.

Transient plane Couette flow, Eq. (8) with the sum starting at n = 1
(docs/physics.md, "The analytic solution, Eq. (8)", fixes the paper's n = 0 typo):

    v_y(x, t) = V_w x/L + sum_{n>=1} (2 V_w/(n pi)) (-1)^n sin(n pi x/L) exp(-n^2 pi^2 nu t/L^2)

The series is truncated where the factor exp(-n^2 pi^2 nu t / L^2) (times the
2/(n pi) amplitude) falls below ``tol`` relative to V_w, so the cut-off grows
as t -> 0 (about 150 terms at t = 1e-4 s for Table 1, 46,000 at 1e-9 s).
"""
from functools import lru_cache
import math

from .closures import G_A, G_B, modulus

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


def poiseuille_velocity(x, t, nu, L, F, tol=1e-17):
    """Start-up of plane Poiseuille flow between fixed plates driven by a body force F along y.

    dv/dt = nu v'' + F, v(0) = v(L) = 0, v(x, 0) = 0 (Morris, Fox & Zhu 1997):

        v = F x (L - x) / (2 nu) - sum_{n odd} 4 F L^2 / (nu pi^3 n^3) sin(n pi x / L) exp(-n^2 pi^2 nu t / L^2)
    """
    x = np.asarray(x, dtype=float)
    v = F * x * (L - x) / (2.0 * nu)
    if t == 0:
        return np.zeros_like(x)
    a = math.pi ** 2 * nu * t / L ** 2
    n = 1
    while True:
        amp = 4.0 * F * L ** 2 / (nu * math.pi ** 3 * n ** 3) * math.exp(-n * n * a)
        v = v - amp * np.sin(n * math.pi * x / L)
        if amp < tol * max(abs(F) * L ** 2 / nu, 1e-300) and n > 1:
            return v
        n += 2


def settling_equilibrium(x, theta0, L, rho_s, g, G_a=G_A, G_b=G_B, steps=4000, form="closure"):
    """Volume fraction of a granular column at rest between a floor (x = 0) and a lid (x = L).

    Hydrostatic balance with grad p_s = G(theta) grad theta and gravity g (> 0)
    along -x:  G(theta) dtheta/dx = -rho_s theta g,  with the mass fixed:
    int_0^L theta dx = theta0 L. Integrated with RK4 from the floor value, which
    is found by bisection on the mass. Raises ValueError if the column would
    not reach the lid (a free surface: theta -> 0 below x = L).

    ``form="paper"`` gives instead the balance that the paper's pressure term
    of Eq. (5) converges to: with G taken at the pair mean it discretises
    grad(G theta) = G (1 + G_a ln(10) theta) grad theta, a stiffer column.

    Points x outside [0, L] get the same balance continued beyond the plates
    (the values the ghost wall particles there hold). The bisection (seconds:
    RK4 in Python) is done once per column and kept (:func:`_settled_column`).
    """
    args = (rho_s, g, G_a, G_b, G_a * math.log(10.0) if form == "paper" else 0.0)
    theta_b, xs, th = _settled_column(theta0, L, rho_s, g, G_a, G_b, steps, form)
    x = np.asarray(x, dtype=float)
    lo_x, hi_x = min(float(x.min(initial=0.0)), 0.0), max(float(x.max(initial=L)), L)
    if lo_x < 0.0:  # below the floor: the balance continued downwards
        xb, tb = _column(theta_b, lo_x, max(1, int(steps * -lo_x / L)), *args)
        xs, th = np.concatenate([xb[:0:-1], xs]), np.concatenate([tb[:0:-1], th])
    if hi_x > L:  # above the lid
        xt, tt = _column(th[-1], hi_x - L, max(1, int(steps * (hi_x - L) / L)), *args)
        xs, th = np.concatenate([xs, L + xt[1:]]), np.concatenate([th, tt[1:]])
    return np.interp(x, xs, th)


def _column(theta_b, end, n, rho_s, g, G_a, G_b, stiff):
    """RK4 of G(theta) (1 + stiff theta) dtheta/dx = -rho_s theta g from theta_b at x = 0 to x = end
    (either side of 0) in n steps: (x, theta)."""
    def rhs(th):
        return -rho_s * g * th / (modulus(th, G_a, G_b) * (1.0 + stiff * th))

    xs = np.linspace(0.0, end, n + 1)
    th = np.empty_like(xs)
    th[0] = theta_b
    dx = end / n
    for i in range(n):
        t = th[i]
        k1 = rhs(t)
        k2 = rhs(t + 0.5 * dx * k1)
        k3 = rhs(t + 0.5 * dx * k2)
        k4 = rhs(t + dx * k3)
        th[i + 1] = t + dx / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return xs, th


@lru_cache(maxsize=32)
def _settled_column(theta0, L, rho_s, g, G_a, G_b, steps, form):
    """(floor value, x, theta(x)) on [0, L] of the column holding theta0 L: the floor value bisected on
    the mass (read-only arrays, shared by every call with these arguments)."""
    args = (rho_s, g, G_a, G_b, G_a * math.log(10.0) if form == "paper" else 0.0)

    def mass(theta_b):
        xs, th = _column(theta_b, L, steps, *args)
        return np.sum(0.5 * (th[1:] + th[:-1]) * np.diff(xs))

    lo, hi = theta0, 1.0
    if mass(hi) < theta0 * L:
        raise ValueError("no equilibrium below theta = 1")
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if mass(mid) < theta0 * L:
            lo = mid
        else:
            hi = mid
    theta_b = 0.5 * (lo + hi)
    xs, th = _column(theta_b, L, steps, *args)
    if th[-1] < 1e-3 * theta0:
        raise ValueError("the column does not reach the lid (free surface)")
    xs.setflags(write=False)
    th.setflags(write=False)
    return theta_b, xs, th
