"""The gas solve's band split in two at a separator (docs/performance.md, "The band split in two"): the cells
numbered x slowest, one row of cells across x in the middle (``w`` cells: the band's half-width) separates the
rows below it (block 0) from those above (block 1, numbered from the top down, so that its row next to the
separator comes last too). With A = [[A_0, 0, D_0], [0, A_1, D_1], [D_0^T, D_1^T, A_s]]:

    S = A_s - D_0^T A_0^-1 D_0 - D_1^T A_1^-1 D_1

and only the blocks' last w x w corner of A_b^-1 enters it: with A_b = U^T U (banded Cholesky), that corner is
(U_c^T U_c)^-1, U_c the last w x w block of U, so each block's share of S costs a triangular solve of w x w.
A solve: y_b = A_b^-1 b_b, x_s = S^-1 (b_s - sum D_b^T y_b), x_b = A_b^-1 (b_b - D_b x_s).

Each block's factorisation and solves are independent: a rank does its own (``share``: which blocks are this
process's, and how the others' results reach it: :class:`Local` in one process, or
:class:`parsph.parallel.block_share.BlockShare` over the ranks). The arithmetic of a block is the same
wherever it runs, so the result is the same bits on any rank count. Two blocks cost what the whole band costs
(n w^2 each half) and run side by side on two ranks.
"""
import numpy as np
import scipy.linalg as sla

BLOCKS = 2


class Local:
    """Every block in this process."""

    def mine(self, block):
        return True

    def share_all(self, arrays):
        return list(arrays)

    def agree_failed(self, failed):
        return failed


class SplitBand:
    """The split of one matrix pattern (CSR ``indptr``, ``indices``, the cells numbered x slowest) of ``nx``
    rows of ``w`` cells across x."""

    def __init__(self, indptr, indices, nx, w):
        n = nx * w
        m = nx // 2
        self.w = w
        self.rows = [np.arange(0, m * w), np.arange((m + 1) * w, n)[::-1]]
        self.sep = np.arange(m * w, (m + 1) * w)
        rows_of = np.repeat(np.arange(n), np.diff(indptr))
        cols_of = np.asarray(indices)
        sep = np.full(n, -1)  # a separator cell's place in it
        sep[self.sep] = np.arange(w)
        self.band = []    # per block: (the entries of data it takes, their places in its upper band)
        self.coupling = []  # per block: (entries, places in D_b (its last w cells x the separator))
        for cells in self.rows:
            place = np.full(n, -1)
            place[cells] = np.arange(cells.size)
            pr, pc = place[rows_of], place[cols_of]
            upper = (pr >= 0) & (pc >= 0) & (pr <= pc)
            self.band.append((np.nonzero(upper)[0], (w + pr[upper] - pc[upper], pc[upper])))
            last = np.full(n, -1)
            last[cells[-w:]] = np.arange(w)
            couple = (last[rows_of] >= 0) & (sep[cols_of] >= 0)
            self.coupling.append((np.nonzero(couple)[0], (last[rows_of][couple], sep[cols_of][couple])))
        inside = (sep[rows_of] >= 0) & (sep[cols_of] >= 0)
        self.sep_entries = (np.nonzero(inside)[0], (sep[rows_of][inside], sep[cols_of][inside]))
        self.factors = [None] * BLOCKS
        self.D = [None] * BLOCKS
        self.S = None
        self.n = n

    def factorise(self, data, share):
        """The blocks' banded Cholesky (this process's) and the separator's; raises np.linalg.LinAlgError on
        every process where any block's matrix is not positive definite."""
        w = self.w
        corners = []
        failed = False
        for b in range(BLOCKS):
            take, at = self.coupling[b]
            D = np.zeros((w, w))
            D[at] = data[take]
            self.D[b] = D
            corner = np.zeros((w, w))
            if share.mine(b):
                take, at = self.band[b]
                # in LAPACK's (Fortran) order and factorised in place: scipy would copy a C-ordered band into
                # that order first (8 MB a block on 80 x 160 cells: 11-13 against 8.5-9 ms; the same bits)
                ab = np.zeros((w + 1, self.rows[b].size), order="F")
                ab[at] = data[take]
                try:
                    c = sla.cholesky_banded(ab, overwrite_ab=True, check_finite=False)
                except np.linalg.LinAlgError:
                    failed = True
                else:
                    self.factors[b] = c
                    corner = self._corner(c, D)
            corners.append(corner)
        if share.agree_failed(failed):
            raise np.linalg.LinAlgError("a block of the split band is not positive definite")
        take, at = self.sep_entries
        S = np.zeros((w, w))
        S[at] = data[take]
        for corner in share.share_all(corners):
            S -= corner
        self.S = sla.cho_factor(S, check_finite=False)

    def _corner(self, c, D):
        """D^T (A_b^-1 restricted to its last w cells) D = X^T X, U_c^T X = D, U_c the factor's last w x w."""
        w, nb = self.w, c.shape[1]
        ii, jj = np.triu_indices(w)
        U = np.zeros((w, w))
        U[ii, jj] = c[w + ii - jj, nb - w + jj]
        X = sla.solve_triangular(U, D, trans="T", check_finite=False)
        return X.T @ X

    def solve(self, rhs, share):
        """A^-1 rhs, the same on every process."""
        w = self.w
        tips = []
        for b in range(BLOCKS):
            tip = np.zeros(w)
            if share.mine(b):
                y = sla.cho_solve_banded((self.factors[b], False), rhs[self.rows[b]], check_finite=False)
                tip = self.D[b].T @ y[-w:]
            tips.append(tip)
        tips = share.share_all(tips)
        g = rhs[self.sep] - tips[0] - tips[1]
        xs = sla.cho_solve(self.S, g, check_finite=False)
        x = np.empty(self.n)
        x[self.sep] = xs
        parts = []
        for b in range(BLOCKS):
            part = np.zeros(self.rows[b].size)
            if share.mine(b):
                r = rhs[self.rows[b]].copy()
                r[-w:] -= self.D[b] @ xs
                part = sla.cho_solve_banded((self.factors[b], False), r, check_finite=False)
            parts.append(part)
        for b, part in enumerate(share.share_all(parts)):
            x[self.rows[b]] = part
        return x
