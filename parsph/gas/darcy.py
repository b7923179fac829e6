"""The solve of the gas pressure's equation (:mod:`parsph.gas.finite_volumes`; docs/physics.md, "The solved
gas"). The solves are a well-kept library's: where x has sides the cells are ordered so that the matrix is a
narrow band (:func:`band_order`: half-width ny, or 2 nx with a periodic y folded; ny nz in 3-D) and LAPACK's
banded Cholesky (scipy.linalg.cholesky_banded) factorises it, 2-3x faster than SuperLU on the grids of a bed
up to a half-width of :data:`BAND_MAX` (:data:`BAND_MAX_3D` in 3-D); past it, and where x is periodic,
scipy's sparse LU (SuperLU), ordered by minimum degree on A + A^T where the band was too wide (on one idle
core: 80 x 160 cells, half-width 160, 20.6 ms the band and 19.6 ms SuperLU; 160 x 320, half-width 320, 625 and
142 ms). A band of :data:`SPLIT_MIN` or wider factorises as two blocks and a separator, one block a rank
(:mod:`parsph.gas.split_band`).

A factorisation costs 20-30 times a use of its factor (2-3 ms against 0.1 on 38 x 112 cells), and K changes little
from one step to the next, so :class:`Darcy` keeps the factor of an earlier K and solves by conjugate gradients
preconditioned with it, started from p' extrapolated from the last two solves, 2 p_1 - p_2 (on the 2-D bed of
docs/performance.md a third of the factorisations that the last p' alone needs), until every cell's flux
imbalance is below :data:`RTOL` of the largest given one (a whole band's iteration compiled,
:mod:`parsph.gas.band_pcg`, with the kept factor in single precision: its sweeps read half the bytes and the
iterations are as many as with the double; the solve right after a factorisation is the double's own); a
solve that needs more than :data:`REFRESH_ITER` iterations makes the next one factorise afresh, and one that
has not converged in :data:`MAX_ITER` factorises at once. What a solve starts from (the factor's K and the
warm start) is :meth:`Darcy.start`, which a restart point keeps so that a restarted run makes the same solves.
A matrix that is not positive definite or a non-finite result raises :class:`SolveFailed`.

:class:`Darcy` keeps the matrix's pattern of one grid and its sides, and fills its values, the right-hand side
and the fluxes with :mod:`parsph.gas.finite_volumes`' loops.
"""
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from . import band_pcg
from . import finite_volumes as fv
from .finite_volumes import FLUX, PERIODIC, PRESSURE
from .split_band import Local, SplitBand

RTOL = 1e-10       # the preconditioned solve's end: max |residual| <= RTOL max |right-hand side|
# iterations before the solve gives up on the old factor and factorises: a bubbling bed's K moves so fast that
# no solve converges on an earlier factor, and each try costs iterations (2 ms for 12 on its 80 x 40 cells,
# against 1.3 ms for the factorisation); a bed at rest converges in 3-5
MAX_ITER = 6
REFRESH_ITER = 4   # a solve that needed more makes the next one factorise
# the widest band factorised as a band: at half-width 160 (80 x 160 cells) the band and SuperLU take the same
# (20 ms), at 120 the band 10 ms against 18; the band's cost grows as n w^2, SuperLU's with minimum degree
# about as n^1.5 (docs/performance.md)
BAND_MAX = 160
# in 3-D minimum degree leaves SuperLU far more fill (a 3-D grid's separators are planes), and the band wins to
# a half-width of about 900 (docs/performance.md, "The solved gas in 3-D"); a band past BAND_BYTES goes to
# SuperLU all the same
BAND_MAX_3D = 900
BAND_BYTES = 512 * 2 ** 20
# a band this wide or wider, numbered x slowest, factorises as two blocks and a separator
# (:mod:`parsph.gas.split_band`): 80 x 160 cells 7.5 and 6.4 ms a block against 18.3 ms whole, the blocks side by
# side on two ranks (docs/performance.md, "The band split in two"); narrower bands (every shipped scene's) whole
SPLIT_MIN = 128
# a split band tries its kept factor only where no cell's K moved by more than this in log since the factor's K:
# in run/bubbling_bed.toml's first 300 steps every try that converged had moved at most 0.125 and the tries
# that failed (6 preconditioned iterations each, then a factorisation) 0.064-1.7, median 0.26
SPLIT_TRY_CHANGE = 0.2
KINDS = {"flux": FLUX, "pressure": PRESSURE}


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
    p: np.ndarray    # p' per cell (nx, ny[, nz]) [Pa]
    jx: np.ndarray   # the mixture's flux along +x through the x-faces (nx + 1, ny[, nz]) [m/s]
    jy: np.ndarray   # along +y through the y-faces (nx, ny + 1[, nz]) [m/s]
    jz: np.ndarray = None  # along +z through the z-faces (nx, ny, nz + 1) [m/s] (3-D)

    def centred(self):
        """j at the cell centres (cells..., dim): the mean of each cell's two faces along each axis."""
        nx, ny = self.p.shape[:2]
        nz = self.p.shape[2] if self.p.ndim == 3 else 1
        dim = 2 if self.jz is None else 3
        out = np.empty((nx, ny, nz, dim))
        jz = self.jz if self.jz is not None else np.zeros((1, 1, 1))
        fv.centred(np.ascontiguousarray(self.jx).reshape(nx + 1, ny, nz),
                   np.ascontiguousarray(self.jy).reshape(nx, ny + 1, nz), np.ascontiguousarray(jz), out)
        return out.reshape(self.p.shape + (dim,))


