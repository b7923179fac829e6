"""The slabs of a decomposition along y, as pure functions a serial test can check: their edges, the cell rows
each one touches, whether their ghost rows fit in the neighbouring slabs, and the largest rank count or the
smallest L_y that works. No MPI here: :class:`parsph.parallel.slab_ring.SlabRing` uses them.
"""
import math

import numpy as np


def slab_bounds(Ly, P):
    """Edges of P equal slabs on [0, Ly): a pure function, checked serially."""
    b = np.array([r * Ly / P for r in range(P + 1)])
    b[-1] = Ly
    return b


def cell_rows(bounds, side, ny):
    """(first, last) cell rows touched by each slab (the last one conservatively, for rounding)."""
    first = np.clip(np.floor(bounds[:-1] / side).astype(np.int64), 0, ny - 1)
    last = np.clip(np.floor(bounds[1:] / side).astype(np.int64), 0, ny - 1)
    return first, last


def fits(Ly, P, side, ny, m):
    """Whether every slab's ghost rows (M rows beyond its own) lie in its two neighbouring slabs."""
    b = slab_bounds(Ly, P)
    first, last = cell_rows(b, side, ny)
    for r in range(P):
        top = b[r + 2] if r + 2 <= P else b[(r + 2) - P] + Ly
        bottom = b[r - 1] if r >= 1 else b[P - 1] - Ly
        if (last[r] + m + 1) * side > top * (1 + 1e-12) + 1e-300 or (first[r] - m) * side < bottom - 1e-12 * Ly:
            return False
    return True


def rows_of_length(Ly, cutoff, m):
    """(side, ny) of the y rows: ny = floor(m Ly / cutoff) rows tile [0, Ly) (cells.Axis)."""
    ny = max(1, int(math.floor(m * Ly / cutoff * (1 + 1e-12))))
    return Ly / ny, ny


def max_ranks(Ly, cutoff, m):
    """The largest rank count whose slabs are wide enough for the ghost rows of a list with this cutoff."""
    side, ny = rows_of_length(Ly, cutoff, m)
    P = max(1, ny)
    while P > 1 and not fits(Ly, P, side, ny, m):
        P -= 1
    return P


def min_length(P, cutoff, m):
    """The smallest Ly (3 significant digits, rounded up) whose P slabs fit their ghost rows."""
    Ly = P * cutoff
    while True:
        shown = float(f"{Ly:.3g}")
        if shown < Ly:
            shown = float(f"{shown + 10 ** (math.floor(math.log10(Ly)) - 2):.3g}")
        side, ny = rows_of_length(shown, cutoff, m)
        if fits(shown, P, side, ny, m):
            return shown
        Ly *= 1.001
