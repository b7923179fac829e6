"""Accuracy against cost for the Couette case: run a grid of numerical choices, find the frontier.

    nice -n 10 .venv/bin/python scripts/sweep.py            # default grid (docs/accuracy.md)
    nice -n 10 .venv/bin/python scripts/sweep.py --quick    # a few minutes
    .venv/bin/python scripts/sweep.py --report-only         # CSV, plots and summary from the runs so far
    options: --jobs N (runs at once; default 1), --out DIR, --rerun (ignore finished runs),
             --max-cost S (skip runs whose estimated CPU time exceeds S seconds), --list,
             --no-snapshot (see below)

Each run is one process (scripts/sweep_run.py) on one rank: the paper case
(Table 1 physics, read from run/couette_paper.toml) with the run's choices of
N_x, h/dx, kernel, integrator, dt ("auto" with a safety factor, or fixed),
beta_max, wall layers and end time. It reports the particle count, steps, dt,
wall and process CPU time of the time loop (numba's cache load is done in an
untimed warm-up) and the errors against Eq. (8) at t = 0.01, 0.05, 0.2, 0.5 s.
Finished runs are appended to DIR/runs.jsonl and are not run again (a killed
sweep resumes). The first run copies parsph/ to DIR/code and every run imports
that copy, so that edits to the working tree during a sweep do not mix code
versions (--rerun takes a fresh copy; each record carries a hash of the code). Written to DIR (default results/sweep, or results/sweep_quick):

    sweep.csv                 one row per run (columns: see CSV_COLUMNS)
    accuracy_pareto.png       max error against CPU time at t = 0.05 and 0.5 s, Pareto frontier drawn
    accuracy_pareto_wall.png  the same against wall time (shared machine: other people's load included)
    accuracy_convergence.png  max error against dx per kernel / integrator / h/dx, fitted orders
    summary.md                orders, frontier, the cheapest 1 % setting, the best within 10x the paper case

Cost is the process CPU time of the time loop up to the output time: on this
shared machine wall time also counts other people's work (both are in the CSV).
"""
import argparse
import concurrent.futures as cf
import csv
import json
import math
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
sys.path.insert(0, ROOT)

from parsph.physics.lattice_sums import sheared_lattice_bias, viscosity_bias  # noqa: E402
from sweep_run import DEFAULTS, TIMES, build_config, choices, run_id  # noqa: E402

PAPER_CASE = {"Nx": 50, "dt": 1e-5, "t_end": 0.5}  # Table 1: h = 1.25 dx, cubic, Eqs. (6)-(7), dt = 1e-5 s
NO_CAP = 1e6  # beta_max "none": 1 + d_j/d_i never reaches it


