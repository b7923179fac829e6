"""Brute-force lattice sums for the tests (not a test module): the kernels typed from their formulas
(Eq. (4) and Wendland C2 on support 2h, 2-D and 3-D) and the sheared lattice enumerated point by point
as (i, (j + i s) dy, l dz), dx = 1, without the reduction of the shift mod 1 that
:mod:`parsph.physics.lattice_sums` uses.
"""
import math

import numpy as np

ALPHA = {("cubic_spline", 2): 5 / (14 * math.pi), ("cubic_spline", 3): 1 / (4 * math.pi),
         ("wendland_c2", 2): 7 / (4 * math.pi), ("wendland_c2", 3): 21 / (16 * math.pi)}


def kernel(name, dim, q):
    """(W, dW/dq) at q = r / h for h = 1 in ``dim`` dimensions (numpy arrays)."""
    a = ALPHA[name, dim]
    q = np.asarray(q, float)
    if name == "cubic_spline":
        w = np.where(q < 1, 4 - 6 * q ** 2 + 3 * q ** 3, np.where(q < 2, (2 - q) ** 3, 0.0))
        dw = np.where(q < 1, -12 * q + 9 * q ** 2, np.where(q < 2, -3 * (2 - q) ** 2, 0.0))
    else:
        t = np.maximum(1 - q / 2, 0.0)
        w = t ** 4 * (2 * q + 1)
        dw = -2 * t ** 3 * (2 * q + 1) + 2 * t ** 4
    return a * w, a * dw


def sheared_sums(name, h_over_dx, s, dim=2, dy=1.0, dz=1.0):
    """(nu_eff / nu, dx dy (dz) sum_j W_ij): the Morris sum dy dz sum_j (-x_j^2) W'(r_j) / r_j and the
    density sum at a particle of the lattice whose column i is shifted by i s dy along y."""
    h = float(h_over_dx)
    reach = 2 * h
    ni = int(math.ceil(reach)) + 1
    nj = int(math.ceil(reach / dy)) + ni + 2  # + the shift of the outermost columns
    axes = [np.arange(-ni, ni + 1), np.arange(-nj, nj + 1)]
    if dim == 3:
        nz = int(math.ceil(reach / dz)) + 1
        axes.append(np.arange(-nz, nz + 1))
    grid = [g.ravel().astype(float) for g in np.meshgrid(*axes, indexing="ij")]
    x = grid[0]
    y = (grid[1] + x * s) * dy
    r2 = x * x + y * y + ((grid[2] * dz) ** 2 if dim == 3 else 0.0)
    r = np.sqrt(r2)
    w, dwdq = kernel(name, dim, r / h)
    w, dwdr = w / h ** dim, dwdq / h ** (dim + 1)
    vol = dy * (dz if dim == 3 else 1.0)
    off = r > 0
    lap = float(np.sum(-x[off] ** 2 * dwdr[off] / r[off]))
    return vol * lap, vol * float(np.sum(w))


def mean_bias(name, h_over_dx, dim=2, offsets=40, dy=1.0, dz=1.0):
    """b in nu_eff = (1 + b) nu averaged over the shifts s = 0, 1/offsets, ... (what a shear flow
    passes through as its columns slide)."""
    return float(np.mean([sheared_sums(name, h_over_dx, k / offsets, dim, dy, dz)[0]
                          for k in range(offsets)])) - 1.0
