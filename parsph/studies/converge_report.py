"""The analysis half of ``parsph converge`` (rank 0, files only): estimates per family and output
time from the levels' outputs (:class:`parsph.studies.converge.FamilyRuns`), the --target choice, the
printed report, converge.json and the PNG.
"""
import json
import math
import os

import numpy as np

from parsph.output import read_profile
from parsph.setup import config
from parsph.setup.runfile import RunFile
from . import estimates
from .levels import level_run_file


def analyse(results, ratio, target=None, dt_scaling="limit"):
    """Estimates per family and output time from the runs of each family (FamilyRuns); the --target choice."""
    fams = [_family_report(item, ratio, target, dt_scaling) for item in results]
    report = {"ratio": ratio, "target": target, "families": fams, "dt_scaling": dt_scaling}
    if target is not None:
        ok = [f for f in fams if f["target"]["Nx"] is not None]
        best = min(ok, key=lambda f: f["target"]["cpu_s"]) if ok else None
        report["choice"] = None if best is None else {"family": best["family"], **best["target"]}
    return report


def _family_report(item, ratio, target, dt_scaling):
    """One family (FamilyRuns): the estimate at every output time, and its setting for the target."""
    runs, bias_run, time_run = item.levels, item.bias, item.time
    profs = [read_profile(r.dir) for r in runs]
    bprof = read_profile(bias_run.dir) if bias_run is not None else None
    tprof = read_profile(time_run.dir) if time_run is not None else None
    dts = None
    if tprof is not None:  # the finest level's dt and the time-step run's
        dts = (config.loads(runs[-1].run_file).dt, config.loads(time_run.run_file).dt)
    cfg = config.loads(profs[0]["attrs"]["run_file"])
    nxs = [r.Nx for r in runs]
    times = [_time_row(cfg, i, float(t), profs, bprof, tprof, dts, runs, ratio)
             for i, t in enumerate(profs[0]["time"])]
    cautions = estimates.times_caution([r["estimate"]["order"] for r in times if r["estimate"]["asymptotic"]])
    fam_rep = {"family": item.family, "scene": cfg.scene.name, "field": cfg.scene.error_field, "Nx": nxs,
               "particles": [r.particles for r in runs], "levels": [r.record() for r in runs], "times": times,
               "caution": cautions, "bias": None if bias_run is None else bias_run.bias,
               "bias_run": None if bias_run is None else bias_run.record(),
               "time_run": None if time_run is None else time_run.record()}
    if target is not None:
        fam_rep["target"] = _target_setting(runs, nxs, times, target, dts, dt_scaling)
    return fam_rep


def _time_row(cfg, i, t, profs, bprof, tprof, dts, runs, ratio):
    """Output time i: the levels on the coarsest bins, the estimate, the true error where there is a
    reference, and the time-step run's effect."""
    field = cfg.scene.error_field
    period = None if cfg.scene.walls else cfg.L
    xc = profs[0]["x"]
    scale = cfg.error_scale(t)
    on_coarse = [profs[0][field][i]] + [estimates.to_coarse(p["x"], p[field][i], xc, period)
                                        for p in profs[1:]]
    bias = None if bprof is None else np.asarray(bprof[field][i]) - np.asarray(profs[0][field][i])
    est = estimates.estimate(on_coarse, ratio, scale, bias=bias)
    row = {"t": t, "scale": scale, "estimate": est.as_dict(),
           "cpu_s": [r.cpu_s[i] for r in runs], "steps": [r.steps[i] for r in runs]}
    if cfg.scene.reference is not None and field in cfg.scene.reference(cfg, xc[:1], t):
        ref = cfg.scene.reference(cfg, xc, t)[field]
        ok = np.all(np.isfinite(on_coarse), axis=0)
        row["true_max"] = [float(np.max(np.abs(f - ref)[ok]) / scale) for f in on_coarse]
        row["true_rms"] = [float(np.sqrt(np.mean(((f - ref)[ok] / scale) ** 2))) for f in on_coarse]
        # each level on its own bins, as `parsph check` reports it
        row["check_max"] = [float(np.nanmax(np.abs(p[field][i] - p[field + "_exact"][i])) / scale)
                            for p in profs]
    if tprof is not None:
        pf = profs[-1]
        dT = (estimates.to_coarse(pf["x"], tprof[field][i], xc, period)
              - estimates.to_coarse(pf["x"], pf[field][i], xc, period)) / scale
        row["time_effect_max"] = float(np.nanmax(np.abs(dT)))
        row["_T"] = dT[est.used] / (dts[1] - dts[0])
    row["_est"] = est
    return row


