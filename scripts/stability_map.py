#!/usr/bin/env python
"""Measured stability map of the Couette case against the predicted time-step limit (docs/stability.md).

    .venv/bin/python scripts/stability_map.py                      # the grid -> results/stability/
    .venv/bin/python scripts/stability_map.py --nx 50 --refine --long   # bisect the limits, confirm
    .venv/bin/python scripts/stability_map.py --integrator midpoint     # the dense corner, midpoint
    .venv/bin/python scripts/stability_map.py --plot-only          # redraw PNGs, summary, merged CSV
    .venv/bin/python scripts/stability_map.py --quick --out DIR    # a 12-run smoke test
    .venv/bin/python scripts/stability_map.py --scene settling [--refine]  # the granular column (gravity on)
    .venv/bin/python scripts/stability_map.py --damping --nx 200,400   # margin of the damping constant
    .venv/bin/python scripts/stability_map.py --pred all --nx 200 --bracket --tol 1.1   # bracket every column
                                                 # against parsph.physics.limits' prediction, + one dt = "auto" run each
    .venv/bin/python scripts/stability_map.py --pred all --nx 50 --auto-only   # auto only ("midpoint": its corner)
    .venv/bin/python scripts/stability_map.py --scene settling --pred all      # auto in the settling columns
    .venv/bin/python scripts/stability_map.py --scene settling --pred all --bracket --tol 1.1   # + fixed dt, bracketed
    .venv/bin/python scripts/stability_map.py --longer 50:0.7:2000:40:20000    # one run of any length
    .venv/bin/python scripts/stability_map.py --ratios CSV... [--auto AUTO_CSV]  # measured / predicted per column
    .venv/bin/python scripts/stability_map.py --figures CSV...    # every figure against the prediction now

Every run is the real solver (``parsph.simulation.solver.Simulation.run``, the loop that
``parsph run`` drives) on ``MPI.COMM_SELF`` in this one process: the flow is
1-D in x, so a short periodic box ``L_y = 8 h`` (10 rows) carries it and the
slab decomposition plays no part. Each run takes ``STEPS`` = 2,000 steps of a
fixed

    dt = multiple * predicted limit,  predicted limit = min(von Neumann limit of the integrator, 0.5 h / V_w)

(``parsph.physics.limits``, as config.build takes it; ``numerics.allow_unstable_dt = true`` lets the
multiples above 1 run). The package's guard (``parsph.simulation.guards``) runs every
step (``checks.every = 1``) with the thresholds below and stops the run; an
observer (``Simulation.run(observe=...)``, ``parsph.studies.stability.Recorder``) records the
four criteria separately at every step from ``Simulation.particles()`` (the guard's own
criteria, ``parsph.simulation.guards.read``), and a guard failure counts for its
criterion by its ``GuardResult.code``:

    nonfinite  a fluid particle with a non-finite position or velocity (the guard: acceleration too)
    wall       a fluid particle beyond a wall plane (x < 0 or x > L)
    theta      max |theta - theta_0| / theta_0 over fluid particles > THETA_FRAC
    energy     fluid kinetic energy > 1/2 M V_w^2 (the maximum principle |v| <= V_w)

A run is *unstable* if any of them fired (or the solver raised anything else:
column ``crash``), *stable* otherwise. The CSV has one row per run, with the
step each criterion first fired (-1: never), the largest theta deviation, the
largest kinetic-energy ratio and speed ratio seen, the guard's message, the
profile error against Eq. (8) at the end of stable runs, and the short commit
the run was made at (``commit``: empty in rows from before the column; a CSV
whose header lacks it is appended to without it).

Not every failure is a time-step failure: some come at the same physical time
whatever dt (the flow itself compacts near the moving plate). ``verdict``
(``parsph.studies.stability``, with the bracketing and the resumable CSV) tells them apart (two failing runs >= 8 % apart in dt, same criterion, same
time within 5 %: ``physical``); ``--long`` confirms each such column with a
run at half the dt continued to 1.3x that time. Measured limits count
time-step failures only.

The grid (issue "Stability map"): theta_0 x Re x multiple at N_x = 10, 50 and
200 (the whole grid at each). Re = V_w L rho_s / (k theta_0), so k = V_w L rho_s /
(Re theta_0). ``--refine`` extends each N_x = 50 (theta_0, Re) column beyond
the grid (multiples up to 64 or down to 1/64) and bisects its time-step limit
to within 10 %. Outputs: stability_map.csv (paper integrator),
stability_map_midpoint.csv, stability_long.csv, stability_all.csv (all of
them, with integrator and verdict: docs/stability_map.csv), summary*.txt and
the PNGs. Rows already in a CSV are not run again (delete it to start afresh).

``--scene settling`` maps the granular column of run/settling.toml instead
(gravity -30 m/s^2 along x, floor and lid, k = 1, the consistent pressure
form, the paper integrator): theta_0 in SETTLING["theta0"] x the same
multiples at N_x = SETTLING["nx"], L_y = 8 h. There the predicted limit is
config.build's (the one a fixed dt is refused against): min(CFL with
sqrt(g h), viscous, force with |g|, damping) at theta_0; each run lasts the
same simulated time, SETTLING["steps"] steps of the predicted limit (the
column's first transient, not its settling: that takes 0.4 s), and at least
SETTLING["min_steps"] steps. Criteria: non-finite; wall = a fluid particle
below the floor or above the lid; theta = max |theta - theta_eq(x)| /
theta_eq(x) > THETA_FRAC against the settling equilibrium
(parsph.physics.analytic.settling_equilibrium, the form the run's pressure term
converges to: scenes/settling.wall_theta); energy = fluid kinetic energy above
the scene's own bound (settling.max_kinetic_energy: M g L). The recorder stops a
run at its first failure (these are not the guard's criteria). Output: stability_settling.csv and
stability_settling.png (docs/).
"""
import argparse
import csv
import math
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
# one process, one core: numba's threads would only contend (a run of 260 particles
# took 31 ms a step with 2 threads on the loaded 2-core machine, 2.4 ms with 1)
os.environ.setdefault("NUMBA_NUM_THREADS", "1")


