"""A granular column settling under gravity between a floor (x = 0) and a lid (x = L).

Gravity ``body_force.g = [-g, 0]`` along -x; both plates are fixed ghost
walls; y (and z) periodic. This is the scene that exercises the pressure
closure: at rest G(theta) dtheta/dx = -rho_s theta g with the mass fixed
(:func:`parsph.physics.analytic.settling_equilibrium`, computed independently by an
ODE solve). Errors are reported for theta(x), normalised by theta_0.
"""
import math

import numpy as np

from parsph.physics.analytic import settling_equilibrium
from . import Scene, Terms, lattice


def particles(cfg, y_lo, y_hi):
    return lattice(cfg, y_lo, y_hi)


def _weight(cfg):
    """The column's gravity along -x [m/s^2], with buoyancy in a gas (docs/physics.md, "The solid phase in a gas")."""
    return -cfg.g[0] * (1.0 - cfg.gas.rho / cfg.rho_s if cfg.gas is not None else 1.0)


def reference(cfg, x, t):
    """The balance at rest without gas flow; a column fed at U > 0 has drag in its balance (no reference
    here: the steady column is parsph.physics.bed_expansion.steady_column, with a free top)."""
    if cfg.gas is not None and (cfg.gas.U > 0 or not cfg.gas.fed):
        return {}
    theta = settling_equilibrium(x, cfg.theta0, cfg.L, cfg.rho_s, _weight(cfg), cfg.G_a, cfg.G_b)
    return {"theta": theta, "vy": np.zeros_like(theta)}


def wall_theta(cfg, x):
    """Walls hold the equilibrium column continued beyond the plates (docs/physics.md, "Walls": a mirror).

    The balance is the one the chosen pressure form converges to (the paper's
    form: grad(G theta); the consistent form: G grad theta).

    Held at theta_0 instead, floor and lid push with the pressure of theta_0
    while the fluid beside them is at 0.58 and 0.50: the first fluid row is
    squeezed from 0.5 dx to 0.3 dx above the floor (0.64 h from the first wall row, inside
    the cubic spline's 2h/3 where the repulsion weakens as particles close in)
    and, settled, slides into the wall from t = 0.45 s on (measured; growing
    at 70/s, the same with any dt or with the midpoint scheme).
    """
    form = "paper" if cfg.get("numerics.pressure_form") == "paper" else "closure"
    return settling_equilibrium(x, cfg.theta0, cfg.L, cfg.rho_s, _weight(cfg), cfg.G_a, cfg.G_b, form=form)


def max_kinetic_energy(cfg, fluid_mass):
    """At most all the potential energy: every particle falling the full height."""
    return fluid_mass * abs(cfg.g[0]) * cfg.L


SCENE = Scene(name="settling", terms=Terms(pressure=True, viscosity=True, body_force=True),
              particles=particles, reference=reference, error_field="theta",
              velocity_scale=lambda cfg: math.sqrt(abs(cfg.g[0]) * cfg.h),
              max_kinetic_energy=max_kinetic_energy, walls=True, wall_theta=wall_theta)
