"""The SPH equations of the paper as numba loops over the unique pairs of the neighbour list.

- Eq. (3): summation density ``rho_bar_i = sum_j m_j W_ij`` (fluid and wall j,
  and i itself), ``theta_i = rho_bar_i / rho_s``.
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

Each pair (i, j) of :mod:`parsph.sph.cells` is evaluated once: W and
(dW/dr)/r in the density pass, and in the momentum pass the two factors
symmetric in i and j: ``P`` (pressure, G at the pair mean factorised as
10^G_b 10^(G_a theta_i/2) 10^(G_a theta_j/2)) and ``V`` (viscous). Particle
i receives ``m_j (P r_ij + mu_i beta V v_ij)``, particle j the exact
negative of ``m_i (P r_ij + mu_j beta V v_ij)``. Every particle adds its
contributions in pair order (its neighbours' sorted order) starting from the
same value, whether the serial loops scatter them pair by pair or the
threaded loops (``prange``) store the pair values and gather them per
particle: the result is the same bit for bit on any thread and rank count.
The serial passes skip the candidates beyond 2h; the threaded ones add
their exact zeros (the kernel is branch-free and vanishes there). Only
owned fluid particles receive sums; wall particles hold their density.
These functions know nothing of MPI: ghosts are ordinary particles.

A pass takes its data as a few named groups (:mod:`parsph.sph.pass_data`):
the neighbour list and the arrays indexed like it, the particles' fields,
the run's numbers and the terms a scene uses (pressure, viscosity,
symmetric viscosity, walls, consistent pressure, three dimensions) as
compile-time switches, so that a term switched off leaves no branch in the
pair loop. The threaded passes hand plain arguments on to their parallel
kernels (numba's parallel loops misread the arrays of a named tuple).

How the loops are written for speed (docs/performance.md, "Pair passes"):
the density pass takes the particles' rows a few at a time, about
:data:`CHUNK` pairs. A scalar loop computes |r_ij|^2 (LLVM vectorises no
loop that loads through an index and stores, as it cannot rule out that the
two overlap; into a buffer on the stack it does, with AVX-512 gathers that
measured slower than scalar loads on AMD Zen 4) and compacts the pairs
closer than 2h (about three quarters of the list) without a branch: each
pair is stored at the end of the compact list and the count advanced only
for those. A loop over that contiguous stretch evaluates the branch-free
kernel on vector registers (vsqrtpd, vdivpd on ymm or zmm), and a scalar
loop adds the sums in pair order. The pairs beyond 2h are never evaluated:
they would add exact zeros. The momentum pass walks the compact list: one
scalar loop per particle with no test of a pair's distance (the test of the
full list, taken or not at random in a disordered state, was mispredicted
often enough to cost a third of the pass). Its work is the neighbour's
fields, loaded through an index, and the scatter; split into gather, vector
and scatter loops it measured slower. Where every particle of the run has
the same mass (``Switches.uniform_mass``, agreed by all ranks at set-up),
the serial passes take it from the constants and load none: the kernel
loop writes m W, the product both members of a pair add. All loops index
with unsigned integers (numba tests a signed index for a negative value)
and use numpy's error model (no test for a zero divisor). The operations
and their order are those of :mod:`parsph.sph.reference_passes`, the scalar
loops, so the results are theirs bit for bit; no ``fastmath``.
"""
import math

import numpy as np
from numba import njit, prange, uintp

from parsph.physics.closures import half_modulus, modulus_unchecked
from parsph.physics.drag import GIDASPOW, STOKES, WEN_YU, rate
from parsph.physics.kernels import kernel_w_f
from .pair_terms import pressure_term, viscosity_coefficient, viscous_term, wall_factor
from .particles import FLUID
from .pass_data import COLUMN, SOLVED  # the gas's flows (GasConstants.flow)
from .pass_data import INV_RHO, INV_THETA, PRESS, THETA, VX, VY, VZ  # the columns of PairList.fields

CHUNK = 1024  # pairs per chunk of the density pass's vector loop (its scratch: 8 KiB)
DRAG_CHUNK = 512  # particles per parallel chunk of the drag's rates (threaded momentum pass)


