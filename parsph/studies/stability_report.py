"""The stability map's figures, summaries and tables (docs/stability.md), from the runs' CSVs.

Each column's measured limit is bracketed by :func:`parsph.studies.stability.dt_bounds`
(time-step failures only: a failure at the column's physical failure time is
told apart by ``verdict``) and drawn or tabulated against the prediction
(:func:`parsph.studies.stability_cases.prediction`), so that a change of the
prediction redraws every figure from the runs already made.
"""
import math
import os

import numpy as np

from .runs import load_rows, write_rows
from .stability import column, dt_bounds, measured_bounds, physical_time, verdict
from .stability_cases import FIELDS, SETTLING, STEPS, columns_of, prediction, settling_limits

MARK = {"nonfinite": ("X", "tab:red"), "wall": ("v", "tab:purple"), "theta": ("s", "tab:orange"),
        "energy": ("^", "tab:red"), "jump": ("*", "tab:brown")}


def measured_limits(rows, nx):
    """{(theta0, Re): (lo, hi)} of dt_bounds for every column at nx."""
    keys = {(float(r["theta0"]), float(r["Re"])) for r in rows if int(r["nx"]) == nx}
    return {k: dt_bounds(column(rows, nx, *k)) for k in keys}


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    return plt, Line2D


def _draw_runs(ax, t, col, ms, fill="full"):
    """One column's runs at theta_0 = t: marker by verdict and first failure."""
    phys = physical_time(col)
    for r in col:
        m, v = float(r["multiple"]), verdict(r, phys)
        if v == "stable":
            ax.plot(t, m, "o", color="tab:green", ms=ms, fillstyle=fill(r) if callable(fill) else fill)
        elif v == "physical":
            ax.plot(t, m, "D", color="tab:gray", ms=ms, fillstyle=fill(r) if callable(fill) else fill)
        elif r["crash"]:
            ax.plot(t, m, "P", color="k", ms=ms + 1, fillstyle=fill(r) if callable(fill) else fill)
        else:
            mk, c = MARK.get(r["first_failure"], ("D", "k"))
            ax.plot(t, m, mk, color=c, ms=ms + 1, fillstyle=fill(r) if callable(fill) else fill)


