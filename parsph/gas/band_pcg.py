"""Uses of a banded Cholesky factor in compiled code: the direct solve, and conjugate gradients preconditioned
with the factor of an earlier matrix (:class:`parsph.gas.darcy.Darcy`).

The factor is LAPACK's (scipy.linalg.cholesky_banded, upper form: ``ab[w + r - c, c] = U[r, c]``); its
transpose ``T`` (n, w + 1), where ``T[c, k] = U[c - w + k, c]`` and ``T[c, w]`` is the diagonal, holds each
column of U contiguously (scipy returns the factor in Fortran order, so ``c.T`` costs nothing). The cells are in
the band's order: place k of the band is the cell ``order[k]``. A use is two sweeps over the band:

    U^T y = b:  y_c = (b_c - sum_{r=c-w}^{c-1} U_rc y_r) / U_cc     (a dot product along column c)
    U x = y:    x_c = y_c / U_cc, then y_r -= U_rc x_c, r < c       (an axpy along column c, c from the top)

one pass each, as fast as scipy's ``cho_solve_banded`` (LAPACK's dpbtrs: 0.11 against 0.13 ms on a bed's
38 x 112 cells, half-width 76), and the second two columns at a time, each row's two terms in the one-column
order (15% off a use of that factor: it reads and writes the rows above half as often); the iteration's
vector arithmetic in the same compiled loop is what was numpy's, which cost a 2-D bed's gas stage a third of
its time (docs/performance.md, "The solved gas"). The dot products keep four partial sums in a fixed order:
the same bits on every machine and rank. The sweeps run in T's precision: :class:`parsph.gas.darcy.Darcy` keeps
the factor it preconditions with in single precision (1.3 MB instead of 2.6 on those cells, in a core's L2: a use
109 against 187 us), and solves directly with the double one.
"""
import numpy as np
from numba import njit, uintp

from .finite_volumes import matvec


@njit(cache=True, inline="always")
def _dot4(a, a0, b, b0, m):
    """sum_{k<m} a[a0 + k] b[b0 + k] in four interleaved partial sums (a fixed order: vector registers, the
    same bits everywhere), in a's precision (single for the kept factor's sweeps: 15% faster than summing
    them in double); unsigned indices, which numba checks for no wraparound."""
    s0 = s1 = s2 = s3 = a.dtype.type(0.0)
    aa = a[a0:a0 + m]
    bb = b[b0:b0 + m]
    q = m // 4
    for i in range(uintp(q)):
        k = i * uintp(4)
        s0 += aa[k] * bb[k]
        s1 += aa[k + uintp(1)] * bb[k + uintp(1)]
        s2 += aa[k + uintp(2)] * bb[k + uintp(2)]
        s3 += aa[k + uintp(3)] * bb[k + uintp(3)]
    for k in range(uintp(4 * q), uintp(m)):
        s0 += aa[k] * bb[k]
    return (s0 + s1) + (s2 + s3)


@njit(cache=True)
def band_solve(T, order, b, x, work):
    """x = A^-1 b for A = P U^T U P^T (U's transpose ``T``, (n, w + 1); ``order`` the band's cells); ``work``
    (n) scratch, in T's precision: the sweeps run in it. ``x`` may be ``b``."""
    n, w1 = T.shape
    w = w1 - 1
    flat = T.reshape(-1)
    for k in range(n):
        work[k] = b[order[k]]
    for c in range(n):  # U^T y = b
        k0 = max(0, w - c)
        row = c * w1
        work[c] = (work[c] - _dot4(flat, row + k0, work, c - w + k0, w - k0)) / flat[row + w]
    c = n - 1
    while c >= 0:  # U x = y: two columns a pass where both reach w rows up
        row = c * w1
        xc = work[c] / flat[row + w]
        work[c] = xc
        if c - 1 < w or w < 2:
            k0 = max(0, w - c)
            col = flat[row + k0:row + w]
            above = work[c - w + k0:c]
            for k in range(uintp(w - k0)):
                above[k] -= col[k] * xc
            c -= 1
            continue
        # column c's term of row c - 1 makes x_{c-1}; then each row above takes column c's term and column
        # c - 1's, in that order (the one-column sweep's order: the same bits), in one pass over them
        below = (c - 1) * w1
        work[c - 1] -= flat[row + w - 1] * xc
        xb = work[c - 1] / flat[below + w]
        work[c - 1] = xb
        work[c - 1 - w] -= flat[below] * xb
        col_c = flat[row:row + w - 1]          # rows c - w .. c - 2
        col_b = flat[below + 1:below + w]      # the same rows in column c - 1
        above = work[c - w:c - 1]
        for k in range(uintp(w - 1)):
            above[k] = (above[k] - col_c[k] * xc) - col_b[k] * xb
        c -= 2
    for k in range(n):
        x[order[k]] = work[k]


@njit(cache=True)
def largest(r):
    """max_k |r_k| in four running maxima (no chain through every element), and whether every r_k is finite."""
    n = len(r)
    m0 = m1 = m2 = m3 = 0.0
    ok = True
    q = n // 4
    for i in range(q):
        k = 4 * i
        a0, a1, a2, a3 = abs(r[k]), abs(r[k + 1]), abs(r[k + 2]), abs(r[k + 3])
        m0, m1, m2, m3 = max(m0, a0), max(m1, a1), max(m2, a2), max(m3, a3)
        ok = ok & (a0 < np.inf) & (a1 < np.inf) & (a2 < np.inf) & (a3 < np.inf)
    for k in range(4 * q, n):
        a0 = abs(r[k])
        m0 = max(m0, a0)
        ok = ok & (a0 < np.inf)
    return max(max(m0, m1), max(m2, m3)), ok


@njit(cache=True)
def pcg(indptr, indices, data, T, order, b, x, rtol, max_iter, scratch, work):
    """A x = b (A in CSR form) by conjugate gradients preconditioned with the factor (``T``, ``order``:
    :func:`band_solve`) of an earlier matrix, from x as given, x updated in place; ``scratch`` (4, n), ``work``
    (n) in T's precision (the sweeps').
    Returns the iterations, or -1 where max |residual| has not reached rtol max |b| in ``max_iter`` or is
    not finite."""
    n = len(b)
    r, z, d, Ap = scratch[0], scratch[1], scratch[2], scratch[3]
    scale, _ = largest(b)
    if scale == 0.0:
        x[:] = 0.0
        return 0
    matvec(indptr, indices, data, x, r)
    for k in range(n):
        r[k] = b[k] - r[k]
    big, finite = largest(r)
    rz_old = 0.0
    for it in range(max_iter + 1):
        if not finite:
            return -1
        if big <= rtol * scale:
            return it
        if it == max_iter:
            return -1
        band_solve(T, order, r, z, work)
        rz = _dot4(r, 0, z, 0, n)
        if it == 0:
            d[:] = z
        else:
            beta = rz / rz_old
            for k in range(n):
                d[k] = z[k] + beta * d[k]
        alpha = rz / matvec(indptr, indices, data, d, Ap)  # and d . Ap
        for k in range(n):
            x[k] += alpha * d[k]
            r[k] -= alpha * Ap[k]
        big, finite = largest(r)
        rz_old = rz
    return -1
