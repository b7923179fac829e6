"""Eq. (5) of the paper, the momentum balance, as numba loops over the unique pairs of the neighbour list.
For fluid particle i:

    dv_i/dt = - (1/rho_s^2) sum_j m_j G((theta_i+theta_j)/2) (1/theta_i + 1/theta_j) (r_ij/r_ij) dW/dr
              + mu_i sum_j m_j v_ij (theta_i+theta_j)/(rho_bar_i rho_bar_j) (1/r_ij) dW/dr
              + g,      mu_i = k theta_i,

(``consistent``: the pressure term replaced by the symmetric SPH gradient sum_j m_j (p_i/rho_bar_i^2 +
p_j/rho_bar_j^2) dW/dr r_ij/r_ij of p = G / (G_a ln 10), whose gradient is G grad theta as the closure says;
the paper's form converges to grad(G theta) instead; ``symmetric_mu``: mu_i replaced by the pair mean
k (theta_i + theta_j)/2, the same in a uniform state but antisymmetric per pair, so that momentum is conserved
exactly), with wall particles j (Morris et al. 1997) seen through ``v_ij = beta (v_i - v_j)``,
``beta = min(beta_max, 1 + d_j/d_i)``, d the distance to the wall's plate (x = 0 or x = L). The per-particle
tail (g with buoyancy, the gas's drag) is :mod:`parsph.sph.body_force`'s.

Each pair is evaluated once, as in :mod:`parsph.sph.density` (whose notes on pair order, the named groups and
bit-for-bit results hold here): the momentum pass forms the two factors symmetric in i and j, ``P``
(pressure, G at the pair mean factorised as 10^G_b 10^(G_a theta_i/2) 10^(G_a theta_j/2)) and ``V``
(viscous), from the rows :func:`particle_factors` writes. Particle i receives m_j (P r_ij + mu_i beta V v_ij),
particle j the exact negative of m_i (P r_ij + mu_j beta V v_ij).

How the loops are written for speed (docs/performance.md, "Pair passes"): the momentum pass walks the density
pass's compact list, one scalar loop per particle with no test of a pair's distance (the test of the full
list, taken or not at random in a disordered state, was mispredicted often enough to cost a third of the
pass). Its work is the neighbour's fields, loaded through an index, and the scatter; split into gather, vector
and scatter loops it measured slower. The operations and their order are those of
:mod:`parsph.sph.reference_passes`; no ``fastmath``.
"""
import math

from numba import njit, prange, uintp

from parsph.physics.closures import half_modulus, modulus_unchecked, packing_pressure
from .body_force import drag_plain, drag_rates, finish_acc
from .pair_terms import pressure_term, viscosity_coefficient, viscous_term, wall_factor
from .particles import GRAIN
from .pass_data import INV_RHO, INV_THETA, PRESS, THETA, VX, VY, VZ  # the columns of PairList.fields

DRAG_CHUNK = 512  # particles per parallel chunk of the drag's rates (threaded momentum pass)


# ---- the rows the pair loops read ------------------------------------------------------------------
@njit(cache=True, inline="always")
def pressure_factor(th, rho_i, G_a, G_b, consistent, packing, theta_min, theta_max):
    """The per-particle factor of the pressure term at theta = rho_bar / rho_s.

    10^(G_a theta / 2) for the paper's form (G at the pair mean is
    10^G_b press_i press_j) and p(theta) / rho_bar^2 for the consistent form,
    with p = G(theta) / (G_a ln 10) so that grad p = G grad theta exactly
    (``packing`` on: plus the frictional p_f of :func:`.closures.packing_pressure`; a compiled switch, so that
    the loops of a run without it hold none of its code: a branch at run time made every loop's compile 25%
    longer).
    """
    if len(consistent):
        p = modulus_unchecked(th, G_a, G_b) / (G_a * math.log(10.0))
        if len(packing):
            p += packing_pressure(th, theta_min, theta_max)[0]
        return p / (rho_i * rho_i)
    return half_modulus(th, G_a)


