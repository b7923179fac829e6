"""Eq. (3)'s volume fraction averaged over the cross directions, and the height of a layer's top from it.

A layer on the floor varies along x only; its particles sit in rows. Eq. (3), theta(r) = sum_j m_j W(r - r_j)
/ rho_s, averaged over y (and z) across the periodic box is

    theta_bar(x) = sum_j m_j Wp(x - x_j) / (rho_s Ly [Lz]),

with Wp(x) = int W(sqrt(x^2 + y^2 [+ z^2])) dy [dz] the kernel integrated over the cross directions (the
periodic images of a particle together cover the whole line or plane once). Wp is even, has support 2h and
int Wp dx = 1, so theta_bar is a 1-D SPH sum over the particles' x alone: a uniform lattice gives theta0 to
the 1-D lattice sum's accuracy, wherever the particles sit across.

Wp is tabulated once per (kernel, dim) in q = |x| / h with h = 1 (Wp(x; h) = wp(|x|/h) / h exactly, the
kernel's normalisation scaling as h^-dim): in 2-D by quadrature along y (scipy.integrate.quad, a break at
the kernel's inner knot), in 3-D as 2 pi int_|x|^2h W(r) r dr (the cross-plane integral in polar
coordinates, by quadrature too); then a cubic spline on 2001 points of [0, 2].

:func:`interface_height` is the one measure of a layer's top used by the tests and the studies: the highest
x where theta_bar falls through a level (theta0 / 2 by default), by brentq on theta_bar. For a sharp lattice
top at H (rows at H - dx/2, H - 3dx/2, ...) the rows below H carry half the lattice sum at x = H (the full
lattice's rows sit symmetrically about H), so the theta0 / 2 level is at H to the lattice sum's accuracy.

Post-processing (numpy, scipy), not a hot loop; vectorised over particles.
"""
from functools import lru_cache
import math

import numpy as np
from scipy.integrate import quad
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

from parsph.physics.kernels import get_kernel

_NQ = 2001        # table points on q in [0, 2]
_CHUNK = 1 << 22  # pair evaluations per block of theta_bar


def _w(kern, dim):
    """W(r) at h = 1 as a plain Python function."""
    norm = kern.norm(1.0, dim)
    return lambda r: float(kern.w(float(r), 1.0, norm))


@lru_cache(maxsize=None)
def _table(kernel, dim):
    """CubicSpline of wp(q), q in [0, 2] (h = 1), for kernel name ``kernel`` in ``dim`` dimensions."""
    kern = get_kernel(kernel, dim)
    s = kern.support
    w = _w(kern, dim)
    q = np.linspace(0.0, s, _NQ)
    wp = np.zeros_like(q)
    opts = dict(epsabs=1e-14, epsrel=1e-12, limit=200)
    for i, qi in enumerate(q[:-1]):
        if dim == 1:
            wp[i] = w(qi)
        elif dim == 2:
            top = math.sqrt(s * s - qi * qi)
            pts = [math.sqrt(1.0 - qi * qi)] if qi < 1.0 else None
            wp[i] = 2.0 * quad(lambda y: w(math.sqrt(qi * qi + y * y)), 0.0, top, points=pts, **opts)[0]
        else:
            pts = [1.0] if qi < 1.0 else None
            wp[i] = 2.0 * math.pi * quad(lambda r: w(r) * r, qi, s, points=pts, **opts)[0]
    # even in q: the spline's slope at q = 0 is 0
    return CubicSpline(q, wp, bc_type=((1, 0.0), "not-a-knot"))


def projected_kernel(cfg, x):
    """Wp(x) [1/m]: the run's kernel integrated over the cross directions, at offsets x [m] (an array)."""
    spline = _table(cfg.kernel, cfg.dim)
    q = np.abs(np.asarray(x, dtype=float)) / cfg.h
    support = get_kernel(cfg.kernel, cfg.dim).support
    return np.where(q < support, spline(np.minimum(q, support)), 0.0) / cfg.h


def _cross_section(cfg):
    """Ly (2-D, per unit depth in z) or Ly Lz (3-D) [m or m^2]."""
    return cfg.Ly * (cfg.Lz if cfg.dim == 3 else 1.0)


def projected_theta(cfg, x_eval, x, mass):
    """theta_bar at heights ``x_eval`` [m] of particles at heights ``x`` [m] with masses ``mass`` [kg/m or kg]
    (the fluid particles; numpy arrays): sum_j m_j Wp(x_eval - x_j) / (rho_s Ly [Lz]). Returns x_eval's shape."""
    xe = np.asarray(x_eval, dtype=float)
    flat = xe.ravel()
    x = np.asarray(x, dtype=float).ravel()
    m = np.asarray(mass, dtype=float).ravel()
    if x.shape != m.shape:
        raise ValueError("x and mass must have one entry per particle")
    out = np.zeros(flat.size)
    step = max(1, _CHUNK // max(1, x.size))
    for a in range(0, flat.size, step):
        block = flat[a:a + step]
        out[a:a + step] = projected_kernel(cfg, block[:, None] - x[None, :]) @ m
    return out.reshape(xe.shape) / (cfg.rho_s * _cross_section(cfg))


def interface_height(cfg, x, mass, level=None):
    """The layer's top [m]: the highest x where theta_bar (:func:`projected_theta`) falls through ``level``
    (default theta0 / 2) going up, found by brentq between samples h/8 apart. ``x``, ``mass``: the fluid
    particles' x positions [m] and masses (numpy arrays). ValueError where theta_bar never reaches the level."""
    level = 0.5 * cfg.theta0 if level is None else float(level)
    x = np.asarray(x, dtype=float).ravel()
    m = np.asarray(mass, dtype=float).ravel()
    if not level > 0:
        raise ValueError("the level must be > 0")
    reach = get_kernel(cfg.kernel, cfg.dim).support * cfg.h
    grid = np.arange(x.min() - reach, x.max() + reach + cfg.h / 8, cfg.h / 8)
    f = projected_theta(cfg, grid, x, m) - level
    above = np.flatnonzero(f >= 0.0)
    if above.size == 0:
        raise ValueError(f"theta_bar stays below {level:g} everywhere")
    i = above[-1]
    if f[i] == 0.0:
        return float(grid[i])
    return brentq(lambda s: projected_theta(cfg, s, x, m) - level, grid[i], grid[i + 1],
                  xtol=1e-12 * cfg.h, rtol=4.0 * np.finfo(float).eps)
