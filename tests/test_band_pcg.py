"""The compiled uses of a banded Cholesky factor (parsph.gas.band_pcg) against scipy: the direct solve against
LAPACK's dpbtrs (scipy.linalg.cho_solve_banded), the preconditioned conjugate gradients against a sparse LU
solve of the same matrix."""
import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from parsph.gas import band_pcg
from parsph.gas import finite_volumes as fv


def _band(n, w, seed):
    """A random symmetric positive definite band matrix: its upper form (w + 1, n) and as CSR."""
    rng = np.random.default_rng(seed)
    ab = np.zeros((w + 1, n))
    ab[:w] = -rng.random((w, n))
    ab[w] = 2.0 * w + 1.0  # diagonally dominant
    for r in range(w):  # the unused corner of the upper form
        ab[r, :w - r] = 0.0
    upper = sp.triu(sp.dia_matrix((ab[::-1], np.arange(0, w + 1)), shape=(n, n)), 1)
    A = (sp.diags(ab[w]) + upper + upper.T).tocsr()
    A.sort_indices()
    return ab, A


@pytest.mark.parametrize("n, w", [(200, 7), (50, 1), (9, 12), (300, 33)])
def test_band_solve_is_lapacks_in_any_order(n, w):
    ab, _ = _band(n, w, 1)
    c = sla.cholesky_banded(ab, check_finite=False)
    rng = np.random.default_rng(2)
    order = rng.permutation(n).astype(np.int64)
    b = rng.normal(size=n)
    x = np.empty(n)
    band_pcg.band_solve(np.ascontiguousarray(c.T), order, b, x, np.empty(n))
    ref = np.empty(n)
    ref[order] = sla.cho_solve_banded((c, False), b[order])
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-14 * np.abs(ref).max())


def _two_sweeps(T, order, b):
    """The two sweeps of band_pcg's doc in plain Python floats, one column at a time: U^T y = b with each
    column's dot product in four interleaved partial sums (the rest after the last whole four added to the
    first), combined as (s0 + s1) + (s2 + s3); U x = y with column c's terms subtracted from the rows above it,
    c from the last. The order every rank and machine must reproduce."""
    n, w = T.shape[0], T.shape[1] - 1
    y = [float(b[order[k]]) for k in range(n)]
    for c in range(n):
        k0 = max(0, w - c)
        m = w - k0
        s = [0.0, 0.0, 0.0, 0.0]
        for i in range(m):
            s[i % 4 if i < 4 * (m // 4) else 0] += float(T[c, k0 + i]) * y[c - w + k0 + i]
        y[c] = (y[c] - ((s[0] + s[1]) + (s[2] + s[3]))) / float(T[c, w])
    for c in range(n - 1, -1, -1):
        y[c] = y[c] / float(T[c, w])
        for k in range(max(0, w - c), w):
            y[c - w + k] -= float(T[c, k]) * y[c]
    x = np.empty(n)
    x[order] = y
    return x


@pytest.mark.parametrize("n, w", [(200, 7), (50, 1), (9, 12), (300, 33), (301, 16), (40, 2), (5, 0)])
def test_band_solve_makes_the_one_column_sweeps_operations(n, w):
    """Bit for bit the sweeps' arithmetic written out one column at a time (:func:`_two_sweeps`), whatever
    the compiled loops group: the same bits on every machine and rank count."""
    rng = np.random.default_rng(n + w)
    T = rng.random((n, w + 1)) * 0.3
    T[:, w] = 1.0 + rng.random(n)
    order = rng.permutation(n).astype(np.int64)
    b = rng.normal(size=n)
    x = np.empty(n)
    band_pcg.band_solve(T, order, b, x, np.empty(n))
    assert np.array_equal(x, _two_sweeps(T, order, b))


@pytest.mark.parametrize("single", [False, True])
def test_preconditioned_cg_converges_to_the_sparse_lu_solve(single):
    """The factor of a nearby matrix (each entry off by up to 5%) preconditions A, in double precision or rounded
    to single with sweeps in single (darcy's kept factor): the iteration reaches max |r| <= rtol max |b|, its x
    agrees with SuperLU's to that tolerance; with one iteration allowed it does not converge (-1); a NaN in b is
    no convergence either."""
    n, w = 400, 20
    ab, A = _band(n, w, 3)
    near = ab * (1.0 + 0.05 * np.random.default_rng(4).uniform(-1, 1, ab.shape))
    c = sla.cholesky_banded(near, check_finite=False)
    kind = np.float32 if single else np.float64
    T, order = np.ascontiguousarray(c.T).astype(kind), np.arange(n, dtype=np.int64)
    b = np.random.default_rng(5).normal(size=n)
    x = np.zeros(n)
    scratch, work = np.zeros((4, n)), np.zeros(n, kind)
    indptr, indices = A.indptr.astype(np.int64), A.indices.astype(np.int64)
    its = band_pcg.pcg(indptr, indices, A.data, T, order, b, x, 1e-12, 50, scratch, work)
    assert 1 < its < 50
    ref = spla.splu(A.tocsc()).solve(b)
    assert np.abs(A @ x - b).max() <= 1e-12 * np.abs(b).max()
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-10 * np.abs(ref).max())
    assert band_pcg.pcg(indptr, indices, A.data, T, order, b, np.zeros(n), 1e-12, 1, scratch, work) == -1
    bad = b.copy()
    bad[7] = np.nan
    assert band_pcg.pcg(indptr, indices, A.data, T, order, bad, np.zeros(n), 1e-12, 50, scratch, work) == -1


def test_matvec_is_the_sparse_product_and_returns_the_dot_in_four_partial_sums():
    """fv.matvec: A x against scipy's CSR product (rows of five and of other lengths), and its x . A x bit for bit
    the dot product of band_pcg's four interleaved partial sums, written out here in plain Python."""
    rng = np.random.default_rng(6)
    indptr, indices = fv.pattern(7, 9, 1, True, False)  # rows of 4 at the walls, 5 inside
    data = rng.normal(size=len(indices))
    A = sp.csr_matrix((data, indices, indptr), shape=(63, 63))
    x = rng.normal(size=63)
    out = np.empty(63)
    dot = fv.matvec(indptr, indices, data, x, out)
    np.testing.assert_allclose(out, A @ x, rtol=1e-14, atol=1e-14 * np.abs(A @ x).max())
    s = [0.0, 0.0, 0.0, 0.0]
    for k in range(63):
        s[k % 4 if k < 60 else 0] += x[k] * out[k]
    assert dot == (s[0] + s[1]) + (s[2] + s[3])
    assert dot == band_pcg._dot4(x, 0, out, 0, 63)