@njit(cache=True, inline="always")
def _factors_one(k, rho, rho_sum, kind, owned_stop, rho_s, G_a, G_b, pressure, consistent, packing, theta_min,
                 theta_max, vel, theta, fields):
    """rho, theta and the pair loops' row of particle k."""
    if k < owned_stop and kind[k] == GRAIN:
        rho[k] = rho_sum[k]
    r = rho[k]
    th = r / rho_s
    theta[k] = th
    for d in range(vel.shape[1]):
        fields[k, d] = vel[k, d]
    fields[k, THETA] = th
    fields[k, INV_RHO] = 1.0 / r
    fields[k, INV_THETA] = 1.0 / th
    if len(pressure):
        fields[k, PRESS] = pressure_factor(th, r, G_a, G_b, consistent, packing, theta_min, theta_max)


@njit(cache=True, parallel=True)
def _particle_factors(rho, rho_sum, kind, start, stop, owned_stop, rho_s, G_a, G_b, pressure, consistent, packing,
                      theta_min, theta_max, vel, theta, fields):
    """:func:`particle_factors` on plain arguments (see :func:`parsph.sph.density._density_threaded`)."""
    for k in prange(start, stop):
        _factors_one(k, rho, rho_sum, kind, owned_stop, rho_s, G_a, G_b, pressure, consistent, packing, theta_min,
                     theta_max, vel, theta, fields)


@njit(cache=True)
def particle_factors(lst, parts, c, sw, start, stop):
    """Per particle of start..stop-1: rho (owned fluid: from ``rho_sum``), theta, and the row the pairs read.

    ``fields[k]`` = (vx, vy, vz, theta, 1/rho_bar, 1/theta, pressure factor,
    mu/k = theta): one row per particle, so that a pair reads one cache line
    of its neighbour. Owned wall particles and halo copies keep their rho.
    """
    _particle_factors(parts.rho, lst.rho_sum, parts.kind, start, stop, parts.n_own, c.rho_s, c.G_a, c.G_b,
                      sw.pressure, sw.consistent, sw.packing, c.theta_min, c.theta_max, parts.vel, parts.theta,
                      lst.fields)


@njit(cache=True)
def particle_factors_serial(lst, parts, c, sw, start, stop):
    """:func:`particle_factors` on one thread (no parallel region to start: the compiled step's choice).

    The body written out: called through an inlined helper with the arrays, this loop ran 7x slower;
    unsigned indices (no test for a negative one): 25% faster."""
    rho, rho_sum, kind, vel, theta, fields = parts.rho, lst.rho_sum, parts.kind, parts.vel, parts.theta, lst.fields
    owned_stop, rho_s, G_a, G_b, pressure, consistent = parts.n_own, c.rho_s, c.G_a, c.G_b, sw.pressure, sw.consistent
    packing, theta_min, theta_max = sw.packing, c.theta_min, c.theta_max
    dim = vel.shape[1]
    own = uintp(owned_stop)
    for k in range(uintp(start), uintp(max(start, stop))):
        if k < own and kind[k] == GRAIN:
            rho[k] = rho_sum[k]
        r = rho[k]
        th = r / rho_s
        theta[k] = th
        for d in range(dim):
            fields[k, d] = vel[k, d]
        fields[k, THETA] = th
        fields[k, INV_RHO] = 1.0 / r
        fields[k, INV_THETA] = 1.0 / th
        if len(pressure):
            fields[k, PRESS] = pressure_factor(th, r, G_a, G_b, consistent, packing, theta_min, theta_max)



# ---- Eq. (5) ------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def momentum_serial(lst, parts, c, sw):
    """Eq. (5) into ``acc`` of the owned particles (walls: zero), each pair once, in pair order.

    Pair (i, j): P (pressure) and V (viscous) are symmetric; i gets
    m_j (P r_ij + mu_i beta V v_ij), j the exact negative of m_i (P r_ij +
    mu_j beta V v_ij). The pairs are those within 2h, from the compact list
    :func:`density_serial` wrote (the pairs beyond add nothing and are
    skipped without a test). Indices are unsigned (no test for negative ones) and
    the error model is numpy's (no test for a zero divisor, which beta's
    branch excludes): the loop is scalar, and short for it.
    """
    order, cstart, cj, cf, n, fields, need = lst.order, lst.cstart, lst.cj, lst.cf, lst.n, lst.fields, lst.need
    pos, mass, kind, acc, n_own = parts.pos, parts.mass, parts.kind, parts.acc, parts.n_own
    rho_s, G_b, k_visc, L, beta_max, g, m_all = c.rho_s, c.G_b, c.k_visc, c.L, c.beta_max, c.g, c.mass
    pressure, viscosity, symmetric_mu, walls, consistent, three_d, uniform_mass, drag_on, _, _ = sw
    c_press = -(10.0 ** G_b) / (rho_s * rho_s)
    dim = acc.shape[1]
    for k in range(n):
        for d in range(dim):
            acc[k, d] = 0.0
    for a in range(n):
        lo = uintp(cstart[a])
        hi = uintp(cstart[a + 1])
        if lo == hi:
            continue
        i = uintp(order[a])
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
        mi = m_all if len(uniform_mass) else mass[i]
        ax = acc[i, 0]
        ay = acc[i, 1]
        az = acc[i, 2] if len(three_d) else 0.0
        for p in range(lo, hi):
            f = cf[p]
            j = uintp(cj[p])
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
                m = m_all if len(uniform_mass) else mass[j]
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
    finish_acc(acc, kind, g, three_d, n_own, drag_on, parts.vel, parts.theta, rho_s, c.gas, parts.drag_coef,
                parts.drag_rate, parts.flux)



