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
arrays (z = 0 in 2-D, so one code path serves both). The density pass finds
each fluid particle's neighbours by visiting the 3^dim surrounding cells in a
fixed order and the particles of a cell in gid order; it stores them, with
(dW/dr)/r, in a neighbour list that the momentum pass walks in the same
order. Every sum is thus taken in an order that does not depend on the
decomposition. These functions know nothing of MPI: halo copies are ordinary
neighbours.

The switches of :func:`momentum` (pressure, viscosity, symmetric viscosity,
walls) are compile-time constants made by :func:`switch`: an empty tuple is
off, ``(1,)`` is on, so each value is its own type, numba compiles one version
per combination a scene uses, ``len(switch)`` is a constant, and a term
switched off leaves no branch in the pair loop. (``numba.literally`` does the
same but costs tens of milliseconds per call.)
"""
import math

from numba import njit

from .kernels import kernel_dwdr, kernel_w
from .particles import FLUID

ON, OFF = (1,), ()


def switch(flag):
    """A compile-time switch for the loops below."""
    return ON if flag else OFF


@njit(cache=True)
def density(n, sx, sy, sz, sm, skind, owned, cell_of, start, ncx, ncy, ncz, h, norm,
            kid, rho_wall, srho, nbr_start, nbr_j, nbr_f):
    """Eq. (3) for the owned fluid particles among sorted places 0..n-1; owned walls hold rho_wall.

    Also fills the neighbour list: fluid particle k's neighbours are
    ``nbr_j[nbr_start[k]:nbr_start[k+1]]`` with ``nbr_f = (dW/dr)/r``.
    Returns the number of list entries needed; if that exceeds
    ``len(nbr_j)`` the list is incomplete and the call must be repeated with
    larger arrays.
    """
    inv_h = 1.0 / h
    support2 = 4.0 * h * h
    zr = 1 if ncz > 1 else 0
    cap = nbr_j.shape[0]
    p = 0
    for i in range(n):
        nbr_start[i] = p
        if not owned[i]:
            continue
        if skind[i] != FLUID:
            srho[i] = rho_wall
            continue
        s = 0.0
        xi = sx[i]
        yi = sy[i]
        zi = sz[i]
        c0 = cell_of[i]
        cx0 = c0 % ncx
        cy0 = (c0 // ncx) % ncy
        cz0 = c0 // (ncx * ncy)
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
                    c = (cz * ncy + cy) * ncx + cx
                    for j in range(start[c], start[c + 1]):
                        dx = xi - sx[j]
                        dy = yi - sy[j]
                        dz = zi - sz[j]
                        r2 = dx * dx + dy * dy + dz * dz
                        if r2 < support2:
                            r = math.sqrt(r2)
                            s += sm[j] * kernel_w(kid, r, inv_h, norm)
                            if j != i:
                                if p < cap:
                                    nbr_j[p] = j
                                    nbr_f[p] = kernel_dwdr(kid, r, inv_h, norm) / r
                                p += 1
        srho[i] = s
    nbr_start[n] = p
    return p


@njit(cache=True)
def volume_fraction(rho, n, rho_s, G_a, G_b, theta, press, pressure, consistent):
    """theta = rho_bar / rho_s and the per-particle factor of the pressure term.

    ``press`` is 10^(G_a theta / 2) for the paper's form (G at the pair mean is
    10^G_b press_i press_j) and p(theta) / rho_bar^2 for the consistent form,
    with p = G(theta) / (G_a ln 10) so that grad p = G grad theta exactly.
    """
    ln10 = math.log(10.0)
    for i in range(n):
        th = rho[i] / rho_s
        theta[i] = th
        if len(pressure):
            if len(consistent):
                press[i] = 10.0 ** (G_a * th + G_b) / (G_a * ln10) / (rho[i] * rho[i])
            else:
                press[i] = 10.0 ** (0.5 * G_a * th)


@njit(cache=True)
def momentum(n, sx, sy, sz, svx, svy, svz, sm, skind, srho, stheta, spress, owned,
             nbr_start, nbr_j, nbr_f, rho_s, G_b, k_visc, L, beta_max, g,
             pressure, viscosity, symmetric_mu, walls, consistent, sax, say, saz):
    """Eq. (5): acceleration of each owned fluid particle (sorted places; walls: zero)."""
    G_pref = 10.0 ** G_b
    inv_rho_s2 = 1.0 / (rho_s * rho_s)
    for i in range(n):
        sax[i] = 0.0
        say[i] = 0.0
        saz[i] = 0.0
        if not owned[i] or skind[i] != FLUID:
            continue
        th_i = stheta[i]
        inv_th_i = 1.0 / th_i
        mu_i = k_visc * th_i
        rho_i = srho[i]
        pr_i = spress[i]
        xi = sx[i]
        yi = sy[i]
        zi = sz[i]
        ax = 0.0
        ay = 0.0
        az = 0.0
        for p in range(nbr_start[i], nbr_start[i + 1]):
            j = nbr_j[p]
            f_over_r = nbr_f[p]
            m_j = sm[j]
            if len(pressure):
                if len(consistent):
                    cp = -m_j * (pr_i + spress[j]) * f_over_r
                else:
                    cp = -m_j * inv_rho_s2 * G_pref * pr_i * spress[j] * (inv_th_i + 1.0 / stheta[j]) * f_over_r
                ax += cp * (xi - sx[j])
                ay += cp * (yi - sy[j])
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
                cv = mu * m_j * (th_i + stheta[j]) / (rho_i * srho[j]) * f_over_r * beta
                ax += cv * (svx[i] - svx[j])
                ay += cv * (svy[i] - svy[j])
                az += cv * (svz[i] - svz[j])
        sax[i] = ax + g[0]
        say[i] = ay + g[1]
        saz[i] = az + g[2]
