"""A picture sequence of a bubbling bed for docs/validation.md: at each time given, the particles (coloured by
theta) above the gas grid's theta, upright in mm, one column a time, one colour scale. A 3-D bed is drawn in
the middle layer of cells across z: its grid's cells and the particles in that layer.

    .venv/bin/python scripts/bed_pictures.py OUT --times 0.1 0.2 0.3 0.4 --png docs/bubbling_bed.png [--top MM]

OUT is a run's output directory (``parsph run``); the pieces are ``parsph plot``'s
(:mod:`parsph.cli.grid_plot`). --top crops the pictures at that height [mm] (default: the box).
"""
import argparse

import h5py
import matplotlib

from parsph.cli import grid_plot
from parsph.sph.particles import GRAIN

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--times", type=float, nargs="+", required=True)
    ap.add_argument("--png", required=True)
    ap.add_argument("--top", type=float, default=None, help="crop at this height [mm]")
    a = ap.parse_args()
    rows = grid_plot.grid_outputs(a.out, a.times)
    n = len(rows)
    fig, ax = plt.subplots(2, n, figsize=(1.9 * n + 1.2, 5.0), squeeze=False, layout="constrained")
    for k, row in enumerate(rows):
        t, fn = row[0], row[1]
        with h5py.File(fn, "r") as f:
            p = f["particles"]
            fluid = p["kind"][()] == GRAIN
            x, th = p["position"][()][fluid], p["theta"][()][fluid]
        if x.shape[1] == 3:  # the middle layer of cells across z, as grid_plot.draw draws the grid
            hz, nz = row[3][2], row[2]["theta"].shape[2]
            mid = nz // 2
            sel = (x[:, 2] >= mid * hz) & (x[:, 2] < (mid + 1) * hz)
            x, th = x[sel], th[sel]
        ax[0, k].scatter(x[:, 1] * 1e3, x[:, 0] * 1e3, c=th, s=0.3, vmin=0.0, vmax=0.8, cmap="viridis_r",
                              rasterized=True)
        ax[0, k].set_aspect("equal")
        ax[0, k].set_title(f"t = {t:.3g} s", fontsize=9)
        mesh = grid_plot.draw(ax[1, k], row, "theta", (0.0, 0.8))
        ax[1, k].set_title("")
        for r in (0, 1):
            ax[r, k].set_xlim(0, row[2]["theta"].shape[1] * row[3][1] * 1e3)
            ax[r, k].set_ylim(0, a.top or row[2]["theta"].shape[0] * row[3][0] * 1e3)
            if k:
                ax[r, k].set_ylabel("")
                ax[r, k].set_yticklabels([])
            ax[r, k].set_xlabel("y [mm]")
        ax[0, 0].set_ylabel("height [mm]: particles")
        ax[1, 0].set_ylabel("height [mm]: gas grid")
    fig.colorbar(mesh, ax=ax.ravel().tolist(), shrink=0.6, label="theta (grains' volume fraction)")
    fig.savefig(a.png, dpi=110)
    print(f"wrote {a.png}")


if __name__ == "__main__":
    main()
