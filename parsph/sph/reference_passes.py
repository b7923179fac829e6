"""Scalar pair passes of Eq. (3) and Eq. (5): the reference that tests and ``scripts/bench_pairs.py`` compare
the passes of :mod:`parsph.sph.density` and :mod:`parsph.sph.momentum` against, on the same pair list, bit for bit. Not called by the solver.

Each particle's pairs are walked one by one: a branch skips a candidate
beyond 2h, the neighbour's position and fields are loaded through its index
and its sum is scattered to (``rho_sum[j] += ...``, ``acc[j] -= ...``); the
threaded passes store the pair values and gather them per particle in pair
order. The same floating-point operations in the same order as
:mod:`parsph.sph.density` and :mod:`parsph.sph.momentum`, and the same signatures; LLVM keeps these
loops scalar (signed indices, zero-divisor tests, the branch).
"""
import math

from numba import njit, prange

from parsph.physics.kernels import kernel_w_f
from .pair_terms import pressure_term, viscosity_coefficient, viscous_term, wall_factor
from .particles import GRAIN
from .pass_data import INV_RHO, INV_THETA, PRESS, THETA, VX, VY, VZ  # the columns of PairList.fields


# ---- Eq. (3) ------------------------------------------------------------------------------------
@njit(cache=True)
def density_serial(lst, parts, c, sw):
    """Eq. (3) into ``lst.rho_sum`` for particles 0..n-1; (dW/dr)/r of each pair into ``lst.fp``.

    Particle order[a]'s pairs are pstart[a] .. pstart[a+1]-1 (its later
    neighbours). Its sum starts with its own term, gets the pairs of earlier
    particles as they come, then its own pairs: the pair order.
    """
    order, pstart, pj, n, fp, rho_sum = lst.order, lst.pstart, lst.pj, lst.n, lst.fp, lst.rho_sum
    pos, mass = parts.pos, parts.mass
    kid, inv_h, norm, w0 = c.kid, c.inv_h, c.norm, c.w0
    three_d = sw.three_d
    support2 = 4.0 / (inv_h * inv_h)
    for k in range(n):
        rho_sum[k] = mass[k] * w0
    for a in range(n):
        lo = pstart[a]
        hi = pstart[a + 1]
        if lo == hi:
            continue
        i = order[a]
        xi = pos[i, 0]
        yi = pos[i, 1]
        zi = pos[i, 2] if len(three_d) else 0.0
        mi = mass[i]
        s = rho_sum[i]
        for p in range(lo, hi):
            j = pj[p]
            dx = xi - pos[j, 0]
            dy = yi - pos[j, 1]
            r2 = dx * dx + dy * dy
            if len(three_d):
                dz = zi - pos[j, 2]
                r2 += dz * dz
            if r2 >= support2:  # beyond 2h (in the skin): W and dW/dr are exactly zero
                fp[p] = 0.0
                continue
            w, f = kernel_w_f(kid, math.sqrt(r2), inv_h, norm)
            fp[p] = f
            s += mass[j] * w
            rho_sum[j] += mi * w
        rho_sum[i] = s


@njit(cache=True, parallel=True)
def _density_threaded(order, pstart, pi, pj, n, npairs, pos, mass, kid, inv_h, norm, w0, three_d, rho_sum, fp,
                     wp, need, offset, entry):
    """:func:`density_threaded` on plain arguments (numba's parallel loops read the arrays of named
    tuples wrongly: a sum stayed at its first term)."""
    support2 = 4.0 / (inv_h * inv_h)
    for p in prange(npairs):
        i = pi[p]
        j = pj[p]
        dx = pos[i, 0] - pos[j, 0]
        dy = pos[i, 1] - pos[j, 1]
        r2 = dx * dx + dy * dy
        if len(three_d):
            dz = pos[i, 2] - pos[j, 2]
            r2 += dz * dz
        if r2 >= support2:
            wp[p] = 0.0
            fp[p] = 0.0
        else:
            w, f = kernel_w_f(kid, math.sqrt(r2), inv_h, norm)
            wp[p] = w
            fp[p] = f
    for k in prange(n):
        s = mass[k] * w0
        if need[k]:
            for e in range(offset[k], offset[k + 1]):
                p = entry[e] >> 1
                if fp[p] == 0.0:  # beyond 2h: skipped as the serial loop skips it
                    continue
                other = pi[p] if entry[e] & 1 else pj[p]
                s += mass[other] * wp[p]
        rho_sum[k] = s


