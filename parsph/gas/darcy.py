"""The gas pressure on the grid (docs/physics.md, "The solved gas"): with K = eps^2 / beta on the cells and V
the solids' velocity, the mixture's volume flux j = V - K grad p' has no divergence,

    div(K grad p') = div V,

written in finite volumes on the cell-centred grid (:mod:`parsph.gas.grid`): per cell, the outward fluxes
through its faces sum to zero, a face's flux (V_f - K_f (p_nb - p_c) / h) times its length, K_f the
harmonic mean of the two cells' K (exact for layers in series), V_f their mean. The solids do not cross a
boundary face (V_f = 0 there). A side is periodic, or has a given normal flux (a floor fed at U(y); U = 0
closes it), or a given pressure at the face (p' = 0: an open top). The matrix is symmetric positive
definite (semi-definite where every side is periodic: then p' is pinned to 0 in the first cell, as its
constant is free). scipy's sparse direct solve (SuperLU): no iteration to fail; a singular matrix or a
non-finite result raises :class:`SolveFailed`.
"""
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


class SolveFailed(ArithmeticError):
    """The pressure solve gave no finite answer."""


@dataclass(frozen=True)
class Side:
    """One side of the grid: ``kind`` "flux" (``values``: the flux along +axis through each face, m/s) or
    "pressure" (``values``: p' at each face, Pa); a periodic axis has no sides."""
    kind: str
    values: np.ndarray


@dataclass
class Solution:
    p: np.ndarray    # p' per cell (nx, ny) [Pa]
    jx: np.ndarray   # the mixture's flux along +x through the x-faces (nx + 1, ny) [m/s]
    jy: np.ndarray   # along +y through the y-faces (nx, ny + 1) [m/s]

    def centred(self):
        """j at the cell centres (nx, ny, 2): the mean of each cell's two faces along each axis."""
        return np.stack([0.5 * (self.jx[:-1] + self.jx[1:]), 0.5 * (self.jy[:, :-1] + self.jy[:, 1:])], axis=-1)


def harmonic(a, b):
    """The face value of K between two cells: 2 a b / (a + b)."""
    return 2.0 * a * b / (a + b)