def plot(rows, outdir, nx_list, tag=""):
    """stability_map[_TAG]_nx<N_x>.png per N_x (and, without a tag, stability_dt.png); their paths."""
    plt, Line2D = _pyplot()
    figs = []
    for nx in nx_list:
        sel = [r for r in rows if int(r["nx"]) == nx]
        if not sel:
            continue
        res_here = sorted({float(r["Re"]) for r in sel})
        fig, axes = plt.subplots(1, len(res_here), figsize=(2.9 * len(res_here) + 0.6, 4.4), sharey=True,
                                 squeeze=False)
        lims = measured_limits(rows, nx)
        for ax, Re in zip(axes[0], res_here):
            ts = sorted({float(r["theta0"]) for r in sel if float(r["Re"]) == Re})
            for t in ts:
                _draw_runs(ax, t, column(rows, nx, t, Re), 5, lambda r: "full" if r["source"] == "grid" else "none")
            mx = [(t, math.sqrt(lims[(t, Re)][0] * lims[(t, Re)][1])) for t in ts
                  if lims.get((t, Re), (None, None))[0] and lims[(t, Re)][1]]
            if mx:
                ax.plot(*zip(*mx), "-", color="k", lw=1.2)
            tt = np.linspace(0.05, 0.7, 60)
            integ = "midpoint" if tag == "midpoint" else "paper"
            ac = [prediction(t, Re, nx).acoustic_damping / min(prediction(t, Re, nx, integ).limits.values())
                  for t in tt]
            ax.plot(tt, ac, ":", color="tab:blue", lw=1.2)
            ax.axhline(1.0, color="tab:gray", lw=1.5, ls="--")
            ax.set_yscale("log", base=2)
            ax.set_ylim(1 / 80, 80)
            ax.set_xlim(0.0, 0.75)
            ax.set_title(f"Re = {Re:g}", fontsize=10)
            ax.set_xlabel(r"$\theta_0$")
            ax.grid(alpha=0.3, which="major")
        axes[0][0].set_ylabel("dt / predicted limit")
        handles = [Line2D([], [], marker="o", ls="", color="tab:green", label="stable (2,000 steps)"),
                   Line2D([], [], marker="^", ls="", color="tab:red", label="unstable: energy"),
                   Line2D([], [], marker="s", ls="", color="tab:orange", label="unstable: theta"),
                   Line2D([], [], marker="X", ls="", color="tab:red", label="unstable: non-finite"),
                   Line2D([], [], marker="v", ls="", color="tab:purple", label="unstable: wall"),
                   Line2D([], [], marker="*", ls="", color="tab:brown", label="unstable: moved > h (check 5)"),
                   Line2D([], [], marker="P", ls="", color="k", label="crash (no guard)"),
                   Line2D([], [], marker="D", ls="", color="tab:gray", label="fails at a fixed time, any dt"),
                   Line2D([], [], marker="o", ls="", color="tab:gray", fillstyle="none", label="bisection run"),
                   Line2D([], [], ls="--", color="tab:gray", label="predicted limit"),
                   Line2D([], [], ls="-", color="k", label="measured limit"),
                   Line2D([], [], ls=":", color="tab:blue", label=r"$2\nu/c^2$")]
        fig.legend(handles=handles, loc="lower center", ncol=6, fontsize=7.5, frameon=False)
        what = f"{tag} integrator, " if tag else ""
        fig.suptitle(f"Couette stability, N_x = {nx}, {what}{STEPS} steps of a fixed dt; y: dt / the limit of "
                     "parsph.physics.limits",
                     fontsize=10)
        fig.tight_layout(rect=(0, 0.1, 1, 0.95))
        png = os.path.join(outdir, f"stability_map{'_' + tag if tag else ''}_nx{nx}.png")
        fig.savefig(png, dpi=80)
        plt.close(fig)
        figs.append(png)
    if tag:
        return figs

    # measured stable dt [s] against the predicted limit, per theta_0 (N_x = 50 and 200)
    nxs = [nx for nx in (50, 200) if measured_limits(rows, nx)]
    if nxs:
        fig, axes = plt.subplots(1, len(nxs), figsize=(6.2 * len(nxs), 4.8), squeeze=False, sharey=True)
        for ax, nx in zip(axes[0], nxs):
            lims = measured_limits(rows, nx)
            res_here = sorted({k[1] for k in lims})
            colors = plt.cm.viridis(np.linspace(0, 0.9, len(res_here)))
            for col, Re in zip(colors, res_here):
                ts = sorted(t for t, r in lims if r == Re)
                tt = np.linspace(min(ts), max(ts), 40)
                ax.plot(tt, [min(prediction(t, Re, nx).limits.values()) for t in tt], "--", color=col, lw=1)
                pts = [(t, lims[(t, Re)][0] * min(prediction(t, Re, nx).limits.values())) for t in ts
                       if lims[(t, Re)][0] is not None]
                if pts:
                    ax.plot(*zip(*pts), "o-", color=col, ms=4, label=f"Re = {Re:g}")
            ax.set_yscale("log")
            ax.set_xlabel(r"$\theta_0$")
            ax.set_title(f"N_x = {nx}", fontsize=10)
            ax.grid(alpha=0.3, which="both")
        axes[0][0].set_ylabel("dt [s]")
        axes[0][0].legend(fontsize=8)
        fig.suptitle("Largest dt without a time-step failure in 2,000 steps (points) against the predicted "
                     "limit of parsph.physics.limits (dashed), paper integrator", fontsize=9)
        fig.tight_layout()
        png = os.path.join(outdir, "stability_dt.png")
        fig.savefig(png, dpi=80)
        plt.close(fig)
        figs.append(png)
    return figs


def _settling_column(rows, t):
    return sorted([r for r in rows if abs(float(r["theta0"]) - t) < 1e-9], key=lambda r: float(r["multiple"]))


