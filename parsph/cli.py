"""The ``parsph`` command: run, check, plot.

    parsph run CONFIG [--set section.key=value ...] [--out DIR] [--force] [--restart OUTPUT] [--quiet]
    parsph check OUTPUT [--tol 0.02]
    parsph converge CONFIG [--levels 3] [--ratio 2] [--target ERR] [--out DIR] [--family NAME ...] [--dt-scaling dx2|limit]
    parsph plot OUTPUT [--png FILE]

Exit codes: 0 success; 1 ``check`` above tolerance or an unexpected error;
2 bad input (run file, options, output path); 3 a run-time check failed;
130 / 143 stopped by SIGINT / SIGTERM after writing a restart point.
"""
import argparse
import os
import signal
import sys

EXIT_ERROR, EXIT_BAD_INPUT, EXIT_GUARD = 1, 2, 3
EXIT_SIGNAL = {signal.SIGINT: 130, signal.SIGTERM: 143}
# Sections a restart may change; every other key is physics and must match.
RESTART_FREE = ("output", "checks")


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


class _Signals:
    """SIGINT/SIGTERM set a flag that the time loop polls; the step in hand finishes."""

    def __init__(self):
        self.received = None
        for sig in EXIT_SIGNAL:
            signal.signal(sig, self._handle)

    def _handle(self, signum, frame):
        self.received = signum

    def __call__(self):
        """The number of the signal received (0: none)."""
        return int(self.received or 0)

    def release(self):
        """Once the run is over, a signal ends the process at once again: mpirun's SIGTERM to a rank
        still in MPI_Finalize after another rank's non-zero exit must not be swallowed by the flag."""
        for sig in EXIT_SIGNAL:
            signal.signal(sig, signal.SIG_DFL)


def cmd_run(args):
    from mpi4py import MPI
    comm = MPI.COMM_WORLD  # the one place the world communicator is fetched
    root = comm.rank == 0
    signals = _Signals()

    def say(msg):
        if root:
            print(msg, flush=True)

    try:
        return _run_reporting(comm, args, say, signals)
    finally:
        signals.release()


def _run_reporting(comm, args, say, signals):
    """_run, with every way it can end turned into one message and an exit code."""
    from .solver import GuardError, Interrupted
    root = comm.rank == 0
    try:
        return _run(comm, args, say, signals)
    except UsageError as e:
        if root:
            print(f"parsph: error: {e}", file=sys.stderr, flush=True)
        return EXIT_BAD_INPUT
    except GuardError as e:  # raised on every rank alike
        if root:
            print(f"parsph: error: {e}; earlier outputs are intact", file=sys.stderr, flush=True)
        return EXIT_GUARD
    except Interrupted as e:  # raised on every rank alike, with the signal they agreed on
        if root:
            print(f"parsph: {signal.Signals(e.signum).name}: {e}", file=sys.stderr, flush=True)
        return EXIT_SIGNAL.get(e.signum, EXIT_ERROR)
    except Exception as e:  # noqa: BLE001 - any failure must end every rank
        print(f"parsph: error on rank {comm.rank}: {type(e).__name__}: {e}", file=sys.stderr, flush=True)
        if comm.size > 1:
            comm.Abort(EXIT_ERROR)
        return EXIT_ERROR


def _restart_state(cfg, path):
    """The snapshot to continue from, after checking from its attributes alone (no particle
    arrays) that its physics matches ``cfg``: {"attrs": ..., "path": ...} for Simulation,
    whose ranks then read only their own slab's particles (output.read_particles)."""
    from . import config
    from .output import last_snapshot, output_files, read_state
    try:
        files = output_files(path)
        snap = last_snapshot(path) if len(files) != 1 else files[0]
        state = read_state(snap)
        old = config.loads(state["attrs"]["run_file"]).values
    except FileNotFoundError:
        raise UsageError(f"--restart {path}: no such output, or no complete output with particles in it") from None
    except (ValueError, OSError, KeyError, config.ConfigError) as e:
        raise UsageError(f"--restart {path}: not a usable parsph output ({e})") from None
    for section, keys in cfg.values.items():
        if section in RESTART_FREE:
            continue
        for key, value in keys.items():
            if old.get(section, {}).get(key) != value:
                raise UsageError(f"--restart: {section}.{key} = {value!r} differs from {old[section][key]!r} "
                                 f"in {snap}; a restart may change only [output] and [checks]")
    return state


