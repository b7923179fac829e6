"""``parsph plot --particles``: a PNG per output time of the particles themselves, coloured by a field.

Serial (h5py, matplotlib; no MPI): it reads the output files alone, so it works on a copy of them.
Axes as in the run: x wall-normal (horizontal), y streamwise (vertical), to scale; a layer (sedimentation,
fluidized_bed: x the height, gravity along -x, y periodic) is drawn upright instead, its height vertical and
gravity down, with the heights below which 95% of its mass lies, the reference's (what ``parsph check`` judges
by) and the SPH's, as horizontal lines (the same heights against time: ``parsph plot``'s
``<stem>_interface.png``). Fluid particles are
coloured by v_x, v_y or theta (one colour scale for every picture of the call, so that they compare);
wall particles are tan, and the wall planes are lines marked with their velocity. In 3-D the picture
is a slice: the particles of the lattice layer nearest the middle of z (those within half a layer of it, where
the grains move across z).
"""
import os
import re

import numpy as np

from parsph.errors import UsageError
from parsph.sph.particles import GRAIN, MOVING_WALL as MOVING  # particle kinds (docs/output.md)

FIELDS = {"vy": ("velocity", 1, "v_y [m/s]"), "vx": ("velocity", 0, "v_x [m/s]"),
          "theta": ("theta", None, "theta (volume fraction) [1]")}
LAYER_SCENES = ("sedimentation", "fluidized_bed")  # a layer on the floor x = 0 under a lid at x = L
WALL_COLOUR = "tan"   # not in the colour map, and not a grey that anti-aliased text makes


def field_values(snap, field):
    key, col, _ = FIELDS[field]
    a = snap[key]
    return a[:, col] if col is not None else a


def middle_layer(z, lattice=None):
    """Rows of the particles in the z-layer nearest the middle of their z range (a 3-D slice). ``lattice``: z of
    particles that keep their lattice levels (a scene's walls), where the others move across z (a bed): the
    slice is then the particles within half a level's spacing of the middle level."""
    if lattice is not None and lattice.size:
        levels = np.unique(np.round(lattice, 12))
        if levels.size >= 2:
            mid = levels[np.argmin(np.abs(levels - 0.5 * (levels[0] + levels[-1])))]
            return np.abs(z - mid) < 0.5 * float(np.min(np.diff(levels))), mid
    levels = np.unique(np.round(z, 12))
    span = levels[-1] - levels[0]
    # levels a hair apart (a layer's particles drifted in z by round-off) are one lattice level
    levels = levels[np.r_[True, np.diff(levels) > 1e-3 * span]] if span > 0 else levels
    mid = levels[np.argmin(np.abs(levels - 0.5 * (levels[0] + levels[-1])))]
    if levels.size < 2:
        return np.abs(z - mid) <= 1e-9 * max(1.0, abs(mid)), mid
    return np.abs(z - mid) < 0.25 * float(np.min(np.diff(levels))), mid


def snapshot_files(path, times):
    """(time, file) of the outputs with particles, all or those at ``times`` (to 1e-9 relative)."""
    import h5py
    from parsph.output import output_files
    found = []
    for fn in output_files(path):
        with h5py.File(fn, "r") as f:
            if "particles" in f:
                found.append((float(f.attrs["time"]), fn))
    found.sort()
    if not found:
        raise UsageError(f"{path}: no output with particles (run with output.snapshots = true)")
    return at_times(found, times, "particles")


def at_times(found, times, what):
    """The rows of ``found`` (time first, in time order) at each of ``times`` (to 1e-9 relative), all of them
    without ``times``; a time with none is a UsageError naming it and the times there are."""
    if not times:
        return found
    chosen = []
    for t in times:
        match = [tf for tf in found if abs(tf[0] - t) <= 1e-9 * max(abs(t), 1e-300) or tf[0] == t]
        if not match:
            raise UsageError(f"--times {t:g}: no output with {what} at that time "
                             f"(there are: {', '.join(f'{tf[0]:g}' for tf in found)})")
        chosen.append(match[0])
    return chosen


def colour_limits(vals):
    """(lo, hi) of the finite ``vals`` for one colour bar, widened where they are all alike."""
    vals = vals[np.isfinite(vals)]
    lo, hi = (float(vals.min()), float(vals.max())) if vals.size else (0.0, 1.0)
    if hi <= lo:
        lo, hi = lo - 0.5 * max(abs(lo), 1e-12), hi + 0.5 * max(abs(hi), 1e-12)
    return lo, hi


