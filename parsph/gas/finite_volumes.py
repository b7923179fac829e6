"""The gas pressure's equation on the grid in finite volumes (docs/physics.md, "The solved gas"): with K =
eps^2 / beta on the cells and V the solids' velocity, the mixture's volume flux j = V - K grad p' has no
divergence,

    div(K grad p') = div V,

written on the cell-centred grid (:mod:`parsph.gas.grid`): per cell, the outward fluxes through its faces sum
to zero, a face's flux (V_f - K_f (p_nb - p_c) / h) times its area, K_f the harmonic mean of the two cells' K
and V_f their mean weighted by 1/K (both exact for layers in series). The solids do not cross a boundary face
(V_f = 0 there). A side is periodic, or has a given normal flux (a floor fed at U(y); U = 0 closes it), or a
given pressure at the face (p' = 0: an open top); a periodic x may carry a mean gradient (``drive``). The
matrix is symmetric positive definite (semi-definite where no side has a given pressure: then p' is pinned to
0 in the first cell, as its constant is free).

The loops see every grid as three-dimensional (nx, ny, nz), the cells numbered x slowest, z fastest; a 2-D
grid has nz = 1 and no faces across z. The solve of the system is :mod:`parsph.gas.darcy`'s.
"""
import numpy as np
from numba import njit

PERIODIC, FLUX, PRESSURE = 0, 1, 2


def pattern(nx, ny, nz, x_bounded, y_bounded):
    """The matrix's pattern (CSR ``indptr``, ``indices``, each row's columns sorted): each cell and its
    neighbours across inner (or periodic) faces; z periodic, with faces across it where nz > 1."""
    idx = np.arange(nx * ny * nz).reshape(nx, ny, nz)
    cols = [idx]
    for axis, bounded in ((0, x_bounded), (1, y_bounded), (2, False)):
        if axis == 2 and nz == 1:
            continue
        up, down = np.roll(idx, -1, axis), np.roll(idx, 1, axis)
        if bounded:
            last = [slice(None)] * 3
            last[axis] = -1
            first = [slice(None)] * 3
            first[axis] = 0
            up[tuple(last)], down[tuple(first)] = idx[tuple(last)], idx[tuple(first)]
        cols += [up, down]
    rows = np.sort(np.stack([c.ravel() for c in cols], axis=1), axis=1)
    keep = np.ones(rows.shape, bool)
    keep[:, 1:] = rows[:, 1:] != rows[:, :-1]
    indptr = np.concatenate([[0], np.cumsum(keep.sum(axis=1))]).astype(np.int64)
    return indptr, rows[keep].astype(np.int64)


@njit(cache=True, inline="always")
def _harm(a, b):
    """The face value of K between two cells: 2 a b / (a + b)."""
    return 2.0 * a * b / (a + b)


@njit(cache=True, inline="always")
def _face_v(Ka, Kb, Va, Vb):
    """The face value of V between two cells: their mean weighted by resistance 1/K, (K_b V_a + K_a V_b) /
    (K_a + K_b). With K_f harmonic it is exact for two half cells in series (the same j through both, the
    pressure drops (h/2)(j - V)/K added): j - V_f = K_f (p_a - p_b) / h. It also makes the faces' drag
    the cells' own: the sum over the x-faces of (j_f - V_f) / K_f is that of the cells' (j_c - V_c) / K_c
    (j_c the mean of a cell's two faces), so the pressure drop across a bed is the drag the grains feel."""
    return (Kb * Va + Ka * Vb) / (Ka + Kb)


def face_arrays(nx, ny, nz):
    """Zeroed arrays for :func:`face_values`: per axis the faces across it, (nx + 1, ny, nz), (nx, ny + 1, nz),
    (nx, ny, nz + 1)."""
    return tuple(np.zeros(s) for s in ((nx + 1, ny, nz), (nx, ny + 1, nz), (nx, ny, nz + 1)))


@njit(cache=True, inline="always")
def _joined(f, n, periodic):
    """The two cells that face f across an axis of n cells joins (below, above): f - 1 and f inside, n - 1 and 0
    at either end of a periodic axis, (-1, -1) at a bounded axis's ends."""
    if 0 < f < n:
        return f - 1, f
    if periodic:
        return n - 1, 0
    return -1, -1


