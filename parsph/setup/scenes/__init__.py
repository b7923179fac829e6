"""Scenes: geometry, walls, body force, initial state and reference solution.

A scene is one module defining ``SCENE = Scene(...)``: it declares the terms of
Eq. (5) it needs and whether plates bound the fluid at x = 0 and x = L, builds
the particles of one slab, and gives its reference profile. To add one: write
``parsph/setup/scenes/<name>.py`` (``periodic_box.py`` is the smallest example), add
the name to ``SCENE_NAMES`` below, and write ``run/<name>.toml``.
"""
from dataclasses import dataclass
import importlib
import math
from typing import Callable, Optional

import numpy as np

from parsph.sph.particles import GRAIN, WALL, MOVING_WALL

SCENE_NAMES = ("couette", "poiseuille", "settling", "periodic_box", "sedimentation", "fluidized_bed")


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
    # particles(cfg, y_lo, y_hi) -> (gid, kind, mass, pos, vel) for y_lo <= y < y_hi
    particles: Callable
    # reference(cfg, x, t) -> {"vy": array} and/or {"theta": array}, or None
    reference: Optional[Callable] = None
    # the profile field that errors are reported for: "vy" or "theta"
    error_field: str = "vy"
    # velocity_scale(cfg): normalises v_y errors and enters the CFL limit [m/s]
    velocity_scale: Callable = lambda cfg: abs(cfg.V_w)
    # max_kinetic_energy(cfg, fluid_mass): bound on the fluid's kinetic energy [J/m], constant in time
    # (the compiled blocks take it once per run)
    max_kinetic_energy: Callable = lambda cfg, mass: math.inf
    # plates at x = 0 and x = L (wall particles beyond them); else x is periodic with length L
    walls: bool = True
    # wall_theta(cfg, x) -> the volume fraction Morris walls at x hold; None: theta_0
    # (docs/physics.md, "Walls": wall theta is held, not evolved; free-surface scenes' walls follow the solids)
    wall_theta: Optional[Callable] = None
    # current_scale(cfg, t) -> what is left of the flow at time t [m/s], for flows that decay:
    # errors are then reported relative to it (None: to the fixed scale, V_w or theta_0;
    # RunConfig.error_scale)
    current_scale: Optional[Callable] = None
    # check(cfg) raises ConfigError naming the key where the run file asks what the scene cannot do
    check: Optional[Callable] = None
    # a layer on the floor under clear gas (fluid up to scene.height, nothing above it but the lid)
    free_surface: bool = False
    # file_attributes(cfg) -> the scene's own quantities among an output file's root attributes (None: V_w, nu)
    file_attributes: Optional[Callable] = None


def get_scene(name):
    if name not in SCENE_NAMES:
        raise KeyError(name)
    return importlib.import_module(f"{__name__}.{name}").SCENE


def lattice(cfg, y_lo, y_hi, right_wall=WALL, right_velocity=0.0, fluid_columns=None):
    """Fluid (and wall) particles of the slab y_lo <= y < y_hi on the square lattice.

    Fluid at x = (i + 1/2) dx, i < Nx (i < ``fluid_columns`` where given: a layer on the floor, the lattice
    empty above it up to the lid); with walls, ``cfg.layers`` columns
    continue the lattice beyond x = 0 (fixed) and x = L (``right_wall``,
    moving along y at ``right_velocity``). y = (j + 1/2) dy, z = (k + 1/2) dz; with side walls
    (``cfg.side_layers``) the rows j >= Ny are fixed wall across the whole lattice, plates included.
    The global id numbers lattice sites (``(k Ny' + row) ncol + col``, Ny' the rows with the side walls'),
    so each rank builds its own particles without communication.
    """
    nw = cfg.layers if cfg.scene.walls else 0
    ncol = cfg.Nx + 2 * nw
    col = np.arange(ncol)
    x = (col - nw + 0.5) * cfg.dx
    kind_col = np.where(col < nw, WALL, np.where(col >= nw + cfg.Nx, right_wall, GRAIN))
    keep = np.ones(ncol, bool)
    if fluid_columns is not None:
        keep = (col < nw + fluid_columns) | (col >= nw + cfg.Nx)
    rows_all = cfg.Ny + cfg.side_layers
    rows = np.arange(rows_all)
    rows = rows[((rows + 0.5) * cfg.dy >= y_lo) & ((rows + 0.5) * cfg.dy < y_hi)]
    side = rows >= cfg.Ny
    layers = np.arange(cfg.Nz)
    parts = []
    for rws, cols, kinds in ((rows[~side], col[keep], kind_col[keep]), (rows[side], col, np.full(ncol, WALL))):
        K, R, C = np.meshgrid(layers, rws, np.arange(cols.size), indexing="ij")
        p = np.empty((K.size, cfg.dim))
        p[:, 0] = x[cols[C.ravel()]]
        p[:, 1] = (R.ravel() + 0.5) * cfg.dy
        if cfg.dim == 3:
            p[:, 2] = (K.ravel() + 0.5) * cfg.dz
        parts.append((((K * rows_all + R) * ncol + cols[C]).ravel(), kinds[C.ravel()], p))
    gid = np.concatenate([q[0] for q in parts])
    kind = np.concatenate([q[1] for q in parts])
    pos = np.concatenate([q[2] for q in parts])
    order = np.argsort(gid, kind="stable")
    gid, kind, pos = gid[order], kind[order], pos[order]
    vel = np.zeros_like(pos)
    vel[kind == MOVING_WALL, 1] = right_velocity
    mass = np.full(gid.size, cfg.mass)
    return gid.astype(np.int64), kind.astype(np.int64), mass, pos, vel