from parsph.setup import config  # noqa: E402
from parsph.setup.runfile import RunFile  # noqa: E402
from parsph.physics import limits  # noqa: E402
from parsph.physics import table1  # noqa: E402
from parsph.setup.schema import SCHEMA  # noqa: E402
from parsph.studies import cases  # noqa: E402
from parsph.physics.closures import G_A, G_B, modulus  # noqa: E402
from parsph.studies.stability import (Recorder, Results, append_row, column, dt_bounds, load_rows,  # noqa: E402
                                     measured_bounds, physical_time, run_and_classify, search, verdict)

THETAS = (0.05, 0.1, 0.2, 0.35, 0.5, 0.6, 0.64, 0.7)
RES = (1.0, 10.0, 57.0, 400.0, 2000.0)
MULTS = (0.25, 0.5, 1.0, 1.5, 2.0, 4.0)
NXS = (10, 50, 200)
STEPS = 2000
THETA_FRAC = 0.2       # criterion "theta": largest accepted |theta - theta0| / theta0
H_OVER_DX = table1.H_OVER_DX
LY_IN_H = 8            # L_y = 8 h = 10 dx: 10 lattice rows

FIELDS = ["nx", "theta0", "Re", "k", "multiple", "dt", "dt_limit", "limit_term", "dt_cfl", "dt_viscous",
          "dt_acoustic_damping", "steps_planned", "steps_done", "t_done", "stable", "first_failure",
          "fail_step", "nonfinite_step", "wall_step", "theta_step", "energy_step", "max_theta_dev",
          "max_ke_ratio", "max_speed_ratio", "err_max", "err_rms", "guard", "crash", "message", "wall_s",
          "source", "commit"]


def _commit():
    """The short commit the rows are run at (a row without one predates the column: see docs/stability.md)."""
    import subprocess
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return ""


COMMIT = _commit()


def physics(theta0, Re, nx, integrator="paper"):
    """k, h, the predicted limits of one (theta_0, Re, N_x) (parsph.physics.limits, as config.build takes them:
    the von Neumann limit of the integrator, advection with V_w), the binding term, and 2 nu / c_eff^2."""
    L, rho_s, V_w = table1.L, table1.RHO_S, table1.V_W
    k = abs(V_w) * L * rho_s / (Re * theta0)
    dx = L / nx
    h = H_OVER_DX * dx
    lim = limits.limits(theta0, abs(V_w), 0.0, limits.Material(rho_s, k, G_A, G_B),
                        limits.Lattice(h, (dx, dx), beta_max=SCHEMA["walls"]["beta_max"].default),
                        integrator=integrator)
    term = min(lim, key=lim.get)
    c2 = limits.sound_speed(theta0, rho_s, G_A, G_B, "paper") ** 2
    return k, h, lim, term, 2.0 * k * theta0 / rho_s / c2


def case_config(theta0, Re, nx, multiple, steps=STEPS, theta_frac=THETA_FRAC, extra=(), integrator="paper"):
    """The column's Couette case (cases.couette: L_y = 8 h) at dt = multiple x the predicted limit for
    ``steps`` steps, the guard at every step with the map's theta threshold."""
    k, h, lim, term, _ = physics(theta0, Re, nx, integrator)
    return cases.couette(nx, h_over_dx=H_OVER_DX, ly_in_h=LY_IN_H, dt=multiple * lim[term], steps=steps, overrides=[
        f"material.theta0={theta0!r}", f"material.k={k!r}", "numerics.allow_unstable_dt=true", "checks.every=1",
        f"checks.theta_change={theta_frac!r}", "checks.energy=true", f'numerics.integrator="{integrator}"', *extra])


def run_case(theta0, Re, nx, multiple, steps=STEPS, theta_frac=THETA_FRAC, source="grid", integrator="paper"):
    """Run one case; return its CSV row (dict)."""
    cfg = case_config(theta0, Re, nx, multiple, steps, theta_frac, integrator=integrator)
    k, h, lim, term, dt_ac = physics(theta0, Re, nx, integrator=integrator)
    outcome = run_and_classify(cfg, Recorder(cfg, theta_frac))
    return {
        "nx": nx, "theta0": theta0, "Re": Re, "k": k, "multiple": multiple, "dt": cfg.dt,
        "dt_limit": lim[term], "limit_term": term, "dt_cfl": lim["advection"],
        "dt_viscous": lim.get("viscous", math.inf), "dt_acoustic_damping": dt_ac, "steps_planned": cfg.nsteps,
        **outcome, "source": source, "commit": COMMIT, "integrator": integrator,
    }


