"""The data the passes of :mod:`parsph.sph.density` and :mod:`parsph.sph.momentum` take, as named groups that numba compiles like its other
arguments: the neighbour list and the arrays indexed like it (:class:`PairList`), the particles' fields
(:class:`ParticleArrays`), the run's numbers (:class:`Constants`), the terms a scene uses
(:class:`Switches`) and the threaded passes' scratch (:class:`Gather`). A field added to a group reaches
every pass through the group.

The switches are compile-time constants made by :func:`switch`: an empty
tuple is off, ``(1,)`` is on, so each value is its own type, numba compiles
one version per combination a scene uses, and a term switched off leaves no
branch in the pair loop.
"""
from typing import NamedTuple

import numpy as np

ON, OFF = (1,), ()
# columns of the per-particle row the pair loops read (``PairList.fields``)
VX, VY, VZ, THETA, INV_RHO, INV_THETA, PRESS = 0, 1, 2, 3, 4, 5, 6
# the gas's flow (GasConstants.flow): a given stream, a column's closure, the solved gas's flux per particle;
# TOWARD_FLUX: body_force.drag_rates at the slip toward a given flux per particle (what the solved gas's stage
# deposits; in the solved flow the passes read those rates, ParticleArrays.drag_rate, and compute none)
STREAM, COLUMN, SOLVED, TOWARD_FLUX = 0, 1, 2, 3
FLOWS = {"stream": STREAM, "column": COLUMN, "solved": SOLVED}


def switch(flag):
    """A compile-time switch for the loops below."""
    return ON if flag else OFF


class Switches(NamedTuple):
    """The terms of Eq. (5) a scene uses and its dimension, each :data:`ON` or :data:`OFF`."""
    pressure: tuple
    viscosity: tuple
    symmetric_mu: tuple  # mu of a pair: k (theta_i + theta_j) / 2 instead of k theta_i
    walls: tuple         # plates bound the box: wall particles get beta (Morris et al. 1997)
    consistent: tuple    # pressure as the symmetric SPH gradient of p = G / (G_a ln 10)
    three_d: tuple
    uniform_mass: tuple  # every particle of the run has the mass Constants.mass: the serial passes load none
    drag: tuple          # the solids are in a gas (Constants.gas): drag per particle, gravity with buoyancy
    mirror: tuple        # the walls continue the fluid's state (parsph.sph.walls; free-surface scenes)
    packing: tuple       # the consistent form's p has the packing limit's p_f (Constants.theta_min, theta_max)


class GasConstants(NamedTuple):
    """The gas of a run with drag (gas_config.Gas) as the loops take it (zeros where there is none)."""
    model: int        # parsph.physics.drag.MODELS
    rho: float        # [kg/m^3]
    mu: float         # [Pa s]
    d: float          # grain diameter [m]
    flow: int         # STREAM, COLUMN (the gas velocity follows from U) or SOLVED (from ParticleArrays.flux)
    axis: int         # column: the axis of gravity
    sign: float       # column: e = sign * unit(axis), opposite to gravity
    U: float          # column: superficial velocity [m/s]
    u: np.ndarray     # stream: the gas velocity, 3 components [m/s]


class Constants(NamedTuple):
    """The numbers of a run the passes use: the kernel's and Eq. (5)'s."""
    kid: int           # kernel id (kernels.kernel_w_f)
    inv_h: float
    norm: float        # the kernel's normalisation at h
    w0: float          # W(0), a particle's own term in Eq. (3)
    rho_s: float
    G_a: float
    G_b: float
    k_visc: float      # mu_s = k theta
    L: float           # distance of the plates (beta)
    beta_max: float
    g: np.ndarray      # body force, 3 components (with a gas: (1 - rho_g / rho_s) g, buoyancy included)
    mass: float        # every particle's mass where Switches.uniform_mass is on (else unused)
    gas: GasConstants  # the gas where Switches.drag is on (else zeros)
    wall_volume: float  # the volume a wall particle stands for where Switches.mirror is on (one lattice site)
    theta_min: float    # the packing limit's frictional pressure where Switches.packing is on
    theta_max: float    # (closures.packing_pressure), else 0
    side: float         # with side walls (walls.sides): their distance Ly [m], else 0
    ring: float         # the period along y [m] (Ly, and with side walls their rows beyond it)