# ---- Eq. (3) ------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _squared_distances(pos, pi, pj, lo, hi, r2, three_d):
    """|r_i - r_j|^2 of pairs lo..hi-1 into r2[0 .. hi-lo-1] (scalar: the loads are gathers)."""
    pib = pi[lo:hi]
    pjb = pj[lo:hi]
    for q in range(hi - lo):
        i = uintp(pib[q])
        j = uintp(pjb[q])
        dx = pos[i, 0] - pos[j, 0]
        dy = pos[i, 1] - pos[j, 1]
        d2 = dx * dx + dy * dy
        if len(three_d):
            dz = pos[i, 2] - pos[j, 2]
            d2 += dz * dz
        r2[q] = d2


@njit(cache=True, inline="always")
def _kernel_values(kid, inv_h, norm, r2, w, f, m, mass, uniform_mass):
    """W and (dW/dr)/r of the m distances^2 in r2 into w and f (f may be r2 itself): contiguous arrays and a
    branch-free kernel, so that this loop runs on vector registers (4 pairs an instruction on AVX2). With
    ``uniform_mass`` on, w gets m W, the term of Eq. (3) both members of a pair receive (the product the
    sums would form, so the same bits).

    Beyond 2h both are zero (``+ 0.0`` turns the kernel's -0.0 into +0.0, the value the serial pass's
    skipped pairs stand for, so that the threaded passes' fp has the same bits).
    """
    for q in range(m):
        wq, fq = kernel_w_f(kid, math.sqrt(r2[q]), inv_h, norm)
        w[q] = mass * wq if len(uniform_mass) else wq
        f[q] = fq + 0.0


@njit(cache=True)
def density_serial(lst, parts, c, sw):
    """Eq. (3) into ``lst.rho_sum`` for particles 0..n-1, and the pairs within 2h with their (dW/dr)/r into
    the compact list ``lst.cstart``, ``cj``, ``cf`` that :func:`momentum_serial` walks.

    Particle order[a]'s pairs are pstart[a] .. pstart[a+1]-1 (its later
    neighbours). Its sum starts with its own term, gets the pairs of earlier
    particles as they come, then its own pairs: the pair order.
    """
    density_chunks(lst, parts, c, sw, CHUNK)


@njit(cache=True, error_model="numpy")
def density_chunks(lst, parts, c, sw, chunk):
    """:func:`density_serial` taking the places' rows a few at a time, about ``chunk`` pairs (at least one
    row): their squared distances, each pair's stored at the end of the compact list and the count advanced
    only for those within 2h (the reference loops' test, without a branch); W and (dW/dr)/r of those pairs
    (a vector loop, (dW/dr)/r over the distance in place); then each particle's sum and the scatter to its
    neighbours in pair order. The pairs beyond 2h, about a quarter of the list, would add exact zeros and
    are not evaluated. Any chunk gives the same numbers bit for bit."""
    order, pstart, pj, n, rho_sum = lst.order, lst.pstart, lst.pj, lst.n, lst.rho_sum
    cstart, cj, cf = lst.cstart, lst.cj, lst.cf
    pos, mass = parts.pos, parts.mass
    kid, inv_h, norm, w0, m_all = c.kid, c.inv_h, c.norm, c.w0, c.mass
    three_d, uniform_mass = sw.three_d, sw.uniform_mass
    support2 = 4.0 / (inv_h * inv_h)
    longest = uintp(chunk)
    for k in range(n):
        rho_sum[k] = (m_all if len(uniform_mass) else mass[k]) * w0
        longest = max(longest, uintp(pstart[k + 1]) - uintp(pstart[k]))
    wb = np.empty(longest)
    cnt = uintp(0)
    a0 = 0
    while a0 < n:
        c0 = cnt
        a1 = a0
        while a1 < n and (a1 == a0 or uintp(pstart[a1 + 1]) - uintp(pstart[a0]) <= uintp(chunk)):
            cstart[a1] = cnt
            i = uintp(order[a1])
            xi = pos[i, 0]
            yi = pos[i, 1]
            zi = pos[i, 2] if len(three_d) else 0.0
            for p in range(uintp(pstart[a1]), uintp(pstart[a1 + 1])):
                j = pj[p]
                dx = xi - pos[uintp(j), 0]
                dy = yi - pos[uintp(j), 1]
                r2 = dx * dx + dy * dy
                if len(three_d):
                    dz = zi - pos[uintp(j), 2]
                    r2 += dz * dz
                cj[cnt] = j  # compacted without a branch: cf holds |r_ij|^2 until the kernel loop
                cf[cnt] = r2
                cnt += uintp(r2 < support2)
            a1 += 1
        cstart[a1] = cnt
        cfb = cf[c0:cnt]  # one slice as input and output: LLVM sees the loop's in-place access
        _kernel_values(kid, inv_h, norm, cfb, wb, cfb, cnt - c0, m_all, uniform_mass)
        for a in range(a0, a1):
            i = uintp(order[a])
            s = rho_sum[i]
            if len(uniform_mass):  # wb holds m W: no mass to load or multiply
                for p in range(uintp(cstart[a]), uintp(cstart[a + 1])):
                    mw = wb[p - c0]
                    s += mw
                    rho_sum[uintp(cj[p])] += mw
            else:
                mi = mass[i]
                for p in range(uintp(cstart[a]), uintp(cstart[a + 1])):
                    j = uintp(cj[p])
                    w = wb[p - c0]
                    s += mass[j] * w
                    rho_sum[j] += mi * w
            rho_sum[i] = s
        a0 = a1
    cstart[n] = cnt