# ---- the grid ------------------------------------------------------------------------------------
def grid(nxs, quick=False):
    if quick:
        return [(t, r, 50, m) for t in (0.05, 0.7) for r in (57.0, 2000.0) for m in (0.5, 1.0, 4.0)]
    cases = []
    for nx in nxs:
        for t in THETAS:
            for r in RES:
                cases += [(t, r, nx, m) for m in MULTS]
    return cases


def couette_results(path, integrator="paper"):
    """The resumable CSV of the Couette runs of one integrator."""
    return Results(path, lambda t, r, nx, m, source: run_case(t, r, nx, m, source=source, integrator=integrator),
                   FIELDS)


def settling_results(path):
    """The resumable CSV of the settling column's runs."""
    return Results(path, lambda t, r, nx, m, source: run_settling_case(t, r, nx, m, source), SETTLING_FIELDS)


def refine(res, theta0, Re, nx=50, tol=1.1, span=64.0, max_runs=12):
    """Bisect the column's time-step limit (failures at the physical failure time do not count)."""
    for m in MULTS:
        res.get(theta0, Re, nx, m)
    return search(res, theta0, Re, nx, lambda hi: (hi or MULTS[0]) / 4, lambda lo: lo * 2,
                  tol, span, max_runs, "refine")


def long_checks(res, out_dir, nx=50, ratio=2.0, extend=1.3, tol=0.1):
    """Confirm each physical failure time: run half the smallest such multiple to 1.3x that time.

    A time-step instability would fail later there or not at all; the verdict is ``physical``
    when it fails within ``tol`` of the same time. Rows go to stability_long.csv.
    """
    path = os.path.join(out_dir, "stability_long.csv")
    done = {(round(float(r["theta0"]), 6), round(float(r["Re"]), 6)): r for r in load_rows(path)}
    out = []
    for t in THETAS:
        for Re in RES:
            col = column(res.rows, nx, t, Re)
            phys = physical_time(col)
            if phys is None:
                continue
            key = (round(t, 6), round(Re, 6))
            if key in done:
                out.append(done[key])
                continue
            m = min(float(r["multiple"]) for r in col if verdict(r, phys) == "physical")
            lim = float(col[0]["dt_limit"])
            steps = int(math.ceil(extend * phys[0] / (m / ratio * lim)))
            row = run_case(t, Re, nx, m / ratio, steps=steps, source="long")
            ok = not row["stable"] and abs(row["t_done"] / phys[0] - 1.0) <= tol
            row.update({"t_phys": phys[0], "criterion_phys": phys[1], "confirmed": int(ok)})
            append_row(path, FIELDS + ["t_phys", "criterion_phys", "confirmed"], row)
            print(f"long check theta0={t:g} Re={Re:g}: failures by {phys[1]} at t = {phys[0]:.4g} s; "
                  f"dt/limit = {m / ratio:.3g} to {steps} steps: {row['first_failure'] or 'stable'} at "
                  f"t = {row['t_done']:.4g} s -> {'confirmed' if ok else 'NOT confirmed'}", flush=True)
            out.append({k: str(v) for k, v in row.items()})
    return out


# ---- figures -----------------------------------------------------------------------------------------
MARK = {"nonfinite": ("X", "tab:red"), "wall": ("v", "tab:purple"), "theta": ("s", "tab:orange"),
        "energy": ("^", "tab:red"), "jump": ("*", "tab:brown")}


def measured_limits(rows, nx):
    """{(theta0, Re): (lo, hi)} of dt_bounds for every column at nx."""
    keys = {(float(r["theta0"]), float(r["Re"])) for r in rows if int(r["nx"]) == nx}
    return {k: dt_bounds(column(rows, nx, *k)) for k in keys}


