"""``parsph converge``: run a scene at several resolutions and estimate each one's error.

    [mpirun -n P] parsph converge CONFIG [--levels L] [--ratio R] [--target ERR] [--out DIR]
                                 [--family NAME ...] [--dt-scaling dx2|limit] [--set S.K=V ...]
                                 [--force] [--threads N]

Level l of a family is the run file with N_x R^l particles across (h / dx
fixed; dt ~ dx^2 from the coarsest level's, or each level at its own limit
with --dt-scaling limit: ``level_raw``), written as an ordinary run file
DIR/<family>/nx<N_x>/<name>.toml and run by the same code as ``parsph run``,
on the same communicator, one level after another, without particle
snapshots. Two more runs complete a study: the coarsest level with the
viscosity k / (1 + b), b the kernel's viscosity bias at this h / dx (its
effect is an error every level shares: DIR/<family>/nx<N_x>_bias), and,
with --target, the finest level at its stability limit (the time error's
share: DIR/<family>/nx<N_x>_dtlimit). The estimates are
``parsph.convergence``'s; the cost of a level is the process CPU time of its
time loop summed over ranks, up to each output time. A level whose
``level.json`` records the same run file is reused, so a stopped study
resumes.

Writes DIR/converge.json and DIR/converge.png (error against cost).
"""
import json
import math
import os
import sys
import time
import tomllib

import numpy as np

from . import convergence
from .cli import EXIT_BAD_INPUT, EXIT_ERROR, EXIT_GUARD, UsageError, _agree, _fits_in_memory, _run_reporting, _Signals

# Numerics of the presets (docs/accuracy.md, "The frontier"), for --family; "given" is the run file's own.
FAMILIES = {
    "fast": {"kernel": "cubic_spline", "h_over_dx": 1.25, "beta_max": 6.0},       # run/couette_fast.toml
    "accurate": {"kernel": "wendland_c2", "h_over_dx": 2.5, "beta_max": 8.0},     # run/couette_accurate.toml
    "paper": {"kernel": "cubic_spline", "h_over_dx": 1.25, "beta_max": 1.5},      # run/couette_paper.toml
}


class _TimedOutput:
    """Wraps a run's Output: records (t, step, process CPU s since the loop began) at each output."""

    def __init__(self, out):
        self.out = out
        self.records = []
        self.cpu0 = time.process_time()

    def __call__(self, sim, **kw):
        self.records.append((sim.t, sim.step, time.process_time() - self.cpu0, self.out.N))
        return self.out(sim, **kw)


def _family_raw(raw, family):
    """The raw run-file dict with a family's numerics (dt "auto" for a preset family)."""
    raw = {s: dict(v) if isinstance(v, dict) else v for s, v in raw.items()}
    if family == "given":
        return raw
    f = FAMILIES[family]
    num = raw.setdefault("numerics", {})
    num.pop("h", None)
    num.update(kernel=f["kernel"], h_over_dx=f["h_over_dx"], dt="auto")
    raw.setdefault("walls", {})["beta_max"] = f["beta_max"]
    return raw


DT_SCALINGS = ("limit", "dx2")


def level_raw(raw, nx, dt_scaling="limit"):
    """Level N_x of a raw run file: h / dx kept, dt by ``dt_scaling``.

    ``"limit"``: ``dt = "auto"`` kept (each level at its own stability limit, times the
    run file's dt_safety), a fixed dt scaled with the limit (its margin kept). Cheapest,
    but the binding limit can change between levels (advection ~ dx, damping ~ 1,
    viscous ~ dx^2), so the first-order time error of Eqs. (6)-(7) is then not one
    power of dx across them. ``"dx2"``: dt_l = dt_0 (N_x0 / N_x)^2 from the base level's
    (its automatic dt at theta_0 for "auto", kept automatic with the dt_safety that gives
    dt_l at theta_0, so it still follows the state), so the time error falls as dx^2 at
    every level; every limit shrinks at most as dx^2, so dt_l stays within them.
    """
    from . import config
    if dt_scaling not in DT_SCALINGS:
        raise ValueError(f"dt_scaling {dt_scaling!r}: one of {DT_SCALINGS}")
    base = config.build(raw, config.dumps(raw))
    out = {s: dict(v) if isinstance(v, dict) else v for s, v in raw.items()}
    num = out["numerics"]
    num["Nx"] = int(nx)
    if num.get("h") is not None:
        num["h"] = base.h * base.Nx / nx
    probe = {s: dict(v) if isinstance(v, dict) else v for s, v in out.items()}
    probe["numerics"]["dt"] = "auto"
    lim = min(config.build(probe, config.dumps(probe)).limits.values())
    if dt_scaling == "dx2":
        dt = float(base.dt) * (base.Nx / nx) ** 2
        if num.get("dt") == "auto":
            num["dt_safety"] = min(1.0, dt / lim)
        else:
            num["dt"] = dt
    elif num.get("dt") != "auto":
        num["dt"] = float(base.dt) * lim / min(base.limits.values())
    out.setdefault("output", {})["snapshots"] = False
    return out


