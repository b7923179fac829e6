"""Reference 8 (docs/physics.md, "The solved gas"): a bubbling bed of grains in air above minimum fluidisation.
Its time-averaged pressure drop is its buoyant weight per unit area (:func:`parsph.setup.scenes.layer.numbers`'
``dp_bed``); a single bubble of equivalent diameter D rises at about :func:`rise_velocity` (Davidson & Harrison 1963 in
2-D, Davies & Taylor 1950 in 3-D: loose checks, the constants are experiments'), and the gas through a bubble of
radius r_b in a bed at U_mf is :func:`throughflow` (per unit depth in 2-D: reference 6, :mod:`.inclusion`, with
kappa -> infinity; in 3-D the sphere's, whose inside flux is 3 kappa / (kappa + 2) U -> 3 U)."""
import math

RISE_CONSTANT = {2: 0.5, 3: 0.711}  # u_b = c sqrt(g D): a 2-D (cylindrical) bubble, a 3-D (spherical-cap) one


def rise_velocity(D, g, dim=2):
    """u_b = c sqrt(g D) [m/s]: a bubble of equivalent diameter D [m] under gravity |g| [m/s^2]; c = 0.5 in
    2-D, 0.711 in 3-D."""
    return RISE_CONSTANT[dim] * math.sqrt(abs(g) * D)


def throughflow(U_mf, r_b, dim=2):
    """The gas through a bubble of radius r_b [m] in a bed whose dense phase passes U_mf [m/s]: Davidson's
    4 U_mf r_b [m^2/s] per unit depth in 2-D (twice the flux far away through the bubble's diameter), and
    3 pi U_mf r_b^2 [m^3/s] in 3-D (three times it through the sphere's cross-section)."""
    if dim == 3:
        return 3.0 * math.pi * U_mf * r_b ** 2
    return 4.0 * U_mf * r_b