def solve(K, V, hx, hy, x_sides=None, y_sides=None):
    """p' and the face fluxes for K (nx, ny) [m^2/(Pa s)] and V (nx, ny, 2) [m/s]; ``x_sides`` = (low, high)
    :class:`Side` at x = 0 and x = nx hx, None for periodic; likewise ``y_sides``."""
    nx, ny = K.shape
    idx = np.arange(nx * ny).reshape(nx, ny)
    rows, cols, vals = [], [], []
    b = np.zeros(nx * ny)
    diag = np.zeros(nx * ny)
    # interior faces along x (periodic: the face between the last cell and the first too)
    gx_len, gy_len = hy, hx  # the length of an x-face, of a y-face

    def couple(a_idx, b_idx, g, v_ab):
        """Faces between cells a and b (b on the + side): conductance g, the solids' V_f along + (a -> b)."""
        a_idx, b_idx, g = a_idx.ravel(), b_idx.ravel(), g.ravel()
        np.add.at(diag, a_idx, g)
        np.add.at(diag, b_idx, g)
        rows.extend([a_idx, b_idx])
        cols.extend([b_idx, a_idx])
        vals.extend([-g, -g])
        np.add.at(b, a_idx, -v_ab.ravel())   # outward from a: + V_f length
        np.add.at(b, b_idx, v_ab.ravel())    # outward from b: - V_f length

    Kx = harmonic(K[:-1], K[1:])
    couple(idx[:-1], idx[1:], gx_len * Kx / hx, gx_len * 0.5 * (V[:-1, :, 0] + V[1:, :, 0]))
    if x_sides is None:
        Kw = harmonic(K[-1], K[0])
        couple(idx[-1], idx[0], gx_len * Kw / hx, gx_len * 0.5 * (V[-1, :, 0] + V[0, :, 0]))
    Ky = harmonic(K[:, :-1], K[:, 1:])
    couple(idx[:, :-1], idx[:, 1:], gy_len * Ky / hy, gy_len * 0.5 * (V[:, :-1, 1] + V[:, 1:, 1]))
    if y_sides is None:
        Kw = harmonic(K[:, -1], K[:, 0])
        couple(idx[:, -1], idx[:, 0], gy_len * Kw / hy, gy_len * 0.5 * (V[:, -1, 1] + V[:, 0, 1]))
    # boundary faces: (cells, K there, face length, distance centre-face, outward sign)
    bounds = []
    if x_sides is not None:
        bounds += [(x_sides[0], idx[0], K[0], gx_len, 0.5 * hx, -1.0), (x_sides[1], idx[-1], K[-1], gx_len, 0.5 * hx, 1.0)]
    if y_sides is not None:
        bounds += [(y_sides[0], idx[:, 0], K[:, 0], gy_len, 0.5 * hy, -1.0),
                   (y_sides[1], idx[:, -1], K[:, -1], gy_len, 0.5 * hy, 1.0)]
    pinned = True
    for side, cells, Kc, length, dist, sign in bounds:
        values = np.broadcast_to(np.asarray(side.values, float), cells.shape)
        if side.kind == "flux":
            np.add.at(b, cells, -sign * length * values)
        else:
            g = length * Kc / dist
            np.add.at(diag, cells, g)
            np.add.at(b, cells, g * values)
            pinned = False
    if pinned:  # every side periodic or fed: p' up to a constant; 0 in the first cell
        diag[0] += 1.0 if diag[0] == 0.0 else diag[0]
    rows.append(np.arange(nx * ny))
    cols.append(np.arange(nx * ny))
    vals.append(diag)
    A = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nx * ny,) * 2)
    with np.errstate(all="ignore"):
        try:
            p = spla.spsolve(A, b)
        except RuntimeError as e:  # SuperLU: a singular factor
            raise SolveFailed(str(e)) from None
    if not np.all(np.isfinite(p)):
        raise SolveFailed("the pressure is not finite")
    p = p.reshape(nx, ny)
    return Solution(p, *_fluxes(p, K, V, hx, hy, x_sides, y_sides))


def _fluxes(p, K, V, hx, hy, x_sides, y_sides):
    """The mixture's flux through every face from the solved p'."""
    nx, ny = p.shape
    jx = np.zeros((nx + 1, ny))
    jy = np.zeros((nx, ny + 1))
    jx[1:-1] = 0.5 * (V[:-1, :, 0] + V[1:, :, 0]) - harmonic(K[:-1], K[1:]) * (p[1:] - p[:-1]) / hx
    jy[:, 1:-1] = 0.5 * (V[:, :-1, 1] + V[:, 1:, 1]) - harmonic(K[:, :-1], K[:, 1:]) * (p[:, 1:] - p[:, :-1]) / hy
    if x_sides is None:
        jx[0] = jx[-1] = 0.5 * (V[-1, :, 0] + V[0, :, 0]) - harmonic(K[-1], K[0]) * (p[0] - p[-1]) / hx
    else:
        jx[0] = _side_flux(x_sides[0], p[0], K[0], 0.5 * hx, -1.0)
        jx[-1] = _side_flux(x_sides[1], p[-1], K[-1], 0.5 * hx, 1.0)
    if y_sides is None:
        jy[:, 0] = jy[:, -1] = 0.5 * (V[:, -1, 1] + V[:, 0, 1]) - harmonic(K[:, -1], K[:, 0]) * (p[:, 0] - p[:, -1]) / hy
    else:
        jy[:, 0] = _side_flux(y_sides[0], p[:, 0], K[:, 0], 0.5 * hy, -1.0)
        jy[:, -1] = _side_flux(y_sides[1], p[:, -1], K[:, -1], 0.5 * hy, 1.0)
    return jx, jy


def _side_flux(side, p_cell, K_cell, dist, sign):
    """The flux along +axis through a boundary face: given, or -K dp'/dn from the face's pressure."""
    values = np.broadcast_to(np.asarray(side.values, float), p_cell.shape)
    if side.kind == "flux":
        return values.copy()
    return -K_cell * sign * (values - p_cell) / dist
