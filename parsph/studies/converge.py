"""``parsph converge``: run a scene at several resolutions and estimate each one's error.

    [mpirun -n P] parsph converge CONFIG [--levels L] [--ratio R] [--target ERR] [--out DIR]
                                 [--family NAME ...] [--dt-scaling dx2|limit] [--set S.K=V ...]
                                 [--force] [--threads N]

Level l of a family is the run file with N_x R^l particles across (h / dx
fixed; dt ~ dx^2 from the coarsest level's, or each level at its own limit
with --dt-scaling limit: ``level_run_file``), written as an ordinary run file
DIR/<family>/nx<N_x>/<name>.toml and run by the same code as ``parsph run``,
on the same communicator, one level after another, without particle
snapshots. Two more runs complete a study: the coarsest level with the
viscosity k / (1 + b), b the kernel's viscosity bias at this h / dx (its
effect is an error every level shares: DIR/<family>/nx<N_x>_bias), and,
with --target, the finest level at its stability limit (the time error's
share: DIR/<family>/nx<N_x>_dtlimit). The estimates are
``parsph.studies.estimates``'s; the cost of a level is the process CPU time of its
time loop summed over ranks, up to each output time. A level whose
``level.json`` records the same run file is reused, so a stopped study
resumes.

Writes DIR/converge.json and DIR/converge.png (error against cost).
"""
import json
import os
import sys
import time

import numpy as np

from parsph.setup import config
from parsph.setup.runfile import RunFile
from . import estimates
from .converge_report import analyse, jsonable, plot, print_report
from parsph.cli.run import Signals, fits_in_memory, run_reporting
from parsph.cli.exits import EXIT_BAD_INPUT, EXIT_ERROR, EXIT_GUARD
from parsph.errors import ConfigError, GuardError, UsageError, agree

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


def family_run_file(run_file, family):
    """The run file with a family's numerics (dt "auto" for a preset family)."""
    if family == "given":
        return run_file
    f = FAMILIES[family]
    return (run_file.drop("numerics", "h").set("numerics", kernel=f["kernel"], h_over_dx=f["h_over_dx"], dt="auto")
            .set("walls", beta_max=f["beta_max"]))


DT_SCALINGS = ("limit", "dx2")


def level_run_file(run_file, nx, dt_scaling="limit"):
    """Level N_x of a run file: h / dx kept, dt by ``dt_scaling``.

    ``"limit"``: ``dt = "auto"`` kept (each level at its own stability limit, times the
    run file's dt_safety), a fixed dt scaled with the limit (its margin kept). Cheapest,
    but the binding limit can change between levels (advection ~ dx, damping ~ 1,
    viscous ~ dx^2), so the first-order time error of Eqs. (6)-(7) is then not one
    power of dx across them. ``"dx2"``: dt_l = dt_0 (N_x0 / N_x)^2 from the base level's
    (its automatic dt at theta_0 for "auto", kept automatic with the dt_safety that gives
    dt_l at theta_0, so it still follows the state), so the time error falls as dx^2 at
    every level; every limit shrinks at most as dx^2, so dt_l stays within them.
    """
    if dt_scaling not in DT_SCALINGS:
        raise ValueError(f"dt_scaling {dt_scaling!r}: one of {DT_SCALINGS}")
    base = config.build(run_file)
    out = run_file.set("numerics", Nx=int(nx))
    if out.get("numerics", "h") is not None:
        out = out.set("numerics", h=base.h * base.Nx / nx)
    lim = min(config.build(out.set("numerics", dt="auto")).limits.values())
    if dt_scaling == "dx2":
        dt = float(base.dt) * (base.Nx / nx) ** 2
        if out.get("numerics", "dt") == "auto":
            out = out.set("numerics", dt_safety=min(1.0, dt / lim))
        else:
            out = out.set("numerics", dt=dt)
    elif out.get("numerics", "dt") != "auto":
        out = out.set("numerics", dt=float(base.dt) * lim / min(base.limits.values()))
    return out.set("output", snapshots=False)


def _plan(args):
    """[(family, [(N_x, run file), ...])], validated on every rank."""
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
    base = RunFile.read(args.config).override(args.set or ())
    plan = []
    for fam in dict.fromkeys(families):
        frf = family_run_file(base, fam)
        try:
            # the family's base level validated first: its errors name the run file's keys
            nx0 = config.build(frf).Nx
            scaling = getattr(args, "dt_scaling", None) or "dx2"
            levels = [(nx0 * args.ratio ** l, level_run_file(frf, nx0 * args.ratio ** l, scaling))
                      for l in range(args.levels)]
            for nx, lr in levels:
                cfg = config.build(lr)
        except ConfigError as e:
            raise UsageError(str(e) if fam == "given" else f"family {fam}: {e}") from None
        if len(cfg.output_times) == 0:
            raise UsageError("output.times is empty: the levels are compared at the output times")
        plan.append((fam, levels))
    return plan


def cmd_converge(args):
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    signals = Signals()
    try:
        return _converge(comm, args, signals)
    except UsageError as e:
        if comm.rank == 0:
            print(f"parsph: error: {e}", file=sys.stderr, flush=True)
        return EXIT_BAD_INPUT
    finally:
        signals.release()


def _warm_up(comm, run_file):
    """A few steps of a level, untimed, so that loading numba's compiled code is not counted as cost."""
    from parsph.simulation.solver import Simulation
    cfg = config.build(run_file)
    Simulation(config.build(run_file.set("output", t_end=2.5 * cfg.dt, times=[])), comm).run()


