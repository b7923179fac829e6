"""The ``parsph`` command: run, check, plot.

    parsph run CONFIG [--set section.key=value ...] [--out DIR] [--force]
    parsph check OUTPUT [--tol 0.02]
    parsph plot OUTPUT [--png FILE]

Exit codes: 0 success; 1 ``check`` above tolerance or an unexpected error;
2 bad input (run file, options, output path); 3 a run-time check failed.
"""
import argparse
import os
import sys
import time

EXIT_BAD_INPUT, EXIT_GUARD = 2, 3


class UsageError(Exception):
    """Bad command-line input (not the run file)."""


def _fmt_time(s):
    s = int(round(s))
    return f"{s // 3600}h{s % 3600 // 60:02d}m" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"


def _agree(comm, fn):
    """Run fn on every rank; if it raises a bad-input error anywhere, raise it everywhere.

    Validation must end every rank alike, or the ranks that passed would wait
    forever in the first collective call.
    """
    from .config import ConfigError
    from .decomposition import DecompositionError
    err = None
    try:
        result = fn()
    except (ConfigError, DecompositionError, UsageError) as e:
        err, result = str(e), None
    errs = comm.allgather(err)
    first = next((e for e in errs if e is not None), None)
    if first is not None:
        raise UsageError(first)
    return result


def cmd_run(args):
    from mpi4py import MPI
    comm = MPI.COMM_WORLD  # the one place the world communicator is fetched
    root = comm.rank == 0

    def say(msg):
        if root:
            print(msg, flush=True)

    try:
        return _run(comm, args, say)
    except UsageError as e:
        if root:
            print(f"parsph: error: {e}", file=sys.stderr, flush=True)
        return EXIT_BAD_INPUT
    except Exception as e:  # noqa: BLE001 - any failure must end every rank
        from .solver import GuardError
        if isinstance(e, GuardError):  # raised on every rank alike
            if root:
                print(f"parsph: error: {e}", file=sys.stderr, flush=True)
            return EXIT_GUARD
        print(f"parsph: error on rank {comm.rank}: {type(e).__name__}: {e}", file=sys.stderr, flush=True)
        if comm.size > 1:
            comm.Abort(1)
        return 1


def _run(comm, args, say):
    from . import config
    from .output import Output
    from .solver import Simulation

    stem = os.path.splitext(os.path.basename(args.config))[0]
    out_dir = args.out or os.path.join("out", stem)
    path = os.path.join(out_dir, stem + ".h5")

    def prepare():
        cfg = config.load(args.config, args.set or ())
        if os.path.exists(path) and not args.force:
            raise UsageError(f"output {path} exists; pass --force to overwrite it")
        if comm.rank == 0:
            try:
                os.makedirs(out_dir, exist_ok=True)
            except OSError as e:
                raise UsageError(f"cannot create output directory {out_dir}: {e.strerror}") from None
        return cfg

    def writable():
        if not os.access(out_dir, os.W_OK):
            raise UsageError(f"output directory {out_dir} is not writable")

    cfg = _agree(comm, prepare)
    _agree(comm, writable)
    sim = _agree(comm, lambda: Simulation(cfg, comm))
    if cfg.dt > min(cfg.limits.values()):
        say(f"parsph: warning: dt = {cfg.dt:g} s is above the stability limit {min(cfg.limits.values()):.3g} s")
    say(f"parsph {cfg.values['scene']['name']}: {sim.n_total} particles on {comm.size} rank(s), "
        f"dt = {cfg.dt:.4g} s, {cfg.nsteps} steps to t = {cfg.t_end:g} s; "
        f"Re = {cfg.reynolds:.4g}, nu = {cfg.nu:.4g} m^2/s -> {path}")
    out = Output(comm, path, cfg, sim)

    def progress(s, rate, eta):
        say(f"  step {s.step:>7d}/{cfg.nsteps}  t = {s.t:.5f} s  {rate:.3g} particle-steps/s  "
            f"left {_fmt_time(eta)}")

    try:
        sim.run(output=out, progress=progress if not args.quiet else None)
    finally:
        out.close()
    total = sim.wall_time
    rate = sim.n_total * cfg.nsteps / total if total > 0 else float("nan")
    say(f"done: {cfg.nsteps} steps in {total:.1f} s ({rate:.3g} particle-steps/s)")
    if comm.rank == 0 and len(cfg.output_times):
        print_table(path)
    return 0


def print_table(path, tol=None):
    """Print the error table of an output file; return the worst max error."""
    from .output import read_profile
    p = read_profile(path)
    print(f"{'t [s]':>10} {'max |err|/V_w':>14} {'rms err/V_w':>12}")
    worst = 0.0
    for t, emax, erms in zip(p["time"], p["err_max"], p["err_rms"]):
        flag = "" if tol is None or emax <= tol else "  > tol"
        print(f"{t:>10.4g} {emax:>14.3e} {erms:>12.3e}{flag}")
        worst = max(worst, emax)
    return worst


def _output_path(arg):
    if os.path.isdir(arg):
        files = sorted(f for f in os.listdir(arg) if f.endswith(".h5"))
        if len(files) != 1:
            raise UsageError(f"{arg} holds {len(files)} .h5 files; name one")
        return os.path.join(arg, files[0])
    if not os.path.exists(arg):
        raise UsageError(f"no such output: {arg}")
    return arg


def cmd_check(args):
    path = _output_path(args.output)
    worst = print_table(path, args.tol)
    if worst != worst or worst > args.tol:
        print(f"parsph check: max error {worst:.3e} above tolerance {args.tol:g}", file=sys.stderr)
        return 1
    print(f"parsph check: all errors within {args.tol:g}")
    return 0


def cmd_plot(args):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from .output import read_profile
    path = _output_path(args.output)
    p = read_profile(path)
    png = args.png or os.path.splitext(path)[0] + "_profile.png"
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    colors = plt.cm.viridis(__import__("numpy").linspace(0, 0.9, max(1, len(p["time"]))))
    L = p["attrs"]["L"]
    for c, t, vy, ve in zip(colors, p["time"], p["vy"], p["vy_exact"]):
        ax.plot(p["x"] / L, ve, "-", color=c, lw=1.2)
        ax.plot(p["x"] / L, vy, "o", color=c, ms=3, label=f"t = {t:g} s")
    ax.set_xlabel("x / L")
    ax.set_ylabel("v_y [m/s]")
    ax.set_title("SPH (points) against Eq. (8) (lines)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    print(f"wrote {png}")
    return 0


def build_parser():
    p = argparse.ArgumentParser(prog="parsph", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a case (under mpirun for several ranks)")
    r.add_argument("config", help="run file (TOML)")
    r.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE", help="override a run-file key")
    r.add_argument("--out", help="output directory (default out/<run-file name>)")
    r.add_argument("--force", action="store_true", help="overwrite an existing output file")
    r.add_argument("--quiet", action="store_true", help="no progress lines")
    c = sub.add_parser("check", help="print the error table of an output; exit 1 above --tol")
    c.add_argument("output", help="output file or directory")
    c.add_argument("--tol", type=float, default=0.02, help="largest max error / V_w accepted (default 0.02)")
    pl = sub.add_parser("plot", help="PNG of the simulated profiles over the reference")
    pl.add_argument("output", help="output file or directory")
    pl.add_argument("--png", help="PNG path (default next to the output file)")
    return p


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        if args.command == "run":
            return cmd_run(args)
        return {"check": cmd_check, "plot": cmd_plot}[args.command](args)
    except UsageError as e:
        print(f"parsph: error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
