"""Scenes: geometry, walls, body force, initial state and reference solution.

A scene module defines a :class:`Scene` instance named ``SCENE``. The solver
asks it for the particles of one slab and for the terms of Eq. (5) it needs.
"""
from dataclasses import dataclass
import math
from typing import Callable, Optional


@dataclass(frozen=True)
class Terms:
    """Which terms of Eq. (5) a scene needs; the loops compute no others."""
    pressure: bool = True
    viscosity: bool = True
    body_force: bool = False


@dataclass(frozen=True)
class Scene:
    name: str
    terms: Terms
    # particles(cfg, y_lo, y_hi) -> (gid, kind, mass, pos, vel) for lo <= y < hi
    particles: Callable
    # exact_profile(cfg, x, t) -> v_y(x, t), or None when there is no reference
    exact_profile: Optional[Callable] = None
    # wall velocity scale used to normalise errors
    velocity_scale: Callable = lambda cfg: 1.0
    # max_kinetic_energy(cfg, fluid_mass, t): bound on the fluid's kinetic energy [J/m]
    max_kinetic_energy: Callable = lambda cfg, mass, t: math.inf
    # whether fluid is confined between plates at x = 0 and x = L
    walls: bool = True


def get_scene(name):
    if name == "couette":
        from .couette import SCENE
        return SCENE
    raise KeyError(name)