def band_order(nx, ny, periodic_y):
    """The cells in the order of the narrowest band and its half-width: along y first (cell i ny + j, half-width
    ny), or along x first with y folded where it is periodic (j = 0, ny - 1, 1, ny - 2, ...: a ring's
    neighbours at most 2 apart, half-width 2 nx; nx without the fold) where that is narrower.
    ``order[k]``: the cell (i ny + j) in place k."""
    idx = np.arange(nx * ny).reshape(nx, ny)
    across = 2 * nx if periodic_y else nx
    if across >= ny:
        return idx.ravel(), ny
    js = np.arange(ny)
    if periodic_y:  # 0, ny-1, 1, ny-2, ...
        js = np.empty(ny, np.int64)
        js[0::2] = np.arange((ny + 1) // 2)
        js[1::2] = ny - 1 - np.arange(ny // 2)
    return idx[:, js].T.ravel(), across


class Darcy:
    """The solve on one grid (nx x ny cells of hx x hy; x nz cells of hz along a periodic z in 3-D, nz > 1)
    with its sides: ``x_sides`` = (low, high) :class:`Side` at x = 0 and x = nx hx, None for periodic;
    likewise ``y_sides``. Periodic axes need 3 cells or more (a cell's two neighbours along them are then
    distinct).

    ``mean_flux`` (x periodic): the mixture's flux through every cross-section of x, per unit length of it
    (a box periodic along gravity fed at U). Then p' = p~ - G x, p~ periodic: the solve for p~ with G = 0 and
    with the unit G (one matrix, two right-hand sides), superposed with the G that carries the flux.

    ``reuse`` False: every solve factorises (the reference the preconditioned solves are measured against).
    ``method``: "band", "split" (the band as two blocks and a separator) or "superlu" (minimum degree) where x
    has sides, instead of the choice by the band's half-width (benchmarks and tests). ``share``: where a split
    band's blocks are factorised (:class:`parsph.parallel.block_share.BlockShare` over the ranks; default all
    here); every process of a share must make the same calls."""

    def __init__(self, nx, ny, hx, hy, x_sides=None, y_sides=None, mean_flux=None, reuse=True, nz=1, hz=1.0,
                 method=None, share=None):
        if mean_flux is not None and x_sides is not None:
            raise ValueError("a mean flux drives a periodic x only")
        self.mean_flux = mean_flux
        self.gradient = 0.0  # G of the last solve: p' = p~ - G x
        self.nx, self.ny, self.hx, self.hy = nx, ny, hx, hy
        self.nz, self.hz = nz, (hz if nz > 1 else 1.0)
        self.dim = 3 if nz > 1 else 2
        self.shape = (nx, ny) + ((nz,) if nz > 1 else ())
        axes = ((nx, x_sides, "x"), (ny, y_sides, "y")) + (((nz, None, "z"),) if nz > 1 else ())
        for n, sides, name in axes:
            if n < 3 and sides is None:
                raise ValueError(f"a periodic axis needs 3 cells or more ({name}: {n})")
        none = Side("flux", np.zeros(1))
        xs = x_sides or (none, none)
        ys = y_sides or (none, none)
        self.kinds = np.array([PERIODIC if x_sides is None else KINDS[xs[0].kind],
                               PERIODIC if x_sides is None else KINDS[xs[1].kind],
                               PERIODIC if y_sides is None else KINDS[ys[0].kind],
                               PERIODIC if y_sides is None else KINDS[ys[1].kind]], np.int64)
        # own writable copies: one array type for every side (a read-only view would be a type of its own to the
        # compiled loops: a version more of each); per face, (j, k) flattened on an x side, (i, k) on a y side
        self.values = [np.array(np.broadcast_to(np.asarray(s.values, float), (m,)))
                       for s, m in ((xs[0], ny * nz), (xs[1], ny * nz), (ys[0], nx * nz), (ys[1], nx * nz))]
        self.pin = not np.any(self.kinds == PRESSURE)
        n = nx * ny * nz
        self.indptr, self.indices = fv.pattern(nx, ny, nz, x_sides is not None, y_sides is not None)
        self.places = fv.places(self.indptr, self.indices, nx, ny, nz)  # where the assembly adds
        self.data = np.zeros(len(self.indices))
        self.periodic = (x_sides is None, y_sides is None)
        self.kf = fv.face_arrays(nx, ny, nz)  # the faces' K_f and V_f (finite_volumes.face_values)
        self.vf = fv.face_arrays(nx, ny, nz)
        self.unit_vf = fv.face_arrays(nx, ny, nz) if mean_flux is not None else None  # V = 0: the unit gradient's
        # the band where x has sides (upper form: ab[w + r - c, c] = A[r, c] for c >= r, in the band's order)
        if nz > 1:  # x slowest: half-width ny nz
            self.order, w = np.arange(n), ny * nz
        else:
            self.order, w = band_order(nx, ny, y_sides is None)
        new = np.empty_like(self.order)
        new[self.order] = np.arange(n)
        rows_of = new[np.repeat(np.arange(n), np.diff(self.indptr))]
        cols_of = new[self.indices]
        self.upper = cols_of >= rows_of
        self.band_at = (w + rows_of[self.upper] - cols_of[self.upper], cols_of[self.upper])
        self.width = w
        self.banded = (x_sides is not None and w <= (BAND_MAX_3D if nz > 1 else BAND_MAX)
                       and 8 * (w + 1) * n <= BAND_BYTES)
        natural = nz > 1 or np.array_equal(self.order, np.arange(n))  # x slowest
        self.split = self.banded and natural and w >= SPLIT_MIN and nx >= 4
        if method is not None:
            if method not in ("band", "split", "superlu") or x_sides is None or (method == "split" and not natural):
                raise ValueError(f"method {method!r}: 'band', 'split' (cells numbered x slowest) or 'superlu', "
                                 "where x has sides")
            self.banded = method in ("band", "split")
            self.split = method == "split"
        self.share = share or Local()
        self._split = SplitBand(self.indptr, self.indices, nx, w) if self.split else None
        self.ordered = x_sides is not None and not self.banded  # SuperLU with minimum degree on A + A^T
        self.rhs = np.zeros(n)
        self.unit_rhs = np.zeros(n)
        self.unit_data = np.zeros_like(self.data)
        self.ab = np.zeros((w + 1, n)) if self.banded and not self.split else None
        self._scratch = np.zeros((4, n)) if self.ab is not None else None  # band_pcg.pcg's vectors
        self._work = ({np.dtype(t): np.zeros(n, t) for t in (np.float64, np.float32)}  # the sweeps', per precision
                      if self.ab is not None else None)
        self._band = None      # a whole band's factor (its transpose, the band's order), for band_pcg
        self.reuse = reuse
        self._factor = None    # solves with the factor of factor_K's matrix (None: the next solve factorises)
        self.factor_K = None
        self.warm = None       # the last solve's p' (and the unit gradient's, with a mean flux), then the one's before
        self.iterations = 0    # the last solve's (0: it factorised)
        self.factorisations = 0

    def feed(self, values):
        """The flux through the x = 0 side's faces from the next solve on (a floor whose feed changes in
        time): a flux side enters the right-hand side only, so the matrix and its factor stay."""
        if self.kinds[0] != KINDS["flux"]:
            raise ValueError("feed: the x = 0 side is not a flux side")
        self.values[0] = np.array(np.broadcast_to(np.asarray(values, float), (self.ny * self.nz,)))

    def start(self):
        """What the next solve starts from: the K whose factor preconditions it (None: it factorises) and the
        last two solves' p' (:meth:`_warm_start`), a tuple of flat arrays (None); what a restart point keeps."""
        return (self.factor_K if self._factor is not None else None), self.warm

    def restore(self, factor_K, warm):
        """Start from :meth:`start`'s values (a restart's): the factor of factor_K's matrix, made again."""
        self.warm = None if warm is None else tuple(np.array(w, float) for w in warm)
        self._factor, self.factor_K = None, None
        if factor_K is not None:
            K = np.ascontiguousarray(factor_K, float)
            K3 = K.reshape(self.nx, self.ny, self.nz)
            fv.face_values(K3, np.zeros(K3.shape + (self.dim,)), *self.periodic, *self.kf, *self.vf)
            fv.assemble(K3, *self.kf, *self.vf, self.hx, self.hy, self.hz, self.kinds, *self.values, *self.places,
                        self.data, np.zeros(K.size), self.pin, 0.0)
            self._factorise(K)

    def _factorise(self, K):
        """Factorise the assembled matrix (of K) and keep the factor; returns the direct solve with it (a whole
        band's in double precision, kept in single: the module docstring)."""
        n = self.nx * self.ny * self.nz
        self._band = None
        if self.split:
            split, share = self._split, self.share
            split.factorise(self.data, share)
            self._factor = lambda b: split.solve(b, share)
        elif self.banded:
            self.ab[:] = 0.0
            self.ab[self.band_at] = self.data[self.upper]
            T = np.ascontiguousarray(sla.cholesky_banded(self.ab, check_finite=False).T)
            order = np.ascontiguousarray(self.order, np.int64)
            # the solve right after is the double factor's; the iterations after it are preconditioned with the
            # factor in single precision (module docstring)
            self._band = (T.astype(np.float32), order)
            self._factor = self._band_solve(*self._band)
            direct = self._band_solve(T, order)
        else:
            A = sp.csc_matrix(sp.csr_matrix((self.data, self.indices, self.indptr), shape=(n, n)))
            if self.ordered:
                self._factor = spla.splu(A, permc_spec="MMD_AT_PLUS_A", options={"SymmetricMode": True}).solve
            else:
                self._factor = spla.splu(A).solve
        self.factor_K = K.copy()
        self.factorisations += 1
        return direct if self._band is not None else self._factor

    def _band_solve(self, T, order):
        """x = A^-1 b with a whole band's factor ``T`` (double: the direct solve; single: the preconditioner)."""
        work = self._work[T.dtype]

        def solve(b):
            x = np.empty_like(b)
            band_pcg.band_solve(T, order, b, x, work)
            return x
        return solve

    def _pcg(self, b, x0):
        """A x = b by conjugate gradients preconditioned with the kept factor, from x0; (x, iterations), x
        None where it has not converged in MAX_ITER."""
        if self._band is not None:  # compiled: the same iteration with the band's sweeps (band_pcg)
            x = x0.copy()
            T, order = self._band
            it = band_pcg.pcg(self.indptr, self.indices, self.data, T, order, b, x, RTOL, MAX_ITER, self._scratch,
                              self._work[T.dtype])
            return (x, it) if it >= 0 else (None, MAX_ITER)
        scale = np.abs(b).max()
        if scale == 0.0:
            return np.zeros_like(b), 0
        x = x0.copy()
        r = np.empty_like(b)
        fv.matvec(self.indptr, self.indices, self.data, x, r)
        r = b - r
        Ap = np.empty_like(b)
        rz_old, d = 0.0, None
        for it in range(MAX_ITER + 1):
            if np.abs(r).max() <= RTOL * scale:
                return x, it
            if it == MAX_ITER or not np.isfinite(r).all():
                break
            z = self._factor(r)
            rz = r @ z
            d = z if d is None else z + (rz / rz_old) * d
            fv.matvec(self.indptr, self.indices, self.data, d, Ap)
            alpha = rz / (d @ Ap)
            x += alpha * d
            r -= alpha * Ap
            rz_old = rz
        return None, MAX_ITER

    def _warm_start(self, m):
        """Each of the m right-hand sides' start: 2 p_1 - p_2 from the last two solves (``warm``: the last's m, then
        the one's before), the last's where there is one only."""
        last, before = self.warm[:m], self.warm[m:]
        return last if not before else tuple(2.0 * a - b for a, b in zip(last, before))

    def _worth_trying(self, K):
        """Whether the kept factor is worth a try: always for a whole band; for a split band (its factorisation
        shared by the ranks, so the tries weigh more against it) where no cell's K moved by more than
        :data:`SPLIT_TRY_CHANGE` in log since the factor's (a function of what a restart point keeps)."""
        if not self.split:
            return True
        with np.errstate(all="ignore"):
            return bool(np.abs(np.log(K / self.factor_K)).max() <= SPLIT_TRY_CHANGE)

    def solve(self, K, V):
        """p' and the faces' fluxes for K (nx, ny[, nz]) [m^2/(Pa s)] and V (nx, ny[, nz], dim) [m/s]."""
        K = np.ascontiguousarray(K, float)
        V = np.ascontiguousarray(V, float)
        shape3 = (self.nx, self.ny, self.nz)
        K3, V3 = K.reshape(shape3), V.reshape(shape3 + (self.dim,))
        h = (self.hx, self.hy, self.hz)
        fv.face_values(K3, V3, *self.periodic, *self.kf, *self.vf)
        fv.assemble(K3, *self.kf, *self.vf, *h, self.kinds, *self.values, *self.places, self.data, self.rhs, self.pin,
                    0.0)
        rhs = [self.rhs]
        if self.mean_flux is not None:  # the unit gradient's right-hand side, on the same matrix (V = 0)
            fv.assemble(K3, *self.kf, *self.unit_vf, *h, self.kinds, *self.values, *self.places, self.unit_data,
                        self.unit_rhs, self.pin, 1.0)
            rhs.append(self.unit_rhs)
        with np.errstate(all="ignore"):
            ps = None
            if self.reuse and self._factor is not None and self.warm is not None and self._worth_trying(K):
                tried = [self._pcg(b, w) for b, w in zip(rhs, self._warm_start(len(rhs)))]
                self.iterations = max(it for _, it in tried)
                if all(x is not None for x, _ in tried):
                    ps = [x for x, _ in tried]
            if ps is None:
                try:
                    direct = self._factorise(K)
                    ps = [direct(b) for b in rhs]
                except (RuntimeError, np.linalg.LinAlgError, ValueError) as e:  # singular or indefinite
                    self._factor = None
                    raise SolveFailed(str(e)) from None
                self.iterations = 0
            if not self.reuse or self.iterations > REFRESH_ITER:
                self._factor = None
        if not all(band_pcg.largest(x)[1] for x in ps):  # every p' finite
            self._factor = None
            raise SolveFailed("the pressure is not finite")
        self.warm = tuple(ps) + (self.warm[:len(ps)] if self.warm is not None else ())
        flat = self._grid_shape
        p = ps[0]
        js = [flat(j) for j in fv.faces(K3, self.kf, self.vf, h, self.kinds, self.values, p.reshape(shape3), 0.0)]
        if self.mean_flux is not None:
            p1 = ps[1]
            js1 = [flat(j) for j in fv.faces(K3, self.kf, self.unit_vf, h, self.kinds, self.values,
                                           p1.reshape(shape3), 1.0)]
            G = (self.mean_flux * (self.ny * self.nz) - js[0][0].sum()) / js1[0][0].sum()
            if not np.isfinite(G):
                raise SolveFailed("the mean pressure gradient is not finite")
            p = p + G * p1
            js = [j + G * j1 for j, j1 in zip(js, js1)]
            self.gradient = float(G)
        return Solution(p.reshape(self.shape), *js)

    def _grid_shape(self, j):
        """A faces' array (…, nz) as the grid's own: without the z axis in 2-D."""
        return j[:, :, 0] if self.nz == 1 else j


def solve(K, V, hx, hy, x_sides=None, y_sides=None, mean_flux=None, hz=1.0):
    """One solve (:class:`Darcy` made for it: a factorisation); K (nx, ny) or, in 3-D, (nx, ny, nz)."""
    nz = K.shape[2] if K.ndim == 3 else 1
    return Darcy(K.shape[0], K.shape[1], hx, hy, x_sides, y_sides, mean_flux, nz=nz, hz=hz).solve(K, V)
