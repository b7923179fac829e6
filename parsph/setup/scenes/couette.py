"""Transient plane Couette flow (the paper's case, Table 1), in 2-D or 3-D.

Plates at x = 0 (fixed) and x = L (moving along +y at V_w from t = 0) with
Morris ghost walls; y (and z in 3-D) periodic. Needs the pressure and
viscous terms, no body force. Reference: Eq. (8).
"""
from parsph.physics.analytic import couette_velocity
from parsph.sph.particles import MOVING_WALL
from . import Scene, Terms, lattice


def particles(cfg, y_lo, y_hi):
    return lattice(cfg, y_lo, y_hi, right_wall=MOVING_WALL, right_velocity=cfg.V_w)


def reference(cfg, x, t):
    return {"vy": couette_velocity(x, t, cfg.nu, cfg.L, cfg.V_w)}


def max_kinetic_energy(cfg, fluid_mass):
    """Flow driven by the plates obeys a maximum principle: |v| <= |V_w|."""
    return 0.5 * fluid_mass * cfg.V_w ** 2


SCENE = Scene(name="couette", terms=Terms(pressure=True, viscosity=True, body_force=False),
              particles=particles, reference=reference, velocity_scale=lambda cfg: abs(cfg.V_w),
              max_kinetic_energy=max_kinetic_energy, walls=True)