def _target_setting(runs, nxs, times, target, dts, dt_scaling):
    """The cheapest N_x (and dt_safety) of this family predicted to meet the target at every time."""
    costs = [r.cpu_s[-1] for r in runs]
    if dts is not None:  # a time-step run: trade dt against N_x
        cfgs = [config.loads(r.run_file) for r in runs]
        s0 = cfgs[0].values["numerics"]["dt_safety"]  # the base level's margin below its limit
        measured = [(n, c.limits) for n, c in zip(nxs, cfgs)]

        def dt_limit(n):
            lim = estimates.limit_at(n, measured)
            return None if lim is None else s0 * lim
        best = estimates.predict_setting(
            nxs, [(r["t"], r["_est"], r["_T"]) for r in times], target, (dts[0], dt_limit),
            lambda n: estimates.cost_at(n, nxs, costs)[0])
        if best[0] is None:
            return {"Nx": None, "why_not": best[1]}
        n, dt, lim, err, cost = best
        return {"Nx": n, "why_not": None, "cpu_s": cost, "predicted_err": err,
                "cost_exponent": estimates.cost_at(n, nxs, costs)[1],
                "to_time": times[-1]["t"], "set": f"numerics.dt_safety={s0 * dt / lim:.4g}"}
    need, why = estimates.predict_nx(nxs, [(r["t"], r["_est"]) for r in times], target)
    setting = {"Nx": need, "why_not": why}
    if need is not None:
        cost, a = estimates.cost_at(need, nxs, costs)
        setting.update(cpu_s=cost, cost_exponent=a, to_time=times[-1]["t"])
        if dt_scaling == "dx2":  # the errors were measured with dt ~ dx^2: the setting needs that dt
            lr = level_run_file(RunFile.parse(runs[0].run_file), need, "dx2")
            setting["set"] = (f"numerics.dt_safety={lr.get('numerics', 'dt_safety'):.4g}"
                              if lr.get("numerics", "dt") == "auto" else f"numerics.dt={lr.get('numerics', 'dt'):.4g}")
    return setting