def plot(rows, outdir, nx_list, tag=""):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

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
                col = column(rows, nx, t, Re)
                phys = physical_time(col)
                for r in col:
                    m, v = float(r["multiple"]), verdict(r, phys)
                    fill = "full" if r["source"] == "grid" else "none"
                    if v == "stable":
                        ax.plot(t, m, "o", color="tab:green", ms=5, fillstyle=fill)
                    elif v == "physical":
                        ax.plot(t, m, "D", color="tab:gray", ms=5, fillstyle=fill)
                    elif r["crash"]:
                        ax.plot(t, m, "P", color="k", ms=6, fillstyle=fill)
                    else:
                        mk, c = MARK.get(r["first_failure"], ("D", "k"))
                        ax.plot(t, m, mk, color=c, ms=6, fillstyle=fill)
            mx = [(t, math.sqrt(lims[(t, Re)][0] * lims[(t, Re)][1])) for t in ts
                  if lims.get((t, Re), (None, None))[0] and lims[(t, Re)][1]]
            if mx:
                ax.plot(*zip(*mx), "-", color="k", lw=1.2)
            tt = np.linspace(0.05, 0.7, 60)
            integ = "midpoint" if tag == "midpoint" else "paper"
            ac = [physics(t, Re, nx)[4] / min(physics(t, Re, nx, integrator=integ)[2].values()) for t in tt]
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
                ax.plot(tt, [min(physics(t, Re, nx)[2].values()) for t in tt], "--", color=col, lw=1)
                pts = [(t, lims[(t, Re)][0] * min(physics(t, Re, nx)[2].values())) for t in ts
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


_PRED = {}


def predicted(integrator, nx, theta0, Re):
    """parsph.physics.limits' prediction now for a Couette column (memoised)."""
    key = (integrator, nx, round(theta0, 6), round(Re, 6))
    if key not in _PRED:
        k, h, lim, term, _ = physics(theta0, Re, nx, integrator=integrator)
        _PRED[key] = lim[term]
    return _PRED[key]


def renormalised(rows, integrator="paper"):
    """The rows with ``multiple`` = dt / the prediction now (runs made against any earlier prediction
    are at an absolute dt), so that bounds, verdicts and figures are in multiples of the new limit."""
    out = []
    for r in rows:
        integ = r.get("integrator") or integrator
        p = predicted(integ, int(r["nx"]), float(r["theta0"]), float(r["Re"]))
        out.append({**r, "integrator": integ, "multiple": repr(float(r["dt"]) / p), "dt_limit": repr(p)})
    return out


def renormalised_settling(rows):
    """Settling rows against the prediction now: multiple, dt_limit, the limit at the floor's theta and the
    classical terms (what plot_settling draws)."""
    out, cache = [], {}
    for r in rows:
        t = float(r["theta0"])
        if t not in cache:
            lim = settling_limits(t, SETTLING["nx"])
            eq = settling_limits(t, SETTLING["nx"], float(r["theta_eq_max"]))
            cache[t] = {"dt_limit": min(lim.values()), "limit_term": min(lim, key=lim.get),
                        "dt_limit_eq": min(eq.values()), "dt_cfl": lim["advection"],
                        "dt_viscous": lim.get("viscous", math.inf), "dt_force": lim["force"]}
        c = cache[t]
        out.append({**r, **{k: repr(v) if isinstance(v, float) else v for k, v in c.items()},
                    "multiple": repr(float(r["dt"]) / c["dt_limit"])})
    return out


def main_figures(a):
    """Every figure of docs/stability.md against the prediction now, from the CSVs given (--figures):
    Couette runs of both integrators (the integrator column, or 'midpoint' in the file name) and the
    settling runs (stability_settling.csv)."""
    paper, mid, settle = [], [], []
    for path in a.figures:
        rows = load_rows(path)
        if "settling" in os.path.basename(path):
            settle += rows
            continue
        for r in rows:
            integ = r.get("integrator") or ("midpoint" if "midpoint" in os.path.basename(path) else "paper")
            (mid if integ == "midpoint" else paper).append({**r, "integrator": integ})
    figs = []
    if paper:
        figs += plot(renormalised(paper), a.out, sorted({int(r["nx"]) for r in paper}))
    if mid:
        figs += plot(renormalised(mid), a.out, sorted({int(r["nx"]) for r in mid}), tag="midpoint")
    if settle:
        figs.append(plot_settling(renormalised_settling(settle), a.out))
    for png in figs:
        print(f"wrote {png}")
    return 0


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
        k, h, lim, term, ac = physics(t, Re, nx)
        f = lambda v: "-" if v is None else f"{v:.3g}"  # noqa: E731
        first = next((r for r in col if float(r["multiple"]) == hi), None) if hi else None
        how = f"{first['first_failure']} at step {first['fail_step']}" if first else ""
        if phys:
            how += f"; {phys[1]} at t = {phys[0]:.3g} s whatever dt"
        lines.append(f"{t:>6g} {Re:>6g} {term:>8} {lim[term]:>10.3g} {f(lo):>7} {f(hi):>7} {ac / lim[term]:>11.3g}  {how}")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(ROOT / "results" / "stability"), help="results directory")
    ap.add_argument("--nx", default=",".join(map(str, NXS)), help="comma-separated N_x of the grid")
    ap.add_argument("--refine", action="store_true", help="bisect the measured limit of each N_x = 50 column")
    ap.add_argument("--long", action="store_true",
                    help="confirm the failures at a fixed physical time with a longer run at half the dt")
    ap.add_argument("--quick", action="store_true", help="12 runs only (smoke test)")
    ap.add_argument("--plot-only", action="store_true", help="redraw from the CSV")
    ap.add_argument("--integrator", default="paper", choices=("paper", "midpoint"),
                    help="time integrator (midpoint: its own CSV, the dense corner only)")
    ap.add_argument("--scene", default="couette", choices=("couette", "settling"),
                    help="couette (the map) or settling (the granular column, gravity on)")
    ap.add_argument("--damping", action="store_true",
                    help="theta_0 = 0.7, Re = 57 at the --nx given: fixed dt = DAMPING_FRACTIONS x nu/c^2, "
                         "and dt = \"auto\" (the margin of the damping limit)")
    ap.add_argument("--pred", default="",
                    help="columns 'theta:Re,...', 'all' (the grid) or 'midpoint' (its corner) at each --nx: fixed dt = "
                         "PRED_MULTS x the predicted limit (stability_pred_<integrator>.csv) and one dt = \"auto\" "
                         "run (stability_auto.csv); with --scene settling: auto in each column")
    ap.add_argument("--bracket", action="store_true",
                    help="with --pred: bracket each column's limit to --tol (1, 1.5, 2, doubling or halving, bisection); "
                         "with --scene settling too")
    ap.add_argument("--seed", nargs="*", default=[],
                    help="with --bracket: CSVs of earlier runs; a column whose bounds there lie beyond 1.5x (stable) or "
                         "3x (failing) the prediction starts its bracket from them")
    ap.add_argument("--tol", type=float, default=1.25, help="with --bracket: bisect until failing / stable <= TOL")
    ap.add_argument("--auto-only", action="store_true", help="with --pred: only the dt = \"auto\" runs")
    ap.add_argument("--longer", default="", help="'nx:theta:Re:multiple:steps,...': single runs of any length")
    ap.add_argument("--commits", nargs="*", default=[], help="with --ratios: only the runs made at these commits")
    ap.add_argument("--auto", default="", help="with --ratios: the dt = \"auto\" runs (stability_auto.csv)")
    ap.add_argument("--figures", nargs="*", default=None,
                    help="CSVs of runs (any prediction): redraw every figure against the prediction now")
    ap.add_argument("--ratios", nargs="*", default=None,
                    help="CSVs of runs (any prediction): measured stable dt / the predicted limit per column")
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    if a.ratios is not None:
        return main_ratios(a)
    if a.figures is not None:
        return main_figures(a)
    if a.longer:
        return main_longer(a)
    if a.pred and a.scene == "settling":
        return main_settling_auto(a)
    if a.pred:
        return main_pred(a)
    if a.damping:
        return main_damping(a)
    if a.scene == "settling":
        return main_settling(a)
    if a.integrator == "midpoint":
        return main_midpoint(a)
    res = couette_results(os.path.join(a.out, "stability_map.csv"))
    nxs = [int(x) for x in a.nx.split(",") if x]
    if not a.plot_only:
        for t, r, nx, m in grid(nxs, a.quick):
            res.get(t, r, nx, m)
        if a.refine:
            for t in THETAS:
                for r in RES:
                    lo, hi = refine(res, t, r)
                    print(f"refined theta0={t:g} Re={r:g}: no time-step failure <= {lo}, one at {hi}", flush=True)
        if a.long:
            long_checks(res, a.out)
    for png in plot(res.rows, a.out, sorted({int(r["nx"]) for r in res.rows})):
        print(f"wrote {png}")
    print(f"wrote {write_merged(a.out)}")
    text = "\n\n".join(summary(res.rows, nx) for nx in sorted({int(r["nx"]) for r in res.rows}))
    print(text)
    with open(os.path.join(a.out, "summary.txt"), "w") as f:
        f.write(text + "\n")
    return 0