@njit(cache=True, parallel=True, error_model="numpy")
def _density_threaded(order, pstart, pi, pj, n, npairs, pos, mass, kid, inv_h, norm, w0, three_d, rho_sum, fp,
                     wp, need, offset, entry):
    """:func:`density_threaded` on plain arguments (numba's parallel loops read the arrays of named
    tuples wrongly: a sum stayed at its first term)."""
    nchunks = (npairs + CHUNK - 1) // CHUNK
    for b in prange(nchunks):
        lo = uintp(b * CHUNK)
        hi = min(lo + uintp(CHUNK), uintp(npairs))
        fpb = fp[lo:hi]
        _squared_distances(pos, pi, pj, lo, hi, fpb, three_d)
        _kernel_values(kid, inv_h, norm, fpb, wp[lo:hi], fpb, hi - lo, 1.0, ())
    for k in prange(n):
        s = mass[k] * w0
        if need[k]:
            for e in range(uintp(offset[k]), uintp(offset[k + 1])):
                p = uintp(entry[e] >> 1)
                other = uintp(pi[p] if entry[e] & 1 else pj[p])
                s += mass[other] * wp[p]  # beyond 2h: an exact zero, as the serial loop adds it
        rho_sum[k] = s


@njit(cache=True)
def density_threaded(lst, parts, c, sw, gather):
    """As :func:`density_serial` for the particles that ``need`` sums, with threads: pairs, then a gather."""
    _density_threaded(lst.order, lst.pstart, lst.pi, lst.pj, lst.n, lst.npairs, parts.pos, parts.mass, c.kid,
                      c.inv_h, c.norm, c.w0, sw.three_d, lst.rho_sum, lst.fp, gather.wp, lst.need, gather.offset,
                      gather.entry)


@njit(cache=True, inline="always")
def pressure_factor(th, rho_i, G_a, G_b, consistent):
    """The per-particle factor of the pressure term at theta = rho_bar / rho_s.

    10^(G_a theta / 2) for the paper's form (G at the pair mean is
    10^G_b press_i press_j) and p(theta) / rho_bar^2 for the consistent form,
    with p = G(theta) / (G_a ln 10) so that grad p = G grad theta exactly.
    """
    if len(consistent):
        return modulus_unchecked(th, G_a, G_b) / (G_a * math.log(10.0)) / (rho_i * rho_i)
    return half_modulus(th, G_a)


@njit(cache=True, inline="always")
def _factors_one(k, rho, rho_sum, kind, owned_stop, rho_s, G_a, G_b, pressure, consistent, vel, theta, fields):
    """rho, theta and the pair loops' row of particle k."""
    if k < owned_stop and kind[k] == FLUID:
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
        fields[k, PRESS] = pressure_factor(th, r, G_a, G_b, consistent)


