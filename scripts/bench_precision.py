"""float32 against float64 in the two pair passes (Eq. (3) density, Eq. (5) forces): speed and accuracy.

    NUMBA_NUM_THREADS=1 .venv/bin/python scripts/bench_precision.py [--nx 200] [--rounds 7] [--json FILE]

Used by docs/accuracy.md ("Floating-point precision"). The paper lattice
(Couette case of run/couette_paper.toml, h = 1.25 dx, cubic spline) at N_x
is built and advanced a few steps, so that the wall-adjacent rows move; then,
on one thread, on the solver's own sorted arrays and cell grid:

1. **The solver's loops** (``parsph.equations.density`` and ``momentum``,
   recompiled here without numba's disk cache, so parsph's cache is not
   touched) called with float64 arrays and with float32 copies of every
   floating-point array and scalar. The types numba infers for the float32
   call are printed: the float literals of the loops (``2.0 - q``,
   ``0.5 * k_visc``, ...) are float64, so the kernel and most of the pair
   arithmetic are promoted back to float64 and only the loads and stores are
   float32.
2. **A float32 copy of the two pair loops** (:func:`make_loops`: the same
   row-by-row candidate search, the branch-free cubic spline, the neighbour
   list, the paper's pressure term and the Morris viscous term with the
   wall factor beta), built once with float64 and once with float32
   constants, so that float32 stays float32; the sums (density, the
   accelerations) accumulate in float64, the cell ranges are found in
   float64 (the 1e-9 h pad of the solver is below float32's resolution).

Times: best of ``--rounds`` interleaved repetitions of each variant (each a
few calls; the machine's speed drifts), in ns per neighbour pair. Accuracy:
the float32 copy's density and accelerations against the float64 copy's on
the same state (relative to the largest value), and the density of the
undisturbed lattice.
"""
import argparse
import io
import json
import math
import os
import re
import sys
import time
import tomllib

import numpy as np
import numba
from numba import njit, prange

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from mpi4py import MPI  # noqa: E402

from parsph import config, equations, neighbours  # noqa: E402
from parsph.particles import FLUID  # noqa: E402
from parsph.solver import Simulation  # noqa: E402


def make_config(nx):
    raw = tomllib.loads(open(os.path.join(ROOT, "run", "couette_paper.toml")).read())
    del raw["numerics"]["h"]
    config.apply_overrides(raw, [f"numerics.Nx={nx}", "numerics.h_over_dx=1.25", 'numerics.dt="auto"',
                                 "output.times=[]", "output.t_end=1.0"])
    return config.build(raw, config.dumps(raw))


