"""Batch sedimentation (docs/physics.md, "The solid phase in a gas", reference 4; Kynch 1952, MFiX's PIC04): a
uniform layer theta0 of height H0 (``scene.height``) on the floor x = 0, clear gas above, a lid at x = L, the
gas a closed column (``gas.flow = "column"``, U = 0) or absent (the layer then falls under gravity alone to
the same hydrostatic end state). The layer's parts are in :mod:`.layer`.

Reference (theta, errors relative to theta0): Kynch's profile until the top interface meets the rising
sediment, 0 above H(t) = H0 + v0 t, theta0 between the sediment front h(t) and H(t), the sediment's mean
theta_packed below h(t); the hydrostatic sediment after (the end state, reached as it consolidates). Without
a gas, the hydrostatic sediment at all times (the end state). v_x (the profile's settling velocity): Kynch's v0
in the suspension, 0 in the sediment and in the end state, none (NaN) above the top.
"""
import math

import numpy as np

from parsph.errors import ConfigError
from . import Scene, Terms, layer


def reference(cfg, x, t):
    x = np.asarray(x, dtype=float)
    end = layer.end_state(cfg)
    final = end.theta_at(np.maximum(x, 0.0))
    at_rest = {"theta": final, "vy": np.zeros_like(final), "vx": np.where(final > 0.0, 0.0, np.nan)}
    if cfg.gas is None:
        return at_rest
    k = layer.sedimentation(cfg)
    if t > k.meeting_time:
        return at_rest
    top, front = k.H0 + k.settling_velocity * t, k.front_speed * t
    theta = np.where(x > top, 0.0, np.where(x > front, cfg.theta0, k.theta_packed))
    vx = np.where(x > top, np.nan, np.where(x > front, k.settling_velocity, 0.0))
    return {"theta": theta, "vy": np.zeros_like(theta), "vx": vx}


def check(cfg):
    gas = cfg.gas
    if gas is not None and not gas.fed:
        raise ConfigError("gas.flow", 'the sedimentation scene settles in a closed column: give gas.flow = "column" '
                          '(its closure) or "solved" (the grid\'s pressure)')
    if gas is not None and gas.U > 0:
        raise ConfigError("gas.U", "the sedimentation scene is a closed column (U = 0); a bed fed at U > 0 is "
                          "the fluidized_bed scene")
    layer.check(cfg, "sedimentation")
    if gas is not None:
        try:
            layer.sedimentation(cfg)
        except ValueError as e:
            raise ConfigError("material.theta0", f"Kynch's solution does not hold: {e}") from None


SCENE = Scene(name="sedimentation", terms=Terms(pressure=True, viscosity=True, body_force=True),
              particles=layer.particles, reference=reference, error_field="theta",
              velocity_scale=lambda cfg: math.sqrt(abs(cfg.g[0]) * cfg.h),
              max_kinetic_energy=layer.max_kinetic_energy, walls=True,
              check=check, free_surface=True, file_attributes=layer.file_attributes)