def _set_threads(n):
    """numba threads per rank for the prange loops (results do not depend on the count)."""
    import numba
    most = numba.config.NUMBA_NUM_THREADS
    if not 1 <= n <= most:
        raise UsageError(f"--threads {n}: must be between 1 and {most} (NUMBA_NUM_THREADS, default the core count)")
    numba.set_num_threads(n)


def _run(comm, args, say, signals):
    from . import config
    from .output import Output, output_files
    from .solver import Simulation

    stem = os.path.splitext(os.path.basename(args.config))[0]
    if args.out:
        out_dir = args.out
    elif args.restart:
        out_dir = args.restart if os.path.isdir(args.restart) else os.path.dirname(os.path.abspath(args.restart))
    else:
        out_dir = os.path.join("out", stem)

    def prepare():
        cfg = config.load(args.config, args.set or ())
        state = _restart_state(cfg, args.restart) if args.restart else None
        first = 0 if state is None else int(state["attrs"]["index"]) + 1
        if os.path.isdir(out_dir) and not args.force:
            # unfinished (.part) files are debris of a killed run, not outputs
            taken = [f for f, k in _existing(out_dir, stem) if k >= first and not f.endswith(".part")]
            if taken:
                raise UsageError(f"output {os.path.join(out_dir, taken[0])} exists; "
                                 f"pass --force to overwrite, or choose --out")
        return cfg, state, first

    def make_dir():
        if comm.rank == 0:
            try:
                os.makedirs(out_dir, exist_ok=True)
            except OSError as e:
                raise UsageError(f"cannot create output directory {out_dir}: {e.strerror}") from None

    def writable():
        if not os.access(out_dir, os.W_OK):
            raise UsageError(f"output directory {out_dir} is not writable")

    cfg, state, first = _agree(comm, prepare)
    _agree(comm, lambda: _set_threads(args.threads))
    _agree(comm, lambda: _fits_in_memory(comm, cfg))
    _agree(comm, make_dir)
    _agree(comm, writable)
    if comm.rank == 0:
        for f, k in _existing(out_dir, stem):
            if k >= first and (args.force or f.endswith(".part")):
                os.remove(os.path.join(out_dir, f))
    comm.Barrier()
    sim = _agree(comm, lambda: Simulation(cfg, comm, state=state))
    if not cfg.dt_auto and cfg.dt > min(cfg.limits.values()):
        say(f"parsph: warning: dt = {cfg.dt:g} s is above the stability limit {min(cfg.limits.values()):.3g} s")
    steps = f"dt = {cfg.dt:.4g} s, {cfg.nsteps} steps" if not cfg.dt_auto else \
        f"dt auto ({cfg.dt:.4g} s at theta0, the {min(cfg.limits, key=cfg.limits.get)} limit; recomputed every step)"
    start = f" from t = {sim.t:g} s (step {sim.step})" if state is not None else ""
    say(f"parsph {cfg.values['scene']['name']}: {sim.n_total} particles on {comm.size} rank(s), "
        f"{steps} to t = {cfg.t_end:g} s{start}; "
        f"Re = {cfg.reynolds:.4g}, nu = {cfg.nu:.4g} m^2/s -> {out_dir}/{stem}_NNNN.h5")
    out = Output(comm, out_dir, stem, cfg, sim.n_total, first_index=first)
    if getattr(args, "wrap_output", None) is not None:  # parsph converge times the loop through it
        out = args.wrap_output(out)

    def progress(s, rate, eta):
        of = "" if cfg.dt_auto else f"/{cfg.nsteps}"
        say(f"  step {s.step:>7d}{of}  t = {s.t:.5f} s  {rate:.3g} particle-steps/s  "
            f"left {_fmt_time(eta)}")

    step0 = sim.step
    sim.run(output=out, progress=None if args.quiet else progress, stop_requested=signals)
    total = sim.wall_time
    steps_done = sim.step - step0
    rate = sim.n_total * steps_done / total if total > 0 else float("nan")
    say(f"done: {steps_done} steps in {total:.1f} s ({rate:.3g} particle-steps/s; "
        f"neighbour list built {sim.rebuilds} times)")
    if comm.rank == 0 and output_files(out_dir):
        print_table(out_dir)
    return 0