@njit(cache=True)
def face_values(K, V, periodic_x, periodic_y, kx, ky, kz, vx, vy, vz):
    """K_f (:func:`_harm`) and V_f (:func:`_face_v`) of every face between two cells, once for the matrix
    (:func:`assemble`) and the fluxes (:func:`faces`); face f along an axis lies below cell f, and a periodic
    axis's faces 0 and n both join cell n - 1 to cell 0 (a bounded axis's are left as they are). K (nx, ny, nz),
    V (nx, ny, nz, dim); faces across z where nz > 1 (z periodic)."""
    nx, ny, nz = K.shape
    for a in range(nx + 1):
        lo, hi = _joined(a, nx, periodic_x)
        if lo < 0:
            continue
        for b in range(ny):
            for c in range(nz):
                Ka, Kb = K[lo, b, c], K[hi, b, c]
                kx[a, b, c] = _harm(Ka, Kb)
                vx[a, b, c] = _face_v(Ka, Kb, V[lo, b, c, 0], V[hi, b, c, 0])
    for a in range(nx):
        for b in range(ny + 1):
            lo, hi = _joined(b, ny, periodic_y)
            if lo < 0:
                continue
            for c in range(nz):
                Ka, Kb = K[a, lo, c], K[a, hi, c]
                ky[a, b, c] = _harm(Ka, Kb)
                vy[a, b, c] = _face_v(Ka, Kb, V[a, lo, c, 1], V[a, hi, c, 1])
    if nz > 1:
        for a in range(nx):
            for b in range(ny):
                for c in range(nz + 1):
                    lo, hi = _joined(c, nz, True)
                    Ka, Kb = K[a, b, lo], K[a, b, hi]
                    kz[a, b, c] = _harm(Ka, Kb)
                    vz[a, b, c] = _face_v(Ka, Kb, V[a, b, lo, 2], V[a, b, hi, 2])


@njit(cache=True, inline="always")
def _through(kf, vf, drive, p_lo, p_hi, h):
    """A face's flux from its K_f, V_f and the pressures either side."""
    return vf + drive * kf - kf * (p_hi - p_lo) / h


@njit(cache=True, inline="always")
def _given(kind, v, K, p, sign, h):
    """A boundary face's flux: the given one, or through half a cell to the given pressure (sign: -1 on the
    low side, 1 on the high)."""
    if kind == FLUX:
        return v
    return -K * sign * (v - p) / (0.5 * h)


@njit(cache=True)
def axis_faces(K, kf, vf, axis, h, kind_lo, kind_hi, vals_lo, vals_hi, p, out, drive):
    """The mixture's flux along ``axis`` through the faces across it, out (the shape of ``kf``), from the solved
    p' (a given flux where a side gives it) and the faces' K_f, V_f (:func:`face_values`); K, p (nx, ny, nz).
    ``drive``: a mean gradient -drive of p' along a periodic axis adds drive K_f to the faces' flux. A side's
    values are per face, (j, k) flattened on an x side, (i, k) on a y side; z has none (periodic). The inner
    faces in loops of their own, the sides' after them."""
    nx, ny, nz = K.shape
    periodic = kind_lo == PERIODIC
    if axis == 0:
        for a in range(1, nx):
            for b in range(ny):
                for c in range(nz):
                    out[a, b, c] = _through(kf[a, b, c], vf[a, b, c], drive, p[a - 1, b, c], p[a, b, c], h)
        for b in range(ny):
            for c in range(nz):
                for a in (0, nx):
                    if periodic:
                        out[a, b, c] = _through(kf[a, b, c], vf[a, b, c], drive, p[nx - 1, b, c], p[0, b, c], h)
                    else:
                        cell = 0 if a == 0 else nx - 1
                        out[a, b, c] = _given(kind_lo if a == 0 else kind_hi,
                                              vals_lo[b * nz + c] if a == 0 else vals_hi[b * nz + c],
                                              K[cell, b, c], p[cell, b, c], -1.0 if a == 0 else 1.0, h)
    elif axis == 1:
        for a in range(nx):
            for b in range(1, ny):
                for c in range(nz):
                    out[a, b, c] = _through(kf[a, b, c], vf[a, b, c], drive, p[a, b - 1, c], p[a, b, c], h)
            for c in range(nz):
                for b in (0, ny):
                    if periodic:
                        out[a, b, c] = _through(kf[a, b, c], vf[a, b, c], drive, p[a, ny - 1, c], p[a, 0, c], h)
                    else:
                        cell = 0 if b == 0 else ny - 1
                        out[a, b, c] = _given(kind_lo if b == 0 else kind_hi,
                                              vals_lo[a * nz + c] if b == 0 else vals_hi[a * nz + c],
                                              K[a, cell, c], p[a, cell, c], -1.0 if b == 0 else 1.0, h)
    else:
        for a in range(nx):
            for b in range(ny):
                for c in range(1, nz):
                    out[a, b, c] = _through(kf[a, b, c], vf[a, b, c], drive, p[a, b, c - 1], p[a, b, c], h)
                for c in (0, nz):
                    out[a, b, c] = _through(kf[a, b, c], vf[a, b, c], drive, p[a, b, nz - 1], p[a, b, 0], h)