def png_name(h5, field):
    """DIR/<stem>_<field>_NNNN.png beside DIR/<stem>_NNNN.h5."""
    m = re.search(r"^(.*)_(\d{4,})\.h5$", os.path.basename(h5))
    return os.path.join(os.path.dirname(h5), f"{m.group(1)}_{field}_{m.group(2)}.png")


def layer_reference_heights(snaps):
    """{time: (the reference's, the SPH's) height below which 95% of the layer's mass lies} of layer-scene
    snapshots, the reference as ``parsph check`` judges by (layer_report.measures: the initial layer at t = 0, the
    transient after, without a gas the end state); {} where the snapshots are no layer's or carry no run file."""
    from parsph.errors import ConfigError
    from parsph.setup.config import loads
    from parsph.sph.profiles import mass_quantiles
    if not snaps or snaps[0]["attrs"].get("scene", "") not in LAYER_SCENES:
        return {}
    try:
        cfg = loads(snaps[0]["attrs"]["run_file"])
    except (ConfigError, KeyError):
        return {}
    from parsph.setup.scenes import layer
    times = [float(s["attrs"]["time"]) for s in snaps]
    positive = [t for t in times if t > 0]
    tr = layer.transient(cfg, positive) if positive else None
    out = {}
    for t, s in zip(times, snaps):
        if cfg.gas is not None and t > 0:
            ref = float(tr.quantiles(t, [FRACTION_95])[0])
        elif cfg.gas is not None:   # t = 0: the initial layer
            ref = FRACTION_95 * layer.layer_height(cfg)
        else:
            ref = float(layer.end_state(cfg).quantiles([FRACTION_95])[0])
        fluid = s["kind"] == GRAIN
        sph = float(mass_quantiles(s["position"][fluid, 0], s["mass"][fluid], [FRACTION_95])[0]) \
            if fluid.any() else None
        out[t] = (ref, sph)
    return out


FRACTION_95 = 0.95   # the bed's height in the pictures: the height below which 95% of its mass lies


