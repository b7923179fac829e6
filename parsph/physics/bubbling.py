"""Reference 8 (docs/physics.md, "The solved gas"): a bubbling bed of grains in air above minimum fluidisation.
Its time-averaged pressure drop is its buoyant weight per unit area (:func:`parsph.setup.scenes.layer.numbers`'
``dp_bed``); a single bubble of equivalent diameter D rises at about :func:`rise_velocity` in 2-D (Davidson &
Harrison 1963: a loose check, the constant is an experiment's), and the gas through a bubble of radius r_b in a
bed at U_mf is :func:`throughflow` per unit depth (reference 6, :mod:`.inclusion`, with kappa -> infinity)."""
import math

RISE_CONSTANT_2D = 0.5  # u_b = 0.5 sqrt(g D) for a 2-D (cylindrical) bubble


def rise_velocity(D, g):
    """u_b = 0.5 sqrt(g D) [m/s]: a bubble of equivalent diameter D [m] under gravity |g| [m/s^2], in 2-D."""
    return RISE_CONSTANT_2D * math.sqrt(abs(g) * D)


def throughflow(U_mf, r_b):
    """Davidson's 4 U_mf r_b [m^2/s]: the gas through a 2-D bubble of radius r_b [m] per unit depth, in a bed
    whose dense phase passes U_mf [m/s] (twice the flux far away through the bubble's diameter)."""
    return 4.0 * U_mf * r_b