@njit(cache=True)
def centred(jx, jy, jz, out):
    """out (nx, ny, nz, dim) = the faces' flux at the cell centres, the mean of each cell's two faces along each
    axis; jx (nx + 1, ny, nz), jy (nx, ny + 1, nz), jz (nx, ny, nz + 1) (3-D)."""
    nx, ny, nz, dim = out.shape
    for a in range(nx):
        for b in range(ny):
            for c in range(nz):
                out[a, b, c, 0] = 0.5 * (jx[a, b, c] + jx[a + 1, b, c])
                out[a, b, c, 1] = 0.5 * (jy[a, b, c] + jy[a, b + 1, c])
                if dim == 3:
                    out[a, b, c, 2] = 0.5 * (jz[a, b, c] + jz[a, b, c + 1])


def faces(K, kf, vf, h, kinds, values, p, drive):
    """The mixture's flux through every face along each axis, [jx, jy(, jz)] ((nx + 1, ny, nz), ...), from K,
    p' (nx, ny, nz) and the faces' K_f and V_f (:func:`face_values`: per axis); ``drive`` along x only (z
    periodic)."""
    out = []
    for a in range(3 if K.shape[2] > 1 else 2):
        j = np.zeros(kf[a].shape)
        lo, hi = (values[2 * a], values[2 * a + 1]) if a < 2 else (values[0], values[0])
        kind_lo, kind_hi = (kinds[2 * a], kinds[2 * a + 1]) if a < 2 else (PERIODIC, PERIODIC)
        axis_faces(K, kf[a], vf[a], a, h[a], kind_lo, kind_hi, lo, hi, p, j, drive if a == 0 else 0.0)
        out.append(j)
    return out


@njit(cache=True)
def places(indptr, indices, nx, ny, nz):
    """Where :func:`assemble` adds on the pattern ``indptr``, ``indices``: per cell c its diagonal's place in
    ``data`` (``diag[c]``), and per cell and side (-x, +x, -y, +y, -z, +z) the place of the neighbour across it,
    the axis wrapped (``across[c, side]``; -1 where the row holds no such column). Found once per pattern, so
    that the assembly does not search each row for them."""
    n = nx * ny * nz
    diag = np.full(n, -1, np.int64)
    across = np.full((n, 6), -1, np.int64)
    nbs = np.empty(6, np.int64)
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                c = (i * ny + j) * nz + k
                nbs[0] = (((i - 1) % nx) * ny + j) * nz + k
                nbs[1] = (((i + 1) % nx) * ny + j) * nz + k
                nbs[2] = (i * ny + (j - 1) % ny) * nz + k
                nbs[3] = (i * ny + (j + 1) % ny) * nz + k
                nbs[4] = (i * ny + j) * nz + (k - 1) % nz
                nbs[5] = (i * ny + j) * nz + (k + 1) % nz
                for q in range(indptr[c], indptr[c + 1]):
                    col = indices[q]
                    if col == c:
                        diag[c] = q
                    else:
                        for side in range(6):
                            if col == nbs[side]:
                                across[c, side] = q
    return diag, across