def write_merged(out_dir):
    """One CSV of every run (both integrators, bisection and long runs) with each row's verdict."""
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
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, FIELDS + extra, extrasaction="ignore")
        w.writeheader()
        w.writerows(merged)
    return path


MIDPOINT = {"theta0": (0.5, 0.6, 0.64, 0.7), "Re": (10.0, 57.0, 400.0, 2000.0), "multiple": (0.5, 1.0, 2.0)}


def main_midpoint(a):
    """The dense, weakly damped corner again with the second-order integrator (same criteria)."""
    res = couette_results(os.path.join(a.out, "stability_map_midpoint.csv"), integrator="midpoint")
    if not a.plot_only:
        for t in MIDPOINT["theta0"]:
            for r in MIDPOINT["Re"]:
                for m in MIDPOINT["multiple"]:
                    res.get(t, r, 50, m)
    for png in plot(res.rows, a.out, [50], tag="midpoint"):
        print(f"wrote {png}")
    text = summary(res.rows, 50, ", midpoint integrator")
    print(text)
    with open(os.path.join(a.out, "summary_midpoint.txt"), "w") as f:
        f.write(text + "\n")
    return 0


# ---- the granular column (--scene settling) -------------------------------------------------------
SETTLING_TOML = ROOT / "run" / "settling.toml"
SETTLING = {"theta0": (0.55, 0.6, 0.64, 0.7), "nx": 20, "steps": 2000, "min_steps": 1000}
SETTLING_FIELDS = FIELDS + ["integrator", "dt_force", "dt_damping", "theta_eq_max", "dt_limit_eq",
                            "limit_term_eq", "ke_bound"]


def settling_limits(theta0, nx, theta=None):
    """The predicted limits of the column at theta (default theta_0): parsph.physics.limits as config.build
    takes them (velocity scale sqrt(g h), |g|, the run file's integrator and pressure form)."""
    rf = RunFile.read(SETTLING_TOML)
    L = rf.get("domain", "L")
    over = [f"numerics.Nx={nx}", f"material.theta0={theta0!r}", f"domain.Ly={LY_IN_H * rf.get('numerics', 'h_over_dx') * L / nx!r}",
            'numerics.dt="auto"']
    cfg = config.build(rf.override(over))
    g = math.sqrt(sum(x * x for x in cfg.g))
    return limits.run_limits(cfg, theta0 if theta is None else theta, cfg.velocity_scale, g)


def settling_config(theta0, nx, multiple, steps=None, extra=()):
    """The column at dt = multiple x the predicted limit, for steps x that limit in time, and for
    at least SETTLING["min_steps"] steps (a time-step instability grows per step)."""
    rf = RunFile.read(SETTLING_TOML)
    lim = min(settling_limits(theta0, nx).values())
    steps = max(steps or SETTLING["steps"], SETTLING["min_steps"] * multiple)
    h = rf.get("numerics", "h_over_dx") * rf.get("domain", "L") / nx
    over = [f"material.theta0={theta0!r}", f"numerics.Nx={nx}", f"domain.Ly={LY_IN_H * h!r}",
            f"numerics.dt={multiple * lim!r}", "numerics.allow_unstable_dt=true",
            f"output.t_end={steps * lim!r}", "output.times=[]", "output.progress_interval=0",
            "checks.every=1", "checks.theta_change=1.0", "checks.energy=true", *extra]
    return config.build(rf.override(over))