@njit(cache=True, parallel=True)
def _particle_factors(rho, rho_sum, kind, start, stop, owned_stop, rho_s, G_a, G_b, pressure, consistent, vel,
                     theta, fields):
    """:func:`particle_factors` on plain arguments (see :func:`_density_threaded`)."""
    for k in prange(start, stop):
        _factors_one(k, rho, rho_sum, kind, owned_stop, rho_s, G_a, G_b, pressure, consistent, vel, theta, fields)


@njit(cache=True)
def particle_factors(lst, parts, c, sw, start, stop):
    """Per particle of start..stop-1: rho (owned fluid: from ``rho_sum``), theta, and the row the pairs read.

    ``fields[k]`` = (vx, vy, vz, theta, 1/rho_bar, 1/theta, pressure factor,
    mu/k = theta): one row per particle, so that a pair reads one cache line
    of its neighbour. Owned wall particles and halo copies keep their rho.
    """
    _particle_factors(parts.rho, lst.rho_sum, parts.kind, start, stop, parts.n_own, c.rho_s, c.G_a, c.G_b,
                      sw.pressure, sw.consistent, parts.vel, parts.theta, lst.fields)


@njit(cache=True)
def particle_factors_serial(lst, parts, c, sw, start, stop):
    """:func:`particle_factors` on one thread (no parallel region to start: the compiled step's choice).

    The body written out: called through an inlined helper with the arrays, this loop ran 7x slower;
    unsigned indices (no test for a negative one): 25% faster."""
    rho, rho_sum, kind, vel, theta, fields = parts.rho, lst.rho_sum, parts.kind, parts.vel, parts.theta, lst.fields
    owned_stop, rho_s, G_a, G_b, pressure, consistent = parts.n_own, c.rho_s, c.G_a, c.G_b, sw.pressure, sw.consistent
    dim = vel.shape[1]
    own = uintp(owned_stop)
    for k in range(uintp(start), uintp(max(start, stop))):
        if k < own and kind[k] == FLUID:
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
            fields[k, PRESS] = pressure_factor(th, r, G_a, G_b, consistent)


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
    pressure, viscosity, symmetric_mu, walls, consistent, three_d, uniform_mass, drag_on, _ = sw
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
        fluid_i = kind[i] == FLUID
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
                    if len(walls) and kind[j] != FLUID:
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
    _finish_acc(acc, kind, g, three_d, n_own, drag_on, parts.vel, parts.theta, rho_s, c.gas, parts.drag,
                parts.drag_rate, parts.flux)


@njit(cache=True, error_model="numpy")
def _finish_acc(acc, kind, g, three_d, n_own, drag_on, vel, theta, rho_s, gas, drag, drag_rate, flux):
    """Owned fluid particles: + g, + the gas's drag (:func:`drag_rates` first, then :func:`drag_plain` per
    particle, with ``drag_on``); owned walls: zero (one call: an inlined call per particle would count
    references to its arrays every time). numpy's error model: with Python's, the drag's divisions and powers
    test for zero and took 4x as long."""
    if len(drag_on):
        drag_rates(n_own, vel, theta, rho_s, gas.model, gas.rho, gas.mu, gas.d, gas.flow, gas.axis, gas.sign,
                   gas.U, gas.u, flux, drag_rate, three_d)
    for k in range(n_own):
        if kind[k] == FLUID:
            acc[k, 0] += g[0]
            acc[k, 1] += g[1]
            if len(three_d):
                acc[k, 2] += g[2]
            if len(drag_on):
                drag_plain(k, vel, 1.0 - theta[k], gas.flow, gas.axis, gas.sign, gas.U, gas.u, flux, acc, drag,
                           drag_rate[k], three_d)
        else:
            acc[k, 0] = 0.0
            acc[k, 1] = 0.0
            if len(three_d):
                acc[k, 2] = 0.0


