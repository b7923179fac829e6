"""``parsph plot --grid``: the solved gas's grid as a run's outputs hold it (``/grid``, docs/output.md), one PNG
per output and, with ``--animate``, one animation over the outputs.

Serial (h5py, matplotlib; no MPI). The bed is drawn upright: its height x vertical, gravity down, the periodic
y horizontal, both in mm and to scale; each cell a rectangle coloured by theta or p' (one colour scale for
every picture of the call, so that they compare), a colour bar with units, the time in the title. The
animation is a GIF (matplotlib's Pillow writer; Pillow comes with matplotlib), or an MP4 where the name asks
for it and ffmpeg is on the PATH.
"""
import shutil

import numpy as np

from parsph.errors import UsageError
from .particles_plot import at_times, colour_limits, png_name

GRID_FIELDS = {"theta": "theta (grains' volume fraction) [1]", "p": "p' (gas pressure less hydrostatic) [Pa]"}


def holds_grid(path):
    """Whether an output of ``path`` (a directory or one file) holds the gas's grid."""
    import h5py
    from parsph.output import output_files
    for fn in output_files(path):
        with h5py.File(fn, "r") as f:
            if "grid" in f and "theta" in f["grid"]:
                return True
    return False


def grid_outputs(path, times=None):
    """(time, file, {field: array}, cell (h_x, h_y[, h_z]), scene) of the outputs with a grid, in time order."""
    import h5py
    from parsph.output import output_files
    found = []
    for fn in output_files(path):
        with h5py.File(fn, "r") as f:
            if "grid" in f and "theta" in f["grid"]:
                g = f["grid"]
                found.append((float(f.attrs["time"]), fn, {k: g[k][()] for k in GRID_FIELDS},
                              tuple(float(h) for h in g.attrs["cell"]), str(f.attrs["scene"])))
    found.sort(key=lambda r: r[0])
    if not found:
        raise UsageError(f"{path}: no output holds the gas's grid (only gas.flow = \"solved\" writes one)")
    return at_times(found, times, "a grid")


def draw(ax, row, field, limits):
    """The cells of one output on ``ax``, upright (y across, x up), mm; returns the mesh. A 3-D grid is drawn
    in its middle layer of cells across z."""
    t, _, fields, cell, scene = row
    hx, hy = cell[:2]
    values = fields[field]                      # (n_x, n_y[, n_z]): x the height
    where = ""
    if values.ndim == 3:
        k = values.shape[2] // 2
        values = values[:, :, k]
        where = f" (z = {(k + 0.5) * cell[2] * 1e3:.3g} mm)"
    nx, ny = values.shape
    y_edges = np.arange(ny + 1) * hy * 1e3
    x_edges = np.arange(nx + 1) * hx * 1e3
    mesh = ax.pcolormesh(y_edges, x_edges, values, vmin=limits[0], vmax=limits[1], cmap="viridis_r"
                         if field == "theta" else "viridis", shading="flat")
    ax.set_aspect("equal")
    ax.set_xlabel("y (periodic) [mm]")
    ax.set_ylabel("x (height, gravity down) [mm]")
    ax.set_title(f"{scene}: {field} on the gas grid{where}, t = {t:.4g} s", fontsize=9)
    return mesh


def plot_grid(path, field="theta", times=None, animate=None):
    """One PNG per output with a grid (and the animation ``animate``, a .gif or .mp4 path); returns the paths."""
    if field not in GRID_FIELDS:
        raise UsageError(f"--field {field}: the grid has {', '.join(GRID_FIELDS)}")
    if animate and not animate.endswith((".gif", ".mp4")):
        raise UsageError(f"--animate {animate}: give a .gif or .mp4 name")
    if animate and animate.endswith(".mp4") and shutil.which("ffmpeg") is None:
        raise UsageError(f"--animate {animate}: an MP4 needs ffmpeg on the PATH (a .gif needs nothing more)")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = grid_outputs(path, times)
    limits = colour_limits(np.concatenate([r[2][field].ravel() for r in rows]))
    written = []
    for row in rows:
        fig, ax = plt.subplots(figsize=(6.4, 4.8))
        fig.colorbar(draw(ax, row, field, limits), ax=ax, label=GRID_FIELDS[field])
        fig.tight_layout()
        png = png_name(row[1], "grid_" + field)  # DIR/<stem>_grid_<field>_NNNN.png
        fig.savefig(png, dpi=120)
        plt.close(fig)
        written.append(png)
    if animate:
        written.append(_animate(rows, field, limits, animate))
    return written


def _animate(rows, field, limits, out):
    import matplotlib.pyplot as plt
    from matplotlib.animation import FFMpegWriter, FuncAnimation, PillowWriter
    writer = FFMpegWriter(fps=5) if out.endswith(".mp4") else PillowWriter(fps=5)
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    fig.colorbar(draw(ax, rows[0], field, limits), ax=ax, label=GRID_FIELDS[field])
    fig.tight_layout()

    def frame(k):
        for m in list(ax.collections):
            m.remove()
        draw(ax, rows[k], field, limits)
    FuncAnimation(fig, frame, frames=len(rows)).save(out, writer=writer, dpi=100)
    plt.close(fig)
    return out
