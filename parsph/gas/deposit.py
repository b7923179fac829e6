"""The particles on the grid and the grid at the particles, with one set of weights both ways (cloud in
cell: bilinear in the cell centres, trilinear in 3-D), so that the force the grid's fields put on the solids
is the reaction of what they deposited (docs/physics.md, "The solved gas"). Each particle deposits its
volume (theta) and its drag resistance m C (C its drag rate, 1/s) and that times v: the cell's R, whose
inverse is the cell's K, and the velocity its grains' drag is weighted by.

A particle of volume m / rho_s adds w_c m / (rho_s V) to theta of the four cells c around it (eight in 3-D;
V a cell's volume, its area in 2-D; the w_c summing to 1), and w_c m C / V to R. Where a cell would lie
beyond a plate, its weight folds onto the cell inside (the mirror image of the particle across the plate),
so that theta does not fall off at a wall; likewise at side walls across y. y without side walls (and x
without plates) wraps around the period.

The sums are kept in fixed point (int64, :data:`SCALE` per unit): each term is rounded once, and integers add
in any order to the same bits, so the grid is the same on any rank count and in any particle order (the
float sum over ranks would not be). 2^-40 of a unit is far below any other error.
"""
import math

import numpy as np
from numba import njit

SCALE = 2.0 ** 40
RATE_SCALE = 2.0 ** 36  # the resistance, relative to a reference (a rate 2^27 times the reference's fits)
GRAIN = 0  # parsph.sph.particles.GRAIN (the gas layer imports nothing of sph)


@njit(cache=True, inline="always")
def _axis_weights(x, h, n, length, bounded, period):
    """The two cells along one axis and their weights for a coordinate x (cell centres at (i + 1/2) h):
    x taken into [0, period) where ``period`` > 0 (positions wrap at rebuilds only), then onto [0, length]
    where ``bounded``."""
    if period > 0.0:
        if x < 0.0:
            x += period
        elif x >= period:
            x -= period
    if bounded:
        x = min(max(x, 0.0), length)
    f = x / h - 0.5
    i0 = int(math.floor(f))
    w1 = f - i0
    i1 = i0 + 1
    if bounded:
        if i0 < 0:
            i0 = 0
        if i1 > n - 1:
            i1 = n - 1
    else:
        if i0 < 0:
            i0 += n
        if i1 > n - 1:
            i1 -= n
    return i0, i1, 1.0 - w1, w1


@njit(cache=True)
def weights(pos, kind, n_own, nx, ny, nz, hx, hy, hz, Lx, Ly, Lz, walls, sides, ring, cells, w):
    """The cloud in cell's cells and weights of the owned particles, made once for a deposit and the
    interpolations at the same places (together 1.9x faster than each finding them: docs/performance.md): per
    axis a the two cells ``cells[k, 2a]``, ``cells[k, 2a + 1]`` and their weights ``w[k, 2a]``, ``w[k, 2a + 1]``
    (cells (n, 2 dim) int32, w (n, 2 dim)); ``cells[k, 0]`` = -1 where particle k is not a grain. ``walls``: x
    bounded by plates (else periodic); ``sides``: y bounded by side walls at 0 and Ly (else periodic), in the
    particles' period ``ring`` along y; z periodic (3-D, nz > 1; in 2-D nz = 1, hz = 1)."""
    for k in range(n_own):
        if kind[k] != GRAIN:
            cells[k, 0] = -1
            continue
        i0, i1, wx0, wx1 = _axis_weights(pos[k, 0], hx, nx, Lx, walls, 0.0 if walls else Lx)
        j0, j1, wy0, wy1 = _axis_weights(pos[k, 1], hy, ny, Ly, sides, ring)
        cells[k, 0], cells[k, 1], cells[k, 2], cells[k, 3] = i0, i1, j0, j1
        w[k, 0], w[k, 1], w[k, 2], w[k, 3] = wx0, wx1, wy0, wy1
        if nz > 1:
            k0, k1, wz0, wz1 = _axis_weights(pos[k, 2], hz, nz, Lz, False, Lz)
            cells[k, 4], cells[k, 5] = k0, k1
            w[k, 4], w[k, 5] = wz0, wz1