def settling_recorder(cfg):
    """The column's criteria, the run stopped at the first that fails: theta against the balance the
    run's pressure form converges to (what the scene's walls hold), the scene's energy bound; and
    that balance on 2,001 points of [0, L]."""
    xs = np.linspace(0.0, cfg.L, 2001)
    theta_eq = cfg.scene.wall_theta(cfg, xs)
    return Recorder(cfg, THETA_FRAC, theta_ref=lambda x: np.interp(x, xs, theta_eq), stop=True), theta_eq


def run_settling_case(theta0, Re, nx, multiple, source="grid", steps=None):
    """One column run; its CSV row (Re is the column's, sqrt(g h) L / nu: one k)."""
    cfg = settling_config(theta0, nx, multiple, steps)
    lim = settling_limits(theta0, nx)
    term = min(lim, key=lim.get)
    rec, theta_eq = settling_recorder(cfg)
    th_eq = float(theta_eq.max())
    lim_eq = settling_limits(theta0, nx, th_eq)
    outcome = run_and_classify(cfg, rec)
    c2 = modulus(theta0, cfg.G_a, cfg.G_b) / cfg.rho_s
    return {
        "nx": nx, "theta0": theta0, "Re": Re, "k": cfg.k, "multiple": multiple, "dt": cfg.dt,
        "dt_limit": lim[term], "limit_term": term, "dt_cfl": lim["advection"],
        "dt_viscous": lim.get("viscous", math.inf),
        "dt_acoustic_damping": 2.0 * cfg.nu / c2, "steps_planned": cfg.nsteps,
        **outcome, "source": source, "commit": COMMIT,
        "integrator": cfg.integrator, "dt_force": lim["force"], "dt_damping": lim.get("damping", math.inf),
        "theta_eq_max": th_eq, "dt_limit_eq": min(lim_eq.values()), "limit_term_eq": min(lim_eq, key=lim_eq.get),
        "ke_bound": cfg.scene.max_kinetic_energy(cfg, 1.0),
    }


def settling_re(theta0, nx):
    cfg = settling_config(theta0, nx, 1.0)
    return round(cfg.reynolds, 6)


def plot_settling(rows, outdir):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, ax = plt.subplots(figsize=(6.4, 5.4))
    nx = SETTLING["nx"]
    ts = sorted({float(r["theta0"]) for r in rows})
    meas = []
    for t in ts:
        col = sorted([r for r in rows if abs(float(r["theta0"]) - t) < 1e-9], key=lambda r: float(r["multiple"]))
        phys = physical_time(col)
        for r in col:
            m, v = float(r["multiple"]), verdict(r, phys)
            if v == "stable":
                ax.plot(t, m, "o", color="tab:green", ms=6)
            elif v == "physical":
                ax.plot(t, m, "D", color="tab:gray", ms=6)
            elif r["crash"]:
                ax.plot(t, m, "P", color="k", ms=7)
            else:
                mk, c = MARK.get(r["first_failure"], ("D", "k"))
                ax.plot(t, m, mk, color=c, ms=7)
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


def summary_settling(rows):
    lines = [f"settling column, N_x = {SETTLING['nx']}: measured dt / predicted limit (at theta_0), last without "
             "a time-step failure .. first with one",
             f"{'theta0':>6} {'term':>8} {'limit [s]':>10} {'ok<=':>6} {'fail>=':>6} {'eq/lim':>7} "
             f"{'force/lim':>9}  first failure"]
    for t in sorted({float(r["theta0"]) for r in rows}):
        col = sorted([r for r in rows if abs(float(r["theta0"]) - t) < 1e-9], key=lambda r: float(r["multiple"]))
        lo, hi = dt_bounds(col)
        r0 = col[0]
        lim = float(r0["dt_limit"])
        first = next((r for r in col if float(r["multiple"]) == hi), None) if hi else None
        how = f"{first['first_failure']} at step {first['fail_step']} (t = {float(first['t_done']):.3g} s)" \
            if first else ""
        f = lambda v: "-" if v is None else f"{v:.3g}"  # noqa: E731
        lines.append(f"{t:>6g} {r0['limit_term']:>8} {lim:>10.3g} {f(lo):>6} {f(hi):>6} "
                     f"{float(r0['dt_limit_eq']) / lim:>7.3g} {float(r0['dt_force']) / lim:>9.3g}  {how}")
    return "\n".join(lines)


def main_settling(a):
    nx = SETTLING["nx"]
    res = settling_results(os.path.join(a.out, "stability_settling.csv"))
    if not a.plot_only:
        for t in SETTLING["theta0"]:
            Re = settling_re(t, nx)
            for m in MULTS:
                res.get(t, Re, nx, m)
            if a.refine:   # beyond the grid (up to 64x or down to 1/64), bisected to within 10 %
                lo, hi = refine(res, t, Re, nx=nx)
                print(f"refined settling theta0={t:g}: no time-step failure <= {lo}, one at {hi}", flush=True)
    print(f"wrote {plot_settling(res.rows, a.out)}")
    text = summary_settling(res.rows)
    print(text)
    with open(os.path.join(a.out, "summary_settling.txt"), "w") as f:
        f.write(text + "\n")
    return 0