def plot_settling(rows, outdir):
    """stability_settling.png: the settling column's runs against the prediction; its path."""
    plt, Line2D = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 5.4))
    nx = SETTLING["nx"]
    ts = sorted({float(r["theta0"]) for r in rows})
    meas = []
    for t in ts:
        col = _settling_column(rows, t)
        _draw_runs(ax, t, col, 6)
        lo, hi = dt_bounds(col)
        if lo and hi:
            meas.append((t, math.sqrt(lo * hi)))
    if meas:
        ax.plot(*zip(*meas), "-", color="k", lw=1.2)
    eq, nodamp = [], []   # the limit at the settled floor's theta (where auto ends up); without damping
    for t in ts:
        r = next(r for r in rows if abs(float(r["theta0"]) - t) < 1e-9)
        eq.append((t, float(r["dt_limit_eq"]) / float(r["dt_limit"])))
        nodamp.append((t, min(float(r[k]) for k in ("dt_cfl", "dt_viscous", "dt_force")) / float(r["dt_limit"])))
    ax.plot(*zip(*eq), "-.", color="tab:blue", lw=1.2)
    ax.plot(*zip(*nodamp), ":", color="tab:purple", lw=1.2)
    ax.axhline(1.0, color="tab:gray", lw=1.5, ls="--")
    ax.set_yscale("log", base=2)
    ax.set_ylim(1 / 8, 80)
    ax.set_xlabel(r"$\theta_0$")
    ax.set_ylabel("dt / predicted limit at $\\theta_0$")
    ax.grid(alpha=0.3)
    handles = [Line2D([], [], marker="o", ls="", color="tab:green", label="stable"),
               Line2D([], [], marker="^", ls="", color="tab:red", label="unstable: energy"),
               Line2D([], [], marker="s", ls="", color="tab:orange", label=r"unstable: $\theta$ vs equilibrium"),
               Line2D([], [], marker="X", ls="", color="tab:red", label="unstable: non-finite"),
               Line2D([], [], marker="v", ls="", color="tab:purple", label="unstable: floor/lid"),
               Line2D([], [], ls="--", color="tab:gray", label=r"predicted limit at $\theta_0$ (config)"),
               Line2D([], [], ls="-.", color="tab:blue", label=r"limit at the floor's $\theta$ (auto, settled)"),
               Line2D([], [], ls=":", color="tab:purple", label="min(CFL, viscous, force): no damping"),
               Line2D([], [], ls="-", color="k", label="measured limit")]
    fig.legend(handles=handles, fontsize=7, loc="lower center", ncol=3, frameon=False)
    ax.set_title(f"Settling column, N_x = {nx}, g = 30 m/s$^2$, k = 1, paper integrator, fixed dt\n"
                 f"(runs of {SETTLING['steps']} steps of the limit they were run against, at least "
                 f"{SETTLING['min_steps']} steps)", fontsize=9)
    fig.tight_layout(rect=(0, 0.14, 1, 1))
    png = os.path.join(outdir, "stability_settling.png")
    fig.savefig(png, dpi=80)
    plt.close(fig)
    return png


def _f(v):
    return "-" if v is None else f"{v:.3g}"


def summary(rows, nx=50, title=""):
    """Text table: per (theta_0, Re) the predicted limit and the measured time-step limit."""
    lines = [f"N_x = {nx}{title}: measured dt / predicted limit, last without a time-step failure .. first with one",
             f"{'theta0':>6} {'Re':>6} {'term':>8} {'limit [s]':>10} {'ok<=':>7} {'fail>=':>7} "
             f"{'2nu/c^2/lim':>11}  first time-step failure; fixed-time failure"]
    keys = sorted({(float(r["theta0"]), float(r["Re"])) for r in rows if int(r["nx"]) == nx})
    for t, Re in keys:
        col = column(rows, nx, t, Re)
        lo, hi = dt_bounds(col)
        phys = physical_time(col)
        p = prediction(t, Re, nx)
        first = next((r for r in col if float(r["multiple"]) == hi), None) if hi else None
        how = f"{first['first_failure']} at step {first['fail_step']}" if first else ""
        if phys:
            how += f"; {phys[1]} at t = {phys[0]:.3g} s whatever dt"
        lines.append(f"{t:>6g} {Re:>6g} {p.term:>8} {p.dt:>10.3g} {_f(lo):>7} {_f(hi):>7} "
                     f"{p.acoustic_damping / p.dt:>11.3g}  {how}")
    return "\n".join(lines)