def _converge(comm, args, signals):
    """The study: check every family's finest level fits, run each family, report."""
    root = comm.rank == 0
    stem = os.path.splitext(os.path.basename(args.config))[0]
    out_dir = args.out or os.path.join("out", stem + "_converge")
    plan = agree(comm, lambda: _plan(args))
    for fam, levels in plan:  # the finest level of each family must fit, before any level runs
        agree(comm, lambda: fits_in_memory(comm, config.build(levels[-1][1])))

    def say(msg):
        if root:
            print(msg, flush=True)

    scaling = getattr(args, "dt_scaling", None) or "dx2"
    results = []
    for fam, levels in plan:
        res = _family(comm, args, signals, say, stem, out_dir, fam, levels, scaling)
        if not isinstance(res, tuple):
            return res
        results.append(res)
    return _report(comm, args, results, out_dir, scaling)


def _family(comm, args, signals, say, stem, out_dir, fam, levels, scaling):
    """A family's levels, its bias run and its time-step run: (fam, runs, bias, time), or an exit code."""
    warm = [False]
    runs = []
    for l, (nx, lr) in enumerate(levels):
        rec = _level(comm, args, signals, say, stem, out_dir, fam, levels, warm, nx, lr,
                     f"level {l + 1}/{len(levels)}", os.path.join(out_dir, fam, f"nx{nx}"))
        if not isinstance(rec, dict):
            return rec
        rec["level"] = l
        runs.append(rec)
    nx0, rf0 = levels[0]
    b = agree(comm, lambda: bias_of(rf0))
    bias_rec = None
    if b is not None and abs(b) > BIAS_MIN:
        # the coarsest level again with k / (1 + b): its difference from the coarsest level is the
        # effect of the kernel's viscosity bias, which every level shares and no difference shows
        bias_rec = _level(comm, args, signals, say, stem, out_dir, fam, levels, warm, nx0, bias_run_file(rf0, b),
                          f"bias run (k / (1 + b), b = {b:+.2e})", os.path.join(out_dir, fam, f"nx{nx0}_bias"))
        if not isinstance(bias_rec, dict):
            return bias_rec
        bias_rec["bias"] = b
    time_rec = None
    nxf, rff = levels[-1]
    s0 = rf0.get("numerics", "dt_safety", 1.0)
    if (args.target is not None and scaling == "dx2" and rff.get("numerics", "dt") == "auto"
            and rff.get("numerics", "dt_safety") < s0 * (1 - 1e-6)):
        # the finest level again at the base level's margin below its own limit: the difference is the
        # time error's share, which --target uses to trade a larger dt against a finer N_x
        time_rec = _level(comm, args, signals, say, stem, out_dir, fam, levels, warm, nxf,
                          rff.set("numerics", dt_safety=s0),
                          f"time-step run (dt_safety {s0:g})", os.path.join(out_dir, fam, f"nx{nxf}_dtlimit"))
        if not isinstance(time_rec, dict):
            return time_rec
    return fam, runs, bias_rec, time_rec


def _report(comm, args, results, out_dir, scaling):
    """Rank 0 analyses the levels and writes converge.json and the PNG; every rank gets its exit code."""
    code = 0
    if comm.rank == 0:  # files only; the other ranks wait for its exit code, so a failure here cannot hang them
        try:
            report = analyse(results, args.ratio, args.target, scaling)
            print_report(report)
            with open(os.path.join(out_dir, "converge.json"), "w") as f:
                json.dump(jsonable(report), f, indent=1)
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
    root = comm.rank == 0
    # the header names no level index, so a study from another base N_x can reuse this level
    text = f"# parsph converge: {args.config}, family {fam}, N_x = {nx}\n" + lr.dump()
    rec = comm.bcast(_reusable(ldir, text) if root else None, root=0)
    if rec is not None:
        say(f"parsph converge: family {fam}, {what}: N_x = {nx}, reusing {ldir}")
        rec["dir"] = ldir  # the study may have been moved since
        return rec
    if not warm[0]:
        try:  # a coarse level too small for the rank count is bad input on every rank alike
            agree(comm, lambda: _warm_up(comm, levels[0][1]))
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
    agree(comm, write)
    comm.Barrier()
    say(f"parsph converge: family {fam}, {what}: N_x = {nx}")
    timed = {}

    def wrap(out):
        timed["t"] = _TimedOutput(out)
        return timed["t"]
    largs = Namespace(config=path, set=None, out=ldir, force=args.force, restart=None,
                      quiet=True, threads=args.threads, wrap_output=wrap)
    code = run_reporting(comm, largs, say, signals)
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


def bias_of(run_file):
    """b in nu_eff = (1 + b) nu for a run file's kernel, h/dx and lattice spacings (None for a scene
    without viscosity)."""
    cfg = config.build(run_file)
    if cfg.k == 0 or not cfg.viscosity:
        return None
    return estimates.kernel_bias(cfg.kernel, cfg.h / cfg.dx, cfg.dim, dy=cfg.dy / cfg.dx, dz=cfg.dz / cfg.dx)


def bias_run_file(run_file, b):
    """The run file with the viscosity k / (1 + b): on a lattice whose operator gives (1 + b) k, the
    flow of viscosity k."""
    return run_file.set("material", k=float(run_file.get("material", "k")) / (1.0 + b))


def _reusable(ldir, text):
    """The record of a finished level with exactly this run file, else None."""
    try:
        with open(os.path.join(ldir, "level.json")) as f:
            rec = json.load(f)
    except (OSError, ValueError):
        return None
    return rec if rec.get("run_file") == text else None
