"""What ``parsph check`` and ``parsph plot`` add for the layer scenes (``sedimentation``, ``fluidized_bed``;
docs/physics.md, "The solid phase in a gas", references 3 and 4). Serial: the output files alone (no MPI).

- sedimentation: the interface (:func:`parsph.sph.projected.interface_height`, theta_bar = theta0 / 2, from
  each output's particles) against Kynch's line H0 + v0 t until the top meets the rising sediment (t_m), and
  after t_m against the end state's height at theta0 / 2; the sediment front h(t) = front_speed t drawn.
- fluidized_bed: the top (theta_bar = theta* / 2) against the steady column's height at theta* / 2, and the
  interior theta (the profile's mean over the bins from 2h above the floor to 2h below where the steady
  column falls to theta* / 2) against theta*.

Heights are compared relative to H0 (``scene.height``); theta relative to theta*.
"""
import math
import os
import re

import numpy as np


def layer_run(p):
    """The run's RunConfig where its scene is a layer scene (``free_surface``), else None; p is read_profile's."""
    from parsph.errors import ConfigError
    from parsph.setup.config import loads
    try:
        cfg = loads(p["attrs"]["run_file"])
    except (ConfigError, KeyError):
        return None
    return cfg if cfg.scene.free_surface else None


def _snapshots(path):
    """(time, fluid x, fluid mass) of every output with particles, by time."""
    import h5py
    from parsph.output import output_files
    from parsph.sph.particles import FLUID
    out = []
    for fn in output_files(path):
        with h5py.File(fn, "r") as f:
            if "particles" not in f:
                continue
            g = f["particles"]
            kind = g["kind"][()]
            fluid = kind == FLUID
            out.append((float(f.attrs["time"]), g["position"][()][fluid, 0], g["mass"][()][fluid]))
    out.sort(key=lambda r: r[0])
    return out


def _level(cfg):
    """The level the top is measured at: theta0 / 2 for a sedimenting layer, theta* / 2 for a bed."""
    from parsph.setup.scenes import layer
    end = layer.end_state(cfg)
    return 0.5 * (end.theta_star if end.U > 0 else cfg.theta0)


def interface_series(path, cfg):
    """(times, measured top [m], reference top [m]) over the outputs with particles: the top at
    :func:`_level`; the reference Kynch's line until t_m, then (and for a bed) the end state's height there."""
    from parsph.setup.scenes import layer
    from parsph.sph import projected
    level = _level(cfg)
    end = layer.end_state(cfg)
    settled = end.height_of(min(level, end.theta_floor))
    kynch = layer.sedimentation(cfg) if cfg.gas is not None and end.U == 0 else None
    times, tops, refs = [], [], []
    for t, x, m in _snapshots(path):
        try:
            top = projected.interface_height(cfg, x, m, level)
        except ValueError:
            top = math.nan
        ref = float(kynch.interface(t)) if kynch is not None else math.nan
        times.append(t)
        tops.append(top)
        refs.append(settled if not math.isfinite(ref) else ref)
    return np.array(times), np.array(tops), np.array(refs)


def interior_span(cfg):
    """[lo, hi] [m]: from 2h above the floor to 2h below where the end state falls to half its interior value."""
    from parsph.setup.scenes import layer
    end = layer.end_state(cfg)
    ref = end.theta_star if end.U > 0 else end.theta_floor
    return 2.0 * cfg.h, end.height_of(0.5 * ref) - 2.0 * cfg.h


def interior_theta(p, cfg):
    """The profile's theta averaged over the interior's bins (weighted by their particle counts), per output."""
    lo, hi = interior_span(cfg)
    sel = (p["x"] >= lo) & (p["x"] <= hi)
    theta, count = np.asarray(p["theta"], float), np.asarray(p["count"], float)
    with np.errstate(invalid="ignore"):
        w = np.where(sel[None, :] & (count > 0), count, 0.0)
        return np.sum(np.nan_to_num(theta) * w, axis=1) / np.sum(w, axis=1)