@njit(cache=True)
def density_threaded(lst, parts, c, sw, gather):
    """As :func:`density_serial` for the particles that ``need`` sums, with threads: pairs, then a gather."""
    _density_threaded(lst.order, lst.pstart, lst.pi, lst.pj, lst.n, lst.npairs, parts.pos, parts.mass, c.kid,
                      c.inv_h, c.norm, c.w0, sw.three_d, lst.rho_sum, lst.fp, gather.wp, lst.need, gather.offset,
                      gather.entry)


# ---- Eq. (5) ------------------------------------------------------------------------------------
@njit(cache=True)
def momentum_serial(lst, parts, c, sw):
    """Eq. (5) into ``acc`` of the owned particles (walls: zero), each pair once, in pair order.

    Pair (i, j): P (pressure) and V (viscous) are symmetric; i gets
    m_j (P r_ij + mu_i beta V v_ij), j the exact negative of m_i (P r_ij +
    mu_j beta V v_ij).
    """
    order, pstart, pj, n, fp, fields, need = lst.order, lst.pstart, lst.pj, lst.n, lst.fp, lst.fields, lst.need
    pos, mass, kind, acc, n_own = parts.pos, parts.mass, parts.kind, parts.acc, parts.n_own
    rho_s, G_b, k_visc, L, beta_max, g = c.rho_s, c.G_b, c.k_visc, c.L, c.beta_max, c.g
    pressure, viscosity, symmetric_mu, walls, consistent, three_d = (sw.pressure, sw.viscosity, sw.symmetric_mu,
                                                                  sw.walls, sw.consistent, sw.three_d)
    c_press = -(10.0 ** G_b) / (rho_s * rho_s)
    dim = acc.shape[1]
    for k in range(n):
        for d in range(dim):
            acc[k, d] = 0.0
    for a in range(n):
        lo = pstart[a]
        hi = pstart[a + 1]
        if lo == hi:
            continue
        i = order[a]
        need_i = need[i]
        fluid_i = kind[i] == GRAIN
        xi = pos[i, 0]
        yi = pos[i, 1]
        zi = pos[i, 2] if len(three_d) else 0.0
        vxi = fields[i, VX]
        vyi = fields[i, VY]
        vzi = fields[i, VZ]
        th_i = fields[i, THETA]
        irho_i = fields[i, INV_RHO]
        ith_i = fields[i, INV_THETA]
        pr_i = fields[i, PRESS]
        mi = mass[i]
        ax = acc[i, 0]
        ay = acc[i, 1]
        az = acc[i, 2] if len(three_d) else 0.0
        for p in range(lo, hi):
            f = fp[p]
            if f == 0.0:  # beyond 2h: the pair adds nothing
                continue
            j = pj[p]
            th_j = fields[j, THETA]
            P = 0.0
            if len(pressure):
                P = pressure_term(pr_i, fields[j, PRESS], ith_i, fields[j, INV_THETA], f, c_press, consistent)
            V = 0.0
            if len(viscosity):
                V = viscous_term(th_i, th_j, irho_i, fields[j, INV_RHO], f)
            rx = xi - pos[j, 0]
            ry = yi - pos[j, 1]
            vx = vxi - fields[j, VX]
            vy = vyi - fields[j, VY]
            rz = 0.0
            vz = 0.0
            if len(three_d):
                rz = zi - pos[j, 2]
                vz = vzi - fields[j, VZ]
            if need_i:
                s = 0.0
                if len(viscosity):
                    mu = viscosity_coefficient(th_i, th_i, th_j, k_visc, symmetric_mu)
                    if len(walls) and kind[j] != GRAIN:
                        mu *= wall_factor(xi, pos[j, 0], L, beta_max)
                    s = mu * V
                m = mass[j]
                ax += m * (P * rx + s * vx)
                ay += m * (P * ry + s * vy)
                if len(three_d):
                    az += m * (P * rz + s * vz)
            if need[j]:
                s = 0.0
                if len(viscosity):
                    mu = viscosity_coefficient(th_j, th_i, th_j, k_visc, symmetric_mu)
                    if len(walls) and not fluid_i:
                        mu *= wall_factor(pos[j, 0], xi, L, beta_max)
                    s = mu * V
                acc[j, 0] -= mi * (P * rx + s * vx)
                acc[j, 1] -= mi * (P * ry + s * vy)
                if len(three_d):
                    acc[j, 2] -= mi * (P * rz + s * vz)
        if need_i:
            acc[i, 0] = ax
            acc[i, 1] = ay
            if len(three_d):
                acc[i, 2] = az
    for k in range(n_own):
        _finish_acc(acc, k, kind, g, three_d)


