"""The reduced velocity profile v_y(x): fluid particles binned in x.

Bins are the lattice columns, [i dx, (i+1) dx) for i = 0 .. Nx-1. Errors
against a reference are normalised by V_w: the max norm and the RMS over bins.
"""
import numpy as np
from numba import njit

from .particles import FLUID


@njit(cache=True)
def bin_sums(pos, vel, kind, n_own, dx, nbins, sums, counts):
    """Add v_y of owned fluid particles into x bins (local part of the reduction)."""
    for b in range(nbins):
        sums[b] = 0.0
        counts[b] = 0.0
    for i in range(n_own):
        if kind[i] != FLUID:
            continue
        b = int(pos[i, 0] / dx)
        if b < 0:
            b = 0
        elif b >= nbins:
            b = nbins - 1
        sums[b] += vel[i, 1]
        counts[b] += 1.0


def bin_centres(L, nbins):
    return (np.arange(nbins) + 0.5) * (L / nbins)


def errors(v_sim, v_ref, scale):
    """(max, rms) of |v_sim - v_ref| / scale over bins with data (NaN bins ignored)."""
    e = np.abs(np.asarray(v_sim) - np.asarray(v_ref)) / abs(scale)
    e = e[np.isfinite(e)]
    if e.size == 0:
        return float("nan"), float("nan")
    return float(e.max()), float(np.sqrt(np.mean(e * e)))
