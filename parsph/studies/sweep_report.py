"""The analysis of the accuracy/speed sweep (docs/accuracy.md): its runs as one CSV row each, the
convergence orders per family of choices, the Pareto frontier of error against cost, the figures and
summary.md, from the records of :mod:`parsph.studies.sweep`.

Cost is the process CPU time of the time loop up to the output time: on a
shared machine wall time also counts other people's work (both are in the
CSV). The kernel's bias at fixed h/dx (nu_eff = (1 + b) nu on the lattice) is
shown beside the errors, since no refinement at fixed h/dx removes it.
"""
import csv
import math
import os

import numpy as np

from parsph.physics.analytic import couette_velocity
from parsph.physics.lattice_sums import sheared_lattice_bias, viscosity_bias
from .fits import local_orders, loglog_slope
from .sweep import NO_CAP, TIMES, build_config


def nu_eff_errors(rec, out_dir):
    """Max error at each output time against Eq. (8) evaluated with nu_eff instead of nu."""
    path = os.path.join(out_dir, "profiles", rec["id"] + ".npz")
    if not os.path.exists(path):
        return {}
    c = rec["choices"]
    cfg = build_config(c)  # the run's own physics (its "set" overrides included)
    ratio = viscosity_bias(c["kernel"], c["h_over_dx"])
    d = np.load(path)
    out = {}
    for t, vy in zip(d["t"], d["vy"]):
        ref = couette_velocity(d["x"], float(t), cfg.nu * ratio, cfg.L, cfg.V_w)
        out[round(float(t), 6)] = float(np.nanmax(np.abs(vy - ref)) / abs(cfg.V_w))
    return out


CSV_COLUMNS = (["id", "groups", "status", "kernel", "integrator", "h_over_dx", "Nx", "dx", "layers", "beta_max",
                "dt_mode", "dt_safety", "dt_first", "dt_mean", "t_end", "perturb", "n_particles", "steps",
                "wall_s", "cpu_s", "particle_steps_per_s", "particle_steps_per_cpu_s", "process_cpu_total_s",
                "nu_eff_over_nu", "set", "code"]
               + [f"{q}_t{t:g}" for t in TIMES
                  for q in ("err_max", "err_rms", "err_int", "x_at_max", "err_max_nueff", "cpu_s", "wall_s")])


def flatten(rec, groups, out_dir):
    c = rec["choices"]
    row = {"id": rec["id"], "groups": " ".join(sorted(groups)), "status": rec["status"],
           "kernel": c["kernel"], "integrator": c["integrator"], "h_over_dx": c["h_over_dx"], "Nx": c["Nx"],
           "dx": rec["dx"], "layers": rec["layers_used"], "beta_max": c["beta_max"],
           "dt_mode": "auto" if c["dt"] == "auto" else "fixed",
           "dt_safety": c["dt_safety"] if c["dt"] == "auto" else "", "dt_first": rec["dt_first"],
           "dt_mean": rec["dt_mean"], "t_end": c["t_end"], "perturb": c["perturb"] or "",
           "n_particles": rec["n_particles"], "steps": rec["steps"], "wall_s": rec["wall_s"],
           "cpu_s": rec["cpu_s"], "particle_steps_per_s": rec["particle_steps_per_s"],
           "particle_steps_per_cpu_s": rec["particle_steps_per_cpu_s"],
           "process_cpu_total_s": rec.get("process_cpu_total_s", ""),
           "nu_eff_over_nu": viscosity_bias(c["kernel"], c["h_over_dx"]),
           "set": " ".join(c.get("set", [])), "code": rec.get("code", "")}
    nueff = nu_eff_errors(rec, out_dir)
    by_t = {round(o["t"], 6): o for o in rec["outputs"]}
    for t in TIMES:
        o = by_t.get(round(t, 6))
        for q in ("err_max", "err_rms", "err_int", "x_at_max", "cpu_s", "wall_s"):
            row[f"{q}_t{t:g}"] = o[q] if o else ""
        row[f"err_max_nueff_t{t:g}"] = nueff.get(round(t, 6), "") if o else ""
    return row


