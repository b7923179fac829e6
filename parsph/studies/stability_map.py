"""The measured stability map against the predicted time-step limit (docs/stability.md): what each mode
of ``scripts/stability_map.py`` runs and writes into its output directory.

The runs are :mod:`parsph.studies.stability_cases`' (each a CSV row; rows
already in a CSV are not run again, so a stopped map resumes), the figures and
tables :mod:`parsph.studies.stability_report`'s. Not every failure is a
time-step failure: some come at the same physical time whatever dt (the flow
itself compacts near the moving plate); ``verdict``
(:mod:`parsph.studies.stability`) tells them apart (two failing runs >= 8 %
apart in dt, same criterion, same time within 5 %: ``physical``), and
:func:`long_checks` confirms each such column with a run at half the dt
continued to 1.3x that time. Measured limits count time-step failures only.

The grid: theta_0 x Re x multiple at N_x = 10, 50 and 200 (the whole grid at
each); ``refine`` extends each N_x = 50 column beyond the grid (multiples up
to 64 or down to 1/64) and bisects its time-step limit to within 10 %.
"""
import math
import os

from .runs import append_row, load_rows
from .stability import column, measured_bounds, physical_time, run_and_classify, search, verdict
from .stability_cases import (FIELDS, MIDPOINT, MULTS, RES, SETTLING, STEPS, THETAS, auto_row, columns_of,
                              couette_results, grid, prediction, record_auto, renormalised, renormalised_settling,
                              run_auto, run_case, settling_config, settling_limits, settling_re, settling_recorder,
                              settling_results)
from .stability_report import plot, plot_settling, summary, summary_settling, write_merged

DAMPING_FRACTIONS = (0.1, 0.13, 0.16, 0.18, 0.2, 0.26)
PRED_MULTS = (1.0, 1.5, 2.0)


def _write(out_dir, name, text):
    with open(os.path.join(out_dir, name), "w") as f:
        f.write(text + "\n")


# ---- searches in one column ----------------------------------------------------------------------------
def refine(res, theta0, Re, nx=50, tol=1.1, span=64.0, max_runs=12):
    """Bisect the column's time-step limit (failures at the physical failure time do not count)."""
    for m in MULTS:
        res.get(theta0, Re, nx, m)
    return search(res, theta0, Re, nx, lambda hi: (hi or MULTS[0]) / 4, lambda lo: lo * 2,
                  tol, span, max_runs, "refine")


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


# ---- the modes -----------------------------------------------------------------------------------------
def couette_map(out_dir, nxs, quick=False, plot_only=False, refine_cols=False, long=False):
    """The grid (stability_map.csv), --refine, --long; the figures, stability_all.csv and summary.txt."""
    res = couette_results(os.path.join(out_dir, "stability_map.csv"))
    if not plot_only:
        for t, r, nx, m in grid(nxs, quick):
            res.get(t, r, nx, m)
        if refine_cols:
            for t in THETAS:
                for r in RES:
                    lo, hi = refine(res, t, r)
                    print(f"refined theta0={t:g} Re={r:g}: no time-step failure <= {lo}, one at {hi}", flush=True)
        if long:
            long_checks(res, out_dir)
    for png in plot(res.rows, out_dir, sorted({int(r["nx"]) for r in res.rows})):
        print(f"wrote {png}")
    print(f"wrote {write_merged(out_dir)}")
    text = "\n\n".join(summary(res.rows, nx) for nx in sorted({int(r["nx"]) for r in res.rows}))
    print(text)
    _write(out_dir, "summary.txt", text)


def midpoint_map(out_dir, plot_only=False):
    """The dense, weakly damped corner again with the second-order integrator (same criteria)."""
    res = couette_results(os.path.join(out_dir, "stability_map_midpoint.csv"), integrator="midpoint")
    if not plot_only:
        for t in MIDPOINT["theta0"]:
            for r in MIDPOINT["Re"]:
                for m in MIDPOINT["multiple"]:
                    res.get(t, r, 50, m)
    for png in plot(res.rows, out_dir, [50], tag="midpoint"):
        print(f"wrote {png}")
    text = summary(res.rows, 50, ", midpoint integrator")
    print(text)
    _write(out_dir, "summary_midpoint.txt", text)


