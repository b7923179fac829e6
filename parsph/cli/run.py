"""``parsph run``: validate on every rank, set up, run the time loop, report, and end with one exit code.

Bad input ends every rank alike with code 2 (:func:`parsph.cli.exits.agree`); a
failed run-time check with 3; SIGINT / SIGTERM after a final snapshot with
130 / 143; anything else on one rank calls ``MPI_Abort``.
"""
import os
import re
import signal
import sys

from .report import print_table
from .exits import EXIT_BAD_INPUT, EXIT_ERROR, EXIT_GUARD, EXIT_SIGNAL, UsageError, agree

# Sections a restart may change; every other key is physics and must match.
RESTART_FREE = ("output", "checks")


class Signals:
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
    signals = Signals()

    def say(msg):
        if root:
            print(msg, flush=True)

    try:
        return run_reporting(comm, args, say, signals)
    finally:
        signals.release()


def run_reporting(comm, args, say, signals):
    """_run, with every way it can end turned into one message and an exit code."""
    from parsph.simulation.solver import GuardError, Interrupted
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


def _out_dir(args, stem):
    """Where the outputs go: --out, else the restart's directory, else out/<run-file name>."""
    if args.out:
        return args.out
    if args.restart:
        return args.restart if os.path.isdir(args.restart) else os.path.dirname(os.path.abspath(args.restart))
    return os.path.join("out", stem)


def _prepare(args, out_dir, stem):
    """The run file, the restart state and the first output index; refuses to overwrite outputs without --force."""
    from parsph.setup import config
    cfg = config.load(args.config, args.set or ())
    state = restart_state(cfg, args.restart) if args.restart else None
    first = 0 if state is None else int(state["attrs"]["index"]) + 1
    if os.path.isdir(out_dir) and not args.force:
        # unfinished (.part) files are debris of a killed run, not outputs
        taken = [f for f, k in _existing(out_dir, stem) if k >= first and not f.endswith(".part")]
        if taken:
            raise UsageError(f"output {os.path.join(out_dir, taken[0])} exists; "
                             f"pass --force to overwrite, or choose --out")
    return cfg, state, first


def _make_dir(comm, out_dir):
    if comm.rank == 0:
        try:
            os.makedirs(out_dir, exist_ok=True)
        except OSError as e:
            raise UsageError(f"cannot create output directory {out_dir}: {e.strerror}") from None


def _writable(out_dir):
    if not os.access(out_dir, os.W_OK):
        raise UsageError(f"output directory {out_dir} is not writable")


def _banner(cfg, sim, comm, state, out_dir, stem):
    steps = f"dt = {cfg.dt:.4g} s, {cfg.nsteps} steps" if not cfg.dt_auto else \
        f"dt auto ({cfg.dt:.4g} s at theta0, the {min(cfg.limits, key=cfg.limits.get)} limit; recomputed every step)"
    start = f" from t = {sim.t:g} s (step {sim.step})" if state is not None else ""
    return (f"parsph {cfg.values['scene']['name']}: {sim.n_total} particles on {comm.size} rank(s), "
            f"{steps} to t = {cfg.t_end:g} s{start}; "
            f"Re = {cfg.reynolds:.4g}, nu = {cfg.nu:.4g} m^2/s -> {out_dir}/{stem}_NNNN.h5")


def _run(comm, args, say, signals):
    from .progress import COMPILING, CompileWatch
    quiet = getattr(args, "quiet", False)
    with CompileWatch(note=None if quiet else lambda: say(f"  {COMPILING}")) as watch:
        return _run_watched(comm, args, say, signals, watch)


def _run_watched(comm, args, say, signals, watch):
    from parsph.output import Output, output_files
    from parsph.simulation.solver import Simulation
    from .progress import Progress

    started = Progress.clock()
    stem = os.path.splitext(os.path.basename(args.config))[0]
    out_dir = _out_dir(args, stem)
    cfg, state, first = agree(comm, lambda: _prepare(args, out_dir, stem))
    agree(comm, lambda: _set_threads(args.threads))
    agree(comm, lambda: fits_in_memory(comm, cfg))
    agree(comm, lambda: _make_dir(comm, out_dir))
    agree(comm, lambda: _writable(out_dir))
    if comm.rank == 0:
        for f, k in _existing(out_dir, stem):
            if k >= first and (args.force or f.endswith(".part")):
                os.remove(os.path.join(out_dir, f))
    comm.Barrier()
    sim = agree(comm, lambda: Simulation(cfg, comm, state=state))
    if not cfg.dt_auto and cfg.dt > min(cfg.limits.values()):
        say(f"parsph: warning: dt = {cfg.dt:g} s is above the stability limit {min(cfg.limits.values()):.3g} s")
    say(_banner(cfg, sim, comm, state, out_dir, stem))
    watch.arm()
    out = Output(comm, out_dir, stem, cfg, sim.n_total, first_index=first)
    if getattr(args, "wrap_output", None) is not None:  # parsph converge times the loop through it
        out = args.wrap_output(out)

    progress = Progress(cfg, sim.n_total, say, watch, started)
    step0 = sim.step
    sim.run(output=out, progress=None if args.quiet else progress, stop_requested=signals)
    say(progress.summary(sim, sim.step - step0))
    if comm.rank == 0 and output_files(out_dir):
        print_table(out_dir)
    return 0


def fits_in_memory(comm, cfg):
    """Refuse a run whose particles cannot fit in the memory of the nodes in use."""
    from mpi4py import MPI
    from parsph.setup.config import ConfigError, bytes_per_particle
    mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    hosts = dict(comm.allgather((MPI.Get_processor_name(), mem)))
    have = sum(hosts.values())
    need = cfg.n_particles * bytes_per_particle(cfg)
    if need > 0.8 * have:
        raise ConfigError("numerics.Nx", f"{cfg.n_particles:,} particles need about {need / 1e9:.3g} GB, "
                          f"more than 80% of the {have / 1e9:.3g} GB of memory on {len(hosts)} node(s)")


def _existing(out_dir, stem):
    """(file name, output index) of the run's outputs in out_dir, unfinished ones too."""
    pat = re.compile(re.escape(stem) + r"_(\d{4,})\.h5(\.part)?$")
    return sorted((f, int(m.group(1))) for f in os.listdir(out_dir) if (m := pat.match(f)))