# ---- grids ----------------------------------------------------------------------------------
def default_grid():
    """(run, groups) pairs of the default grid: 7.1 CPU-minutes of time loops measured at 9a54ef1 (8.6 with start-up)."""
    runs = []

    def add(groups, **run):
        runs.append((run, set(groups.split())))

    # Convergence at fixed h/dx, dt = "auto" (safety 1): (kernel, h/dx, integrator, beta_max,
    # N_x run to t = 0.5 s, N_x run to t = 0.05 s only). The finest resolutions stop at 0.05 s.
    for kernel, hr, integ, beta, nx_long, nx_short in (
            ("cubic_spline", 1.25, "paper", 1.5, (20, 30, 50, 70), (100,)),
            ("cubic_spline", 1.25, "midpoint", 1.5, (20,), (30, 50, 70)),
            ("wendland_c2", 1.25, "paper", 1.5, (20, 30, 50), (70,)),
            ("wendland_c2", 1.25, "midpoint", 1.5, (), (20, 30, 50)),
            ("wendland_c2", 1.5, "paper", 1.5, (20, 30), (50, 70)),
            ("wendland_c2", 2.0, "paper", 1.5, (20, 30), (50, 70)),
            ("cubic_spline", 1.25, "paper", NO_CAP, (20, 30, 50), (70, 100)),
            ("cubic_spline", 1.25, "midpoint", NO_CAP, (20,), (30, 50, 70)),
            ("wendland_c2", 1.25, "paper", NO_CAP, (20, 30, 50), (70,)),
            ("wendland_c2", 2.0, "paper", NO_CAP, (20, 30, 50), (70, 100)),
            ("wendland_c2", 2.0, "midpoint", NO_CAP, (), (20, 30, 50)),
            ("cubic_spline", 2.0, "paper", NO_CAP, (20, 30), (50, 70))):
        for nx in nx_long + nx_short:
            add("conv", Nx=nx, kernel=kernel, h_over_dx=hr, integrator=integ, beta_max=beta,
                t_end=0.5 if nx in nx_long else 0.05)
    # Coarser still, for the cheap end of the frontier (not in the order fits).
    for nx in (12, 16):
        add("coarse", Nx=nx, beta_max=NO_CAP, t_end=0.5)
        add("coarse", Nx=nx, kernel="wendland_c2", h_over_dx=2.0, beta_max=NO_CAP, t_end=0.5)
    # The settings of run/couette_fast.toml and of run/couette_accurate.toml as first chosen
    # (h/dx 2; the preset now uses h/dx 2.5, beta_max 8, measured with scripts/sweep_preset.py), to t = 0.5 s.
    add("preset", Nx=12, beta_max=6.0, t_end=0.5)
    # Coarser than the fast preset, to bracket the cheapest setting with 1 % max error at t = 0.05 s
    # (added after the first sweep, run on the same copy of the code).
    for nx in (6, 8, 10):
        add("coarse", Nx=nx, beta_max=6.0, t_end=0.5)
    add("wall", Nx=20, beta_max=6.0, t_end=0.5)
    add("preset", Nx=100, kernel="wendland_c2", h_over_dx=2.0, beta_max=6.0, t_end=0.5)
    # Time step: the paper case itself (fixed dt = 1e-5 s) and smaller auto steps.
    add("paper dt", **PAPER_CASE)
    add("dt", Nx=50, dt_safety=0.25, t_end=0.05)
    for nx, s in ((50, 0.5), (50, 0.25), (70, 0.5)):
        add("dt", Nx=nx, dt_safety=s, beta_max=NO_CAP, t_end=0.05)
    for nx, s in ((30, 0.25), (50, 0.5), (50, 0.25)):
        add("dt", Nx=nx, dt_safety=s, kernel="wendland_c2", h_over_dx=2.0, beta_max=NO_CAP, t_end=0.05)
    # Wall treatment: the Morris cap between 1 (no amplification) and none, more layers than needed.
    for b in (1.0, 3.0, 6.0):
        add("wall", Nx=50, beta_max=b, t_end=0.05)
    add("wall", Nx=30, beta_max=6.0, t_end=0.5)
    add("wall", Nx=50, layers=5, beta_max=NO_CAP, t_end=0.05)
    # Diagnostic (not on the frontier: it changes the physics): the cubic 1.25 floor with a
    # 400x weaker modulus G (G_b = -1.183 -> -3.8), which removes the pressure noise.
    for nx in (20, 50):
        add("diag", Nx=nx, beta_max=NO_CAP, t_end=0.05, set=["material.G_b=-3.8"])
    # Robustness of the cap: one fluid particle put at d = eps dx from the moving wall,
    # the paper's time step, to t = 0.01 s.
    for eps in (0.1, 0.02, 0.005):
        for b in (1.5, 3.0, 6.0, NO_CAP):
            add("probe", Nx=50, dt=1e-5, beta_max=b, perturb=eps, t_end=0.01)
    return runs


def quick_grid():
    """A few minutes: coarse convergence of both kernels and integrators to t = 0.05 s, one probe pair."""
    runs = []
    for kernel in ("cubic_spline", "wendland_c2"):
        for integ in ("paper", "midpoint"):
            for nx in (16, 24, 32):
                runs.append(({"Nx": nx, "kernel": kernel, "integrator": integ, "t_end": 0.05}, {"conv"}))
    for nx in (16, 24, 32):
        runs.append(({"Nx": nx, "beta_max": NO_CAP, "t_end": 0.05}, {"conv", "wall"}))
    runs.append(({"Nx": 50, "dt": 1e-5, "t_end": 0.05}, {"paper", "dt"}))
    for b in (1.5, NO_CAP):
        runs.append(({"Nx": 24, "dt": 2e-5, "beta_max": b, "perturb": 0.005, "t_end": 0.01}, {"probe"}))
    return runs


def merge(grid):
    """One entry per distinct run; groups united."""
    out = {}
    for run, groups in grid:
        key = run_id(run)
        if key in out:
            out[key][1].update(groups)
        else:
            out[key] = (choices(run), set(groups))
    return out


