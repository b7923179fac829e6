"""A periodic box without walls: a decaying shear wave v_y = U sin(2 pi x / L), alone or in a gas.

The smallest scene. Needs only the viscous term (the wave does not compress
the lattice; ``terms.pressure = true`` adds the pressure term for
conservation checks). Reference: v_y = U sin(k x) exp(-nu k^2 t), k = 2 pi / L.

In a gas (``[gas]``) with Stokes drag the box stays uniform in theta, so the
drag coefficient C of v_y (docs/physics.md: 1/tau) is one number and the flow is
linear: the mean relaxes to v_inf = w + g_y (1 - rho_g/rho_s) / C (w: the gas's
target velocity along y) while the wave decays with nu k^2 + C:

    v_y = v_inf (1 - exp(-C t)) + U sin(k x) exp(-(nu k^2 + C) t)

(docs/physics.md's references 1 and 2, the drag relaxation and hindered settling,
where the wave is absent). Other closures make C depend on the slip: no
closed form, and the scene has no reference there.
"""
import math

import numpy as np

from parsph.physics.drag import STOKES
from . import Scene, Terms, lattice


def particles(cfg, y_lo, y_hi):
    gid, kind, mass, pos, vel = lattice(cfg, y_lo, y_hi)
    vel[:, 1] = cfg.get("scene.amplitude") * np.sin(2 * math.pi * pos[:, 0] / cfg.L)
    return gid, kind, mass, pos, vel


def _drag_y(cfg):
    """(C, v_inf) of v_y in the run's gas at theta_0 with Stokes drag; (0, 0) without a gas."""
    gas = cfg.gas
    C = cfg.drag_coefficient(cfg.theta0, 0.0)  # the largest: along a column's axis
    if gas is None or not 0.0 < C < math.inf:
        return 0.0, 0.0
    w = gas.velocity[1]
    if gas.column:
        w = gas.sign * gas.U if gas.axis == 1 else 0.0
        if gas.axis != 1:
            C *= 1.0 - cfg.theta0  # across the column: rho_s theta eps / beta
    return C, w + cfg.g[1] * (1.0 - gas.rho / cfg.rho_s) / C


def _wave_rate(cfg):
    k = 2 * math.pi / cfg.L
    return cfg.nu * k * k + _drag_y(cfg)[0]


def amplitude(cfg, t):
    """What errors are relative to at time t: the wave left, U exp(-(nu k^2 + C) t), plus in a gas the speed
    |v_inf| the mean relaxes to. Relative to the wave left, an error e is an error e / (nu k^2 t) in the decay
    rate. The mean's part is the whole |v_inf| (the mean reached, |v_inf| (1 - exp(-C t)), plus the slip still
    to relax, |v_inf| exp(-C t)), not the mean reached alone: the drag's error in time is a share of the slip
    (reference 1's discrete solution, Eq. (7) at dt/tau), largest early, when the mean reached is small; in
    run/suspension.toml (dt/tau = 0.06) the mean reached alone made the first outputs' errors 2% of 0.014 m/s
    where they are 1.1% of the 0.0255 m/s of stream and wave (docs/validation.md)."""
    C, v_inf = _drag_y(cfg)
    return abs(cfg.get("scene.amplitude")) * math.exp(-_wave_rate(cfg) * t) + (abs(v_inf) if C > 0 else 0.0)


def reference(cfg, x, t):
    if cfg.gas is not None and cfg.gas.model != STOKES:
        return {}
    k = 2 * math.pi / cfg.L
    C, v_inf = _drag_y(cfg)
    mean = v_inf * -math.expm1(-C * t) if C > 0 else 0.0
    return {"vy": mean + cfg.get("scene.amplitude") * np.sin(k * x) * math.exp(-_wave_rate(cfg) * t)}


def max_kinetic_energy(cfg, fluid_mass):
    """The wave only decays: its initial energy bounds it (without a gas or gravity)."""
    return 0.25 * fluid_mass * cfg.get("scene.amplitude") ** 2 * 1.01


SCENE = Scene(name="periodic_box", terms=Terms(pressure=False, viscosity=True, body_force=False),
              particles=particles, reference=reference,
              velocity_scale=lambda cfg: abs(cfg.get("scene.amplitude")),
              max_kinetic_energy=max_kinetic_energy, walls=False, current_scale=amplitude)