def settling_map(out_dir, plot_only=False, refine_cols=False):
    """The granular column at the grid's multiples (stability_settling.csv), its figure and summary."""
    nx = SETTLING["nx"]
    res = settling_results(os.path.join(out_dir, "stability_settling.csv"))
    if not plot_only:
        for t in SETTLING["theta0"]:
            Re = settling_re(t, nx)
            for m in MULTS:
                res.get(t, Re, nx, m)
            if refine_cols:   # beyond the grid (up to 64x or down to 1/64), bisected to within 10 %
                lo, hi = refine(res, t, Re, nx=nx)
                print(f"refined settling theta0={t:g}: no time-step failure <= {lo}, one at {hi}", flush=True)
    print(f"wrote {plot_settling(res.rows, out_dir)}")
    text = summary_settling(res.rows)
    print(text)
    _write(out_dir, "summary_settling.txt", text)


def damping(out_dir, nxs, theta0=0.7, Re=57.0):
    """Fixed dt at fractions of nu/c^2 (of theta_0) and dt = "auto", theta_0 = 0.7, Re = 57, per N_x
    (stability_damping.csv, summary_damping.txt): the margin of the damping limit."""
    res = couette_results(os.path.join(out_dir, "stability_damping.csv"))
    lines = [f"theta0 = {theta0:g}, Re = {Re:g}: fixed dt = f nu/c^2, {STEPS} steps; and dt = \"auto\""]
    for nx in nxs:
        p = prediction(theta0, Re, nx)
        nu_c2 = 0.5 * p.acoustic_damping
        got = []
        for f in DAMPING_FRACTIONS:
            row = res.get(theta0, Re, nx, f * nu_c2 / p.dt, source="damping")
            got.append(f"{f:g}: {'stable' if row['stable'] == '1' else row['first_failure'] + ' @' + row['fail_step']}")
        out, first = run_auto(theta0, Re, nx)
        lines.append(f"N_x = {nx}: dt_pred = {p.dt:.3g} s ({p.term}) = {p.dt / nu_c2:.3g} nu/c^2; " + "; ".join(got))
        lines.append(f"   auto: first dt {first:.3g} s = {first / nu_c2:.3g} nu/c^2, {out['steps_done']} steps to "
                     f"t = {out['t_done']:.3g} s, {'stable' if out['stable'] else 'unstable: ' + out['first_failure']} "
                     f"{out['message']}")
        print(lines[-2] + "\n" + lines[-1], flush=True)
    _write(out_dir, "summary_damping.txt", "\n".join(lines))


def _seeds(paths, integrator, nx):
    """{(theta_0, Re): (stable, failing) multiples of the prediction now} of earlier runs (absolute dt),
    for the columns whose bounds lie beyond 1.5x (stable) or 3x (failing) the prediction."""
    seeds = {}
    for path in paths:
        for (integ, nx_, t, Re), rows in columns_of(path).items():
            if integ == integrator and nx_ == nx:
                p = prediction(t, Re, nx, integ).dt
                lo, hi = (None if v is None else v / p for v in measured_bounds(rows))
                if (lo is not None and lo > 1.5) or (hi is not None and hi > 3.0):  # else 1, 1.5, 2 is shorter
                    seeds[(t, Re)] = (lo, hi)
    return seeds


