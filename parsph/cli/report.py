"""``parsph check`` and ``parsph plot``: the error table of a run's outputs, and its profiles over the reference
(serial: no MPI needed)."""
import os
import re
import sys

from parsph.errors import ConfigError, UsageError
from .exits import EXIT_ERROR

DEFAULT_TOL = 0.02   # check's tolerance of the error table's max error (layer scenes: layer_report's own)


def _decaying(p):
    """The run of a decaying flow (its scene has a current_scale), else None."""
    from parsph.setup.config import loads
    try:
        cfg = loads(p["attrs"]["run_file"])
    except (ConfigError, KeyError):
        return None
    return cfg if cfg.scene.current_scale is not None else None


def print_table(path, tol=None):
    """Print the error table of a run's outputs; return the worst max error (None: the run's scene has no
    reference, which it says in one line).

    For a decaying flow the errors are relative to what is left of it at each time
    (``RunConfig.error_scale``, as the files' err_max), and also to its initial amplitude."""
    from parsph.output import read_profile
    from parsph.sph.profiles import errors
    p = read_profile(path)
    key = p["attrs"].get("error_field", "vy")
    field = {"vy": "v_y", "theta": "theta"}.get(key, "v_y")
    import numpy as np
    if not np.isfinite(np.asarray(p[key + "_exact"], float)).any():
        print(f"no reference for {field} in this run (its scene gives none here): no error table")
        return None
    from .layer_report import layer_run
    if layer_run(p) is not None:
        print("for information, not the verdict: the pointwise table (its reference steps where the layer is smooth:"
              " Kynch's fronts, the end state while the layer still moves; the layer check below judges)")
    cfg = _decaying(p)
    if cfg is None:
        scale = p["attrs"].get("error_scale", p["attrs"].get("V_w", 1.0))
        print(f"errors of {field} against the reference, relative to {scale:.4g}")
        print(f"{'t [s]':>10} {'max error':>12} {'rms error':>12}")
        rows = [(t, emax, erms, "") for t, emax, erms in zip(p["time"], p["err_max"], p["err_rms"])]
    else:
        initial = cfg.error_scale(0.0)
        print(f"errors of {field} against the reference, relative to the scene's amplitude at each time "
              f"(RunConfig.error_scale; initially {initial:.4g})")
        print(f"{'t [s]':>10} {'amplitude':>12} {'max error':>12} {'rms error':>12} {'max / initial':>13}")
        rows = []
        for t, f, fe in zip(p["time"], p[key], p[key + "_exact"]):
            s = cfg.error_scale(float(t))
            rows.append((t, *errors(f, fe, s), f" {s:>12.4g}", f" {errors(f, fe, initial)[0]:>13.3e}"))
    worst = 0.0
    for t, emax, erms, amp, *initial in rows:
        flag = "" if tol is None or emax <= tol else "  > tol"
        print(f"{t:>10.4g}{amp} {emax:>12.3e} {erms:>12.3e}{''.join(initial)}{flag}")
        worst = max(worst, emax) if emax == emax else float("nan")
    return worst


def _read(path, fn):
    try:
        return fn(path)
    except (FileNotFoundError, ValueError, OSError) as e:
        raise UsageError(f"cannot read output {path}: {e}") from None


def print_layer(path, p, tol=None):
    """A layer scene's check (:func:`.layer_report.report`; a bubbling bed's, :func:`.bed_report.report`): print
    its table, return its Verdict; None for other scenes. ``p``: the output's profile (read_profile's);
    ``tol``: both the heights' (of H0) and the interior theta's tolerance (default each its own), or the bed's
    pressure drop's."""
    from . import layer_report
    from . import bed_report
    cfg = bed_report.bed_run(p)
    if cfg is not None:  # bubbling: no 1-D reference; the drop against the weight judges
        lines, verdict = bed_report.report(path, cfg, bed_report.TOL_DROP if tol is None else tol)
    else:
        cfg = layer_report.layer_run(p)
        if cfg is None:
            return None
        tols = (layer_report.TOL_HEIGHTS, layer_report.TOL_THETA) if tol is None else (tol, tol)
        lines, verdict = layer_report.report(path, p, cfg, *tols)
    for line in lines:
        print(line)
    return verdict


def print_outputs(path, tol=None, table_tol=None):
    """What ``parsph run`` ends with and ``parsph check`` prints: the error table (its rows flagged above
    ``table_tol``; for a layer scene it is information, never flagged) and a layer's check (``tol``:
    :func:`print_layer`). Returns (the table's worst max error or None, the layer's Verdict or None)."""
    from parsph.output import read_profile
    from . import layer_report
    from . import bed_report
    p = _read(path, read_profile)
    layer = layer_report.layer_run(p) is not None
    # a bubbling bed has no reference for its profile (none is 1-D): no table
    worst = None if bed_report.bed_run(p) is not None else _read(path, lambda q: print_table(q, None if layer
                                                                                             else table_tol))
    return worst, _read(path, lambda q: print_layer(q, p, tol))


