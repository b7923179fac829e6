"""The solved gas's grid: uniform cells over the box, aligned with the slabs (docs/physics.md, "The solved
gas"). Cell centres at x = (i + 1/2) hx, y = (j + 1/2) hy (and z = (k + 1/2) hz in 3-D); x spans the plates
(0 .. L) where the scene has walls, else the period; y spans the side walls (0 .. Ly) where there are some,
else the period; z (3-D) its period Lz.

The loops see every grid as three-dimensional: a 2-D grid is nz = 1 cell of depth hz = 1 m (the unit depth a
2-D cell's "volume" is per), with no faces across z."""
from dataclasses import dataclass
import math

import numpy as np


@dataclass(frozen=True)
class Grid:
    nx: int
    ny: int
    hx: float        # cell size along x [m]
    hy: float        # cell size along y [m]
    walls: bool      # x bounded by the plates at 0 and L (else periodic)
    sides: bool = False  # y bounded by side walls at 0 and Ly (else periodic)
    nz: int = 1      # cells along the periodic z (3-D; 1 in 2-D)
    hz: float = 1.0  # their size [m] (2-D: the unit depth)

    @property
    def dim(self):
        return 3 if self.nz > 1 else 2

    @property
    def shape(self):
        """The fields' shape: (nx, ny), or (nx, ny, nz) in 3-D."""
        return (self.nx, self.ny) + ((self.nz,) if self.dim == 3 else ())

    @property
    def shape3(self):
        """The shape the loops see: (nx, ny, nz), nz = 1 in 2-D."""
        return (self.nx, self.ny, self.nz)

    @property
    def cells(self):
        return self.nx * self.ny * self.nz

    @property
    def area(self):
        """A cell's volume [m^3] (2-D: its area, the volume per unit depth)."""
        return self.hx * self.hy * self.hz

    @property
    def cell(self):
        """The cell's sizes per dimension [m]."""
        return [self.hx, self.hy] + ([self.hz] if self.dim == 3 else [])

    def x_centres(self):
        return [(i + 0.5) * self.hx for i in range(self.nx)]


def cells_along(length, cell):
    """The number of cells of size about ``cell`` that tile ``length`` exactly (at least 2)."""
    return max(2, int(math.floor(length / cell + 0.5)))


def grid_of(L, Ly, cell, walls, sides=False, Lz=0.0):
    """The grid of a box L x Ly (x Lz in 3-D, ``Lz`` > 0) with cells of about ``cell`` [m] (their sizes
    adjusted to tile it; 3 or more along a periodic axis)."""
    nx, ny = cells_along(L, cell), cells_along(Ly, cell)
    if not walls:
        nx = max(3, nx)
    if not sides:
        ny = max(3, ny)
    if Lz > 0.0:
        nz = max(3, cells_along(Lz, cell))
        return Grid(nx, ny, L / nx, Ly / ny, bool(walls), bool(sides), nz, Lz / nz)
    return Grid(nx, ny, L / nx, Ly / ny, bool(walls), bool(sides))


def floor_drop(p):
    """The pressure drop across a bed on the floor [Pa]: p' (nx, ny[, nz]) at the floor, extrapolated from the
    first two rows of cells and averaged across (the open top holds p' = 0)."""
    return float(np.mean(1.5 * p[0] - 0.5 * p[1]))
