"""Transient plane Couette flow (the paper's case, Table 1).

Fluid fills 0 < x < L on a square lattice (x = (i + 1/2) dx, y = (j + 1/2) dy);
wall particles continue the lattice for ``layers`` rows beyond each plate
(PHYSICS.md, "Walls"). The plate at x = L moves along +y at V_w from t = 0.
Reference: Eq. (8) (:func:`parsph.analytic.couette_velocity`).
"""
import numpy as np

from ..analytic import couette_velocity
from ..particles import FLUID, WALL, MOVING_WALL
from . import Scene, Terms


def lattice(cfg, y_lo, y_hi):
    """Fluid and wall particles of the slab y_lo <= y < y_hi.

    The global id numbers lattice sites row by row (``row * ncol + col``,
    columns from the outermost left wall layer), so each rank builds its own
    particles without communication.
    """
    nw, Nx = cfg.layers, cfg.Nx
    ncol = Nx + 2 * nw
    col = np.arange(ncol)
    x = (col - nw + 0.5) * cfg.dx
    kind_col = np.where(col < nw, WALL, np.where(col >= nw + Nx, MOVING_WALL, FLUID))
    rows = np.arange(cfg.Ny)
    y = (rows + 0.5) * cfg.dy
    rows = rows[(y >= y_lo) & (y < y_hi)]
    gid = (rows[:, None] * ncol + col[None, :]).ravel()
    pos = np.empty((gid.size, 2))
    pos[:, 0] = np.tile(x, rows.size)
    pos[:, 1] = np.repeat((rows + 0.5) * cfg.dy, ncol)
    kind = np.tile(kind_col, rows.size)
    vel = np.zeros_like(pos)
    vel[kind == MOVING_WALL, 1] = cfg.V_w
    mass = np.full(gid.size, cfg.mass)
    return gid.astype(np.int64), kind.astype(np.int64), mass, pos, vel


def exact(cfg, x, t):
    return couette_velocity(x, t, cfg.nu, cfg.L, cfg.V_w)


def max_kinetic_energy(cfg, fluid_mass, t):
    """Viscous flow driven by the plates obeys a maximum principle: |v| <= |V_w|."""
    return 0.5 * fluid_mass * cfg.V_w ** 2


SCENE = Scene(name="couette", terms=Terms(pressure=True, viscosity=True, body_force=False),
              particles=lattice, exact_profile=exact, velocity_scale=lambda cfg: abs(cfg.V_w) or 1.0,
              max_kinetic_energy=max_kinetic_energy, walls=True)