def num(v):
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def family(row):
    """The choices other than N_x (a convergence series)."""
    dt = f"auto x{num(row['dt_safety']):g}" if row["dt_mode"] == "auto" else f"dt {num(row['dt_first']):g}"
    b = "none" if num(row["beta_max"]) >= NO_CAP else f"{num(row['beta_max']):g}"
    return f"{row['kernel']}, {row['integrator']}, h/dx {num(row['h_over_dx']):g}, {dt}, beta_max {b}"


def short(row):
    k = {"cubic_spline": "CS", "wendland_c2": "WC2"}[row["kernel"]]
    i = {"paper": "Eu", "midpoint": "MP"}[row["integrator"]]
    dt = f"s{num(row['dt_safety']):g}" if row["dt_mode"] == "auto" else f"dt{num(row['dt_first']):g}"
    b = "" if num(row["beta_max"]) == 1.5 else (" nocap" if num(row["beta_max"]) >= NO_CAP
                                                  else f" b{num(row['beta_max']):g}")
    lay = "" if int(num(row["layers"])) == math.ceil(2 * num(row["h_over_dx"]) - 1e-9) else f" L{row['layers']}"
    return f"{k} {i} h{num(row['h_over_dx']):g} N{row['Nx']} {dt}{b}{lay}"


def convergence(rows):
    """{family: {t: (dx list, err list, order, local orders)}} for families with >= 2 resolutions."""
    fams = {}
    for r in rows:
        if r["status"] == "ok" and "conv" in r["groups"].split():
            fams.setdefault(family(r), []).append(r)
    out = {}
    for fam, rs in fams.items():
        rs.sort(key=lambda r: int(r["Nx"]))
        out[fam] = {}
        for t in TIMES:
            pts = [(num(r["dx"]), num(r[f"err_max_t{t:g}"]), num(r[f"err_rms_t{t:g}"]), int(r["Nx"]))
                   for r in rs if math.isfinite(num(r[f"err_max_t{t:g}"]))]
            if len(pts) < 2:
                continue
            dx, em, er, nx = map(list, zip(*pts))
            out[fam][t] = {"dx": dx, "Nx": nx, "err": em, "rms": er, "order": loglog_slope(dx, em),
                           "order_rms": loglog_slope(dx, er), "local": local_orders(dx, em)}
    return out


