"""A fluidised bed (docs/physics.md, "The solid phase in a gas", reference 3): a layer theta0 of height H0
(``scene.height``) on the floor x = 0, gas fed through the floor at superficial velocity U > 0
(``gas.flow = "column"``), clear gas above, a lid at x = L. Above minimum fluidisation the bed expands to
its steady column and stays there. The layer's parts are in :mod:`.layer`.

Reference (theta, errors relative to theta0): the steady column with the bed's mass and a free top
(:func:`parsph.physics.bed_expansion.steady_column`), the state the bed reaches; its interior is theta* where
the bed is much taller than its compression length; v_x 0 in it (NaN above its top, where it has no solids).
"""
import math

import numpy as np

from parsph.errors import ConfigError
from . import Scene, Terms, layer


def reference(cfg, x, t):
    theta = layer.end_state(cfg).theta_at(np.maximum(np.asarray(x, dtype=float), 0.0))
    return {"theta": theta, "vy": np.zeros_like(theta), "vx": np.where(theta > 0.0, 0.0, np.nan)}


def check(cfg):
    gas = cfg.gas
    if gas is None or not gas.fed or not gas.U > 0:
        raise ConfigError("gas.U", 'the fluidized_bed scene needs a gas column fed at U > 0: give gas.drag, '
                          'gas.flow = "column" (or "solved") and gas.U')
    end = layer.check(cfg, "fluidized_bed")
    tail = end.height_of(min(end.theta_floor, 1e-3 * cfg.theta0))
    if not tail + 2.0 * cfg.h <= cfg.L:
        raise ConfigError("domain.L", f"the expanded bed reaches {tail:.3g} m (theta = 1e-3 theta0): raise the "
                          f"lid above it by 2h = {2 * cfg.h:g} m")


SCENE = Scene(name="fluidized_bed", terms=Terms(pressure=True, viscosity=True, body_force=True),
              particles=layer.particles, reference=reference, error_field="theta",
              velocity_scale=lambda cfg: math.sqrt(abs(cfg.g[0]) * cfg.h),
              max_kinetic_energy=layer.max_kinetic_energy, walls=True,
              check=check, free_surface=True, file_attributes=layer.file_attributes)