def _fmt(v, spec=".2e"):
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def print_report(rep):
    for fam in rep["families"]:
        if fam.get("bias") is None:
            bias_note = "no bias run (no viscosity, or |b| < 1e-6)"
        else:
            bias_note = (f"kernel bias b = {fam['bias']:+.2e} (nu_eff = (1 + b) nu, parsph.physics.lattice_sums), its "
                         f"effect from one run of N_x = {fam['Nx'][0]} with k / (1 + b), "
                         f"{fam['bias_run']['cpu_s'][-1]:.3g} CPU s")
        print(f"\nconverge: scene {fam['scene']}, family {fam['family']}, N_x = "
              f"{', '.join(map(str, fam['Nx']))} (ratio {rep['ratio']}); errors of "
              f"{fam['field']} on the N_x = {fam['Nx'][0]} bins, relative to the scale given per time; "
              + bias_note)
        for row in fam["times"]:
            e = row["estimate"]
            state = "asymptotic" if e["asymptotic"] else "NOT asymptotic: " + "; ".join(e["reasons"])
            orders = ", ".join(_fmt(p, ".2f") for p in e["orders"])
            nb = len(fam["levels"]) and e["bins"]
            bins = "" if nb == fam["Nx"][0] else f"; {nb} of {fam['Nx'][0]} bins have data in every level"
            print(f"t = {row['t']:g} s, scale {row['scale']:.4g}{bins}: observed order {orders or '-'}"
                  f" (shape residual {', '.join(_fmt(s, '.2f') for s in e['shapes']) or '-'}); {state}")
            if e.get("bias_max") is not None:
                rich = e.get("richardson_max")
                print(f"  the kernel's viscosity bias (b = {fam['bias']:+.2e}) moves the limit by up to "
                      f"{e['bias_max']:.2e}" + (f"; Richardson alone would give {_fmt(rich[-1])} for the finest level"
                                               if rich else ""))
            has_true = "true_max" in row
            print(f"{'N_x':>6} {'particles':>10} {'steps':>7} {'CPU s':>9} {'|f-f_coarser|':>13} "
                  f"{'est. max err':>12}" + (f" {'true max err':>12} {'ratio':>6} {'check err':>10}" if has_true else ""))
            for l, nx in enumerate(fam["Nx"]):
                est = e["err_max"][l] if e["err_max"] is not None else None
                line = (f"{nx:>6} {fam['particles'][l]:>10} {row['steps'][l]:>7} {row['cpu_s'][l]:>9.3g} "
                        f"{_fmt(e['diff_max'][l - 1]) if l else '-':>13} {_fmt(est):>12}")
                if has_true:
                    tr = row["true_max"][l]
                    ratio = est / tr if est is not None and tr > 0 else None
                    line += f" {_fmt(tr):>12} {_fmt(ratio, '.2f'):>6} {_fmt(row['check_max'][l]):>10}"
                print(line)
        if fam["caution"]:
            print("caution: " + fam["caution"])
        if len(fam["Nx"]) == 3 and any(r["estimate"]["asymptotic"] for r in fam["times"]):
            print("note: three levels give one order and cannot check it; --levels 4 checks the order"
                  + ("" if fam.get("bias") is not None else "; an error that every level shares (the kernel's "
                     "bias at fixed h/dx) is invisible to them"))
        if "target" in fam:
            t = fam["target"]
            if t["Nx"] is None:
                print(f"--target {rep['target']:g}: no prediction for family {fam['family']}: {t['why_not']}")
            else:
                how = (f" with {t['set']}" if t.get("set") else "") + (
                    f" (predicted max error {t['predicted_err']:.2e}; the time error's share from the run of "
                    f"N_x = {fam['Nx'][-1]} at its limit)" if t.get("predicted_err") is not None else "")
                print(f"--target {rep['target']:g}: family {fam['family']}: N_x = {t['Nx']}{how} predicted to meet "
                      f"it at every output time, about {t['cpu_s']:.3g} CPU s to t = {t['to_time']:g} s "
                      f"(cost ~ N_x^{t['cost_exponent']:.2f})")
    if rep.get("target") is not None:
        c = rep["choice"]
        if c is None:
            print(f"--target {rep['target']:g}: no family has estimates to stand behind; refine (more --levels) "
                  f"or try another --family")
        else:
            extra = f", {c['set']}" if c.get("set") else ""
            print(f"--target {rep['target']:g}: cheapest: family {c['family']}, numerics.Nx = {c['Nx']}{extra} "
                  f"(about {c['cpu_s']:.3g} CPU s)")


def jsonable(o):
    """``o`` as JSON takes it: numpy scalars as numbers, non-finite floats as null, keys with a leading _ left out."""
    if isinstance(o, dict):
        return {k: jsonable(v) for k, v in o.items() if not k.startswith("_")}
    if isinstance(o, (list, tuple)):
        return [jsonable(v) for v in o]
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, (np.floating, np.integer)):
        return jsonable(o.item())
    return o


def write_report(report, out_dir):
    """DIR/converge.json and DIR/converge.png; their paths."""
    path = os.path.join(out_dir, "converge.json")
    with open(path, "w") as f:
        json.dump(jsonable(report), f, indent=1)
    png = os.path.join(out_dir, "converge.png")
    plot(report, png)
    return path, png


def plot(rep, png):
    """Estimated (filled) and true (hollow) max error against CPU seconds, per output time and family."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    ntimes = max(len(f["times"]) for f in rep["families"])
    colors = plt.cm.viridis(np.linspace(0, 0.9, max(1, ntimes)))
    markers = "osD^v"
    for k, fam in enumerate(rep["families"]):
        m = markers[k % len(markers)]
        for c, row in zip(colors, fam["times"]):
            est = row["estimate"]["err_max"]
            label = f"{fam['family']}, t = {row['t']:g} s"
            if est is not None:
                ax.loglog(row["cpu_s"], est, "-" + m, color=c, ms=5, label=label)
            else:
                label += " (not asymptotic)"
            if "true_max" in row:
                ax.loglog(row["cpu_s"], row["true_max"], "--" + m, color=c, mfc="none", ms=6,
                          label=None if est is not None else label)
    if rep.get("target") is not None:
        ax.axhline(rep["target"], color="grey", lw=0.8)
    ax.set_xlabel("process CPU s to the output time (all ranks)")
    ax.set_ylabel("max error / scale")
    ax.set_title("estimated (filled, solid) and true (hollow, dashed) error")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)