@njit(cache=True, inline="always")
def _finish_acc(acc, k, kind, g, three_d):
    if kind[k] == GRAIN:
        acc[k, 0] += g[0]
        acc[k, 1] += g[1]
        if len(three_d):
            acc[k, 2] += g[2]
    else:
        acc[k, 0] = 0.0
        acc[k, 1] = 0.0
        if len(three_d):
            acc[k, 2] = 0.0


@njit(cache=True, parallel=True)
def _momentum_threaded(order, pstart, pi, pj, n, npairs, fp, pos, mass, kind, fields, need, n_own, rho_s, G_b,
                      k_visc, L, beta_max, g, pressure, viscosity, symmetric_mu, walls, consistent, three_d, acc,
                      Pp, Vp, offset, entry):
    """:func:`momentum_threaded` on plain arguments (see :func:`_density_threaded`)."""
    c_press = -(10.0 ** G_b) / (rho_s * rho_s)
    dim = acc.shape[1]
    for p in prange(npairs):
        i = pi[p]
        j = pj[p]
        f = fp[p]
        P = 0.0
        if len(pressure):
            P = pressure_term(fields[i, PRESS], fields[j, PRESS], fields[i, INV_THETA], fields[j, INV_THETA], f,
                              c_press, consistent)
        V = 0.0
        if len(viscosity):
            V = viscous_term(fields[i, THETA], fields[j, THETA], fields[i, INV_RHO], fields[j, INV_RHO], f)
        Pp[p] = P
        Vp[p] = V
    for k in prange(n_own):
        ax = 0.0
        ay = 0.0
        az = 0.0
        if need[k]:
            for e in range(offset[k], offset[k + 1]):
                p = entry[e] >> 1
                if fp[p] == 0.0:  # beyond 2h: skipped as the serial loop skips it
                    continue
                i = pi[p]
                j = pj[p]
                o = i if entry[e] & 1 else j
                P = Pp[p]
                V = Vp[p]
                rx = pos[i, 0] - pos[j, 0]
                ry = pos[i, 1] - pos[j, 1]
                vx = fields[i, VX] - fields[j, VX]
                vy = fields[i, VY] - fields[j, VY]
                rz = 0.0
                vz = 0.0
                if len(three_d):
                    rz = pos[i, 2] - pos[j, 2]
                    vz = fields[i, VZ] - fields[j, VZ]
                s = 0.0
                if len(viscosity):
                    mu = viscosity_coefficient(fields[k, THETA], fields[i, THETA], fields[j, THETA], k_visc,
                                               symmetric_mu)
                    if len(walls) and kind[o] != GRAIN:
                        mu *= wall_factor(pos[k, 0], pos[o, 0], L, beta_max)
                    s = mu * V
                m = mass[o]
                if entry[e] & 1:
                    ax -= m * (P * rx + s * vx)
                    ay -= m * (P * ry + s * vy)
                    if len(three_d):
                        az -= m * (P * rz + s * vz)
                else:
                    ax += m * (P * rx + s * vx)
                    ay += m * (P * ry + s * vy)
                    if len(three_d):
                        az += m * (P * rz + s * vz)
        acc[k, 0] = ax
        acc[k, 1] = ay
        if len(three_d):
            acc[k, 2] = az
        _finish_acc(acc, k, kind, g, three_d)


@njit(cache=True)
def momentum_threaded(lst, parts, c, sw, gather):
    """As :func:`momentum_serial` with threads: P and V per pair, then a gather per particle in pair order,
    with the same arithmetic, so that the result is the same bit for bit."""
    _momentum_threaded(lst.order, lst.pstart, lst.pi, lst.pj, lst.n, lst.npairs, lst.fp, parts.pos, parts.mass,
                       parts.kind, lst.fields, lst.need, parts.n_own, c.rho_s, c.G_b, c.k_visc, c.L, c.beta_max,
                       c.g, sw.pressure, sw.viscosity, sw.symmetric_mu, sw.walls, sw.consistent, sw.three_d,
                       parts.acc, gather.Pp, gather.Vp, gather.offset, gather.entry)