@njit(cache=True, parallel=True, error_model="numpy")
def _momentum_threaded(order, pstart, pi, pj, n, npairs, fp, pos, mass, kind, fields, need, n_own, rho_s, G_b,
                      k_visc, L, beta_max, g, pressure, viscosity, symmetric_mu, walls, consistent, three_d, acc,
                      Pp, Vp, offset, entry, drag_on, vel, theta, model, rho_g, mu_g, d_grain, flow, axis, sign,
                      U, u, flux, drag, drag_rate):
    """:func:`momentum_threaded` on plain arguments (see :func:`parsph.sph.density._density_threaded`); the drag's K by
    :func:`parsph.sph.body_force.drag_rates` on chunks of the arrays, in parallel."""
    c_press = -(10.0 ** G_b) / (rho_s * rho_s)
    dim = acc.shape[1]
    for p in prange(npairs):
        i = uintp(pi[p])
        j = uintp(pj[p])
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
    if len(drag_on):  # drag_rates on chunks of DRAG_CHUNK particles
        for c in prange((n_own + DRAG_CHUNK - 1) // DRAG_CHUNK):
            lo = c * DRAG_CHUNK
            hi = min(lo + DRAG_CHUNK, n_own)
            drag_rates(hi - lo, vel[lo:hi], theta[lo:hi], rho_s, model, rho_g, mu_g, d_grain, flow, axis, sign,
                       U, u, flux[lo:hi], drag_rate[lo:hi], three_d)
    for k in prange(n_own):
        ax = 0.0
        ay = 0.0
        az = 0.0
        if need[k]:
            for e in range(uintp(offset[k]), uintp(offset[k + 1])):
                p = uintp(entry[e] >> 1)
                if fp[p] == 0.0:  # beyond 2h: skipped as the serial loop skips it
                    continue
                i = uintp(pi[p])
                j = uintp(pj[p])
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
        if kind[k] != GRAIN:  # walls: zero
            ax = 0.0
            ay = 0.0
            az = 0.0
        else:
            ax += g[0]
            ay += g[1]
            if len(three_d):
                az += g[2]
        acc[k, 0] = ax
        acc[k, 1] = ay
        if len(three_d):
            acc[k, 2] = az
        if len(drag_on) and kind[k] == GRAIN:
            drag_plain(k, vel, 1.0 - theta[k], flow, axis, sign, U, u, flux, acc, drag, drag_rate[k], three_d)


@njit(cache=True)
def momentum_threaded(lst, parts, c, sw, gather):
    """As :func:`momentum_serial` with threads: P and V per pair, then a gather per particle in pair order,
    with the same arithmetic, so that the result is the same bit for bit."""
    _momentum_threaded(lst.order, lst.pstart, lst.pi, lst.pj, lst.n, lst.npairs, lst.fp, parts.pos, parts.mass,
                       parts.kind, lst.fields, lst.need, parts.n_own, c.rho_s, c.G_b, c.k_visc, c.L, c.beta_max,
                       c.g, sw.pressure, sw.viscosity, sw.symmetric_mu, sw.walls, sw.consistent, sw.three_d,
                       parts.acc, gather.Pp, gather.Vp, gather.offset, gather.entry, sw.drag, parts.vel,
                       parts.theta, c.gas.model, c.gas.rho, c.gas.mu, c.gas.d, c.gas.flow, c.gas.axis, c.gas.sign,
                       c.gas.U, c.gas.u, parts.flux, parts.drag_coef, parts.drag_rate)