def _fits_in_memory(comm, cfg):
    """Refuse a run whose particles cannot fit in the memory of the nodes in use."""
    from mpi4py import MPI
    from .config import ConfigError, bytes_per_particle
    mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    hosts = dict(comm.allgather((MPI.Get_processor_name(), mem)))
    have = sum(hosts.values())
    need = cfg.n_particles * bytes_per_particle(cfg)
    if need > 0.8 * have:
        raise ConfigError("numerics.Nx", f"{cfg.n_particles:,} particles need about {need / 1e9:.3g} GB, "
                          f"more than 80% of the {have / 1e9:.3g} GB of memory on {len(hosts)} node(s)")


def _existing(out_dir, stem):
    """(file name, output index) of the run's outputs in out_dir, unfinished ones too."""
    import re
    pat = re.compile(re.escape(stem) + r"_(\d{4,})\.h5(\.part)?$")
    return sorted((f, int(m.group(1))) for f in os.listdir(out_dir) if (m := pat.match(f)))


def _current_scales(p):
    """Per output time, what is left of a decaying flow (the scene's current_scale), else None."""
    from .config import ConfigError, loads
    from .scenes import error_scale
    try:
        cfg = loads(p["attrs"]["run_file"])
    except (ConfigError, KeyError):
        return None
    if cfg.scene.current_scale is None:
        return None
    return [error_scale(cfg, float(t)) for t in p["time"]]


def print_table(path, tol=None):
    """Print the error table of a run's outputs; return the worst max error.

    For a decaying flow the errors are relative to what is left of it at each time."""
    from .output import read_profile
    from .profile import errors
    p = read_profile(path)
    key = p["attrs"].get("error_field", "vy")
    field = {"vy": "v_y", "theta": "theta"}.get(key, "v_y")
    scale = p["attrs"].get("error_scale", p["attrs"].get("V_w", 1.0))
    now = _current_scales(p)
    if now is None:
        print(f"errors of {field} against the reference, relative to {scale:.4g}")
        print(f"{'t [s]':>10} {'max error':>12} {'rms error':>12}")
        rows = [(t, emax, erms, "") for t, emax, erms in zip(p["time"], p["err_max"], p["err_rms"])]
    else:
        print(f"errors of {field} against the reference, relative to the amplitude left at each time "
              f"(initially {scale:.4g})")
        print(f"{'t [s]':>10} {'amplitude':>12} {'max error':>12} {'rms error':>12} {'max / initial':>13}")
        rows = [(t, *errors(f, fe, s), f" {s:>12.4g}", f" {emax:>13.3e}") for t, f, fe, s, emax
                in zip(p["time"], p[key], p[key + "_exact"], now, p["err_max"])]
    worst = 0.0
    for t, emax, erms, amp, *initial in rows:
        flag = "" if tol is None or emax <= tol else "  > tol"
        print(f"{t:>10.4g}{amp} {emax:>12.3e} {erms:>12.3e}{''.join(initial)}{flag}")
        worst = max(worst, emax) if emax == emax else float("nan")
    return worst


def _read(path, fn):
    try:
        return fn(path)
    except (FileNotFoundError, ValueError, OSError) as e:
        raise UsageError(f"cannot read output {path}: {e}") from None


def cmd_check(args):
    worst = _read(args.output, lambda p: print_table(p, args.tol))
    if not worst <= args.tol:
        print(f"parsph check: max error {worst:.3e} above tolerance {args.tol:g}", file=sys.stderr)
        return EXIT_ERROR
    print(f"parsph check: all errors within {args.tol:g}")
    return 0


def reference_lines(p, points=401):
    """The scene's reference at each output time on a fine grid over [0, L] (None where it has none),
    so that the plotted lines reach the plates; p is read_profile's dict."""
    import numpy as np
    from .config import loads
    cfg = loads(p["attrs"]["run_file"])
    field = p["attrs"].get("error_field", "vy")
    x = np.linspace(0.0, p["attrs"]["L"], points)
    lines = [cfg.scene.reference(cfg, x, t)[field]
             if cfg.scene.reference is not None and np.all(np.isfinite(ref)) else None
             for t, ref in zip(p["time"], p[field + "_exact"])]
    return x, lines


