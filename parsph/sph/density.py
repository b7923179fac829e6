"""Eq. (3) of the paper, the summation density, as numba loops over the unique pairs of the neighbour list:

    rho_bar_i = sum_j m_j W_ij   (fluid and wall j, and i itself),   theta_i = rho_bar_i / rho_s.

Each pair (i, j) of :mod:`parsph.sph.cells` is evaluated once (W and (dW/dr)/r, the latter kept for the
momentum pass, :mod:`parsph.sph.momentum`). Every particle adds its contributions in pair order (its
neighbours' sorted order) starting from the same value, whether the serial loop scatters them pair by pair or
the threaded one (``prange``) stores the pair values and gathers them per particle: the result is the same bit
for bit on any thread and rank count. Only owned fluid particles receive sums; wall particles hold their
density (the layers' walls renormalise the sum instead: :mod:`parsph.sph.walls`). These functions know
nothing of MPI: ghosts are ordinary particles.

A pass takes its data as a few named groups (:mod:`parsph.sph.pass_data`): the neighbour list and the arrays
indexed like it, the particles' fields, the run's numbers and the terms a scene uses as compile-time
switches, so that a term switched off leaves no branch in the pair loop. The threaded passes hand plain
arguments on to their parallel kernels (numba's parallel loops misread the arrays of a named tuple).

How the loop is written for speed (docs/performance.md, "Pair passes"): it takes the particles' rows a few at
a time, about :data:`CHUNK` pairs. A scalar loop computes |r_ij|^2 (LLVM vectorises no loop that loads
through an index and stores, as it cannot rule out that the two overlap; into a buffer on the stack it does,
with AVX-512 gathers that measured slower than scalar loads on AMD Zen 4) and compacts the pairs closer than
2h (about three quarters of the list) without a branch: each pair is stored at the end of the compact list and
the count advanced only for those. A loop over that contiguous stretch evaluates the branch-free kernel on
vector registers (vsqrtpd, vdivpd on ymm or zmm), and a scalar loop adds the sums in pair order. The pairs
beyond 2h are never evaluated: they would add exact zeros (the threaded pass adds them: the kernel is
branch-free and vanishes there). Where every particle of the run has the same mass
(``Switches.uniform_mass``, agreed by all ranks at set-up), the serial pass takes it from the constants and
loads none: the kernel loop writes m W. All loops index with unsigned integers (numba tests a signed index
for a negative value) and use numpy's error model (no test for a zero divisor). The operations and their
order are those of :mod:`parsph.sph.reference_passes`, the scalar loops, so the results are theirs bit for
bit; no ``fastmath``.
"""
import math

import numpy as np
from numba import njit, prange, uintp

from parsph.physics.kernels import kernel_w_f

CHUNK = 1024  # pairs per chunk of the vector loop (its scratch: 8 KiB)


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
