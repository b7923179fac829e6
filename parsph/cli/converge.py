"""``parsph converge``: run a scene at several resolutions and estimate each one's error.

    [mpirun -n P] parsph converge CONFIG [--levels L] [--ratio R] [--target ERR] [--out DIR]
                                 [--family NAME ...] [--dt-scaling dx2|limit] [--set S.K=V ...]
                                 [--force] [--threads N]

The options checked and the plan validated on every rank, the runs
(:class:`parsph.studies.converge.Study`: each one what ``parsph run`` runs),
then rank 0 writes DIR/converge.json and DIR/converge.png (error against
cost: :mod:`parsph.studies.converge_report`). Exit codes as ``parsph run``'s;
1 where the analysis fails.
"""
import os
import sys

from parsph.errors import ConfigError, UsageError, agree
from .exits import EXIT_ERROR
from .world import reporting, world_command


def cmd_converge(args):
    return world_command(lambda comm, say, signals: _converge(comm, args, say, signals))


def _plan(args):
    """[FamilyPlan, ...] of the options, validated (UsageError)."""
    from parsph.setup import config
    from parsph.setup.runfile import RunFile
    from parsph.studies.levels import FAMILIES, plan_family
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
    plans = []
    for fam in dict.fromkeys(families):
        try:
            plan = plan_family(base, fam, args.levels, args.ratio, args.dt_scaling)
        except ConfigError as e:
            raise UsageError(str(e) if fam == "given" else f"family {fam}: {e}") from None
        if len(config.build(plan.levels[-1].run_file).output_times) == 0:
            raise UsageError("output.times is empty: the levels are compared at the output times")
        _same_layer(plan)
        plans.append(plan)
    return plans


def _same_layer(plan):
    """A layer scene's levels start from one layer: scene.height (fixed in metres) a whole number of the
    coarsest level's dx, since the lattice fills round(H0 / dx) columns (UsageError naming scene.height)."""
    from parsph.setup import config
    from parsph.setup.scenes import layer
    cfgs = [config.build(level.run_file) for level in plan.levels]
    if not cfgs[0].scene.free_surface:
        return
    heights = [layer.layer_height(c) for c in cfgs]
    if max(heights) - min(heights) > 1e-9 * max(heights):
        c = cfgs[0]
        raise UsageError(f"scene.height: {layer.height(c):g} m is not a whole number of the coarsest level's "
                         f"dx = {c.dx:g} m, so the levels' layers would differ "
                         f"({', '.join(f'{h:g}' for h in heights)} m): give a multiple of it")


def _converge(comm, args, say, signals):
    """The study: check every family's finest level fits, run each family, report."""
    from parsph.setup import config
    from parsph.simulation.case import fits_in_memory
    from parsph.studies.converge import Study
    stem = os.path.splitext(os.path.basename(args.config))[0]
    out_dir = args.out or os.path.join("out", stem + "_converge")
    plans = agree(comm, lambda: _plan(args))
    for plan in plans:  # the finest level of each family must fit, before any level runs
        agree(comm, lambda: fits_in_memory(comm, config.build(plan.levels[-1].run_file)))
    study = Study(comm, plans, args.config, stem, out_dir, time_runs=args.target is not None,
                  dt_scaling=args.dt_scaling, threads=args.threads, force=args.force, say=say,
                  stop_requested=signals)
    results = []
    code = reporting(comm, lambda: results.extend(study.run()))
    if code:
        say(f"parsph converge: {study.running} ended with exit code {code}; stopping")
        return code
    return _report(comm, args, results, out_dir)


def _report(comm, args, results, out_dir):
    """Rank 0 analyses the levels and writes converge.json and the PNG; every rank gets its exit code."""
    from parsph.studies.converge_report import analyse, print_report, write_report
    code = 0
    if comm.rank == 0:  # files only; the other ranks wait for its exit code, so a failure here cannot hang them
        try:
            report = analyse(results, args.ratio, args.target, args.dt_scaling)
            print_report(report)
            path, png = write_report(report, out_dir)
            print(f"wrote {path} and {png}")
        except (OSError, ValueError, KeyError) as e:
            print(f"parsph: error: cannot analyse the levels in {out_dir}: {e}", file=sys.stderr, flush=True)
            code = EXIT_ERROR
    return comm.bcast(code, root=0)