def pareto(points):
    """Indices of the Pareto frontier of (cost, error) points (nothing cheaper is as accurate)."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def candidates(rows, t):
    return [r for r in rows if r["status"] == "ok" and not {"probe", "diag"} & set(r["groups"].split())
            and math.isfinite(num(r[f"err_max_t{t:g}"])) and math.isfinite(num(r[f"cpu_s_t{t:g}"]))]


def is_paper_case(r):
    return (r["kernel"] == "cubic_spline" and r["integrator"] == "paper" and num(r["h_over_dx"]) == 1.25
            and int(r["Nx"]) == 50 and r["dt_mode"] == "fixed" and num(r["dt_first"]) == 1e-5
            and num(r["beta_max"]) == 1.5 and not r["perturb"])


# ---- plots ----------------------------------------------------------------------------------
FAMILY_COLOURS = {("cubic_spline", 1.25): "tab:blue", ("cubic_spline", 1.5): "tab:cyan",
                  ("cubic_spline", 2.0): "tab:green", ("wendland_c2", 1.25): "tab:red",
                  ("wendland_c2", 1.5): "tab:purple", ("wendland_c2", 2.0): "tab:brown"}
MARKERS = {("cubic_spline", 1.25): "o", ("cubic_spline", 1.5): "D", ("wendland_c2", 1.25): "s",
           ("wendland_c2", 1.5): "^", ("wendland_c2", 2.0): "v"}
COLOURS = {"paper": "tab:blue", "midpoint": "tab:orange"}


def style(r):
    """(marker, colour, filled): colour by kernel and h/dx, marker by integrator and dt, filled = cap 1.5."""
    col = FAMILY_COLOURS.get((r["kernel"], num(r["h_over_dx"])), "k")
    dt_varied = r["dt_mode"] == "fixed" or num(r["dt_safety"] or 1) != 1.0
    m = "D" if dt_varied else ("o" if r["integrator"] == "paper" else "s")
    return m, col, num(r["beta_max"]) == 1.5


def plot_pareto(rows, path, cost="cpu"):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    for ax, t in zip(axes, (0.05, 0.5)):
        rs = candidates(rows, t)
        if not rs:
            ax.set_visible(False)
            continue
        pts = [(num(r[f"{cost}_s_t{t:g}"]), num(r[f"err_max_t{t:g}"])) for r in rs]
        for r, (x, y) in zip(rs, pts):
            m, col, filled = style(r)
            ax.plot(x, y, m, ms=6, mfc=col if filled else "none", mec=col, mew=1.3)
            if is_paper_case(r):
                ax.plot(x, y, "*", ms=16, mfc="none", mec="k")
        front = pareto(pts)
        fx, fy = zip(*[pts[i] for i in front])
        ax.step(fx, fy, where="post", color="k", lw=1, alpha=0.6, zorder=0)
        for n, i in enumerate(front):  # labels alternately above and below the line
            ax.annotate(short(rs[i]), pts[i], fontsize=6, xytext=(3, 4) if n % 2 == 0 else (-10, -10),
                        textcoords="offset points")
        ax.axhline(0.01, color="grey", ls=":", lw=1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"process CPU time of the time loop to t = {t:g} s [s]" if cost == "cpu"
                      else f"wall time to t = {t:g} s [s]")
        ax.set_ylabel(f"max |v_y - Eq. (8)| / V_w at t = {t:g} s")
        ax.set_title(f"t = {t:g} s: error against {'CPU' if cost == 'cpu' else 'wall'} time, Pareto frontier (line)")
        ax.grid(True, which="both", alpha=0.2)
    handles = [Line2D([], [], ls="none", marker="o", color=c, label=f"{k.split('_')[0]} h/dx {hr:g}")
               for (k, hr), c in FAMILY_COLOURS.items()
               if any(r["kernel"] == k and num(r["h_over_dx"]) == hr for r in rows)]
    handles += [Line2D([], [], ls="none", marker="o", color="grey", label="Eqs. (6)-(7)"),
                Line2D([], [], ls="none", marker="s", color="grey", label="midpoint"),
                Line2D([], [], ls="none", marker="D", color="grey", label="dt fixed or safety < 1"),
                Line2D([], [], ls="none", marker="o", mfc="none", mec="grey", label="beta_max other than 1.5"),
                Line2D([], [], ls="none", marker="*", ms=12, mfc="none", mec="k", label="paper case (Table 1)")]
    fig.legend(handles=handles, loc="lower center", ncol=6, fontsize=7, frameon=False)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_convergence(conv, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(12, 6.4))
    for ax, t in zip(axes, (0.05, 0.5)):
        any_ = False
        for fam, by_t in sorted(conv.items()):
            if t not in by_t:
                continue
            any_ = True
            d = by_t[t]
            kern, integ, hr = [s.strip() for s in fam.split(",")[:3]]
            hr = float(hr.split()[-1])
            nocap = "beta_max none" in fam
            m = MARKERS.get((kern, hr), "x")
            ls = {(False, "paper"): "-", (False, "midpoint"): "--", (True, "paper"): ":",
                  (True, "midpoint"): "-."}[(nocap, integ)]
            col = FAMILY_COLOURS.get((kern, hr), "k")
            ax.plot(d["dx"], d["err"], ls, marker=m, color=col, ms=6, mfc="none" if nocap else col,
                    label=f"{'CS' if kern.startswith('cubic') else 'WC2'} h/dx {hr:g} "
                          f"{'Eu' if integ == 'paper' else 'MP'} {'no cap' if nocap else 'cap 1.5'}: "
                          f"p = {d['order']:.2f}")
        if not any_:
            ax.set_visible(False)
            continue
        ax.axhline(0.01, color="grey", ls=":", lw=1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("dx [m]  (L / N_x; N_x = 100 ... 20)")
        ax.set_ylabel(f"max error / V_w at t = {t:g} s")
        ax.set_title(f"t = {t:g} s, fixed h/dx, dt = auto: least-squares order p (err ~ dx^p)\n"
                     "filled: Morris cap 1.5 (paper), hollow: no cap; Eu: Eqs. (6)-(7), MP: midpoint",
                     fontsize=9)
        ax.legend(fontsize=7, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.13), frameon=False)
        ax.grid(True, which="both", alpha=0.2)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


# ---- report ---------------------------------------------------------------------------------
def summary(rows, conv, source=None):
    lines = ["# Sweep summary", ""]
    lines.append("Written by `scripts/sweep.py` (docs/accuracy.md explains the grid and the columns). "
                 f"Runs: {len(rows)}, code hash(es) {', '.join(sorted({r['code'] for r in rows}))}"
                 + (f"; {source}" if source else "") + ". Costs are CPU seconds of that code.")
    lines.append("")
    lines.append("## Convergence orders (max error; least squares over all N_x; local orders between "
                 "successive N_x)")
    lines.append("")
    lines.append("| family | t [s] | N_x | max error | order (max) | order (RMS) | local orders |")
    lines.append("| --- | --- | --- | --- | --- | --- | --- |")
    for fam, by_t in sorted(conv.items()):
        for t, d in sorted(by_t.items()):
            lines.append(f"| {fam} | {t:g} | {', '.join(map(str, d['Nx']))} | "
                         f"{', '.join(f'{e:.2e}' for e in d['err'])} | {d['order']:.2f} | {d['order_rms']:.2f} | "
                         f"{', '.join(f'{x:.2f}' for x in d['local'])} |")
    lines.append("")
    paper = [r for r in rows if is_paper_case(r) and r["status"] == "ok"]
    for t in (0.05, 0.5):
        rs = candidates(rows, t)
        if not rs:
            continue
        pts = [(num(r[f"cpu_s_t{t:g}"]), num(r[f"err_max_t{t:g}"])) for r in rs]
        lines.append(f"## Pareto frontier at t = {t:g} s (cost: CPU s of the time loop to t)")
        lines.append("")
        lines.append("| setting | CPU s | wall s | particles | steps to t | max error | RMS error | interior max |"
                     " x of max / L |")
        lines.append("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        for i in pareto(pts):
            r = rs[i]
            steps = round(t / num(r["dt_mean"])) if r["dt_mode"] == "auto" else round(t / num(r["dt_first"]))
            lines.append(f"| {short(r)} | {pts[i][0]:.3g} | {num(r[f'wall_s_t{t:g}']):.3g} | {r['n_particles']} | "
                         f"~{steps} | {pts[i][1]:.2e} | {num(r[f'err_rms_t{t:g}']):.2e} | "
                         f"{num(r[f'err_int_t{t:g}']):.2e} | {num(r[f'x_at_max_t{t:g}']):.2f} |")
        lines.append("")
        ok = [(p, r) for p, r in zip(pts, rs) if p[1] <= 0.01]
        if ok:
            (c, e), r = min(ok, key=lambda pr: pr[0][0])
            lines.append(f"Cheapest setting with max error <= 1% at t = {t:g} s: **{short(r)}**, "
                         f"{e:.2e}, {c:.3g} CPU s.")
        if paper:
            pc = num(paper[0][f"cpu_s_t{t:g}"])
            pe = num(paper[0][f"err_max_t{t:g}"])
            within = [(p, r) for p, r in zip(pts, rs) if p[0] <= 10 * pc]
            (c, e), r = min(within, key=lambda pr: pr[0][1])
            lines.append(f"Paper case at t = {t:g} s: {pe:.2e} for {pc:.3g} CPU s. Most accurate within 10x "
                         f"that cost: **{short(r)}**, {e:.2e}, {c:.3g} CPU s ({c / pc:.2f}x).")
        lines.append("")
    lines.append("## Kernel bias at fixed h/dx (lattice sums, no run needed)")
    lines.append("")
    lines.append("| kernel | h/dx | nu_eff/nu, square lattice | nu_eff/nu, sheared lattices (min, max) | "
                 "dx^2 sum W, sheared (min, max) |")
    lines.append("| --- | --- | --- | --- | --- |")
    for kern, hr in sorted({(r["kernel"], num(r["h_over_dx"])) for r in rows}):
        a, b, c, d = sheared_lattice_bias(kern, hr)
        lines.append(f"| {kern} | {hr:g} | {viscosity_bias(kern, hr):.4f} | {a:.4f}, {b:.4f} | {c:.4f}, {d:.4f} |")
    lines.append("")
    lines.append("Max error against Eq. (8) with nu and with the square-lattice nu_eff (beta_max none):")
    lines.append("")
    lines.append("| setting | t [s] | max error (nu) | max error (nu_eff) |")
    lines.append("| --- | --- | --- | --- |")
    for r in rows:
        if num(r["beta_max"]) >= NO_CAP and r["status"] == "ok" and "conv" in r["groups"].split() \
                and r["integrator"] == "paper":
            for t in (0.01, 0.05):
                if math.isfinite(num(r[f"err_max_t{t:g}"])):
                    lines.append(f"| {short(r)} | {t:g} | {num(r[f'err_max_t{t:g}']):.2e} | "
                                 f"{num(r[f'err_max_nueff_t{t:g}']):.2e} |")
    lines.append("")
    diag = [r for r in rows if "diag" in r["groups"].split() or (
        "dt" in r["groups"].split() and r["status"] == "ok")]
    if diag:
        lines.append("## Time step and diagnostics")
        lines.append("")
        lines.append("| setting | overrides | dt mean [s] | max error 0.01 | max error 0.05 | interior max 0.05 |"
                     " x of max / L |")
        lines.append("| --- | --- | --- | --- | --- | --- | --- |")
        for r in diag:
            lines.append(f"| {short(r)} | {r['set']} | {num(r['dt_mean']):.3g} | {num(r['err_max_t0.01']):.2e} | "
                         f"{num(r['err_max_t0.05']):.2e} | {num(r['err_int_t0.05']):.2e} | "
                         f"{num(r['x_at_max_t0.05']):.2f} |")
        lines.append("")
    probes = [r for r in rows if "probe" in r["groups"].split()]
    if probes:
        lines.append("## Robustness probe: one fluid particle at d = eps dx from the moving wall")
        lines.append("")
        lines.append("| N_x | dt | beta_max | eps | status | max error at 0.01 s |")
        lines.append("| --- | --- | --- | --- | --- | --- |")
        for r in sorted(probes, key=lambda r: (num(r["perturb"]), num(r["beta_max"]))):
            lines.append(f"| {r['Nx']} | {num(r['dt_first']):g} | {num(r['beta_max']):g} | {r['perturb']} | "
                         f"{r['status'][:110]} | {num(r['err_max_t0.01']):.2e} |")
        lines.append("")
    return "\n".join(lines)


def write_report(grid, records, out_dir):
    """sweep.csv, the figures and summary.md in ``out_dir`` from the records ({run_id: record}) of the
    runs of ``grid`` ({run_id: (choices, groups)}); summary.md's text."""
    rows = [flatten(records[k], g, out_dir) for k, (run, g) in grid.items() if k in records]
    missing = [k for k in grid if k not in records]
    if missing:
        print(f"sweep: {len(missing)} runs of the grid have no result: {', '.join(missing)}")
    rows.sort(key=lambda r: (r["groups"], r["kernel"], r["integrator"], num(r["h_over_dx"]), int(r["Nx"])))
    codes = sorted({r["code"] for r in rows})
    if len(codes) > 1:
        print(f"sweep: WARNING: the runs come from {len(codes)} versions of parsph ({', '.join(codes)}); "
              f"costs are comparable only within one (run with --rerun)")
    with open(os.path.join(out_dir, "sweep.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, CSV_COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    conv = convergence(rows)
    plot_pareto(rows, os.path.join(out_dir, "accuracy_pareto.png"))
    plot_pareto(rows, os.path.join(out_dir, "accuracy_pareto_wall.png"), cost="wall")
    plot_convergence(conv, os.path.join(out_dir, "accuracy_convergence.png"))
    src = os.path.join(out_dir, "code", "SOURCE")
    source = None
    if os.path.exists(src):
        with open(src) as f:
            source = f.read().strip().split(",")[0]
    text = summary(rows, conv, source)
    with open(os.path.join(out_dir, "summary.md"), "w") as f:
        f.write(text + "\n")
    return text