# ---- the margin of the damping constant (--damping) ---------------------------------------------------
DAMPING_FRACTIONS = (0.1, 0.13, 0.16, 0.18, 0.2, 0.26)


def run_auto(theta0, Re, nx, steps=STEPS, integrator="paper"):
    """dt = "auto" (the run's limits) for about ``steps`` steps of its first dt (config.build's):
    (the outcome's CSV columns, the first dt)."""
    cfg = case_config(theta0, Re, nx, 1.0, steps, extra=['numerics.dt="auto"'], integrator=integrator)
    return run_and_classify(cfg, Recorder(cfg, THETA_FRAC)), cfg.dt


def main_damping(a, theta0=0.7, Re=57.0):
    """Fixed dt at fractions of nu/c^2 (of theta_0) and dt = "auto", theta_0 = 0.7, Re = 57, per N_x."""
    res = couette_results(os.path.join(a.out, "stability_damping.csv"))
    lines = [f"theta0 = {theta0:g}, Re = {Re:g}: fixed dt = f nu/c^2, {STEPS} steps; and dt = \"auto\""]
    for nx in [int(x) for x in a.nx.split(",") if x]:
        k, h, lim, term, dt_ac = physics(theta0, Re, nx)
        nu_c2 = 0.5 * dt_ac
        got = []
        for f in DAMPING_FRACTIONS:
            row = res.get(theta0, Re, nx, f * nu_c2 / lim[term], source="damping")
            got.append(f"{f:g}: {'stable' if row['stable'] == '1' else row['first_failure'] + ' @' + row['fail_step']}")
        out, first = run_auto(theta0, Re, nx)
        lines.append(f"N_x = {nx}: dt_pred = {lim[term]:.3g} s ({term}) = {lim[term] / nu_c2:.3g} nu/c^2; " + "; ".join(got))
        lines.append(f"   auto: first dt {first:.3g} s = {first / nu_c2:.3g} nu/c^2, {out['steps_done']} steps to "
                     f"t = {out['t_done']:.3g} s, {'stable' if out['stable'] else 'unstable: ' + out['first_failure']} "
                     f"{out['message']}")
        print(lines[-2] + "\n" + lines[-1], flush=True)
    with open(os.path.join(a.out, "summary_damping.txt"), "w") as f:
        f.write("\n".join(lines) + "\n")
    return 0


# ---- the prediction of parsph.physics.limits against runs (--pred, --ratios) ---------------------------------
PRED_MULTS = (1.0, 1.5, 2.0)
AUTO_FIELDS = ["nx", "theta0", "Re", "integrator", "k", "dt_first", "term", "steps_done", "t_done", "stable",
               "fired", "message", "wall_s", "commit"]


def bracket(res, theta0, Re, nx, tol=1.25, span=64.0, max_runs=14, seed=(None, None)):
    """Bracket the column's time-step limit in multiples of the prediction: 1, then 1.5, 2 and doubling
    up (or 0.5 and halving down) to the first change, then bisection until fails/stable <= tol.

    ``seed``: (stable, failing) multiples from earlier runs of the column (either may be None); both
    are run again here and the search starts from them instead of from 1."""
    seeded = [m for m in seed if m is not None]
    for m in seeded or [1.0]:
        res.get(theta0, Re, nx, m, source="pred")
    return search(res, theta0, Re, nx, lambda hi: hi / 2, lambda lo: {1.0: 1.5, 1.5: 2.0}.get(lo, lo * 2),
                  tol, span, max_runs, "bracket")


def auto_row(nx, theta0, Re, integrator, outcome, first, term, k):
    return {"nx": nx, "theta0": repr(theta0), "Re": repr(Re), "integrator": integrator, "k": k,
            "dt_first": first, "term": term, "steps_done": outcome["steps_done"], "t_done": outcome["t_done"],
            "stable": outcome["stable"], "fired": outcome["first_failure"], "message": outcome["message"],
            "wall_s": outcome["wall_s"], "commit": COMMIT}


def record_auto(path, row):
    append_row(path, AUTO_FIELDS, row)
    print(f"auto Nx={row['nx']} theta0={row['theta0']} Re={row['Re']} {row['integrator']}: first dt "
          f"{row['dt_first']:.3g} s ({row['term']}), {row['steps_done']} steps, "
          f"{'stable' if row['stable'] else 'UNSTABLE ' + row['fired'] + ' ' + row['message']}", flush=True)


