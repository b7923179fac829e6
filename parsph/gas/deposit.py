"""The particles on the grid and the grid at the particles, with one set of weights both ways (cloud in
cell: bilinear in the cell centres), so that the force the grid's fields put on the solids is the reaction
of what they deposited (docs/physics.md, "The solved gas"). Besides theta and theta v, each particle
deposits its drag resistance m C (C its drag rate, 1/s): the cell's R, whose inverse is the cell's K.

A particle of volume m / rho_s adds w_c m / (rho_s A) to theta and that times v to theta v of the four
cells c around it (A a cell's area, the w_c summing to 1). Where a cell would lie beyond a plate, its weight
folds onto the cell inside (the mirror image of the particle across the plate), so that theta does not fall
off at a wall; likewise at side walls across y. y without side walls (and x without plates) wraps around the
period.

The sums are kept in fixed point (int64, :data:`SCALE` per unit): each term is rounded once, and integers add
in any order to the same bits, so the grid is the same on any rank count and in any particle order (the
float sum over ranks would not be). 2^-40 of a unit is far below any other error; |theta v| up to 2^22 m/s
fits.
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
def deposit(pos, vel, mass, kind, n_own, rho_s, nx, ny, hx, hy, Lx, Ly, walls, sides, ring, out, rate, rate_ref):
    """Add the owned fluid particles' theta, theta v_x, theta v_y and, where ``rate`` has them, their drag
    resistance m C / (A R_ref) and that times v_x, v_y (fixed point) to out[0..5] (shape (6, nx, ny));
    ``rate[k]``: the particle's drag rate C [1/s], ``rate_ref``: R_ref / rho_s [1/s]. ``walls``: x bounded
    by plates (else periodic); ``sides``: y bounded by side walls at 0 and Ly (else periodic), in the
    particles' period ``ring`` along y."""
    inv = 1.0 / (rho_s * hx * hy)
    resist = len(rate) > 0
    for k in range(n_own):
        if kind[k] != GRAIN:
            continue
        i0, i1, wx0, wx1 = _axis_weights(pos[k, 0], hx, nx, Lx, walls, 0.0 if walls else Lx)
        j0, j1, wy0, wy1 = _axis_weights(pos[k, 1], hy, ny, Ly, sides, ring)
        vol = mass[k] * inv
        vx = vel[k, 0]
        vy = vel[k, 1]
        r = rate[k] / rate_ref if resist else 0.0
        for a in range(4):
            i = i0 if a < 2 else i1
            j = j0 if a % 2 == 0 else j1
            w = (wx0 if a < 2 else wx1) * (wy0 if a % 2 == 0 else wy1) * vol
            out[0, i, j] += np.int64(round(w * SCALE))
            out[1, i, j] += np.int64(round(w * vx * SCALE))
            out[2, i, j] += np.int64(round(w * vy * SCALE))
            if resist:
                out[3, i, j] += np.int64(round(w * r * RATE_SCALE))
                out[4, i, j] += np.int64(round(w * r * vx * RATE_SCALE))
                out[5, i, j] += np.int64(round(w * r * vy * RATE_SCALE))


@njit(cache=True)
def interpolate(pos, kind, n_own, field, nx, ny, hx, hy, Lx, Ly, walls, sides, ring, out):
    """out[k] = the cell-centred ``field`` (nx, ny, c) at the owned fluid particles, with the deposit's weights
    (others get zeros)."""
    nc = field.shape[2]
    for k in range(n_own):
        for c in range(nc):
            out[k, c] = 0.0
        if kind[k] != GRAIN:
            continue
        i0, i1, wx0, wx1 = _axis_weights(pos[k, 0], hx, nx, Lx, walls, 0.0 if walls else Lx)
        j0, j1, wy0, wy1 = _axis_weights(pos[k, 1], hy, ny, Ly, sides, ring)
        for c in range(nc):
            out[k, c] = (wx0 * (wy0 * field[i0, j0, c] + wy1 * field[i0, j1, c])
                         + wx1 * (wy0 * field[i1, j0, c] + wy1 * field[i1, j1, c]))


def resistance_of(sums, rho_s, rate_ref):
    """R = sum_i w m_i C_i / A per cell [kg/(m^3 s)] from the summed deposits, and the velocity its particles'
    drag is weighted by, V_R = sum_i w m_i C_i v_i / sum_i w m_i C_i (nx, ny, 2; 0 where R = 0): the cell's
    particles feel the drag R (W - V_R) for a target W, so that with K = 1 / R and W = V_R - K grad p' the
    grid's -grad p' is the sum of their drag."""
    R = sums[3] / RATE_SCALE * (rho_s * rate_ref)
    V = np.zeros(sums.shape[1:] + (2,))
    some = sums[3] > 0
    V[some, 0] = sums[4][some] / sums[3][some]
    V[some, 1] = sums[5][some] / sums[3][some]
    return R, V


def theta_of(sums):
    """theta per cell (nx, ny) from the summed fixed-point deposits."""
    return sums[0] / SCALE
