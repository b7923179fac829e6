"""Eq. (5) for one pair (i, j), scalars in and out: the one copy of the pair arithmetic that every momentum
loop inlines (the serial and threaded passes of :mod:`.momentum`, their scalar references in
:mod:`.reference_passes`, the benchmarks' ceiling loops).

With f = (dW/dr)/r of the pair and the per-particle factors of :func:`parsph.sph.momentum.pressure_factor`
(``pr``: 10^(G_a theta / 2) for the paper's form, G / (G_a ln 10) / rho^2 for the consistent one), 1/theta,
theta and 1/rho_bar, particle i gets m_j (P r_ij + mu beta V v_ij) from j:

    P = -(10^G_b / rho_s^2) pr_i pr_j (1/theta_i + 1/theta_j) f     (paper: G at the pair mean, Eq. (5))
    P = -(pr_i + pr_j) f                                           (consistent: p = G / (G_a ln 10))
    V = (theta_i + theta_j) / (rho_bar_i rho_bar_j) f               (Morris et al. 1997)
    mu = k theta_i (the paper), or k (theta_i + theta_j) / 2 (numerics.viscosity_form = "symmetric"),
    beta = min(beta_max, 1 + d_wall / d_fluid) where j is a wall particle (docs/physics.md, "Walls").

Scalars only: a helper that takes the particle arrays makes numba count references to them at every call
and keeps LLVM from hoisting the loads (the 7x of momentum.particle_factors_serial's note); inlined with
scalars the loops compile to the same code as written out, bit for bit.
"""
from numba import njit


@njit(cache=True, inline="always")
def pressure_term(pr_i, pr_j, inv_theta_i, inv_theta_j, f, c_press, consistent):
    """P of the pair (``c_press`` = -10^G_b / rho_s^2; ``consistent`` the switch of the pressure form)."""
    if len(consistent):
        return -(pr_i + pr_j) * f
    return c_press * pr_i * pr_j * (inv_theta_i + inv_theta_j) * f


@njit(cache=True, inline="always")
def viscous_term(theta_i, theta_j, inv_rho_i, inv_rho_j, f):
    """V of the pair: (theta_i + theta_j) / (rho_bar_i rho_bar_j) (dW/dr)/r."""
    return (theta_i + theta_j) * inv_rho_i * inv_rho_j * f


@njit(cache=True, inline="always")
def viscosity_coefficient(theta_own, theta_i, theta_j, k_visc, symmetric_mu):
    """mu / 1 of the particle that receives the term: k theta_own, or the pair mean with ``symmetric_mu``."""
    return 0.5 * k_visc * (theta_i + theta_j) if len(symmetric_mu) else k_visc * theta_own


@njit(cache=True, inline="always")
def wall_factor(xk, xo, L, beta_max):
    """The no-slip factor beta = min(beta_max, 1 + d_o/d_k) of fluid particle k seen by wall particle o."""
    if xo < 0.0:
        d_o = -xo
        d_k = xk
    else:
        d_o = xo - L
        d_k = L - xk
    if d_k > 0.0:
        return min(beta_max, 1.0 + d_o / d_k)
    return beta_max
