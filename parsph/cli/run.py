"""``parsph run``: validate on every rank, run the case (:func:`parsph.simulation.case.run_case`), print the
error table (and a layer scene's check, :mod:`.layer_report`, as ``parsph check`` prints them), and end with one
exit code.

Bad input ends every rank alike with code 2 (:func:`parsph.errors.agree`); a
failed run-time check with 3; SIGINT / SIGTERM after a final snapshot with
130 / 143; anything else on one rank calls ``MPI_Abort`` (:func:`parsph.cli.world.reporting`).
"""
import os

from parsph.errors import ConfigError, UsageError, agree
from .report import print_outputs
from .world import world_command

# Sections a restart may change; every other key is physics and must match.
RESTART_FREE = ("output", "checks")


def cmd_run(args):
    return world_command(lambda comm, say, signals: _run(comm, args, say, signals))


def restart_state(cfg, path):
    """The snapshot to continue from, after checking from its attributes alone (no particle
    arrays) that its physics matches ``cfg``: {"attrs": ..., "path": ...} for Simulation,
    whose ranks then read only their own slab's particles (output.read_particles)."""
    from parsph.setup import config
    from parsph.output import last_snapshot, output_files, read_state
    try:
        files = output_files(path)
        snap = last_snapshot(path) if len(files) != 1 else files[0]
        state = read_state(snap)
        old = config.loads(state["attrs"]["run_file"]).values
    except FileNotFoundError:
        raise UsageError(f"--restart {path}: no such output, or no complete output with particles in it") from None
    except (ValueError, OSError, KeyError, ConfigError) as e:
        raise UsageError(f"--restart {path}: not a usable parsph output ({e})") from None
    for section, keys in cfg.values.items():
        if section in RESTART_FREE:
            continue
        for key, value in keys.items():
            if old.get(section, {}).get(key) != value:
                raise UsageError(f"--restart: {section}.{key} = {value!r} differs from {old[section][key]!r} "
                                 f"in {snap}; a restart may change only [output] and [checks]")
    return state


def _out_dir(args, stem):
    """Where the outputs go: --out, else the restart's directory, else out/<run-file name>."""
    if args.out:
        return args.out
    if args.restart:
        return args.restart if os.path.isdir(args.restart) else os.path.dirname(os.path.abspath(args.restart))
    return os.path.join("out", stem)


def _prepare(args):
    """The run file with its overrides, and the restart state."""
    from parsph.setup import config
    cfg = config.load(args.config, args.set or ())
    return cfg, restart_state(cfg, args.restart) if args.restart else None


def _run(comm, args, say, signals):
    from parsph.output import output_files
    from parsph.simulation.case import run_case
    from .progress import COMPILING, CompileWatch, Progress

    started = Progress.clock()
    stem = os.path.splitext(os.path.basename(args.config))[0]
    out_dir = _out_dir(args, stem)
    with CompileWatch(note=None if args.quiet else lambda: say(f"  {COMPILING}")) as watch:
        cfg, state = agree(comm, lambda: _prepare(args))
        report = _Report(cfg, say, watch, started, args.quiet)
        run_case(comm, cfg, out_dir, stem, state=state, force=args.force, threads=args.threads, progress=report,
                 stop_requested=signals, say=say, report=report)
    if comm.rank == 0 and output_files(out_dir):
        print_outputs(out_dir)
    return 0


class _Report:
    """What ``parsph run`` prints of the loop: progress lines from steady steps (:class:`.progress.Progress`),
    a note while numba compiles (the CompileWatch, armed once the banner is out), the summary."""

    def __init__(self, cfg, say, watch, started, quiet):
        self.cfg, self.say, self.watch, self.started, self.quiet = cfg, say, watch, started, quiet
        self.progress = None

    def start(self, sim):
        from .progress import Progress
        self.watch.arm()
        self.progress = Progress(self.cfg, sim.n_total, self.say, self.watch, self.started)

    def __call__(self, sim, *_):
        if not self.quiet:
            self.progress(sim)

    def summary(self, sim, steps_done):
        return self.progress.summary(sim, steps_done)