@njit(cache=True)
def deposit(cells, w, vel, mass, n_own, rho_s, hx, hy, hz, out, drag, theta, rate_ref):
    """out = the owned fluid particles' theta and, where ``drag`` has them, their drag resistance m C / (V R_ref)
    and that times v (fixed point), (nx, ny, nz, 2 + dim): theta, R, R v_x.. of a cell side by side, which a
    particle's corners then touch in one cache line each: 2.4x faster than a plane per quantity. ``cells``, ``w``:
    :func:`weights`'. The particle's drag rate C [1/s] is ``drag[k] / (1 - theta[k])`` (the closure's K per
    particle and its theta), ``rate_ref`` R_ref / rho_s [1/s]; hz = 1 in 2-D."""
    three = out.shape[2] > 1
    inv = 1.0 / (rho_s * hx * hy * hz)
    resist = len(drag) > 0
    out[:] = 0
    k0, k1, wz0, wz1 = 0, 0, 1.0, 0.0
    for k in range(n_own):
        if cells[k, 0] < 0:
            continue
        i0, i1, j0, j1 = cells[k, 0], cells[k, 1], cells[k, 2], cells[k, 3]
        wx0, wx1, wy0, wy1 = w[k, 0], w[k, 1], w[k, 2], w[k, 3]
        if three:
            k0, k1, wz0, wz1 = cells[k, 4], cells[k, 5], w[k, 4], w[k, 5]
        vol = mass[k] * inv
        r = drag[k] / (1.0 - theta[k]) / rate_ref if resist else 0.0
        vx, vy = vel[k, 0], vel[k, 1]
        vz = vel[k, 2] if three else 0.0
        for az in range(2 if three else 1):
            kz = k1 if az else k0
            for ax in range(2):
                i = i1 if ax else i0
                wx = wx1 if ax else wx0
                for ay in range(2):
                    j = j1 if ay else j0
                    wxy = wx * (wy1 if ay else wy0)
                    if three:
                        wxy *= wz1 if az else wz0
                    wk = wxy * vol
                    out[i, j, kz, 0] += np.int64(round(wk * SCALE))
                    if resist:  # the components written out: a loop over them took twice as long
                        wr = wk * r
                        out[i, j, kz, 1] += np.int64(round(wr * RATE_SCALE))
                        out[i, j, kz, 2] += np.int64(round(wr * vx * RATE_SCALE))
                        out[i, j, kz, 3] += np.int64(round(wr * vy * RATE_SCALE))
                        if three:
                            out[i, j, kz, 4] += np.int64(round(wr * vz * RATE_SCALE))


@njit(cache=True, inline="always")
def _bilinear(field, i0, i1, j0, j1, kz, c, wx0, wx1, wy0, wy1):
    return (wx0 * (wy0 * field[i0, j0, kz, c] + wy1 * field[i0, j1, kz, c])
            + wx1 * (wy0 * field[i1, j0, kz, c] + wy1 * field[i1, j1, kz, c]))


@njit(cache=True)
def interpolate(cells, w, n_own, field, out):
    """out[k] = the cell-centred ``field`` (nx, ny, nz, c) at the owned fluid particles, with the deposit's
    weights (:func:`weights`; others get zeros). The first two components written out, the rest in a loop: a
    loop over all of them took 1.5x as long."""
    nc = field.shape[3]
    three = field.shape[2] > 1
    for k in range(n_own):
        if cells[k, 0] < 0:
            for c in range(nc):
                out[k, c] = 0.0
            continue
        i0, i1, j0, j1 = cells[k, 0], cells[k, 1], cells[k, 2], cells[k, 3]
        wx0, wx1, wy0, wy1 = w[k, 0], w[k, 1], w[k, 2], w[k, 3]
        if not three:
            out[k, 0] = _bilinear(field, i0, i1, j0, j1, 0, 0, wx0, wx1, wy0, wy1)
            if nc > 1:
                out[k, 1] = _bilinear(field, i0, i1, j0, j1, 0, 1, wx0, wx1, wy0, wy1)
            for c in range(2, nc):
                out[k, c] = _bilinear(field, i0, i1, j0, j1, 0, c, wx0, wx1, wy0, wy1)
            continue
        k0, k1, wz0, wz1 = cells[k, 4], cells[k, 5], w[k, 4], w[k, 5]
        for c in range(nc):
            out[k, c] = (wz0 * _bilinear(field, i0, i1, j0, j1, k0, c, wx0, wx1, wy0, wy1)
                         + wz1 * _bilinear(field, i0, i1, j0, j1, k1, c, wx0, wx1, wy0, wy1))


def cells_of(sums, rho_s, rate_ref):
    """theta, R and V_R per cell from the summed deposits (cells..., 2 + dim), in one pass over them:
    theta; R = sum_i w m_i C_i / V [kg/(m^3 s)]; and the velocity its particles' drag is weighted by,
    V_R = sum_i w m_i C_i v_i / sum_i w m_i C_i (cells..., dim; 0 where R = 0). The cell's particles feel the
    drag R (W - V_R) for a target W, so that with K = 1 / R and W = V_R - K grad p' the grid's -grad p' is the
    sum of their drag."""
    dim = sums.shape[-1] - 2
    cells = sums.shape[:-1]
    theta, R, V = np.empty(cells), np.empty(cells), np.empty(cells + (dim,))
    _cells(sums.reshape(-1, dim + 2), rho_s * rate_ref, theta.reshape(-1), R.reshape(-1), V.reshape(-1, dim))
    return theta, R, V


@njit(cache=True)
def _cells(sums, scale, theta, R, V):
    dim = V.shape[1]
    for k in range(sums.shape[0]):
        theta[k] = sums[k, 0] / SCALE
        s = sums[k, 1]
        R[k] = s / RATE_SCALE * scale
        for c in range(dim):
            V[k, c] = sums[k, 2 + c] / s if s > 0 else 0.0