# ---- the gas's drag (docs/physics.md, "The solid phase in a gas") --------------------------------------
@njit(cache=True, inline="always")
def stream_slip2(k, vf, u0, u1, u2, three_d):
    """|u_g - v_k|^2 in a stream u_g = (u0, u1, u2): the sum of (u_d - v_k,d)^2 over the components d.
    ``vf``: the velocities flat (:func:`flat`), read at the constant stride dim; u_g as numbers (loads from its
    array in the loop, or strides read from the 2-D array's shape, keep the loop off vector registers)."""
    dim = 3 if len(three_d) else 2
    s0 = u0 - vf[dim * k]
    s1 = u1 - vf[dim * k + 1]
    slip2 = s0 * s0 + s1 * s1
    if len(three_d):
        s2 = u2 - vf[dim * k + 2]
        slip2 += s2 * s2
    return slip2


@njit(cache=True, inline="always")
def column_slip2(k, vf, theta, axis, sign, U, three_d):
    """|u_g,k - v_k|^2 in a column (docs/physics.md): u_g.e = (U - theta v.e) / eps along e = sign * unit(axis), so
    the slip there is (sign U - v_k,axis) / eps, and -v_k,d across. Branch-free: each component a select;
    ``vf`` as in :func:`stream_slip2`."""
    dim = 3 if len(three_d) else 2
    se = (sign * U - vf[dim * k + axis]) / (1.0 - theta[k])
    s0 = se if axis == 0 else vf[dim * k]
    s1 = se if axis == 1 else vf[dim * k + 1]
    slip2 = s0 * s0 + s1 * s1
    if len(three_d):
        s2 = se if axis == 2 else vf[dim * k + 2]
        slip2 += s2 * s2
    return slip2


@njit(cache=True, inline="always")
def flat(a):
    """A C-contiguous (n, dim) array as a flat view (no copy)."""
    return a.reshape(a.shape[0] * a.shape[1])


@njit(cache=True, inline="always")
def solved_slip2(k, vf, theta, flux, three_d):
    """|u_g,k - v_k|^2 in the solved gas: eps (u_g - v) = j - v with j the mixture's flux at the particle
    (``flux[k]``, from the grid: :mod:`parsph.gas`), so the slip is (j - v_k) / eps_k."""
    dim = 3 if len(three_d) else 2
    s0 = flux[k, 0] - vf[dim * k]
    s1 = flux[k, 1] - vf[dim * k + 1]
    slip2 = s0 * s0 + s1 * s1
    if len(three_d):
        s2 = flux[k, 2] - vf[dim * k + 2]
        slip2 += s2 * s2
    e = 1.0 - theta[k]
    return slip2 / (e * e)


@njit(cache=True, error_model="numpy")
def drag_rates(n_own, vel, theta, rho_s, model, rho_g, mu_g, d_grain, flow, axis, sign, U, u, flux, K, three_d):
    """K[k] = :func:`parsph.physics.drag.rate` at (theta_k, |u_g,k - v_k|^2) for k < n_own, walls included
    (unused there): one loop per closure and kind of gas flow, each branch-free (the model a constant) so that
    it runs on vector registers, fastmath's log, exp and atan included. Plain arguments, as drag_plain's;
    :func:`_momentum_threaded` calls it on chunks of the arrays in parallel (a parallel loop of these bodies
    took about 20 s to compile per version). ``flux``: the solved gas's j per particle (else unread)."""
    u0, u1, u2 = u[0], u[1], u[2]
    vf = flat(vel)
    if model == STOKES:
        for k in range(n_own):
            K[k] = rate(STOKES, theta[k], 0.0, rho_s, rho_g, mu_g, d_grain)
    elif flow == COLUMN:
        if model == WEN_YU:
            for k in range(n_own):
                K[k] = rate(WEN_YU, theta[k], column_slip2(k, vf, theta, axis, sign, U, three_d), rho_s, rho_g,
                            mu_g, d_grain)
        else:
            for k in range(n_own):
                K[k] = rate(GIDASPOW, theta[k], column_slip2(k, vf, theta, axis, sign, U, three_d), rho_s, rho_g,
                            mu_g, d_grain)
    elif flow == SOLVED:
        for k in range(n_own):
            K[k] = rate(model, theta[k], solved_slip2(k, vf, theta, flux, three_d), rho_s, rho_g, mu_g, d_grain)
    elif model == WEN_YU:
        for k in range(n_own):
            K[k] = rate(WEN_YU, theta[k], stream_slip2(k, vf, u0, u1, u2, three_d), rho_s, rho_g, mu_g, d_grain)
    else:
        for k in range(n_own):
            K[k] = rate(GIDASPOW, theta[k], stream_slip2(k, vf, u0, u1, u2, three_d), rho_s, rho_g, mu_g, d_grain)


