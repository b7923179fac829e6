"""A periodic box without walls: a decaying shear wave v_y = U sin(2 pi x / L).

The smallest scene. Needs only the viscous term (the wave does not compress
the lattice; ``terms.pressure = true`` adds the pressure term for
conservation checks). Reference: v_y = U sin(k x) exp(-nu k^2 t), k = 2 pi / L.
"""
import math

import numpy as np

from . import Scene, Terms, lattice


def particles(cfg, y_lo, y_hi):
    gid, kind, mass, pos, vel = lattice(cfg, y_lo, y_hi)
    vel[:, 1] = cfg.get("scene.amplitude") * np.sin(2 * math.pi * pos[:, 0] / cfg.L)
    return gid, kind, mass, pos, vel


def amplitude(cfg, t):
    """U exp(-nu k^2 t): what is left of the wave; errors are relative to it, so that they
    measure the decay the scene tests (an error e of it is an error e / (nu k^2 t) in the rate)."""
    k = 2 * math.pi / cfg.L
    return abs(cfg.get("scene.amplitude")) * math.exp(-cfg.nu * k * k * t)


def reference(cfg, x, t):
    k = 2 * math.pi / cfg.L
    return {"vy": cfg.get("scene.amplitude") * np.sin(k * x) * math.exp(-cfg.nu * k * k * t)}


def max_kinetic_energy(cfg, fluid_mass):
    """The wave only decays: its initial energy bounds it."""
    return 0.25 * fluid_mass * cfg.get("scene.amplitude") ** 2 * 1.01


SCENE = Scene(name="periodic_box", terms=Terms(pressure=False, viscosity=True, body_force=False),
              particles=particles, reference=reference,
              velocity_scale=lambda cfg: abs(cfg.get("scene.amplitude")),
              max_kinetic_energy=max_kinetic_energy, walls=False, current_scale=amplitude)