def main_pred(a):
    """Per column: fixed dt at multiples of the prediction (PRED_MULTS, 0.5 too where 1 fails; with
    --bracket: bracketed to 25 %) unless --auto-only, and one dt = "auto" run."""
    res = couette_results(os.path.join(a.out, f"stability_pred_{a.integrator}.csv"), integrator=a.integrator)
    auto_path = os.path.join(a.out, "stability_auto.csv")
    done = {(r["nx"], r["theta0"], r["Re"], r["integrator"]) for r in load_rows(auto_path)}
    if a.pred == "all":
        cols = [(t, Re) for t in THETAS for Re in RES]
    elif a.pred == "midpoint":
        cols = [(t, Re) for t in MIDPOINT["theta0"] for Re in MIDPOINT["Re"]]
    else:
        cols = [tuple(float(x) for x in c.split(":")) for c in a.pred.split(",") if c]
    for nx in [int(x) for x in a.nx.split(",") if x]:
        seeds = {}
        for path in a.seed:     # earlier runs of the column (absolute dt): where the bracket starts
            for (integ, nx_, t, Re), rows in columns_of(path).items():
                if integ == a.integrator and nx_ == nx:
                    p = predicted(integ, nx, t, Re)
                    lo, hi = (None if v is None else v / p for v in measured_bounds(rows))
                    if (lo is not None and lo > 1.5) or (hi is not None and hi > 3.0):  # else 1, 1.5, 2 is shorter
                        seeds[(t, Re)] = (lo, hi)
        for t, Re in cols:
            if a.bracket:
                bracket(res, t, Re, nx, tol=a.tol, seed=seeds.get((round(t, 6), round(Re, 6)), (None, None)))
            elif not a.auto_only:
                for m in PRED_MULTS:
                    row = res.get(t, Re, nx, m, source="pred")
                    if row["stable"] != "1":
                        if m == PRED_MULTS[0]:
                            res.get(t, Re, nx, 0.5, source="pred")
                        break
            if (str(nx), repr(t), repr(Re), a.integrator) in done:
                continue
            outcome, first = run_auto(t, Re, nx, integrator=a.integrator)
            k, h, lim, term, _ = physics(t, Re, nx, integrator=a.integrator)
            record_auto(auto_path, auto_row(nx, t, Re, a.integrator, outcome, first, term, k))
    return 0


def main_settling_auto(a):
    """dt = "auto" in each settling column (SETTLING["steps"] steps of the predicted limit in time); with
    --bracket, first the column's fixed-dt limit bracketed to --tol against the prediction now
    (stability_settling.csv in --out, as --scene settling writes it)."""
    auto_path = os.path.join(a.out, "stability_auto.csv")
    done = {(r["nx"], r["theta0"], r["integrator"]) for r in load_rows(auto_path)}
    nx = SETTLING["nx"]
    res = settling_results(os.path.join(a.out, "stability_settling.csv"))
    for t in SETTLING["theta0"]:
        if a.bracket:
            lo, hi = bracket(res, t, settling_re(t, nx), nx, tol=a.tol)
            print(f"bracketed settling theta0={t:g}: no time-step failure <= {lo}, one at {hi}", flush=True)
        if (str(nx), repr(t), "settling") in done:
            continue
        lim = settling_limits(t, nx)
        cfg = settling_config(t, nx, 1.0, extra=['numerics.dt="auto"'])
        outcome = run_and_classify(cfg, settling_recorder(cfg)[0])
        record_auto(auto_path, auto_row(nx, t, settling_re(t, nx), "settling", outcome, cfg.dt,
                                        min(lim, key=lim.get), cfg.k))
    return 0


def main_longer(a):
    """Runs longer than STEPS at a multiple that was stable for STEPS (--longer 'nx:theta:Re:multiple:steps,...'):
    does a step above the asymptotic limit fail later (stability_longer.csv)?"""
    for spec in a.longer.split(","):
        nx, t, Re, m, steps = spec.split(":")
        res = Results(os.path.join(a.out, "stability_longer.csv"),
                      lambda t_, r_, nx_, m_, source, n=int(steps): run_case(t_, r_, nx_, m_, steps=n, source=source),
                      FIELDS)
        res.get(float(t), float(Re), int(nx), float(m), source=f"longer {steps}")
    return 0


def columns_of(path, cols=None):
    """{(integrator, N_x, theta_0, Re): rows} of a CSV of Couette runs (added to ``cols``)."""
    cols = {} if cols is None else cols
    for r in load_rows(path):
        r.setdefault("integrator", "paper")
        if "midpoint" in os.path.basename(path):
            r["integrator"] = "midpoint"
        key = (r["integrator"] or "paper", int(r["nx"]), round(float(r["theta0"]), 6), round(float(r["Re"]), 6))
        cols.setdefault(key, []).append(r)
    return cols


def main_ratios(a):
    """Per (integrator, N_x, theta_0, Re): the measured bounds over every run in the CSVs (absolute dt)
    divided by parsph.physics.limits' prediction now (stability_ratios.csv); the settling column's runs (a file named
    *settling*) as integrator 'settling'. With --auto: each column's dt = "auto" run, stable or not,
    and its mean step (t / steps) over the prediction and over the largest measured stable dt."""
    cols = {}
    for path in a.ratios:
        if "settling" in os.path.basename(path):
            for r in load_rows(path):
                cols.setdefault(("settling", int(r["nx"]), round(float(r["theta0"]), 6), round(float(r["Re"]), 6)),
                                []).append(r)
        else:
            columns_of(path, cols)
    if a.commits:   # only the runs made at these commits
        cols = {k: [r for r in rows if r.get("commit") in a.commits] for k, rows in cols.items()}
        cols = {k: rows for k, rows in cols.items() if rows}
    autos = {}
    for r in load_rows(a.auto) if a.auto else []:
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
        else:
            k, h, lim, term, dt_ac = physics(t, Re, nx, integrator=integ)
        lo, hi = measured_bounds(rows)
        p = lim[term]
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
    path = os.path.join(a.out, "stability_ratios.csv")
    fields = list(dict.fromkeys(k for r in out for k in r))
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fields)
        w.writeheader()
        w.writerows(out)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
