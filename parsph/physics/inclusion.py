"""Reference 6 (docs/physics.md, "The solved gas"): Darcy flow past a circular inclusion, the gas through
Davidson's bubble in 2-D. Permeability K outside, kappa K inside a circle of radius a at the origin, a
superficial velocity U along +x far away. p' solves div(K grad p') = 0 with p' and the normal flux
continuous at r = a:

    outside  p' = -(U / K) (r + c a^2 / r) cos(phi),   c = (1 - kappa) / (1 + kappa)
    inside   p' = -(U / K) 2 / (1 + kappa) r cos(phi)

so the flux inside is uniform, 2 kappa U / (1 + kappa) along x (2 U as kappa -> infinity: the gas
short-circuits through a void; Davidson's 4 U a per unit depth through a bubble at U = U_mf)."""
import numpy as np


def pressure(x, y, a, kappa, K=1.0, U=1.0):
    """p' [Pa] at (x, y) (arrays)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    r2 = x * x + y * y
    c = (1.0 - kappa) / (1.0 + kappa)
    with np.errstate(divide="ignore", invalid="ignore"):
        outside = -(U / K) * x * (1.0 + c * a * a / r2)
    inside = -(U / K) * 2.0 / (1.0 + kappa) * x
    return np.where(r2 >= a * a, outside, inside)


def inside_flux(kappa, U=1.0):
    """The uniform flux through the inclusion along x [m/s]: 2 kappa U / (1 + kappa)."""
    return 2.0 * kappa * U / (1.0 + kappa)