# ---- 2: a float32 copy of the pair loops ----------------------------------------------------
def make_loops(ft):
    """(density, forces): the solver's two pair loops (2-D, cubic spline, paper pressure, Morris walls)
    with every constant of type ``ft``; sums in float64."""
    Z, HALF, ONE, TWO, FOUR, THREE, NINE, TWELVE = (ft(v) for v in (0.0, 0.5, 1.0, 2.0, 4.0, 3.0, 9.0, 12.0))

    cell_range = equations._cell_range  # cell ranges in float64, as in the solver

    @njit(parallel=True)
    def density(n, sx, sy, sm, skind, owned, start, ncx, ncy, lox, loy, x0, cs, h, norm, rho, nbr_n, nbr_j,
                nbr_f):
        inv_h = ONE / h
        support2 = (TWO * h) * (TWO * h)
        hd = 2.0 * float(h)  # cell ranges in float64
        pad = 1e-9 * float(h)
        c_f = norm * inv_h * inv_h
        last = nbr_j.shape[1] - 1
        for i in prange(n):
            cnt = 0
            if owned[i] and skind[i] == FLUID:
                s = 0.0  # float64 sum
                xi = sx[i]
                yi = sy[i]
                cy_lo, cy_hi = cell_range(float(yi) - hd - pad, 2.0 * (hd + pad), cs, loy, ncy)
                for cy in range(cy_lo, cy_hi + 1):
                    gy = max((cy + loy) * cs - float(yi), float(yi) - (cy + loy + 1) * cs, 0.0)
                    reach2 = hd * hd - gy * gy
                    if reach2 <= 0.0:
                        continue
                    half = math.sqrt(reach2) + pad
                    cx_lo, cx_hi = cell_range(float(xi) - x0 - half, 2.0 * half, cs, lox, ncx)
                    row = cy * ncx
                    for j in range(start[row + cx_lo], start[row + cx_hi + 1]):
                        dx = xi - sx[j]
                        dy = yi - sy[j]
                        r2 = dx * dx + dy * dy
                        if r2 < support2:
                            r = math.sqrt(r2)
                            q = r * inv_h
                            a = max(TWO - q, Z)
                            b = max(ONE - q, Z)
                            w = norm * (a * a * a - FOUR * b * b * b)
                            f = c_f * (NINE * q - TWELVE if q < ONE else -THREE * a * a / q)
                            s += sm[j] * w
                            k = min(cnt, last)
                            nbr_j[i, k] = j
                            nbr_f[i, k] = f
                            cnt += 1 if j != i else 0
                rho[i] = s
            nbr_n[i] = cnt
        return nbr_n[:n].max()

    @njit(parallel=True)
    def forces(n, sx, sy, svx, svy, sm, skind, owned, stheta, sinv, spress, nbr_n, nbr_j, nbr_f, c_press, k_visc,
               L, beta_max, ax_out, ay_out):
        for i in prange(n):
            ax = 0.0  # float64 sums
            ay = 0.0
            if owned[i] and skind[i] == FLUID:
                th_i = stheta[i]
                inv_th_i = sinv[i, 1]
                mu_i = k_visc * th_i
                inv_rho_i = sinv[i, 0]
                cp_i = c_press * spress[i]
                xi = sx[i]
                yi = sy[i]
                vxi = svx[i]
                vyi = svy[i]
                for p in range(nbr_n[i]):
                    j = nbr_j[i, p]
                    f = nbr_f[i, p]
                    m_j = sm[j]
                    cp = m_j * cp_i * spress[j] * (inv_th_i + sinv[j, 1]) * f
                    beta = ONE
                    if skind[j] != FLUID:
                        if sx[j] < Z:
                            d_j = -sx[j]
                            d_i = xi
                        else:
                            d_j = sx[j] - L
                            d_i = L - xi
                        beta = beta_max
                        if d_i > Z:
                            beta = min(beta_max, ONE + d_j / d_i)
                    cv = mu_i * m_j * (th_i + stheta[j]) * inv_rho_i * sinv[j, 0] * f * beta
                    ax += cp * (xi - sx[j]) + cv * (vxi - svx[j])
                    ay += cp * (yi - sy[j]) + cv * (vyi - svy[j])
            ax_out[i] = ax
            ay_out[i] = ay

    return density, forces


# ---- set-up ---------------------------------------------------------------------------------
def state(nx, steps):
    """A Simulation at N_x after ``steps`` steps, its rates evaluated, and the sorted cell grid."""
    sim = Simulation(make_config(nx), MPI.COMM_SELF)
    for _ in range(steps):
        sim.compute_rates()
        sim.advance(sim.cfg.dt)
    sim.compute_rates()
    W, ps = sim.work, sim.ps
    grid = neighbours.sort_into_cells(
        ps.pos, ps.vel, ps.mass, ps.kind, ps.gid, ps.n, ps.n_own, sim.x0, sim.rates.cell,
        W.order, W.cell_of, W.tmp, W.sx, W.sy, W.sz, W.svx, W.svy, W.svz, W.sm, W.skind, W.owned)
    return sim, grid


def solver_args(sim, grid, ft):
    """Arguments of equations.density and equations.momentum, floating-point ones cast to ``ft``."""
    W, ps, R = sim.work, sim.ps, sim.rates
    n = ps.n
    a = lambda x: np.ascontiguousarray(x, dtype=ft)  # noqa: E731
    s = lambda x: ft(x) if isinstance(x, float) else x  # noqa: E731
    arr = {k: a(getattr(W, k)[:n] if getattr(W, k).ndim == 1 else getattr(W, k)[:n])
           for k in ("sx", "sy", "sz", "svx", "svy", "svz", "sm", "stheta", "sinv", "spress", "nbr_f")}
    rho = a(ps.rho)
    dconst = tuple(s(c) for c in R.density_consts)
    mconst = tuple(a(c) if isinstance(c, np.ndarray) else s(c) for c in R.momentum_consts)
    nbr_n, nbr_j = W.nbr_n[:n].copy(), W.nbr_j[:n].copy()
    dargs = (n, arr["sx"], arr["sy"], arr["sz"], arr["sm"], W.skind[:n], W.owned[:n], W.order[:n], W.cell_of[:n],
             *grid, *dconst, rho, arr["stheta"], arr["sinv"], arr["spress"], nbr_n, nbr_j, arr["nbr_f"])
    acc, theta = np.zeros((ps.acc.shape[0], ps.acc.shape[1]), ft), np.zeros(ps.theta.shape[0], ft)
    margs = (n, arr["sx"], arr["sy"], arr["sz"], arr["svx"], arr["svy"], arr["svz"], arr["sm"], W.skind[:n],
             W.owned[:n], W.order[:n], rho, arr["stheta"], arr["sinv"], arr["spress"], nbr_n, nbr_j, arr["nbr_f"],
             *mconst, acc, theta)
    return dargs, margs