def figure(snap, field, limits, heights=None):
    """One picture (a Figure): fluid particles coloured by ``field`` within ``limits``, walls tan and marked.

    Couette-like scenes: x wall-normal horizontal, y streamwise vertical. Layer scenes (x the height, gravity
    along -x, y periodic): upright, the height vertical and gravity down, the floor and lid horizontal lines;
    ``heights`` = (reference, SPH) height below which 95% of the mass lies (:func:`layer_reference_heights`),
    drawn as horizontal lines where given."""
    import matplotlib.pyplot as plt
    a = snap["attrs"]
    pos, kind = snap["position"], snap["kind"]
    keep = np.ones(len(kind), bool)
    where = ""
    if int(a["dim"]) == 3:
        keep, zmid = middle_layer(pos[:, 2], pos[kind != GRAIN, 2])
        where = f", slice z = {zmid * 1e3:.3g} mm"
    x, y = pos[keep, 0], pos[keep, 1]
    values, k = field_values(snap, field)[keep], kind[keep]
    L, Ly = float(a["L"]), float(a["Ly"])
    xlo, xhi = min(0.0, x.min()), max(L, x.max())
    layer = a.get("scene", "") in LAYER_SCENES
    if layer:   # upright: y across, x (the height) up
        height = 7.5
        width = min(6.4, max(3.2, 1.6 + height * Ly / (xhi - xlo)))
        hx, vx = y, x          # what is drawn across and up
        across, up = (0.0, Ly), (xlo, xhi)
    else:
        width = 6.4
        height = min(9.0, max(2.5, width * Ly / (xhi - xlo) * 0.85))
        hx, vx = x, y
        across, up = (xlo, xhi), (0.0, Ly)
    fig, ax = plt.subplots(figsize=(width, height))
    ax.set_aspect("equal")
    ax.set_xlim(across[0] * 1e3, across[1] * 1e3)
    ax.set_ylim(up[0] * 1e3, up[1] * 1e3)
    fig.canvas.draw()
    # round markers about 0.8 lattice spacing wide (points^2), from the axes' size in points
    bbox = ax.get_window_extent().transformed(fig.dpi_scale_trans.inverted())
    spacing = np.sqrt((xhi - xlo) * Ly / max(1, len(x)))  # the side of the area per particle
    if layer:  # most of the box is empty above a layer: the lattice's row spacing, from the walls' rows where
        # there are some (they stay on the lattice; grains that moved give every y a row of its own)
        rows = y[k != GRAIN] if (k != GRAIN).any() else y
        gaps = np.diff(np.unique(np.round(rows, 12)))
        gaps = gaps[gaps > 1e-3 * Ly]   # rows a hair apart (fluid and wall, drifted by round-off) are one row
        spacing = float(np.median(gaps)) if gaps.size else spacing
    side = 72.0 * bbox.width * spacing / (across[1] - across[0])
    s = max(0.05, (0.8 * side) ** 2)
    fluid = k == GRAIN
    sc = ax.scatter(hx[fluid] * 1e3, vx[fluid] * 1e3, c=values[fluid], s=s, marker="o", linewidths=0,
                    cmap="viridis", vmin=limits[0], vmax=limits[1])
    if (~fluid).any():
        ax.scatter(hx[~fluid] * 1e3, vx[~fluid] * 1e3, c=WALL_COLOUR, s=s, marker="o", linewidths=0,
                   label="wall particles")
        # the planes x = 0 and x = L that the wall layers bound, each named by its particles' kind
        vw = float(a.get("V_w", 0.0))
        for xw, side in ((0.0, x < 0.0), (L, x > L)):
            if not (side & ~fluid).any():
                continue
            moving = (k[side & ~fluid] == MOVING).any()
            label = f"moving wall, v_y = {vw:g} m/s" if moving else "fixed wall"
            if layer:
                label = "floor" if xw == 0.0 else "lid"
                ax.axhline(xw * 1e3, color="k", lw=1.0)
                ax.text(0.02 * Ly * 1e3, xw * 1e3, f" {label} ", va="bottom" if xw == 0.0 else "top",
                        ha="left", fontsize=7, color="k", bbox=dict(facecolor="white", alpha=0.6, lw=0, pad=0.5))
                continue
            ax.axvline(xw * 1e3, color="k", lw=1.0)
            ax.text(xw * 1e3, 0.98 * Ly * 1e3, f" {label} ", rotation=90, va="top",
                    ha="left" if xw == 0.0 else "right", fontsize=7, color="k",
                    bbox=dict(facecolor="white", alpha=0.6, lw=0, pad=0.5))
    sides = bool(a.get("side_walls", False))
    if layer and sides:   # the side walls at y = 0 and y = Ly (their particles' rows lie beyond Ly, off the picture)
        for yw in (0.0, Ly):
            ax.axvline(yw * 1e3, color="k", lw=1.5)
    if layer and heights is not None:
        ref, sph = heights
        if ref is not None:
            ax.axhline(ref * 1e3, color="C3", lw=1.2, ls="--", label="95% of the mass below: reference")
        if sph is not None:
            ax.axhline(sph * 1e3, color="C1", lw=1.0, ls=":", label="95% of the mass below: SPH")
    if layer and ax.get_legend_handles_labels()[0]:   # below the narrow column, under its axis label
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.07), fontsize=7, frameon=False)
    elif (~fluid).any():
        ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), fontsize=7, frameon=False)
    if layer:
        ax.set_xlabel("y (between side walls) [mm]" if sides else "y (periodic) [mm]")
        ax.set_ylabel("x (height above the floor) [mm]; gravity down")
    else:
        ax.set_xlabel("x (wall-normal) [mm]")
        ax.set_ylabel("y (streamwise) [mm]")
    title = f"{a.get('scene', '')} t = {float(a['time']):g} s, {len(kind)} particles{where}"
    if layer:
        title = title.replace(" t = ", "\nt = ", 1)
    ax.set_title(title, fontsize=8 if layer else 9, pad=18 if (~fluid).any() and not layer else 6)
    fig.colorbar(sc, ax=ax, label=FIELDS[field][2])
    fig.tight_layout()
    return fig


def draw(snap, field, limits, png, heights=None):
    """Save :func:`figure` as ``png``."""
    import matplotlib.pyplot as plt
    fig = figure(snap, field, limits, heights)
    fig.savefig(png, dpi=120)
    plt.close(fig)


def plot_particles(path, field="vy", times=None):
    """Write one PNG per chosen output time; return their paths."""
    import matplotlib
    matplotlib.use("Agg")
    from parsph.output import read_snapshot
    chosen = snapshot_files(path, times)
    snaps = [(fn, read_snapshot(fn)) for _, fn in chosen]
    lo, hi = colour_limits(np.concatenate([field_values(s, field)[s["kind"] == GRAIN] for _, s in snaps]))
    heights = layer_reference_heights([snap for _, snap in snaps])
    pngs = []
    for fn, snap in snaps:
        png = png_name(fn, field)
        draw(snap, field, (lo, hi), png, heights.get(float(snap["attrs"]["time"])))
        pngs.append(png)
    return pngs
