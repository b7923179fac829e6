"""Transient plane Poiseuille flow: both plates fixed, driven by a body force F along y.

Needs the pressure and viscous terms and the body force ``body_force.g =
[0, F]``. Reference: the series of Morris, Fox & Zhu (1997),
:func:`parsph.physics.analytic.poiseuille_velocity`; errors are normalised by the
steady centre-line velocity F L^2 / (8 nu).
"""
from parsph.physics.analytic import poiseuille_velocity
from . import Scene, Terms, lattice


def particles(cfg, y_lo, y_hi):
    return lattice(cfg, y_lo, y_hi)


def reference(cfg, x, t):
    return {"vy": poiseuille_velocity(x, t, cfg.nu, cfg.L, cfg.g[1])}


def velocity_scale(cfg):
    return abs(cfg.g[1]) * cfg.L ** 2 / (8.0 * cfg.nu) if cfg.nu > 0 else abs(cfg.g[1])


def max_kinetic_energy(cfg, fluid_mass):
    """|v| stays below the steady centre-line velocity (the transient rises monotonically to it)."""
    return 0.5 * fluid_mass * velocity_scale(cfg) ** 2


SCENE = Scene(name="poiseuille", terms=Terms(pressure=True, viscosity=True, body_force=True),
              particles=particles, reference=reference, velocity_scale=velocity_scale,
              max_kinetic_energy=max_kinetic_energy, walls=True)
