"""The reduced profiles v_y(x), theta(x) and v_x(x): fluid particles binned in x.

Bins are the lattice columns, [i dx, (i+1) dx) for i = 0 .. Nx-1. Errors
against a reference are normalised by a scale (V_w for Couette): the max norm
and the RMS over bins.
"""
import numpy as np
from numba import njit

from .particles import GRAIN


@njit(cache=True)
def bin_sums(pos, vel, theta, kind, n_own, dx, nbins, period, sums):
    """Sums of v_y (row 0), theta (row 1), counts (row 2) and v_x (row 3: a layer's settling velocity) of
    owned fluid particles per x bin.

    ``period``: the length of x where it is periodic (positions are wrapped
    only at rebuilds of the neighbour list), 0 between walls.
    """
    for b in range(nbins):
        sums[0, b] = 0.0
        sums[1, b] = 0.0
        sums[2, b] = 0.0
        sums[3, b] = 0.0
    for i in range(n_own):
        if kind[i] != GRAIN:
            continue
        x = pos[i, 0]
        if period > 0.0:
            x = x % period
        b = int(x / dx)
        if b < 0:
            b = 0
        elif b >= nbins:
            b = nbins - 1
        sums[0, b] += vel[i, 1]
        sums[1, b] += theta[i]
        sums[2, b] += 1.0
        sums[3, b] += vel[i, 0]


def bin_centres(L, nbins):
    return (np.arange(nbins) + 0.5) * (L / nbins)


def errors(v_sim, v_ref, scale):
    """(max, rms) of |v_sim - v_ref| / scale over bins with data (NaN bins ignored)."""
    e = np.abs(np.asarray(v_sim) - np.asarray(v_ref)) / abs(scale)
    e = e[np.isfinite(e)]
    if e.size == 0:
        return float("nan"), float("nan")
    return float(e.max()), float(np.sqrt(np.mean(e * e)))


def mass_quantiles(x, mass, fractions=(0.05, 0.25, 0.5, 0.75, 0.95)):
    """The heights below which each fraction of a layer's mass lies: the particles sorted by x, their mass
    summed (each particle's mass at its own x, cumulated to its middle), interpolated linearly."""
    order = np.argsort(x, kind="stable")
    xs, ms = np.asarray(x, float)[order], np.asarray(mass, float)[order]
    cum = np.cumsum(ms) - 0.5 * ms
    return np.interp(np.asarray(fractions, float) * ms.sum(), cum, xs)