@njit(cache=True)
def assemble(K, kx, ky, kz, vx, vy, vz, hx, hy, hz, kinds, vals_lo_x, vals_hi_x, vals_lo_y, vals_hi_y, diag,
             across, data, rhs, pin, drive):
    """The matrix's values (on its fixed pattern, whose places :func:`places` gives as ``diag``, ``across``)
    and the right-hand side: per cell, the sum over its faces of g (p_c - p_nb) = -(the faces' outward V_f +
    given fluxes) times their areas, g = area K_f / distance; ``drive`` as in :func:`axis_faces`. K (nx, ny, nz),
    the faces' K_f and V_f per axis (:func:`face_values`); z periodic, with faces across it in 3-D (nz > 1) only;
    a side's values are per face, (j, k) flattened on an x side, (i, k) on a y side. A cell's sides in the order
    -x, +x, -y, +y(, -z, +z): its diagonal and right-hand side sum them in that order."""
    nx, ny, nz = K.shape
    nsides = 6 if nz > 1 else 4
    data[:] = 0.0
    rhs[:] = 0.0
    for i in range(nx):  # nested loops, not i, j, k divided out of c: 10-14% faster (docs/performance.md)
        for j in range(ny):
            for k in range(nz):
                c = (i * ny + j) * nz + k
                for side in range(nsides):
                    axis = side // 2
                    up = side % 2 == 1          # the face on the + side of the cell
                    if axis == 0:
                        h, area = hx, hy * hz
                    elif axis == 1:
                        h, area = hy, hx * hz
                    else:
                        h, area = hz, hx * hy
                    inside = True
                    if axis == 0:
                        if (i == 0 and not up) or (i == nx - 1 and up):
                            inside = kinds[0] == PERIODIC
                        f = i + 1 if up else i
                        Kf, Vf = kx[f, j, k], vx[f, j, k]
                    elif axis == 1:
                        if (j == 0 and not up) or (j == ny - 1 and up):
                            inside = kinds[2] == PERIODIC
                        f = j + 1 if up else j
                        Kf, Vf = ky[i, f, k], vy[i, f, k]
                    else:
                        f = k + 1 if up else k
                        Kf, Vf = kz[i, j, f], vz[i, j, f]
                    sign = 1.0 if up else -1.0
                    if inside:
                        g = area * Kf / h
                        vout = sign * Vf
                        if axis == 0:
                            vout += sign * drive * Kf
                        rhs[c] -= area * vout
                        data[diag[c]] += g
                        data[across[c, side]] -= g
                    else:
                        kind = kinds[2 * axis + (1 if up else 0)]
                        if axis == 0:
                            v = vals_hi_x[j * nz + k] if up else vals_lo_x[j * nz + k]
                        else:
                            v = vals_hi_y[i * nz + k] if up else vals_lo_y[i * nz + k]
                        if kind == FLUX:
                            rhs[c] -= sign * area * v
                        else:
                            g = area * K[i, j, k] / (0.5 * h)
                            data[diag[c]] += g
                            rhs[c] += g * v
    if pin:
        q = diag[0]
        data[q] += data[q] if data[q] != 0.0 else 1.0


@njit(cache=True)
def matvec(indptr, indices, data, x, out):
    """out = A x for A in CSR form, each row's terms summed in its order; returns x . out, in four interleaved
    partial sums (element k in sum k mod 4, the last n mod 4 in the first, then (s0 + s1) + (s2 + s3):
    :func:`parsph.gas.band_pcg._dot4`'s order and bits), for conjugate gradients' d . A d in the same pass. A row
    of five (a 2-D grid's inner cell) is written out: a loop of unknown length took 1.3x as long, and a helper
    per row 10x (numba counts the arrays' references at each call)."""
    n = len(indptr) - 1
    s = np.zeros(4)
    last = 4 * (n // 4)
    for r in range(n):
        a = indptr[r]
        m = indptr[r + 1] - a
        acc = 0.0
        if m == 5:
            acc += data[a] * x[indices[a]]
            acc += data[a + 1] * x[indices[a + 1]]
            acc += data[a + 2] * x[indices[a + 2]]
            acc += data[a + 3] * x[indices[a + 3]]
            acc += data[a + 4] * x[indices[a + 4]]
        else:
            for q in range(a, a + m):
                acc += data[q] * x[indices[q]]
        out[r] = acc
        s[r & 3 if r < last else 0] += x[r] * acc
    return (s[0] + s[1]) + (s[2] + s[3])