def estimate_cpu(run):
    """Rough CPU seconds of a run on this machine (for ordering and --max-cost only)."""
    c = choices(run)
    nx, hr = c["Nx"], c["h_over_dx"]
    L, nu, v = 0.01, 1.75e-4, 1.0
    h = hr * L / nx
    if c["dt"] == "auto":  # parsph.physics.limits at theta_0: advection, and the derived viscous limit (~0.32 h^2 / nu)
        dt = c["dt_safety"] * min(0.5 * h / v, 0.32 * h * h / nu)
    else:
        dt = float(c["dt"])
    layers = c["layers"] or math.ceil(2 * hr - 1e-9)
    n = (nx + 2 * layers) * nx
    per_step = (0.3e-3 + 0.65e-6 * n * (hr / 1.25) ** 2) * (2 if c["integrator"] == "midpoint" else 1)
    return c["t_end"] / dt * per_step + 2.0


# ---- running --------------------------------------------------------------------------------
def snapshot_code(out_dir, fresh):
    """Copy parsph/ to DIR/code/parsph (once; again with --rerun), so that every run of the sweep
    uses the same code even if the working tree changes while the sweep runs."""
    import shutil
    code = os.path.join(out_dir, "code")
    if fresh and os.path.isdir(code):
        shutil.rmtree(code)
    if not os.path.isdir(os.path.join(code, "parsph")):
        shutil.copytree(os.path.join(ROOT, "parsph"), os.path.join(code, "parsph"),
                        ignore=shutil.ignore_patterns("__pycache__"))
        head = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=ROOT, capture_output=True,
                              text=True).stdout.strip()
        with open(os.path.join(code, "SOURCE"), "w") as f:
            f.write(f"parsph/ of {ROOT} at git {head or '?'}, copied {time.strftime('%Y-%m-%d %H:%M:%S')}\n")
    return code


def run_one(key, run, out_dir, code=None):
    cmd = [sys.executable, os.path.join(HERE, "sweep_run.py"), json.dumps(run),
           "--profiles", os.path.join(out_dir, "profiles")] + (["--code", code] if code else [])
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
    if p.returncode != 0 or not lines:
        return key, None, f"exit {p.returncode}: {p.stderr.strip()[-500:]}", time.perf_counter() - t0
    return key, json.loads(lines[-1]), None, time.perf_counter() - t0


def load_records(out_dir):
    path = os.path.join(out_dir, "runs.jsonl")
    recs = {}
    if os.path.exists(path):
        for line in open(path):
            if line.strip():
                r = json.loads(line)
                recs[r["id"]] = r
    return recs


def execute(grid, out_dir, jobs, rerun, max_cost, snapshot=True):
    os.makedirs(out_dir, exist_ok=True)
    done = {} if rerun else load_records(out_dir)
    if rerun and os.path.exists(os.path.join(out_dir, "runs.jsonl")):
        os.replace(os.path.join(out_dir, "runs.jsonl"), os.path.join(out_dir, "runs.jsonl.old"))
    code = snapshot_code(out_dir, rerun) if snapshot else None
    if code:
        print(f"sweep: code: {open(os.path.join(code, 'SOURCE')).read().strip()}", flush=True)
    todo = [(k, run) for k, (run, _) in grid.items() if k not in done]
    skipped = [k for k, run in todo if max_cost and estimate_cpu(run) > max_cost]
    todo = [(k, run) for k, run in todo if k not in skipped]
    todo.sort(key=lambda kr: estimate_cpu(kr[1]))
    est = sum(estimate_cpu(r) for _, r in todo)
    print(f"sweep: {len(grid)} runs, {len(grid) - len(todo) - len(skipped)} done already, {len(todo)} to run "
          f"(estimated {est / 60:.1f} CPU-minutes), {len(skipped)} skipped by --max-cost", flush=True)
    t_start = time.perf_counter()
    with open(os.path.join(out_dir, "runs.jsonl"), "a") as log, cf.ThreadPoolExecutor(jobs) as pool:
        futs = [pool.submit(run_one, k, run, out_dir, code) for k, run in todo]
        for i, f in enumerate(cf.as_completed(futs), 1):
            key, rec, err, wall = f.result()
            if rec is None:
                print(f"  [{i}/{len(todo)}] {key}: ERROR {err}", flush=True)
                continue
            rec["id"] = key
            log.write(json.dumps(rec) + "\n")
            log.flush()
            e = {o["t"]: o["err_max"] for o in rec["outputs"]}
            errs = " ".join(f"{t:g}:{e[t]:.2e}" for t in sorted(e))
            print(f"  [{i}/{len(todo)}] {key}: {rec['status'][:60]}, {rec['steps']} steps, "
                  f"cpu {rec['cpu_s']:.1f} s, wall {rec['wall_s']:.1f} s, max err {errs} "
                  f"({time.perf_counter() - t_start:.0f} s elapsed)", flush=True)
    print(f"sweep: ran {len(todo)} runs in {time.perf_counter() - t_start:.0f} s wall", flush=True)
    return skipped