def cmd_check(args):
    tol = DEFAULT_TOL if args.tol is None else args.tol
    from .layer_report import Verdict
    worst, verdict = print_outputs(args.output, args.tol, tol)
    if verdict is not None:
        if not verdict.ok:
            for why in verdict.failures():
                print(f"parsph check: {why}", file=sys.stderr)
            return EXIT_ERROR
        if verdict.judged:
            print("parsph check: the layer's heights and interior theta within their tolerances"
                  if isinstance(verdict, Verdict) else
                  "parsph check: the bed's time-averaged pressure drop within its tolerance of its weight")
        elif isinstance(verdict, Verdict):
            print("parsph check: nothing to judge (no output with particles, and the layer in transit at every "
                  "output)")
        else:
            print("parsph check: nothing to judge (the bed's outputs from checks.settle on span under 1 s)")
        return 0
    if worst is None:
        print("parsph check: nothing to check against")
        return 0
    if not worst <= tol:
        print(f"parsph check: max error {worst:.3e} above tolerance {tol:g}", file=sys.stderr)
        return EXIT_ERROR
    print(f"parsph check: all errors within {tol:g}")
    return 0


def reference_lines(p, points=401):
    """The scene's reference at each output time on a fine grid over [0, L] (None where it has none),
    so that the plotted lines reach the plates; p is read_profile's dict."""
    import numpy as np
    from parsph.setup.config import loads
    cfg = loads(p["attrs"]["run_file"])
    field = p["attrs"].get("error_field", "vy")
    x = np.linspace(0.0, p["attrs"]["L"], points)
    lines = [cfg.scene.reference(cfg, x, t)[field]
             if cfg.scene.reference is not None and np.all(np.isfinite(ref)) else None
             for t, ref in zip(p["time"], p[field + "_exact"])]
    return x, lines


def profile_png(first):
    """DIR/<stem>_profile.png for the output file DIR/<stem>_NNNN.h5 (an index of four digits or more)."""
    stem = re.sub(r"_\d{4,}\.h5$", "", os.path.basename(first))
    return os.path.join(os.path.dirname(first), stem + "_profile.png")


def picture_kind(args):
    """"grid", "particles" or None (the profile figure) for ``parsph plot``'s options: as asked, or, where only
    --field, --times or --animate asks for pictures, the grid's where the outputs hold one (an animation, or
    p', always the grid's), else the particles'."""
    grid, particles = getattr(args, "grid", False), getattr(args, "particles", False)
    field, animate = getattr(args, "field", None), getattr(args, "animate", None)
    if grid and particles:
        raise UsageError("--grid and --particles: one picture kind a call")
    if particles and animate:
        raise UsageError("--animate: the animation is of the gas grid's pictures (--grid), not the particles'")
    if grid or particles:
        return "grid" if grid else "particles"
    if not (field or animate or getattr(args, "times", None)):
        return None
    from .grid_plot import holds_grid
    return "grid" if animate or field == "p" or _read(args.output, holds_grid) else "particles"


def cmd_plot(args):
    field = getattr(args, "field", None)
    kind = picture_kind(args)
    if kind == "grid":
        from .grid_plot import plot_grid
        for out in _read(args.output, lambda p: plot_grid(p, field or "theta", args.times, args.animate)):
            print(f"wrote {out}")
        return 0
    if kind == "particles":
        from .particles_plot import plot_particles
        if field == "p":
            raise UsageError("--field p: the particles have vy, vx, theta (p' is the grid's: --grid)")
        for png in _read(args.output, lambda p: plot_particles(p, field or "vy", args.times)):
            print(f"wrote {png}")
        return 0
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from parsph.output import output_files, read_profile
    from . import layer_report
    p = _read(args.output, read_profile)
    first = output_files(args.output)[0]
    png = args.png or profile_png(first)
    cfg = layer_report.layer_run(p)
    from . import bed_report
    if bed_report.bed_run(p) is not None:  # a bubbling bed: its drop, heights and bubbles in time
        png = args.png or re.sub(r"_profile\.png$", "_bed.png", profile_png(first))
        print(f"wrote {_read(args.output, lambda path: layer_report.save(bed_report.figure(path, cfg), png))}")
        return 0
    if cfg is not None:  # a layer: theta(x) and v_x(x), and the interface (or the bed's top and interior) in time
        print(f"wrote {layer_report.save(layer_report.profile_figure(p, cfg), png)}")
        top = layer_report.top_png(png) if png.endswith("_profile.png") else re.sub(r"(\.png)?$", "_interface.png",
                                                                                     png, count=1)
        print(f"wrote {_read(args.output, lambda path: layer_report.save(layer_report.top_figure(path, p, cfg), top))}")
        return 0
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    colors = plt.cm.viridis(np.linspace(0, 0.9, max(1, len(p["time"]))))
    L = p["attrs"]["L"]
    field = p["attrs"].get("error_field", "vy")
    x_fine, lines = reference_lines(p)
    for c, t, sim, line in zip(colors, p["time"], p[field], lines):
        if line is not None:
            ax.plot(x_fine / L, line, "-", color=c, lw=1.2)
        ax.plot(p["x"] / L, sim, "o", color=c, ms=3, label=f"t = {t:g} s")
    ax.set_xlabel("x / L")
    ax.set_ylabel({"vy": "v_y [m/s]", "theta": "theta"}[field])
    ax.set_title("SPH (points) against the reference (lines)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    print(f"wrote {png}")
    return 0
