"""What the layer scenes share (``sedimentation``, ``fluidized_bed``): a layer of solids on the floor x = 0
under clear gas, a lid at x = L, gravity along -x, y (and z) periodic.

The fluid fills the lattice up to ``scene.height`` = H0 (the columns with x < H0); above it there are no
particles up to the lid. The top is a free surface: Eq. (3) sums over the particles there are, so the top
rows' theta falls toward theta0 / 2 over 2h (the kernel's missing half), and Eq. (5) needs nothing more
there: the pressure term's G((theta_i + theta_j)/2) is the smallest where theta is, the 1/theta factors are
at most 1/theta of a particle alone (its own m W(0) / rho_s, 0.29 theta0 at h = 1.25 dx), and gravity holds
the layer down (tests/test_layers_scenes.py: a layer at rest keeps its mass below a height and its top
within a few h of the hydrostatic profile's).

The floor's ghost walls hold the layer's end state continued below the floor (its theta at the floor):
theta and mass both, so that a fluid particle on the floor finds the end state's density in Eq. (3) and its
pressure in Eq. (5). With the mass of theta0, a sediment packed 2-5x denser than theta0 would see a floor
of half its density and be squeezed into it (the settling scene's note on held walls). The lid's walls hold
theta0 and never meet the layer in a run that fits under the lid.

The references are docs/physics.md's 3 and 4 (:mod:`parsph.physics.gas_references`: the end state, Kynch's
solution) and the whole transient between them (:mod:`parsph.physics.consolidation`), built once per run's
values (cached).
"""
from functools import lru_cache
import math

import numpy as np

from parsph.errors import ConfigError
from parsph.physics import consolidation, gas_references as refs
from parsph.sph.particles import FLUID
from . import lattice


def height(cfg):
    """H0 [m]: ``scene.height``, default L / 2."""
    h = cfg.get("scene.height")
    return 0.5 * cfg.L if h is None else h


def fluid_columns(cfg):
    """Lattice columns the layer fills: round(H0 / dx), at least 1."""
    return max(1, int(round(height(cfg) / cfg.dx)))


def layer_height(cfg):
    """The layer's initial height on the lattice [m] (its mass is rho_s theta0 times it)."""
    return fluid_columns(cfg) * cfg.dx


def weight(cfg):
    """|g| with buoyancy (1 - rho_g / rho_s) |g| [m/s^2], along -x."""
    return abs(cfg.g[0]) * (1.0 - (cfg.gas.rho / cfg.rho_s if cfg.gas is not None else 0.0))


def phases(cfg):
    """The run's solids and gas as the references take them (no gas: rho_g = 0, the drag unused)."""
    gas = cfg.gas
    if gas is None:
        return refs.Phases(cfg.rho_s, 0.0, 1.8e-5, cfg.get("material.d"), abs(cfg.g[0]), "stokes")
    return refs.Phases(cfg.rho_s, gas.rho, gas.mu, gas.d, abs(cfg.g[0]), gas.closure)


def form(cfg):
    return "paper" if cfg.get("numerics.pressure_form") == "paper" else "consistent"


@lru_cache(maxsize=16)
def _column(ph, mass, U, G_a, G_b, form):
    return refs.steady_column(mass, U, ph, G_a, G_b, form)


@lru_cache(maxsize=16)
def _sedimentation(ph, theta0, H0, G_a, G_b, form):
    return refs.batch_sedimentation(theta0, H0, ph, G_a, G_b, form)


def mass(cfg):
    """The layer's mass per unit floor area [kg/m^2]."""
    return cfg.rho_s * cfg.theta0 * layer_height(cfg)


def end_state(cfg):
    """The layer's steady state (refs.Column): the hydrostatic sediment (U = 0, or no gas), else the steady
    column at U with the layer's mass."""
    U = cfg.gas.U if cfg.gas is not None else 0.0
    return _column(phases(cfg), mass(cfg), U, cfg.G_a, cfg.G_b, form(cfg))


def sedimentation(cfg):
    """Kynch's solution for the layer (refs.Sedimentation)."""
    return _sedimentation(phases(cfg), cfg.theta0, layer_height(cfg), cfg.G_a, cfg.G_b, form(cfg))


@lru_cache(maxsize=8)
def _transient(ph, theta0, H0, L, U, G_a, G_b, form, times):
    return consolidation.solve(theta0, H0, ph, times, L, U, G_a, G_b, form)


def transient(cfg, times):
    """The layer's whole transient in the column closure with inertia dropped (consolidation.Transient: the
    sedimentation-consolidation equation from the layer at rest, theta0 up to H0, to the lid) at ``times``
    [s] (> 0); None without a gas (the layer then falls under gravity alone: no such reference). It applies to
    ``gas.flow = "solved"`` too, the grid's gas reducing to the column closure in a layer uniform across."""
    if cfg.gas is None:
        return None
    return _transient(phases(cfg), cfg.theta0, layer_height(cfg), cfg.L, cfg.gas.U, cfg.G_a, cfg.G_b, form(cfg),
                      tuple(sorted(set(float(t) for t in times))))


def particles(cfg, y_lo, y_hi):
    gid, kind, m, pos, vel = lattice(cfg, y_lo, y_hi, fluid_columns=fluid_columns(cfg))
    floor = (kind != FLUID) & (pos[:, 0] < 0.0)
    m[floor] *= end_state(cfg).theta_floor / cfg.theta0
    return gid, kind, m, pos, vel


def wall_theta(cfg, x):
    """Floor walls (x < 0): the end state's theta at the floor; the lid's: theta0."""
    x = np.asarray(x, dtype=float)
    return np.where(x < 0.0, end_state(cfg).theta_floor, cfg.theta0)


def check(cfg, scene):
    """Gravity along -x only; H0 inside the box, below the lid by the kernel's reach; the end state exists."""
    g = cfg.g
    if not (g[0] < 0.0 and not any(g[1:])):
        raise ConfigError("body_force.g", f"the {scene} scene needs gravity along -x only (toward the floor), "
                          f"got {list(g)}")
    H0 = height(cfg)
    if not H0 + 2.0 * cfg.h <= cfg.L:
        raise ConfigError("scene.height", f"{H0:g} m leaves less than 2h = {2 * cfg.h:g} m below the lid at "
                          f"domain.L = {cfg.L:g} m")
    if H0 < 0.5 * cfg.dx:
        raise ConfigError("scene.height", f"{H0:g} m is less than half a lattice step dx = {cfg.dx:g} m")
    try:
        end = end_state(cfg)
    except (ValueError, RuntimeError) as e:
        raise ConfigError("scene.height", f"the layer has no steady state: {e}") from None
    if not math.isfinite(end.theta_floor):
        raise ConfigError("scene.height", "the layer's steady state is not finite")
    return end


def max_kinetic_energy(cfg, fluid_mass):
    """At most all the potential energy: every particle falling from the lid to the floor."""
    return fluid_mass * abs(cfg.g[0]) * cfg.L