def summary(path, p, cfg):
    """check's lines for a layer scene (a few): the interface against Kynch's line, or the bed's interior and
    top against the steady column."""
    from parsph.setup.scenes import layer
    H0 = layer.layer_height(cfg)
    end = layer.end_state(cfg)
    times, tops, refs = interface_series(path, cfg)
    lines = []
    if cfg.scene.name == "sedimentation":
        if cfg.gas is None:
            lines.append("no gas: Kynch's line does not apply; the layer falls to the hydrostatic sediment")
        else:
            k = layer.sedimentation(cfg)
            lines.append(f"interface (theta_bar = theta0/2) against Kynch's line H0 + v0 t: H0 = {H0 * 1e3:.4g} mm, "
                         f"v0 = {k.settling_velocity * 1e3:.4g} mm/s until t_m = {k.meeting_time:.4g} s "
                         f"(at {k.meeting_height * 1e3:.4g} mm), then the sediment's "
                         f"{end.height_of(min(0.5 * cfg.theta0, end.theta_floor)) * 1e3:.4g} mm")
        if not times.size:
            lines.append("no output with particles: the interface is not measured (output.snapshots = false)")
        for t, top, ref in zip(times, tops, refs):
            lines.append(f"  t = {t:<8.4g} interface {top * 1e3:9.4g} mm, reference {ref * 1e3:9.4g} mm, "
                         f"difference {(top - ref) / H0 * 100:+.3g}% of H0")
        return lines
    interior = interior_theta(p, cfg)
    lo, hi = interior_span(cfg)
    steady = end.height_of(min(_level(cfg), end.theta_floor))
    lines.append(f"bed interior ({lo * 1e3:.3g} to {hi * 1e3:.3g} mm) against theta* = {end.theta_star:.4g}, "
                 f"top (theta_bar = theta*/2) against the steady column's {steady * 1e3:.4g} mm:")
    tops_at = dict(zip(times, tops))
    for t, th in zip(p["time"], interior):
        top = tops_at.get(float(t), math.nan)
        lines.append(f"  t = {t:<8.4g} interior theta {th:.4g} ({(th / end.theta_star - 1) * 100:+.3g}%), "
                     f"top {top * 1e3:.4g} mm" + ("" if math.isfinite(top) else " (no particles written)"))
    return lines


def profile_figure(p, cfg):
    """theta(x) and v_x(x) over their references, one panel each (a Figure)."""
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.4))
    colors = plt.cm.viridis(np.linspace(0, 0.9, max(1, len(p["time"]))))
    L = cfg.L
    x_fine = np.linspace(0.0, L, 401)
    for c, t, k in zip(colors, p["time"], range(len(p["time"]))):
        ref = cfg.scene.reference(cfg, x_fine, float(t))
        for ax, key in zip(axes, ("theta", "vx")):
            ax.plot(x_fine / L, ref[key], "-", color=c, lw=1.2)
            ax.plot(p["x"] / L, p[key][k], "o", color=c, ms=3, label=f"t = {t:g} s")
    axes[0].set_ylabel("theta")
    axes[1].set_ylabel("v_x [m/s]")
    for ax in axes:
        ax.set_xlabel("x / L (floor 0, lid 1)")
        ax.set_xlim(0.0, 1.0)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{cfg.scene.name}: SPH (points) against the reference (lines)")
    fig.tight_layout()
    return fig


def top_png(profile_png):
    """DIR/<stem>_interface.png beside DIR/<stem>_profile.png."""
    return re.sub(r"_profile\.png$", "_interface.png", profile_png)


def top_figure(path, p, cfg):
    """sedimentation: the interface against Kynch's line and the sediment front; bed: the top against the
    steady column's, and the interior theta against theta*. A Figure."""
    import matplotlib.pyplot as plt
    from parsph.setup.scenes import layer
    times, tops, refs = interface_series(path, cfg)
    end = layer.end_state(cfg)
    t_end = max([cfg.t_end] + list(times))
    if cfg.scene.name == "sedimentation":
        fig, ax = plt.subplots(figsize=(6.4, 4.8))
        settled = end.height_of(min(0.5 * cfg.theta0, end.theta_floor))
        if cfg.gas is not None:
            k = layer.sedimentation(cfg)
            tt = np.linspace(0.0, k.meeting_time, 101)
            ax.plot(tt, k.interface(tt) * 1e3, "-", color="C0", label="Kynch's line H0 + v0 t")
            ax.plot(tt, k.sediment_front(tt) * 1e3, "--", color="C1", label="sediment front (Kynch)")
            t0 = k.meeting_time
        else:
            t0 = 0.0
        ax.plot([t0, t_end], [settled * 1e3] * 2, ":", color="C2", label="end state (theta0/2)")
        ax.plot(times, tops * 1e3, "o", color="k", ms=4, label="SPH interface (theta_bar = theta0/2)")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("height [mm]")
        ax.set_title("sedimentation: the interface against Kynch's line")
        ax.legend(fontsize=8)
    else:
        fig, (a, b) = plt.subplots(1, 2, figsize=(10.0, 4.4))
        a.plot([0.0, t_end], [refs[0] * 1e3 if refs.size else np.nan] * 2, "-", color="C0",
               label="steady column (theta*/2)")
        a.plot(times, tops * 1e3, "o", color="k", ms=4, label="SPH top (theta_bar = theta*/2)")
        a.set_xlabel("t [s]")
        a.set_ylabel("top [mm]")
        a.legend(fontsize=8)
        b.plot([0.0, t_end], [end.theta_star] * 2, "-", color="C0", label="theta*")
        b.plot(p["time"], interior_theta(p, cfg), "o", color="k", ms=4, label="SPH interior theta")
        b.set_xlabel("t [s]")
        b.set_ylabel("theta")
        b.legend(fontsize=8)
        fig.suptitle("fluidized_bed: the top and the interior against the steady column")
    fig.tight_layout()
    return fig


def save(fig, png):
    import matplotlib.pyplot as plt
    os.makedirs(os.path.dirname(os.path.abspath(png)), exist_ok=True)
    fig.savefig(png, dpi=120)
    plt.close(fig)
    return png
