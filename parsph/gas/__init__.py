"""The solved gas (docs/physics.md, "The solved gas"): the gas pressure p' on a uniform grid, two-way
coupled to the particles. ``grid`` the cells and their boundaries, ``deposit`` the particles' volume and
velocity on the cells and the grid's fields back at the particles (one set of weights both ways), ``darcy``
the elliptic equation div(K grad p') = div V and the mixture's flux j = V - K grad p' (scipy.sparse),
``permeability`` K = 1 / R on the cells (R the particles' drag resistance) with its cap. One rank's
arithmetic: no MPI here (the sum of the deposits over ranks is :mod:`parsph.parallel.grid_sum`'s)."""