def _read_raw(path, sets):
    from . import config
    try:
        with open(path, "rb") as f:
            raw = tomllib.loads(f.read().decode("utf-8"))
    except OSError as e:
        raise UsageError(f"cannot read {path}: {e.strerror}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise UsageError(f"{path} is not valid TOML: {e}") from None
    config.apply_overrides(raw, sets or ())
    return raw


def _plan(args):
    """[(family, [(N_x, raw), ...])], validated on every rank."""
    from . import config
    if args.levels < 2:
        raise UsageError(f"--levels {args.levels}: need at least 2 (3 for an order and error estimates)")
    if args.ratio < 2:
        raise UsageError(f"--ratio {args.ratio}: must be an integer of at least 2")
    if args.target is not None and not args.target > 0:
        raise UsageError(f"--target {args.target:g}: must be positive")
    families = args.family or ["given"]
    for f in families:
        if f != "given" and f not in FAMILIES:
            raise UsageError(f"--family {f}: unknown (known: given, {', '.join(FAMILIES)})")
    raw = _read_raw(args.config, args.set)
    plan = []
    for fam in dict.fromkeys(families):
        fraw = _family_raw(raw, fam)
        try:
            # the family's base level validated first: its errors name the run file's keys
            nx0 = config.build(fraw, config.dumps(fraw)).Nx
            scaling = getattr(args, "dt_scaling", None) or "dx2"
            levels = [(nx0 * args.ratio ** l, level_raw(fraw, nx0 * args.ratio ** l, scaling))
                      for l in range(args.levels)]
            for nx, lr in levels:
                cfg = config.build(lr, config.dumps(lr))
        except config.ConfigError as e:
            raise UsageError(str(e) if fam == "given" else f"family {fam}: {e}") from None
        if len(cfg.output_times) == 0:
            raise UsageError("output.times is empty: the levels are compared at the output times")
        plan.append((fam, levels))
    return plan


def cmd_converge(args):
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    signals = _Signals()
    try:
        return _converge(comm, args, signals)
    except UsageError as e:
        if comm.rank == 0:
            print(f"parsph: error: {e}", file=sys.stderr, flush=True)
        return EXIT_BAD_INPUT
    finally:
        signals.release()


def _warm_up(comm, raw):
    """A few steps of a level, untimed, so that loading numba's compiled code is not counted as cost."""
    from . import config
    from .solver import Simulation
    w = {s: dict(v) if isinstance(v, dict) else v for s, v in raw.items()}
    cfg = config.build(w, config.dumps(w))
    w["output"]["t_end"] = 2.5 * cfg.dt
    w["output"]["times"] = []
    Simulation(config.build(w, config.dumps(w)), comm).run()


def _converge(comm, args, signals):
    from . import config
    root = comm.rank == 0
    stem = os.path.splitext(os.path.basename(args.config))[0]
    out_dir = args.out or os.path.join("out", stem + "_converge")
    plan = _agree(comm, lambda: _plan(args))
    for fam, levels in plan:  # the finest level of each family must fit, before any level runs
        _agree(comm, lambda: _fits_in_memory(comm, config.build(levels[-1][1], config.dumps(levels[-1][1]))))

    def say(msg):
        if root:
            print(msg, flush=True)

    scaling = getattr(args, "dt_scaling", None) or "dx2"
    results = []
    for fam, levels in plan:
        warm = [False]
        runs = []
        for l, (nx, lr) in enumerate(levels):
            rec = _level(comm, args, signals, say, stem, out_dir, fam, levels, warm, nx, lr,
                         f"level {l + 1}/{len(levels)}", os.path.join(out_dir, fam, f"nx{nx}"))
            if not isinstance(rec, dict):
                return rec
            rec["level"] = l
            runs.append(rec)
        nx0, raw0 = levels[0]
        b = _agree(comm, lambda: bias_of(raw0))
        bias_rec = None
        if b is not None and abs(b) > BIAS_MIN:
            # the coarsest level again with k / (1 + b): its difference from the coarsest level is the
            # effect of the kernel's viscosity bias, which every level shares and no difference shows
            braw = bias_raw(raw0, b)
            bias_rec = _level(comm, args, signals, say, stem, out_dir, fam, levels, warm, nx0, braw,
                              f"bias run (k / (1 + b), b = {b:+.2e})", os.path.join(out_dir, fam, f"nx{nx0}_bias"))
            if not isinstance(bias_rec, dict):
                return bias_rec
            bias_rec["bias"] = b
        time_rec = None
        nxf, rawf = levels[-1]
        s0 = raw0["numerics"].get("dt_safety", 1.0)
        if (args.target is not None and scaling == "dx2" and rawf["numerics"].get("dt") == "auto"
                and rawf["numerics"]["dt_safety"] < s0 * (1 - 1e-6)):
            # the finest level again at the base level's margin below its own limit: the difference is the
            # time error's share, which --target uses to trade a larger dt against a finer N_x
            traw = {s: dict(v) if isinstance(v, dict) else v for s, v in rawf.items()}
            traw["numerics"]["dt_safety"] = s0
            time_rec = _level(comm, args, signals, say, stem, out_dir, fam, levels, warm, nxf, traw,
                              f"time-step run (dt_safety {s0:g})", os.path.join(out_dir, fam, f"nx{nxf}_dtlimit"))
            if not isinstance(time_rec, dict):
                return time_rec
        results.append((fam, runs, bias_rec, time_rec))
    code = 0
    if root:  # files only; the other ranks wait for its exit code, so a failure here cannot hang them
        try:
            report = analyse(results, args.ratio, args.target, getattr(args, "dt_scaling", None) or "dx2")
            print_report(report)
            with open(os.path.join(out_dir, "converge.json"), "w") as f:
                json.dump(_jsonable(report), f, indent=1)
            png = os.path.join(out_dir, "converge.png")
            plot(report, png)
            print(f"wrote {os.path.join(out_dir, 'converge.json')} and {png}")
        except (OSError, ValueError, KeyError) as e:
            print(f"parsph: error: cannot analyse the levels in {out_dir}: {e}", file=sys.stderr, flush=True)
            code = EXIT_ERROR
    return comm.bcast(code, root=0)


def _level(comm, args, signals, say, stem, out_dir, fam, levels, warm, nx, lr, what, ldir):
    """Run one level (or reuse it): its record, or an exit code."""
    from argparse import Namespace
    from . import config
    from .solver import GuardError
    root = comm.rank == 0
    # the header names no level index, so a study from another base N_x can reuse this level
    text = f"# parsph converge: {args.config}, family {fam}, N_x = {nx}\n" + config.dumps(lr)
    rec = comm.bcast(_reusable(ldir, text) if root else None, root=0)
    if rec is not None:
        say(f"parsph converge: family {fam}, {what}: N_x = {nx}, reusing {ldir}")
        rec["dir"] = ldir  # the study may have been moved since
        return rec
    if not warm[0]:
        try:  # a coarse level too small for the rank count is bad input on every rank alike
            _agree(comm, lambda: _warm_up(comm, levels[0][1]))
        except GuardError as e:  # raised on every rank alike
            say(f"parsph converge: N_x = {levels[0][0]} ({fam}) is unstable: {e}")
            return EXIT_GUARD
        warm[0] = True
    path = os.path.join(ldir, stem + ".toml")

    def write():
        if root:
            try:
                os.makedirs(ldir, exist_ok=True)
                with open(path, "w") as f:
                    f.write(text)
            except OSError as e:
                raise UsageError(f"cannot write {path}: {e.strerror}") from None
    _agree(comm, write)
    comm.Barrier()
    say(f"parsph converge: family {fam}, {what}: N_x = {nx}")
    timed = {}

    def wrap(out):
        timed["t"] = _TimedOutput(out)
        return timed["t"]
    largs = Namespace(config=path, set=None, out=ldir, force=args.force, restart=None,
                      quiet=True, threads=args.threads, wrap_output=wrap)
    code = _run_reporting(comm, largs, say, signals)
    if code != 0:
        say(f"parsph converge: N_x = {nx} ({fam}, {what}) ended with exit code {code}; stopping")
        return code
    r = np.array(timed["t"].records, dtype=float)
    cpu = np.zeros(len(r))
    comm.Allreduce(np.ascontiguousarray(r[:, 2]), cpu)
    rec = {"family": fam, "Nx": nx, "dir": ldir, "run_file": text,
           "particles": int(r[0, 3]), "time": r[:, 0].tolist(), "steps": r[:, 1].astype(int).tolist(),
           "cpu_s": cpu.tolist(), "ranks": comm.size, "threads": args.threads}
    if root:
        with open(os.path.join(ldir, "level.json"), "w") as f:
            json.dump(rec, f, indent=1)
    return rec


BIAS_MIN = 1e-6  # |b| below this: no bias run (its effect is below any error measured here)


def bias_of(raw):
    """b in nu_eff = (1 + b) nu for a run file's kernel and h/dx (None where it is not computed: 3-D,
    or a scene without viscosity)."""
    from . import config
    cfg = config.build(raw, config.dumps(raw))
    if cfg.k == 0 or not cfg.viscosity:
        return None
    return convergence.kernel_bias(cfg.kernel, cfg.h / cfg.dx, cfg.dim)


def bias_raw(raw, b):
    """The run file with the viscosity k / (1 + b): on a lattice whose operator gives (1 + b) k, the
    flow of viscosity k."""
    out = {s: dict(v) if isinstance(v, dict) else v for s, v in raw.items()}
    out["material"]["k"] = float(out["material"]["k"]) / (1.0 + b)
    return out


def _reusable(ldir, text):
    """The record of a finished level with exactly this run file, else None."""
    try:
        with open(os.path.join(ldir, "level.json")) as f:
            rec = json.load(f)
    except (OSError, ValueError):
        return None
    return rec if rec.get("run_file") == text else None


# ---- analysis (rank 0, files only) -----------------------------------------------
def analyse(results, ratio, target=None, dt_scaling="limit"):
    """Estimates per family and output time from the levels' outputs; the --target choice."""
    from . import config
    from .output import read_profile
    from .scenes import error_scale
    fams = []
    for item in results:
        fam, runs = item[0], item[1]
        bias_rec = item[2] if len(item) > 2 else None
        time_rec = item[3] if len(item) > 3 else None
        profs = [read_profile(r["dir"]) for r in runs]
        bprof = read_profile(bias_rec["dir"]) if bias_rec is not None else None
        tprof = read_profile(time_rec["dir"]) if time_rec is not None else None
        if tprof is not None:
            dt_fine = config.loads(runs[-1]["run_file"]).dt
            dt_lim = config.loads(time_rec["run_file"]).dt
        cfg = config.loads(profs[0]["attrs"]["run_file"])
        field = cfg.scene.error_field
        period = None if cfg.scene.walls else cfg.L
        xc = profs[0]["x"]
        nxs = [r["Nx"] for r in runs]
        times = []
        for i, t in enumerate(profs[0]["time"]):
            t = float(t)
            scale = error_scale(cfg, t)
            on_coarse = [profs[0][field][i]] + [convergence.to_coarse(p["x"], p[field][i], xc, period)
                                                for p in profs[1:]]
            bias = None if bprof is None else np.asarray(bprof[field][i]) - np.asarray(profs[0][field][i])
            est = convergence.estimate(on_coarse, ratio, scale, bias=bias)
            row = {"t": t, "scale": scale, "estimate": est.as_dict(),
                   "cpu_s": [r["cpu_s"][i] for r in runs], "steps": [r["steps"][i] for r in runs]}
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
                dT = (convergence.to_coarse(pf["x"], tprof[field][i], xc, period)
                      - convergence.to_coarse(pf["x"], pf[field][i], xc, period)) / scale
                row["time_effect_max"] = float(np.nanmax(np.abs(dT)))
                row["_T"] = dT[est._ok] / (dt_lim - dt_fine)
            row["_est"] = est
            times.append(row)
        cautions = convergence.times_caution([r["estimate"]["order"] for r in times if r["estimate"]["asymptotic"]])
        fam_rep = {"family": fam, "scene": cfg.scene.name, "field": field, "Nx": nxs,
                   "particles": [r["particles"] for r in runs], "levels": runs, "times": times,
                   "caution": cautions, "bias": None if bias_rec is None else bias_rec["bias"],
                   "bias_run": bias_rec}
        fam_rep["time_run"] = time_rec
        if target is not None and time_rec is not None:
            cfgs = [config.loads(r["run_file"]) for r in runs]
            s0 = cfgs[0].values["numerics"]["dt_safety"]  # the base level's margin below its limit
            measured = [(n, c.limits) for n, c in zip(nxs, cfgs)]
            costs = [r["cpu_s"][-1] for r in runs]

            def dt_limit(n):
                lim = convergence.limit_at(n, measured)
                return None if lim is None else s0 * lim
            best = convergence.predict_setting(
                nxs, [(r["t"], r["_est"], r["_T"]) for r in times], target, (dt_fine, dt_limit),
                lambda n: convergence.cost_at(n, nxs, costs)[0])
            if best[0] is None:
                fam_rep["target"] = {"Nx": None, "why_not": best[1]}
            else:
                n, dt, lim, err, cost = best
                safety = s0 * dt / lim
                fam_rep["target"] = {"Nx": n, "why_not": None, "cpu_s": cost, "predicted_err": err,
                                     "cost_exponent": convergence.cost_at(n, nxs, costs)[1],
                                     "to_time": times[-1]["t"], "set": f"numerics.dt_safety={safety:.4g}"}
        elif target is not None:
            need, why = convergence.predict_nx(nxs, [(r["t"], r["_est"]) for r in times], target)
            fam_rep["target"] = {"Nx": need, "why_not": why}
            if need is not None:
                cost, a = convergence.cost_at(need, nxs, [r["cpu_s"][-1] for r in runs])
                fam_rep["target"].update(cpu_s=cost, cost_exponent=a, to_time=times[-1]["t"])
                if dt_scaling == "dx2":  # the errors were measured with dt ~ dx^2: the setting needs that dt
                    lr = level_raw(tomllib.loads(runs[0]["run_file"]), need, "dx2")["numerics"]
                    fam_rep["target"]["set"] = (f"numerics.dt_safety={lr['dt_safety']:.4g}" if lr["dt"] == "auto"
                                                else f"numerics.dt={lr['dt']:.4g}")
        fams.append(fam_rep)
    report = {"ratio": ratio, "target": target, "families": fams, "dt_scaling": dt_scaling}
    if target is not None:
        ok = [f for f in fams if f["target"]["Nx"] is not None]
        best = min(ok, key=lambda f: f["target"]["cpu_s"]) if ok else None
        report["choice"] = None if best is None else {"family": best["family"], **best["target"]}
    return report


def _fmt(v, spec=".2e"):
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def print_report(rep):
    for fam in rep["families"]:
        if fam.get("bias") is None:
            bias_note = "no bias run (3-D, or no viscosity): an error every level shares is not estimated"
        else:
            bias_note = (f"kernel bias b = {fam['bias']:+.2e} (nu_eff = (1 + b) nu, parsph.kernel_analysis), its "
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


def _jsonable(o):
    if isinstance(o, dict):
        return {k: _jsonable(v) for k, v in o.items() if not k.startswith("_")}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, (np.floating, np.integer)):
        return _jsonable(o.item())
    return o


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
