"""The SPH equations of the paper as numba loops over flat arrays.

- Eq. (3): summation density ``rho_bar_i = sum_j m_j W_ij`` (fluid and wall j),
  ``theta_i = rho_bar_i / rho_s``.
- Eq. (5): momentum, for fluid particle i:

      dv_i/dt = - (1/rho_s^2) sum_j m_j G((theta_i+theta_j)/2) (1/theta_i + 1/theta_j) (r_ij/r_ij) dW/dr
                + mu_i sum_j m_j v_ij (theta_i+theta_j)/(rho_bar_i rho_bar_j) (1/r_ij) dW/dr
                + g,      mu_i = k theta_i,

  with wall particles j (Morris et al. 1997) seen through
  ``v_ij = beta (v_i - v_j)``, ``beta = min(beta_max, 1 + d_j/d_i)``, d the
  distance to the wall's plate (x = 0 or x = L).

Particle i visits the 3^dim cells around its own in a fixed order, and the
particles of each cell in gid order (see :mod:`parsph.neighbours`), so every
sum is taken in an order that does not depend on the decomposition. These
functions know nothing of MPI: halo copies are ordinary neighbours.
"""
import math

from numba import njit

from .particles import FLUID


@njit(cache=True, inline="always")
def _cell_index(cx, cy, cz, ncx, ncy):
    return (cz * ncy + cy) * ncx + cx


@njit(cache=True)
def density(pos, mass, kind, n_own, cell_xy, start, order, ncx, ncy, ncz,
            h, norm, kernel_w, rho_wall, rho):
    """Eq. (3) for the owned fluid particles; wall particles hold rho_wall (theta_0)."""
    dim = pos.shape[1]
    inv_h = 1.0 / h
    support2 = 4.0 * h * h
    zr = 1 if dim == 3 else 0
    for i in range(n_own):
        if kind[i] != FLUID:
            rho[i] = rho_wall
            continue
        s = 0.0
        cx0 = cell_xy[i, 0]
        cy0 = cell_xy[i, 1]
        cz0 = cell_xy[i, 2]
        for a in range(-1, 2):
            cx = cx0 + a
            if cx < 0 or cx >= ncx:
                continue
            for b in range(-1, 2):
                cy = cy0 + b
                if cy < 0 or cy >= ncy:
                    continue
                for e in range(-zr, zr + 1):
                    cz = cz0 + e
                    if cz < 0 or cz >= ncz:
                        continue
                    c = _cell_index(cx, cy, cz, ncx, ncy)
                    for k in range(start[c], start[c + 1]):
                        j = order[k]
                        r2 = 0.0
                        for d in range(dim):
                            dd = pos[i, d] - pos[j, d]
                            r2 += dd * dd
                        if r2 < support2:
                            s += mass[j] * kernel_w(math.sqrt(r2), inv_h, norm)
        rho[i] = s


@njit(cache=True)
def volume_fraction(rho, n, rho_s, G_a, theta, half_G):
    """theta = rho_bar / rho_s and the per-particle factor 10^(G_a theta / 2)."""
    for i in range(n):
        th = rho[i] / rho_s
        theta[i] = th
        half_G[i] = 10.0 ** (0.5 * G_a * th)


@njit(cache=True)
def momentum(pos, vel, mass, kind, rho, theta, half_G, n_own,
             cell_xy, start, order, ncx, ncy, ncz, h, norm, kernel_dwdr,
             rho_s, G_b, k_visc, L, beta_max, g, pressure, viscosity, acc):
    """Eq. (5): acceleration of each owned fluid particle (walls: zero)."""
    dim = pos.shape[1]
    inv_h = 1.0 / h
    support2 = 4.0 * h * h
    G_pref = 10.0 ** G_b
    inv_rho_s2 = 1.0 / (rho_s * rho_s)
    zr = 1 if dim == 3 else 0
    ai = g.copy()
    for i in range(n_own):
        for d in range(dim):
            acc[i, d] = 0.0
        if kind[i] != FLUID:
            continue
        th_i = theta[i]
        inv_th_i = 1.0 / th_i
        mu_i = k_visc * th_i
        rho_i = rho[i]
        hg_i = half_G[i]
        x_i = pos[i, 0]
        for d in range(dim):
            ai[d] = 0.0
        cx0 = cell_xy[i, 0]
        cy0 = cell_xy[i, 1]
        cz0 = cell_xy[i, 2]
        for a in range(-1, 2):
            cx = cx0 + a
            if cx < 0 or cx >= ncx:
                continue
            for b in range(-1, 2):
                cy = cy0 + b
                if cy < 0 or cy >= ncy:
                    continue
                for e in range(-zr, zr + 1):
                    cz = cz0 + e
                    if cz < 0 or cz >= ncz:
                        continue
                    c = _cell_index(cx, cy, cz, ncx, ncy)
                    for kk in range(start[c], start[c + 1]):
                        j = order[kk]
                        r2 = 0.0
                        for d in range(dim):
                            dd = pos[i, d] - pos[j, d]
                            r2 += dd * dd
                        if r2 >= support2 or r2 == 0.0:
                            continue
                        r = math.sqrt(r2)
                        f_over_r = kernel_dwdr(r, inv_h, norm) / r
                        m_j = mass[j]
                        if pressure:
                            cp = -m_j * inv_rho_s2 * G_pref * hg_i * half_G[j] \
                                * (inv_th_i + 1.0 / theta[j]) * f_over_r
                            for d in range(dim):
                                ai[d] += cp * (pos[i, d] - pos[j, d])
                        if viscosity:
                            beta = 1.0
                            if kind[j] != FLUID:
                                if pos[j, 0] < 0.0:
                                    d_j = -pos[j, 0]
                                    d_i = x_i
                                else:
                                    d_j = pos[j, 0] - L
                                    d_i = L - x_i
                                beta = beta_max
                                if d_i > 0.0:
                                    beta = min(beta_max, 1.0 + d_j / d_i)
                            cv = mu_i * m_j * (th_i + theta[j]) / (rho_i * rho[j]) * f_over_r * beta
                            for d in range(dim):
                                ai[d] += cv * (vel[i, d] - vel[j, d])
        for d in range(dim):
            acc[i, d] = ai[d] + g[d]
