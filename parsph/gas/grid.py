"""The solved gas's grid: uniform cells over the box, aligned with the slabs (docs/physics.md, "The solved
gas"). Cell centres at x = (i + 1/2) hx, y = (j + 1/2) hy; x spans the plates (0 .. L) where the scene has
walls, else the period; y spans the side walls (0 .. Ly) where there are some, else the period."""
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

    @property
    def shape(self):
        return (self.nx, self.ny)

    @property
    def cells(self):
        return self.nx * self.ny

    @property
    def area(self):
        """A cell's area [m^2] (2-D: volume per unit depth)."""
        return self.hx * self.hy

    def x_centres(self):
        return [(i + 0.5) * self.hx for i in range(self.nx)]


def cells_along(length, cell):
    """The number of cells of size about ``cell`` that tile ``length`` exactly (at least 2)."""
    return max(2, int(math.floor(length / cell + 0.5)))


def grid_of(L, Ly, cell, walls, sides=False):
    """The grid of a box L x Ly with cells of about ``cell`` [m] (their sizes adjusted to tile it; 3 or more
    along a periodic axis)."""
    nx, ny = cells_along(L, cell), cells_along(Ly, cell)
    if not walls:
        nx = max(3, nx)
    if not sides:
        ny = max(3, ny)
    return Grid(nx, ny, L / nx, Ly / ny, bool(walls), bool(sides))


def floor_drop(p):
    """The pressure drop across a bed on the floor [Pa]: p' (nx, ny) at the floor, extrapolated from the first
    two rows of cells and averaged across (the open top holds p' = 0)."""
    return float(np.mean(1.5 * p[0] - 0.5 * p[1]))
