"""The gas solve's direct factorisations on a bubbling bed's grid (docs/performance.md, "The solved gas in 3-D"):
parsph.gas.darcy's banded Cholesky against SuperLU ordered by minimum degree, each a factorisation and a solve
(``Darcy.solve`` with ``reuse=False``), min over repeats, on one thread.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/solve_bench.py [--grids 80x160 40x20x10 20x20x20 30x30x30]

A grid is NX x NY (2-D, y periodic) or NX x NY x NZ (3-D, y and z periodic), x between a floor fed at U and an
open top. K: the bed's 1 with a fifth of the cells (at random, seed 1) voids of 1000. Prints one line a grid:
the band's half-width and ms per solve of each.
"""
import argparse
import time

import numpy as np

from parsph.gas import darcy


def timed(f, repeats):
    f()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t0)
    return best * 1e3


def one(shape, repeats):
    nx, ny = shape[:2]
    nz = shape[2] if len(shape) == 3 else 1
    K = np.where(np.random.default_rng(1).random(shape) < 0.2, 1000.0, 1.0)
    V = np.zeros(shape + (len(shape),))
    sides = (darcy.Side("flux", 0.5), darcy.Side("pressure", 0.0))
    out = {}
    for name in ("band", "superlu"):
        d = darcy.Darcy(nx, ny, 1e-3, 1e-3, sides, None, reuse=False, nz=nz, hz=1e-3, method=name)
        out[name] = timed(lambda: d.solve(K, V), repeats)
    return d.width, out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grids", nargs="+", default=["80x160", "40x20x10", "20x20x20", "30x30x30"])
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    for g in a.grids:
        shape = tuple(int(v) for v in g.split("x"))
        w, t = one(shape, a.repeats)
        print(f"{g}: half-width {w}, band {t['band']:.1f} ms, SuperLU (minimum degree) {t['superlu']:.1f} ms, "
              f"ratio {t['superlu'] / t['band']:.2f}", flush=True)


if __name__ == "__main__":
    main()
