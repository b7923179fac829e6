"""The gas pressure's matrix and right-hand side (parsph.gas.finite_volumes.assemble, on the places that
``places`` finds in the pattern) against a dense build face by face: each face once, its conductance
g = area K_f / h added to the two cells it joins (2 K / h at a face of given pressure), its V_f and given
fluxes to the right-hand side, in 2-D and 3-D with every kind of side."""
import numpy as np
import pytest

from parsph.gas import finite_volumes as fv

P, F, Q = fv.PERIODIC, fv.FLUX, fv.PRESSURE


def _cell(axis, i, a, c):
    """The index (x, y, z) of the cell i along ``axis``, a and c along the next two axes (cyclically)."""
    idx = [0, 0, 0]
    idx[axis], idx[(axis + 1) % 3], idx[(axis + 2) % 3] = i, a, c
    return tuple(idx)


def dense(K, V, h, kinds, values, drive):
    """A and b of the finite volumes, face by face (numpy, dense)."""
    nx, ny, nz = K.shape
    n = K.size
    A, b = np.zeros((n, n)), np.zeros(n)
    cell = np.arange(n).reshape(nx, ny, nz)
    areas = (h[1] * h[2], h[0] * h[2], h[0] * h[1])
    for axis in range(3 if nz > 1 else 2):
        m, area = K.shape[axis], areas[axis]
        periodic = axis == 2 or kinds[2 * axis] == P
        for face in range(m if periodic else m + 1):  # face f lies below cell f along the axis
            for a in range(K.shape[(axis + 1) % 3]):
                for c in range(K.shape[(axis + 2) % 3]):
                    if periodic or 0 < face < m:  # an inner face between lo and hi
                        lo, hi = _cell(axis, (face - 1) % m, a, c), _cell(axis, face, a, c)
                        Kl, Kh = K[lo], K[hi]
                        Kf = 2 * Kl * Kh / (Kl + Kh)
                        g = area * Kf / h[axis]
                        Vf = (Kh * V[lo + (axis,)] + Kl * V[hi + (axis,)]) / (Kl + Kh)
                        if axis == 0:
                            Vf += drive * Kf
                        i, j = cell[lo], cell[hi]
                        A[i, i] += g
                        A[j, j] += g
                        A[i, j] -= g
                        A[j, i] -= g
                        b[i] -= area * Vf   # out of lo through its + face
                        b[j] += area * Vf   # into hi through its - face
                        continue
                    up = face == m  # the high side's face of the last cell, else the low side's of the first
                    inner = _cell(axis, m - 1 if up else 0, a, c)
                    side = 2 * axis + (1 if up else 0)
                    v = values[side][a * nz + c if axis == 0 else c * nz + a]  # per (j, k) or (i, k)
                    i = cell[inner]
                    if kinds[side] == F:
                        b[i] -= (1.0 if up else -1.0) * area * v
                    else:
                        g = area * K[inner] / (0.5 * h[axis])
                        A[i, i] += g
                        b[i] += g * v
    if not np.any(np.asarray(kinds) == Q):
        A[0, 0] += A[0, 0] if A[0, 0] != 0.0 else 1.0
    return A, b


@pytest.mark.parametrize("shape, kinds, drive", [
    ((5, 7, 1), (F, Q, P, P), 0.0),   # a bed's grid: floor fed, top open, y periodic
    ((5, 7, 1), (F, Q, F, F), 0.0),   # side walls
    ((6, 4, 1), (P, P, P, P), 1.0),   # periodic along gravity, driven
    ((4, 5, 3), (F, Q, P, P), 0.0),   # 3-D
    ((4, 6, 3), (F, Q, F, Q), 1.0),
    ((3, 3, 1), (F, F, F, F), 0.0),   # every side fed: the constant pinned
])
def test_assembly_is_the_dense_build_face_by_face(shape, kinds, drive):
    nx, ny, nz = shape
    rng = np.random.default_rng(7)
    K = np.exp(3.0 * rng.normal(size=shape))
    dim = 3 if nz > 1 else 2
    V = rng.normal(size=shape + (dim,))
    h = (0.3, 0.7, 1.1 if nz > 1 else 1.0)
    values = [rng.normal(size=m) for m in (ny * nz, ny * nz, nx * nz, nx * nz)]
    kinds = np.array(kinds, np.int64)
    indptr, indices = fv.pattern(nx, ny, nz, kinds[0] != P, kinds[2] != P)
    data, rhs = np.zeros(len(indices)), np.zeros(K.size)
    kf, vf = fv.face_arrays(nx, ny, nz), fv.face_arrays(nx, ny, nz)
    fv.face_values(K, V, kinds[0] == P, kinds[2] == P, *kf, *vf)
    fv.assemble(K, *kf, *vf, *h, kinds, *values, *fv.places(indptr, indices, nx, ny, nz), data, rhs,
                not np.any(kinds == Q), drive)
    A = np.zeros((K.size, K.size))
    for r in range(K.size):
        A[r, indices[indptr[r]:indptr[r + 1]]] = data[indptr[r]:indptr[r + 1]]
    A_ref, b_ref = dense(K, V, h, kinds, values, drive)
    scale = np.abs(A_ref).max()
    np.testing.assert_allclose(A, A_ref, rtol=1e-13, atol=1e-13 * scale)
    np.testing.assert_allclose(rhs, b_ref, rtol=1e-12, atol=1e-12 * np.abs(b_ref).max())
    np.testing.assert_array_equal(A, A.T)  # symmetric, bit for bit
