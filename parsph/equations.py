"""The SPH equations of the paper as numba loops over flat arrays.

- Eq. (3): summation density ``rho_bar_i = sum_j m_j W_ij`` (fluid and wall j),
  ``theta_i = rho_bar_i / rho_s``.
- Eq. (5): momentum, for fluid particle i:

      dv_i/dt = - (1/rho_s^2) sum_j m_j G((theta_i+theta_j)/2) (1/theta_i + 1/theta_j) (r_ij/r_ij) dW/dr
                + mu_i sum_j m_j v_ij (theta_i+theta_j)/(rho_bar_i rho_bar_j) (1/r_ij) dW/dr
                + g,      mu_i = k theta_i,

  (``consistent``: the pressure term replaced by the symmetric SPH gradient
  sum_j m_j (p_i/rho_bar_i^2 + p_j/rho_bar_j^2) dW/dr r_ij/r_ij of
  p = G / (G_a ln 10), whose gradient is G grad theta as the closure says;
  the paper's form converges to grad(G theta) instead;
  ``symmetric_mu``: mu_i replaced by the pair mean k (theta_i + theta_j)/2,
  which is the same in a uniform state but makes the viscous force of a pair
  antisymmetric, so that momentum is conserved exactly),

  with wall particles j (Morris et al. 1997) seen through
  ``v_ij = beta (v_i - v_j)``, ``beta = min(beta_max, 1 + d_j/d_i)``, d the
  distance to the wall's plate (x = 0 or x = L).

The loops work on copies of the particle fields in cell order (see
:mod:`parsph.neighbours`), positions and velocities as separate x, y, z
arrays (z = 0 in 2-D, so one code path serves both), and write their results
straight back to the particle arrays through ``order``. The density pass
finds each fluid particle's neighbours row by row: for every row of cells
(along x) within 2h of it, the cells of that row that meet its disc of
radius 2h are consecutive in cell order, so their particles are one
contiguous run of candidates, visited in a fixed order and by gid inside a
cell. Candidates within 2h get W and (dW/dr)/r from a branch-free kernel
function; the density pass stores them in a neighbour list of fixed width
per particle that the momentum pass walks in the same order. Every sum is
thus taken in an order that does not depend on the decomposition, and each
particle's sum is independent of the others': the loops run over particles
with ``prange`` (threads inside a rank, ``--threads``), with the same result
bit for bit on any thread count. Wall particles hold their density (set by
the solver). These functions know nothing of MPI: halo copies are ordinary
neighbours.

The switches (pressure, viscosity, symmetric viscosity, walls, consistent
pressure, three dimensions) are compile-time constants made by
:func:`switch`: an empty tuple is off, ``(1,)`` is on, so each value is its own type, numba compiles one version
per combination a scene uses, ``len(switch)`` is a constant, and a term
switched off leaves no branch in the pair loop. (``numba.literally`` does the
same but costs tens of milliseconds per call.)
"""
import math

from numba import njit, prange

from .kernels import kernel_w_f
from .particles import FLUID

ON, OFF = (1,), ()


def switch(flag):
    """A compile-time switch for the loops below."""
    return ON if flag else OFF


@njit(cache=True, inline="always")
def _cell_range(lo_edge, width, cs, origin, ncells):
    """Cells (clamped to 0..ncells-1) that meet [lo_edge, lo_edge + width) on a grid of side cs."""
    first = max(int(math.floor(lo_edge / cs)) - origin, 0)
    last = min(int(math.floor((lo_edge + width) / cs)) - origin, ncells - 1)
    return first, last


@njit(cache=True, parallel=True)
def density(n, sx, sy, sz, sm, skind, owned, order, cell_of, start, ncx, ncy, ncz, lox, loy, loz, x0, cs,
            h, norm, kid, rho_s, G_a, G_b, pressure, consistent, three_d, rho, stheta, sinv, spress,
            nbr_n, nbr_j, nbr_f):
    """Eq. (3) for the owned fluid particles among sorted places 0..n-1 into ``rho[order[i]]``; walls hold theirs.

    Candidates: for each row of cells (along x) within 2h of particle i, the
    run of cells that meets the disc of radius 2h on that row, as one
    contiguous range of sorted places (the cell grid of
    :func:`parsph.neighbours.sort_into_cells`). Also fills the neighbour
    list: fluid particle i's neighbours are ``nbr_j[i, :nbr_n[i]]`` with
    ``nbr_f = (dW/dr)/r``, and the owned particles' factors of Eq. (5)
    (:func:`rho_factors`). Returns the largest neighbour count; if it exceeds
    the list width the list is incomplete and the call must be repeated with
    wider arrays.
    """
    inv_h = 1.0 / h
    support = 2.0 * h
    support2 = support * support
    pad = 1e-9 * h  # rounding of the cell edges: never miss a neighbour at r just below 2h
    width = nbr_j.shape[1]
    last = width - 1
    for i in prange(n):
        cnt = 0
        if owned[i] and skind[i] != FLUID:
            rho_factors(i, rho[order[i]], rho_s, G_a, G_b, pressure, consistent, stheta, sinv, spress)
        elif owned[i]:
            s = 0.0
            xi = sx[i]
            yi = sy[i]
            zi = sz[i]
            cy_lo, cy_hi = _cell_range(yi - support - pad, 2.0 * (support + pad), cs, loy, ncy)
            cz_lo, cz_hi = 0, 0
            if len(three_d):
                cz_lo, cz_hi = _cell_range(zi - support - pad, 2.0 * (support + pad), cs, loz, ncz)
            for cz in range(cz_lo, cz_hi + 1):
                gz = 0.0  # distance from particle i to the layer of cells cz
                if len(three_d):
                    gz = max((cz + loz) * cs - zi, zi - (cz + loz + 1) * cs, 0.0)
                for cy in range(cy_lo, cy_hi + 1):
                    gy = max((cy + loy) * cs - yi, yi - (cy + loy + 1) * cs, 0.0)
                    reach2 = support2 - gy * gy - gz * gz
                    if reach2 <= 0.0:
                        continue
                    half = math.sqrt(reach2) + pad
                    cx_lo, cx_hi = _cell_range(xi - x0 - half, 2.0 * half, cs, lox, ncx)
                    row = (cz * ncy + cy) * ncx
                    for j in range(start[row + cx_lo], start[row + cx_hi + 1]):
                        dx = xi - sx[j]
                        dy = yi - sy[j]
                        r2 = dx * dx + dy * dy
                        if len(three_d):
                            dz = zi - sz[j]
                            r2 += dz * dz
                        if r2 < support2:
                            r = math.sqrt(r2)
                            w, f = kernel_w_f(kid, r, inv_h, norm)
                            s += sm[j] * w
                            k = min(cnt, last)
                            nbr_j[i, k] = j
                            nbr_f[i, k] = f
                            cnt += 1 if j != i else 0
            rho[order[i]] = s
            rho_factors(i, s, rho_s, G_a, G_b, pressure, consistent, stheta, sinv, spress)
        nbr_n[i] = cnt
    return nbr_n[:n].max() if n > 0 else 0


