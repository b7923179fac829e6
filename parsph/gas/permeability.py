"""The gas's permeability on the cells (Darcy's law in the frame of the solids, eps (u_g - v) = -K grad p';
docs/physics.md, "The solved gas"): K = 1 / R, R the drag resistance per unit volume the cell's particles
deposit (sum of w m C over the cell's area; :func:`parsph.gas.deposit.resistance_of`), which in a uniform
state is rho_s theta C = beta / eps^2, so K = eps^2 / beta. In clear gas R -> 0 and K -> infinity: the solve
caps K at K_max (the particles' own drag has no cap)."""
import numpy as np


def from_resistance(R, K_max):
    """K [m^2/(Pa s)] per cell from R [kg/(m^3 s)], capped at K_max (K_max where R = 0)."""
    with np.errstate(divide="ignore"):
        return np.minimum(np.where(R > 0.0, 1.0 / R, np.inf), K_max)


def of_uniform(theta, C, rho_s):
    """K of a uniform state at theta whose particles have the drag rate C [1/s]: 1 / (rho_s theta C)."""
    return 1.0 / (rho_s * theta * C)