def profile_png(first):
    """DIR/<stem>_profile.png for the output file DIR/<stem>_NNNN.h5 (an index of four digits or more)."""
    import re
    stem = re.sub(r"_\d{4,}\.h5$", "", os.path.basename(first))
    return os.path.join(os.path.dirname(first), stem + "_profile.png")


def cmd_plot(args):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from .output import output_files, read_profile
    p = _read(args.output, read_profile)
    first = output_files(args.output)[0]
    png = args.png or profile_png(first)
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    colors = plt.cm.viridis(np.linspace(0, 0.9, max(1, len(p["time"]))))
    L = p["attrs"]["L"]
    field = p["attrs"].get("error_field", "vy")
    x_fine, lines = reference_lines(p)
    for c, t, sim, line in zip(colors, p["time"], p[field], lines):
        if line is not None:
            ax.plot(x_fine / L, line, "-", color=c, lw=1.2)
        ax.plot(p["x"] / L, sim, "o", color=c, ms=3, label=f"t = {t:g} s")
    ax.set_xlabel("x / L")
    ax.set_ylabel({"vy": "v_y [m/s]", "theta": "theta"}[field])
    ax.set_title("SPH (points) against the reference (lines)")
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
    r.add_argument("--out", help="output directory (default out/<run-file name>; with --restart, the restart's)")
    r.add_argument("--force", action="store_true", help="overwrite existing output files")
    r.add_argument("--restart", metavar="OUTPUT",
                   help="continue from the last snapshot of OUTPUT (a directory or one output file)")
    r.add_argument("--quiet", action="store_true", help="no progress lines")
    r.add_argument("--threads", type=int, default=1, metavar="N",
                   help="threads per rank in the particle loops (default 1: one rank per core; "
                        "ranks x threads should not exceed the cores)")
    c = sub.add_parser("check", help="print the error table of a run; exit 1 above --tol")
    c.add_argument("output", help="output directory or file")
    c.add_argument("--tol", type=float, default=0.02, help="largest max error / V_w accepted (default 0.02)")
    cv = sub.add_parser("converge", help="run at several resolutions; estimated error and cost of each "
                                         "(under mpirun for several ranks)")
    cv.add_argument("config", help="run file (TOML): the coarsest level")
    cv.add_argument("--levels", type=int, default=3, help="resolutions N_x, R N_x, R^2 N_x, ... (default 3)")
    cv.add_argument("--ratio", type=int, default=2, help="refinement ratio R (default 2)")
    cv.add_argument("--target", type=float, metavar="ERR",
                    help="predict the cheapest N_x (and --family) with max error <= ERR at every output time")
    cv.add_argument("--out", help="directory of the levels and of converge.json / converge.png "
                                  "(default out/<run-file name>_converge)")
    cv.add_argument("--family", action="append", metavar="NAME",
                    help="numerics to study: given (the run file's; default), fast, accurate, paper "
                         "(the presets'); repeat to compare")
    cv.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE", help="override a run-file key")
    cv.add_argument("--force", action="store_true", help="overwrite a level's outputs that cannot be reused")
    cv.add_argument("--threads", type=int, default=1, metavar="N", help="threads per rank (as for run)")
    cv.add_argument("--dt-scaling", choices=("limit", "dx2"), default="dx2",
                    help="dx2 (default): dt ~ dx^2 from the coarsest level's limit, so the time error falls as "
                         "dx^2 at every level; limit: each level at its own stability limit (cheaper; mixed orders)")
    pl = sub.add_parser("plot", help="PNG of the simulated profiles over the reference")
    pl.add_argument("output", help="output directory or file")
    pl.add_argument("--png", help="PNG path (default next to the outputs)")
    return p


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        if args.command == "run":
            return cmd_run(args)
        if args.command == "converge":
            from .converge import cmd_converge
            return cmd_converge(args)
        return {"check": cmd_check, "plot": cmd_plot}[args.command](args)
    except UsageError as e:
        print(f"parsph: error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