class PairList(NamedTuple):
    """The neighbour list of one build (:mod:`parsph.sph.cells`) and the arrays indexed like it."""
    order: np.ndarray    # order[a]: the particle at sorted place a
    pstart: np.ndarray   # the pairs of place a (with later places): pstart[a] .. pstart[a+1]-1
    pi: np.ndarray       # the pairs' members
    pj: np.ndarray
    need: np.ndarray     # the particles that receive sums: the owned fluid
    n: int               # local particles (owned, ghosts, images) at the build
    npairs: int
    fp: np.ndarray       # (dW/dr)/r per pair: the threaded density pass writes it, the threaded momentum pass reads it
    rho_sum: np.ndarray  # Eq. (3) per particle
    fields: np.ndarray   # per particle the row a pair reads: columns VX .. PRESS
    cstart: np.ndarray   # the pairs within 2h of place a: cstart[a] .. cstart[a+1]-1 of cj, cf (density_serial)
    cj: np.ndarray       # their second members, in pair order
    cf: np.ndarray       # their (dW/dr)/r
    wall_pairs: np.ndarray  # Switches.mirror: the pairs of a wall and a fluid particle (indices p), else empty
    wall_share: np.ndarray  # Switches.mirror: per particle, the share of its kernel in the wall (walls.renormalise)


class Gather(NamedTuple):
    """The threaded passes' scratch: each particle's pairs in pair order and the values per pair."""
    offset: np.ndarray  # the entries of particle k: offset[k] .. offset[k+1]-1
    entry: np.ndarray   # 2 p + side (side 1: the particle is pj[p]); cells.build_entries
    wp: np.ndarray      # W per pair
    Pp: np.ndarray      # pressure factor P per pair
    Vp: np.ndarray      # viscous factor V per pair


class ParticleArrays(NamedTuple):
    """The fields of a :class:`parsph.sph.particles.Particles` set the passes read and write."""
    pos: np.ndarray
    vel: np.ndarray
    mass: np.ndarray
    kind: np.ndarray
    rho: np.ndarray
    theta: np.ndarray
    acc: np.ndarray
    n_own: int
    drag_coef: np.ndarray  # with drag: per owned particle and component the coefficient C of its drag
                           # acceleration C (w - v) (1/tau; the implicit update divides by 1 + dt C); else (0, dim)
    drag_rate: np.ndarray  # with drag: per owned particle the closure's K = beta / (rho_s theta eps) (the drag
                           # loops' contiguous scratch, body_force.drag_rates); else (0,)
    flux: np.ndarray   # the solved gas: per owned particle the mixture's flux j from the grid [m/s]; else (0, dim)


def particle_arrays(ps):
    """The passes' view of a Particles set (its arrays, not copies); ``drag_coef``, ``drag_rate`` (and ``flux``) are
    the set's fields of those names where the run has a gas (the solved gas) (:meth:`parsph.sph.particles.Particles.add_field`), else
    empty arrays."""
    drag = getattr(ps, "drag_coef", None)
    drag_rate = getattr(ps, "drag_rate", None)
    if drag is None:
        drag, drag_rate = np.zeros((0, ps.dim)), np.zeros(0)
    flux = getattr(ps, "flux", None)
    if flux is None:
        flux = np.zeros((0, ps.dim))
    return ParticleArrays(ps.pos, ps.vel, ps.mass, ps.kind, ps.rho, ps.theta, ps.acc, ps.n_own, drag, drag_rate,
                          flux)
