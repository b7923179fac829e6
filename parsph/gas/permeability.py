"""The gas's permeability on the cells (Darcy's law in the frame of the solids, eps (u_g - v) = -K grad p';
docs/physics.md, "The solved gas"): K = 1 / R, R the drag resistance per unit volume the cell's particles
deposit (sum of w m C over the cell's area; :func:`parsph.gas.deposit.cells_of`), which in a uniform
state is rho_s theta C = beta / eps^2, so K = eps^2 / beta. In clear gas R -> 0 and K -> infinity: the solve
caps K at K_max (the particles' own drag has no cap)."""
import numpy as np
from numba import njit


def from_resistance(R, K_max):
    """K [m^2/(Pa s)] per cell from R [kg/(m^3 s)], capped at K_max (K_max where R = 0)."""
    R = np.ascontiguousarray(R, float)
    K = np.empty_like(R)
    _capped_inverse(R.reshape(-1), K_max, K.reshape(-1))
    return K


@njit(cache=True, error_model="numpy")
def _capped_inverse(R, K_max, K):
    """K = min(1 / R, K_max), K_max where R = 0: one pass, no temporaries (numpy's np.where took 3)."""
    for k in range(len(R)):
        K[k] = min(1.0 / R[k], K_max) if R[k] > 0.0 else K_max


def of_uniform(theta, C, rho_s):
    """K of a uniform state at theta whose particles have the drag rate C [1/s]: 1 / (rho_s theta C)."""
    return 1.0 / (rho_s * theta * C)