def summary_settling(rows):
    """Text table of the settling column: per theta_0 the predicted limit and the measured one."""
    lines = [f"settling column, N_x = {SETTLING['nx']}: measured dt / predicted limit (at theta_0), last without "
             "a time-step failure .. first with one",
             f"{'theta0':>6} {'term':>8} {'limit [s]':>10} {'ok<=':>6} {'fail>=':>6} {'eq/lim':>7} "
             f"{'force/lim':>9}  first failure"]
    for t in sorted({float(r["theta0"]) for r in rows}):
        col = _settling_column(rows, t)
        lo, hi = dt_bounds(col)
        r0 = col[0]
        lim = float(r0["dt_limit"])
        first = next((r for r in col if float(r["multiple"]) == hi), None) if hi else None
        how = f"{first['first_failure']} at step {first['fail_step']} (t = {float(first['t_done']):.3g} s)" \
            if first else ""
        lines.append(f"{t:>6g} {r0['limit_term']:>8} {lim:>10.3g} {_f(lo):>6} {_f(hi):>6} "
                     f"{float(r0['dt_limit_eq']) / lim:>7.3g} {float(r0['dt_force']) / lim:>9.3g}  {how}")
    return "\n".join(lines)


def write_merged(out_dir):
    """stability_all.csv: every run (both integrators, bisection and long runs) with each row's verdict."""
    parts = [("stability_map.csv", "paper"), ("stability_map_midpoint.csv", "midpoint"),
             ("stability_long.csv", "paper")]
    extra = ["integrator", "verdict", "t_phys", "criterion_phys", "confirmed"]
    merged = []
    for name, integrator in parts:
        rows = load_rows(os.path.join(out_dir, name))
        for r in rows:
            col = column(rows, int(r["nx"]), float(r["theta0"]), float(r["Re"]))
            phys = physical_time(col) if r["source"] != "long" else (float(r["t_phys"]), r["criterion_phys"])
            merged.append({**r, "integrator": integrator, "verdict": verdict(r, phys)})
    path = os.path.join(out_dir, "stability_all.csv")
    write_rows(path, FIELDS + extra, merged)
    return path


def ratios(paths, out_dir, auto=None, commits=()):
    """stability_ratios.csv: per (integrator, N_x, theta_0, Re) the measured bounds over every run in the
    CSVs (absolute dt) over the prediction now; the settling column's runs (a file named *settling*) as
    integrator 'settling'. With ``auto`` (stability_auto.csv): each column's dt = "auto" run, stable or
    not, and its mean step (t / steps) over the prediction and over the largest measured stable dt.
    Prints one line per column; the CSV's path."""
    cols = {}
    for path in paths:
        columns_of(path, cols)
    if commits:   # only the runs made at these commits
        cols = {k: [r for r in rows if r.get("commit") in commits] for k, rows in cols.items()}
        cols = {k: rows for k, rows in cols.items() if rows}
    autos = {}
    for r in load_rows(auto) if auto else []:
        autos[(r["integrator"], int(r["nx"]), round(float(r["theta0"]), 6), round(float(r["Re"]), 6))] = r
    out = []
    for key, rows in sorted(cols.items()):
        integ, nx, t, Re = key
        if integ == "settling":
            lim = settling_limits(t, nx)
            term = min(lim, key=lim.get)
            rows = sorted(rows, key=lambda r: float(r["dt"]))
            for r in rows:
                r["multiple"] = repr(float(r["dt"]) / lim[term])
            p = lim[term]
        else:
            pred = prediction(t, Re, nx, integ)
            term, p = pred.term, pred.dt
        lo, hi = measured_bounds(rows)
        row = {"integrator": integ, "nx": nx, "theta0": t, "Re": Re, "term": term, "dt_pred": p,
               "stable_to": lo / p if lo else "", "fails_at": hi / p if hi else "", "runs": len(rows)}
        au = autos.get(key)
        if au:
            dt_mean = float(au["t_done"]) / int(au["steps_done"])
            row.update({"auto_stable": au["stable"], "auto_dt_mean": dt_mean, "auto_over_pred": dt_mean / p,
                        "auto_over_stable": dt_mean / lo if lo else ""})
        out.append(row)
        f = lambda v: f"{v:.3g}" if v != "" else "-"  # noqa: E731
        extra = (f"  auto {'stable' if au['stable'] == '1' else 'UNSTABLE'} {f(row['auto_over_pred'])} x pred, "
                 f"{f(row['auto_over_stable'])} x stable") if au else ""
        print(f"{integ:8} {nx:4d} {t:5.2f} {Re:6g} {term:9} {p:9.3g}  {f(row['stable_to']):>6} .. "
              f"{f(row['fails_at']):<6} ({len(rows)} runs){extra}")
    path = os.path.join(out_dir, "stability_ratios.csv")
    write_rows(path, list(dict.fromkeys(k for r in out for k in r)), out)
    return path