@njit(cache=True, inline="always")
def drag_plain(k, vel, eps, flow, axis, sign, U, u, flux, acc, drag, Kk, three_d):
    """The drag on fluid particle k, beside Eq. (5)'s sums and gravity with buoyancy (Constants.g):

        dv_k/dt += beta_k (u_g,k - v_k) / (rho_s theta_k eps_k),   eps = 1 - theta,

    theta_k from Eq. (3), beta_k the closure's at |u_g,k - v_k|, Kk = beta_k / (rho_s theta_k eps_k) from
    :func:`drag_rates`, eps = eps_k. Written per component as C (w - v_k): a stream has C = K and
    w = u_g; a column (gas fed at U along e, opposite to gravity) has u_g.e = (U - theta v.e) / eps, so
    along e C = K / eps and w = U e, across it C = K and w = 0; the solved gas has eps (u_g - v) = j - v
    with j the mixture's flux from the grid (``flux[k]``), so C = K / eps and w = j along every axis (a
    column's along e, exactly, where j = U e). ``drag[k]`` keeps C per component,
    what the implicit update divides by (:mod:`parsph.sph.integrators`) and the auto rule reads.
    Plain arguments: the threaded pass calls it inside a parallel loop, which misreads named tuples' arrays.
    The components written out (``three_d`` a switch; u has 3): a loop over vel.shape[1] took longer; every
    array read unconditionally (``flux`` only in the solved gas, the one flow that has it), else numba counts
    its references per particle."""
    c0 = Kk
    c1 = Kk
    c2 = Kk
    w0 = u[0]
    w1 = u[1]
    w2 = u[2]
    if flow == COLUMN:
        ce = Kk / eps
        we = sign * U
        c0 = ce if axis == 0 else Kk
        c1 = ce if axis == 1 else Kk
        c2 = ce if axis == 2 else Kk
        w0 = we if axis == 0 else 0.0
        w1 = we if axis == 1 else 0.0
        w2 = we if axis == 2 else 0.0
    elif flow == SOLVED:
        c0 = Kk / eps
        c1 = c0
        c2 = c0
        w0 = flux[k, 0]
        w1 = flux[k, 1]
        if len(three_d):
            w2 = flux[k, 2]
    acc[k, 0] += c0 * (w0 - vel[k, 0])
    acc[k, 1] += c1 * (w1 - vel[k, 1])
    drag[k, 0] = c0
    drag[k, 1] = c1
    if len(three_d):
        acc[k, 2] += c2 * (w2 - vel[k, 2])
        drag[k, 2] = c2


@njit(cache=True, parallel=True, error_model="numpy")
def _momentum_threaded(order, pstart, pi, pj, n, npairs, fp, pos, mass, kind, fields, need, n_own, rho_s, G_b,
                      k_visc, L, beta_max, g, pressure, viscosity, symmetric_mu, walls, consistent, three_d, acc,
                      Pp, Vp, offset, entry, drag_on, vel, theta, model, rho_g, mu_g, d_grain, flow, axis, sign,
                      U, u, flux, drag, drag_rate):
    """:func:`momentum_threaded` on plain arguments (see :func:`_density_threaded`); the drag's K by
    :func:`drag_rates` on chunks of the arrays, in parallel."""
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
                    if len(walls) and kind[o] != FLUID:
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
        if kind[k] != FLUID:  # walls: zero
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
        if len(drag_on) and kind[k] == FLUID:
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
                       c.gas.U, c.gas.u, parts.flux, parts.drag, parts.drag_rate)