def pred(out_dir, cols, nxs, integrator="paper", bracketed=False, tol=1.25, seed=(), auto_only=False):
    """Per column (theta_0, Re) at each N_x: fixed dt at PRED_MULTS x the prediction (0.5 too where 1
    fails; ``bracketed``: bracketed to ``tol``) unless ``auto_only`` (stability_pred_<integrator>.csv),
    and one dt = "auto" run (stability_auto.csv). ``cols``: "all" (the grid), "midpoint" (its corner) or
    a list of (theta_0, Re)."""
    res = couette_results(os.path.join(out_dir, f"stability_pred_{integrator}.csv"), integrator=integrator)
    auto_path = os.path.join(out_dir, "stability_auto.csv")
    done = {(r["nx"], r["theta0"], r["Re"], r["integrator"]) for r in load_rows(auto_path)}
    if cols == "all":
        cols = [(t, Re) for t in THETAS for Re in RES]
    elif cols == "midpoint":
        cols = [(t, Re) for t in MIDPOINT["theta0"] for Re in MIDPOINT["Re"]]
    for nx in nxs:
        seeds = _seeds(seed, integrator, nx)
        for t, Re in cols:
            if bracketed:
                bracket(res, t, Re, nx, tol=tol, seed=seeds.get((round(t, 6), round(Re, 6)), (None, None)))
            elif not auto_only:
                for m in PRED_MULTS:
                    row = res.get(t, Re, nx, m, source="pred")
                    if row["stable"] != "1":
                        if m == PRED_MULTS[0]:
                            res.get(t, Re, nx, 0.5, source="pred")
                        break
            if (str(nx), repr(t), repr(Re), integrator) in done:
                continue
            outcome, first = run_auto(t, Re, nx, integrator=integrator)
            p = prediction(t, Re, nx, integrator)
            record_auto(auto_path, auto_row(nx, t, Re, integrator, outcome, first, p.term, p.k))


def settling_auto(out_dir, bracketed=False, tol=1.25):
    """dt = "auto" in each settling column (SETTLING["steps"] steps of the predicted limit in time); with
    ``bracketed``, first the column's fixed-dt limit bracketed to ``tol`` against the prediction now
    (stability_settling.csv, as settling_map writes it)."""
    auto_path = os.path.join(out_dir, "stability_auto.csv")
    done = {(r["nx"], r["theta0"], r["integrator"]) for r in load_rows(auto_path)}
    nx = SETTLING["nx"]
    res = settling_results(os.path.join(out_dir, "stability_settling.csv"))
    for t in SETTLING["theta0"]:
        if bracketed:
            lo, hi = bracket(res, t, settling_re(t, nx), nx, tol=tol)
            print(f"bracketed settling theta0={t:g}: no time-step failure <= {lo}, one at {hi}", flush=True)
        if (str(nx), repr(t), "settling") in done:
            continue
        lim = settling_limits(t, nx)
        cfg = settling_config(t, nx, 1.0, extra=['numerics.dt="auto"'])
        outcome = run_and_classify(cfg, settling_recorder(cfg)[0])
        record_auto(auto_path, auto_row(nx, t, settling_re(t, nx), "settling", outcome, cfg.dt,
                                        min(lim, key=lim.get), cfg.k))


def longer(out_dir, specs):
    """Runs longer than STEPS at a multiple that was stable for STEPS, ``specs`` [(nx, theta, Re, multiple,
    steps)]: does a step above the asymptotic limit fail later (stability_longer.csv)?"""
    for nx, t, Re, m, steps in specs:
        res = couette_results(os.path.join(out_dir, "stability_longer.csv"), steps=steps)
        res.get(t, Re, nx, m, source=f"longer {steps}")


def figures(out_dir, paths):
    """Every figure of docs/stability.md against the prediction now, from the CSVs ``paths``: Couette runs
    of both integrators (the integrator column, or 'midpoint' in the file name) and the settling runs
    (a file named *settling*); the PNGs' paths."""
    paper, mid, settle = [], [], []
    for path in paths:
        rows = load_rows(path)
        if "settling" in os.path.basename(path):
            settle += rows
            continue
        for r in rows:
            integ = r.get("integrator") or ("midpoint" if "midpoint" in os.path.basename(path) else "paper")
            (mid if integ == "midpoint" else paper).append({**r, "integrator": integ})
    figs = []
    if paper:
        figs += plot(renormalised(paper), out_dir, sorted({int(r["nx"]) for r in paper}))
    if mid:
        figs += plot(renormalised(mid), out_dir, sorted({int(r["nx"]) for r in mid}), tag="midpoint")
    if settle:
        figs.append(plot_settling(renormalised_settling(settle), out_dir))
    return figs