def copy_args(sim, grid, ft):
    """Arguments of make_loops' density and forces, floating-point arrays cast to ``ft``."""
    W, ps, cfg, R = sim.work, sim.ps, sim.cfg, sim.rates
    n = ps.n
    a = lambda x: np.ascontiguousarray(x[:n], dtype=ft)  # noqa: E731
    start, ncx, ncy, ncz, lox, loy, loz = grid
    sx, sy, sm = a(W.sx), a(W.sy), a(W.sm)
    nbr_n, nbr_j, nbr_f = np.zeros(n, np.int64), np.zeros_like(W.nbr_j[:n]), np.zeros(W.nbr_j[:n].shape, ft)
    rho = np.zeros(n, np.float64)
    dargs = (n, sx, sy, sm, W.skind[:n], W.owned[:n], start, ncx, ncy, lox, loy, float(sim.x0),
             float(R.cell), ft(cfg.h), ft(sim.kernel.norm(cfg.h, cfg.dim)), rho, nbr_n, nbr_j, nbr_f)
    c_press = -10.0 ** cfg.G_b / cfg.rho_s ** 2
    fargs = (n, sx, sy, a(W.svx), a(W.svy), sm, W.skind[:n], W.owned[:n], a(W.stheta), a(W.sinv), a(W.spress),
             nbr_n, nbr_j, nbr_f, ft(c_press), ft(cfg.k), ft(cfg.L), ft(cfg.beta_max),
             np.zeros(n, np.float64), np.zeros(n, np.float64))
    return dargs, fargs


def float_types(fn, sig):
    """{variable: type} of the floating-point locals numba infers for ``fn``'s ``sig`` (non-parallel copy)."""
    serial = njit(fn.py_func)
    serial.compile(sig)
    buf = io.StringIO()
    serial.inspect_types(file=buf, signature=sig)
    out = {}
    for m in re.finditer(r"^\s*#\s+([A-Za-z_][A-Za-z_0-9.]*) = .*::\s*(float32|float64)\s*$", buf.getvalue(), re.M):
        name = m.group(1).split(".")[0]
        out.setdefault(name, set()).add(m.group(2))
    return {k: "/".join(sorted(v)) for k, v in out.items()}