# ---- analysis -------------------------------------------------------------------------------
def nu_eff_errors(rec, out_dir):
    """Max error at each output time against Eq. (8) evaluated with nu_eff instead of nu."""
    from parsph.physics.analytic import couette_velocity
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


def fit_order(dx, err):
    """Least-squares slope of log(err) against log(dx)."""
    if len(dx) < 2:
        return math.nan
    return float(np.polyfit(np.log(dx), np.log(err), 1)[0])


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
            local = [math.log(em[i] / em[i + 1]) / math.log(dx[i] / dx[i + 1]) for i in range(len(dx) - 1)]
            out[fam][t] = {"dx": dx, "Nx": nx, "err": em, "rms": er, "order": fit_order(dx, em),
                           "order_rms": fit_order(dx, er), "local": local}
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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="the quick grid (a few minutes)")
    ap.add_argument("--out", help="results directory (default results/sweep or results/sweep_quick)")
    ap.add_argument("--jobs", type=int, default=1, help="runs at once (default 1)")
    ap.add_argument("--rerun", action="store_true", help="run every run again")
    ap.add_argument("--report-only", action="store_true", help="no runs: CSV, plots, summary from runs.jsonl")
    ap.add_argument("--max-cost", type=float, default=0.0, help="skip runs estimated above this many CPU s")
    ap.add_argument("--list", action="store_true", help="print the grid with estimated costs and stop")
    ap.add_argument("--no-snapshot", action="store_true",
                    help="run the working tree's parsph, not the copy in DIR/code made at the first run")
    args = ap.parse_args(argv)
    out_dir = args.out or os.path.join(ROOT, "results", "sweep_quick" if args.quick else "sweep")
    grid = merge(quick_grid() if args.quick else default_grid())
    if args.list:
        for k, (run, g) in sorted(grid.items(), key=lambda kv: estimate_cpu(kv[1][0])):
            print(f"{estimate_cpu(run):8.1f} s  {k}  [{' '.join(sorted(g))}]")
        print(f"total {sum(estimate_cpu(r) for r, _ in grid.values()) / 60:.1f} CPU-minutes (estimate)")
        return 0
    if not args.report_only:
        execute(grid, out_dir, args.jobs, args.rerun, args.max_cost, not args.no_snapshot)
    recs = load_records(out_dir)
    rows = [flatten(recs[k], g, out_dir) for k, (run, g) in grid.items() if k in recs]
    missing = [k for k in grid if k not in recs]
    if missing:
        print(f"sweep: {len(missing)} runs of the grid have no result: {', '.join(missing)}")
    rows.sort(key=lambda r: (r["groups"], r["kernel"], r["integrator"], num(r["h_over_dx"]), int(r["Nx"])))
    codes = sorted({r["code"] for r in rows})
    if len(codes) > 1:
        print(f"sweep: WARNING: the runs come from {len(codes)} versions of parsph ({', '.join(codes)}); "
              f"costs are comparable only within one (run with --rerun)")
    csv_path = os.path.join(out_dir, "sweep.csv")
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, CSV_COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    conv = convergence(rows)
    plot_pareto(rows, os.path.join(out_dir, "accuracy_pareto.png"))
    plot_pareto(rows, os.path.join(out_dir, "accuracy_pareto_wall.png"), cost="wall")
    plot_convergence(conv, os.path.join(out_dir, "accuracy_convergence.png"))
    src = os.path.join(out_dir, "code", "SOURCE")
    text = summary(rows, conv, open(src).read().strip().split(",")[0] if os.path.exists(src) else None)
    with open(os.path.join(out_dir, "summary.md"), "w") as f:
        f.write(text + "\n")
    print(text)
    print(f"wrote {csv_path}, accuracy_pareto.png, accuracy_pareto_wall.png, accuracy_convergence.png, summary.md "
          f"in {out_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