@njit(cache=True, inline="always")
def pressure_factor(th, rho_i, G_a, G_b, consistent):
    """The per-particle factor of the pressure term at theta = rho_bar / rho_s.

    10^(G_a theta / 2) for the paper's form (G at the pair mean is
    10^G_b press_i press_j) and p(theta) / rho_bar^2 for the consistent form,
    with p = G(theta) / (G_a ln 10) so that grad p = G grad theta exactly.
    """
    if len(consistent):
        return 10.0 ** (G_a * th + G_b) / (G_a * math.log(10.0)) / (rho_i * rho_i)
    return 10.0 ** (0.5 * G_a * th)


@njit(cache=True, inline="always")
def rho_factors(k, rho_k, rho_s, G_a, G_b, pressure, consistent, stheta, sinv, spress):
    """Per-particle factors of Eq. (5) at sorted place k: theta = rho_bar / rho_s, 1/rho_bar, 1/theta, pressure."""
    th = rho_k / rho_s
    stheta[k] = th
    sinv[k, 0] = 1.0 / rho_k
    sinv[k, 1] = 1.0 / th
    if len(pressure):
        spress[k] = pressure_factor(th, rho_k, G_a, G_b, consistent)


@njit(cache=True, parallel=True)
def momentum(n, sx, sy, sz, svx, svy, svz, sm, skind, owned, order, rho, stheta, sinv, spress,
             nbr_n, nbr_j, nbr_f, rho_s, G_a, G_b, k_visc, L, beta_max, g,
             pressure, viscosity, symmetric_mu, walls, consistent, three_d, acc, theta):
    """Eq. (5): acceleration of each owned fluid particle into ``acc[order[i]]`` (walls: zero).

    The owned particles' factors (:func:`rho_factors`) come from the density
    pass; those of the halo copies are made here from ``rho`` (their
    refreshed densities), in a serial loop: one threaded region per pass.
    Writes theta back for the owned particles.
    """
    G_pref = 10.0 ** G_b
    c_press = -G_pref / (rho_s * rho_s)
    for k in range(n):
        if not owned[k]:
            rho_factors(k, rho[order[k]], rho_s, G_a, G_b, pressure, consistent, stheta, sinv, spress)
    for i in prange(n):
        if owned[i]:
            o = order[i]
            theta[o] = stheta[i]
            ax = 0.0
            ay = 0.0
            az = 0.0
            if skind[i] == FLUID:
                th_i = stheta[i]
                inv_th_i = sinv[i, 1]
                mu_i = k_visc * th_i
                inv_rho_i = sinv[i, 0]
                pr_i = spress[i]
                cp_i = c_press * pr_i
                xi = sx[i]
                yi = sy[i]
                zi = sz[i]
                vxi = svx[i]
                vyi = svy[i]
                vzi = svz[i]
                for p in range(nbr_n[i]):
                    j = nbr_j[i, p]
                    f_over_r = nbr_f[i, p]
                    m_j = sm[j]
                    if len(pressure):
                        if len(consistent):
                            cp = -m_j * (pr_i + spress[j]) * f_over_r
                        else:
                            cp = m_j * cp_i * spress[j] * (inv_th_i + sinv[j, 1]) * f_over_r
                        ax += cp * (xi - sx[j])
                        ay += cp * (yi - sy[j])
                        if len(three_d):
                            az += cp * (zi - sz[j])
                    if len(viscosity):
                        beta = 1.0
                        if len(walls) and skind[j] != FLUID:
                            if sx[j] < 0.0:
                                d_j = -sx[j]
                                d_i = xi
                            else:
                                d_j = sx[j] - L
                                d_i = L - xi
                            beta = beta_max
                            if d_i > 0.0:
                                beta = min(beta_max, 1.0 + d_j / d_i)
                        mu = 0.5 * k_visc * (th_i + stheta[j]) if len(symmetric_mu) else mu_i
                        cv = mu * m_j * (th_i + stheta[j]) * inv_rho_i * sinv[j, 0] * f_over_r * beta
                        ax += cv * (vxi - svx[j])
                        ay += cv * (vyi - svy[j])
                        if len(three_d):
                            az += cv * (vzi - svz[j])
                ax += g[0]
                ay += g[1]
                az += g[2]
            acc[o, 0] = ax
            acc[o, 1] = ay
            if len(three_d):
                acc[o, 2] = az