def best_of(variants, rounds, calls):
    """{name: best seconds per call} over ``rounds`` interleaved rounds of ``calls`` calls each."""
    best = {k: math.inf for k in variants}
    for _ in range(rounds):
        for k, (fn, args) in variants.items():
            t0 = time.perf_counter()
            for _ in range(calls):
                fn(*args)
            best[k] = min(best[k], (time.perf_counter() - t0) / calls)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nx", type=int, default=200)
    ap.add_argument("--steps", type=int, default=50, help="steps taken before the passes are timed")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--calls", type=int, default=5, help="calls per variant per round")
    ap.add_argument("--json", help="append the result as one JSON line")
    a = ap.parse_args()
    numba.set_num_threads(1)
    sim, grid = state(a.nx, a.steps)
    n, pairs = sim.ps.n, sim.work.pairs(sim.ps.n)
    print(f"N_x = {a.nx}: {sim.n_total} particles ({n} with periodic images), {pairs} neighbour pairs, "
          f"t = {sim.t:.3g} s after {sim.step} steps; threads {numba.get_num_threads()}", flush=True)

    # 1. the solver's loops, recompiled without the disk cache, with float64 and float32 arguments
    sdens = njit(parallel=True)(equations.density.py_func)
    smom = njit(parallel=True)(equations.momentum.py_func)
    s64, s32 = solver_args(sim, grid, np.float64), solver_args(sim, grid, np.float32)
    for d, m in (s64, s32):
        sdens(*d)
        smom(*m)
    sig32 = [s for s in sdens.signatures if any(getattr(t, "dtype", None) == numba.float32 for t in s)][0]
    types = float_types(equations.density, sig32)
    promoted = {k: v for k, v in types.items() if k in ("inv_h", "support2", "dx", "r2", "r", "q", "a", "b", "w", "f", "s")}
    print("solver density pass called with float32: inferred types", promoted, flush=True)
    msig32 = [s for s in smom.signatures if any(getattr(t, "dtype", None) == numba.float32 for t in s)][0]
    mtypes = float_types(equations.momentum, msig32)
    mprom = {k: v for k, v in mtypes.items() if k in ("cp", "cv", "mu", "beta", "f_over_r", "ax", "th_i", "cp_i")}
    print("solver momentum pass called with float32: inferred types", mprom, flush=True)

    # 2. the copy with typed constants
    d64, f64 = make_loops(np.float64)
    d32, f32 = make_loops(np.float32)
    c64, c32 = copy_args(sim, grid, np.float64), copy_args(sim, grid, np.float32)
    for (d, f), (da, fa) in (((d64, f64), c64), ((d32, f32), c32)):
        d(*da)
        f(*fa)
    ctypes_ = float_types(d32, d32.signatures[0])
    print("copy, float32: inferred types", {k: v for k, v in ctypes_.items() if k in ("r2", "r", "q", "w", "f", "s")},
          flush=True)
    ftypes_ = float_types(f32, f32.signatures[0])
    print("copy, float32 forces: inferred types", {k: v for k, v in ftypes_.items() if k in ("cp", "cv", "beta", "ax")},
          flush=True)

    variants = {
        "solver density f64": (sdens, s64[0]), "solver density f32 args": (sdens, s32[0]),
        "copy density f64": (d64, c64[0]), "copy density f32": (d32, c32[0]),
        "solver forces f64": (smom, s64[1]), "solver forces f32 args": (smom, s32[1]),
        "copy forces f64": (f64, c64[1]), "copy forces f32": (f32, c32[1]),
    }
    best = best_of(variants, a.rounds, a.calls)
    ns = {k: v / pairs * 1e9 for k, v in best.items()}
    print(f"best of {a.rounds} interleaved rounds x {a.calls} calls, one thread, ns per neighbour pair:")
    for k, v in ns.items():
        print(f"  {k:26s} {v:7.2f} ns/pair  ({best[k] * 1e3:.2f} ms per call)")
    for what in ("density", "forces"):
        print(f"  speed-up float64 -> float32: solver loops with float32 arrays "
              f"{ns[f'solver {what} f64'] / ns[f'solver {what} f32 args']:.3f}x, "
              f"float32 copy {ns[f'copy {what} f64'] / ns[f'copy {what} f32']:.3f}x ({what})")
    both64 = ns["copy density f64"] + ns["copy forces f64"]
    both32 = ns["copy density f32"] + ns["copy forces f32"]
    print(f"  both passes, copy: {both64:.2f} -> {both32:.2f} ns/pair ({both64 / both32:.3f}x)")

    # accuracy of the float32 copy against the float64 copy, same state
    d64(*c64[0])
    f64(*c64[1])
    d32(*c32[0])
    f32(*c32[1])
    W = sim.work
    fl = (W.skind[:n] == FLUID) & W.owned[:n]
    rho64, rho32 = c64[0][15][fl], c32[0][15][fl]
    acc64 = np.hypot(c64[1][-2], c64[1][-1])[fl]
    dacc = np.hypot(c64[1][-2] - c32[1][-2], c64[1][-1] - c32[1][-1])[fl]
    ref_rho = sim.ps.rho[W.order[:n]][fl]
    acc_scale = float(np.max(acc64))
    acc_med = float(np.median(acc64))
    res = {
        "nx": a.nx, "particles": int(sim.n_total), "pairs": int(pairs), "t": float(sim.t), "steps": int(sim.step),
        "threads": numba.get_num_threads(), "rounds": a.rounds, "calls": a.calls, "ns_per_pair": ns,
        "solver_density_types_f32": promoted, "solver_momentum_types_f32": mprom,
        "copy_density_types_f32": {k: v for k, v in ctypes_.items() if k in ("r2", "r", "q", "w", "f", "s")},
        "rho_copy64_vs_solver_max_rel": float(np.max(np.abs(rho64 - ref_rho) / ref_rho)),
        "rho_f32_max_rel": float(np.max(np.abs(rho32 - rho64) / rho64)),
        "acc_max": acc_scale, "acc_median": acc_med,
        "acc_f32_max_abs_err": float(np.max(dacc)), "acc_f32_max_err_rel_to_max": float(np.max(dacc) / acc_scale),
        "acc_f32_median_abs_err": float(np.median(dacc)),
    }
    print(f"accuracy: float64 copy vs solver density, max rel diff {res['rho_copy64_vs_solver_max_rel']:.2e}; "
          f"float32 density max rel err {res['rho_f32_max_rel']:.2e}; accelerations: max |a| {acc_scale:.3g} m/s^2, "
          f"median {acc_med:.3g}, float32 error max {res['acc_f32_max_abs_err']:.3g} "
          f"({res['acc_f32_max_err_rel_to_max']:.2e} of max |a|), median {res['acc_f32_median_abs_err']:.3g} m/s^2")
    if a.json:
        with open(a.json, "a") as fh:
            fh.write(json.dumps(res) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
