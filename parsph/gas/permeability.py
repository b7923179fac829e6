"""The gas's permeability on the cells, K = eps^2 / beta (Darcy's law in the frame of the solids,
eps (u_g - v) = -K grad p'; docs/physics.md, "The solved gas"), from the cell's theta and the closure of
:mod:`parsph.physics.drag` at the cell's slip. In clear gas beta -> 0 and K -> infinity: the solve caps K at
K_max (the particles' own drag has no cap). theta is held below :data:`THETA_CAP` (a cell packed past it
would have eps^2 -> 0 and K -> 0, a wall no gas crosses, and the harmonic face mean of two such cells 0/0)."""
import numpy as np
from numba import njit

from parsph.physics.drag import beta

THETA_CAP = 0.95


@njit(cache=True, error_model="numpy")
def _fill(theta, slip, model, rho_g, mu_g, d, K_max, out):
    for c in range(theta.size):
        th = min(max(theta.flat[c], 0.0), THETA_CAP)
        e = 1.0 - th
        b = beta(model, th, slip.flat[c], rho_g, mu_g, d)
        K = e * e / b if b > 0.0 else K_max
        out.flat[c] = min(K, K_max)


def permeability(theta, slip, model, rho_g, mu_g, d, K_max):
    """K [m^2/(Pa s)] per cell for theta and slip |u_g - v| [m/s] (arrays of one shape), capped at K_max."""
    theta = np.ascontiguousarray(theta, float)
    slip = np.ascontiguousarray(np.broadcast_to(slip, theta.shape), float)
    out = np.empty_like(theta)
    _fill(theta, slip, model, rho_g, mu_g, d, K_max, out)
    return out
