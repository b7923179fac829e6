"""One case from a validated run to its output files (:func:`run_case`): the library call that ``parsph run``
and every run of ``parsph converge`` make, and whether a run fits the machine (memory, rank count).

Collective: every rank calls it with the same arguments. Bad input (the output directory, the memory,
the threads, the decomposition) raises :class:`parsph.errors.UsageError` on every rank alike; a failed
run-time check raises GuardError and a stop signal Interrupted, each on every rank alike.
"""
import os
import re
import time
from dataclasses import dataclass

import numba
from mpi4py import MPI

from parsph.errors import ConfigError, UsageError, agree
from parsph.output import Output
from parsph.parallel import slabs
from parsph.physics.kernels import get_kernel
from parsph.setup.memory import bytes_per_particle
from parsph.sph.cells import grid_for
from .solver import Simulation


@dataclass(frozen=True)
class OutputTime:
    """An output written: its time [s] and step, and the process CPU seconds of this rank's time loop
    up to it (before the file is written)."""
    t: float
    step: int
    cpu_s: float


@dataclass(frozen=True)
class CaseResult:
    """What a case did: the simulation at its end, the steps, wall and process CPU seconds (this rank's)
    of this call's loop, and each output written."""
    sim: Simulation
    steps: int
    wall_s: float
    cpu_s: float
    outputs: tuple

    @property
    def rate(self):
        """Particle-steps per wall second of the loop."""
        return self.sim.n_total * self.steps / self.wall_s if self.wall_s > 0 else float("nan")


class _Timed:
    """A run's Output, recording an OutputTime before each file it writes."""

    def __init__(self, out):
        self.out = out
        self.times = []
        self.cpu0 = time.process_time()

    def __call__(self, frame, **kw):
        self.times.append(OutputTime(frame.t, frame.step, time.process_time() - self.cpu0))
        return self.out(frame, **kw)


def run_case(comm, cfg, out_dir, stem, *, state=None, force=False, threads=1, progress=None,
             stop_requested=None, say=None, report=None):
    """Run ``cfg`` on ``comm`` to its end, writing ``out_dir/<stem>_NNNN.h5`` at its output times.

    ``state``: a restart's (``parsph.cli.run.restart_state``), whose outputs continue its numbering;
    ``force``: overwrite earlier outputs (else refused); ``threads``: numba threads per rank;
    ``progress(sim, rate, eta)`` and ``stop_requested()`` go to :meth:`Simulation.run`;
    ``say(message)``: the warnings, the banner and the summary line (rank 0's, say);
    ``report``: ``start(sim)`` once the banner is out, ``summary(sim, steps)`` the summary line.
    """
    say = say or (lambda msg: None)
    first = 0 if state is None else int(state["attrs"]["index"]) + 1
    agree(comm, lambda: _refuse_overwrite(out_dir, stem, first, force))
    agree(comm, lambda: set_threads(threads))
    agree(comm, lambda: fits_in_memory(comm, cfg, threads))
    agree(comm, lambda: _make_dir(comm, out_dir))
    agree(comm, lambda: _writable(out_dir))
    if comm.rank == 0:
        for f, k in _existing(out_dir, stem):
            if k >= first and (force or f.endswith(".part")):
                os.remove(os.path.join(out_dir, f))
    comm.Barrier()
    sim = agree(comm, lambda: Simulation(cfg, comm, state=state))
    if not cfg.dt_auto and cfg.dt > min(cfg.limits.values()):
        say(f"parsph: warning: dt = {cfg.dt:g} s is above the stability limit {min(cfg.limits.values()):.3g} s")
    if cfg.scene.free_surface:
        from parsph.setup.scenes import layer
        for line in layer.wallis_warnings(cfg):
            say(line)
    say(banner(cfg, sim, comm, state, out_dir, stem))
    if not sim.native:
        say(f"parsph: note: the step's messages go through mpi4py, step by step ({sim.native_why})")
    if report is not None:
        report.start(sim)
    out = _Timed(Output(comm, out_dir, stem, cfg, sim.n_total, first_index=first))
    step0, cpu0 = sim.step, time.process_time()
    sim.run(output=out, progress=progress, stop_requested=stop_requested)
    result = CaseResult(sim, sim.step - step0, sim.wall_time, time.process_time() - cpu0, tuple(out.times))
    # the walls' backstop (collective): a layer's grains put back on a plate, said where it acted
    reflected = sim.reflections()
    tail = f"; a grain put back on a plate {reflected} times (walls.reflect)" if reflected else ""
    if report is not None:
        say(report.summary(sim, result.steps) + tail)
    else:
        say(f"done: {result.steps} steps in {result.wall_s:.1f} s ({result.rate:.3g} particle-steps/s; "
            f"neighbour list built {sim.rebuilds} times{tail})")
    return result


def banner(cfg, sim, comm, state, out_dir, stem):
    """What a run starts with: scene, particles, ranks, steps and where the outputs go, with the scene's scales:
    Re and nu in one line (a channel, a box), or for a layer on the floor (sedimentation, fluidized_bed) two more
    lines of its own (:func:`parsph.setup.scenes.layer.describe`: theta0, H0, u_t, tau, U, U_mf, Wallis's
    margin), where Re = V_w L / nu would read like a particle Reynolds number and mean nothing."""
    steps = f"dt = {cfg.dt:.4g} s, {cfg.nsteps} steps" if not cfg.dt_auto else \
        f"dt auto ({cfg.dt:.4g} s at theta0, the {min(cfg.limits, key=cfg.limits.get)} limit; recomputed every step)"
    start = f" from t = {sim.t:g} s (step {sim.step})" if state is not None else ""
    head = (f"parsph {cfg.values['scene']['name']}: {sim.n_total} particles on {comm.size} rank(s), "
            f"{steps} to t = {cfg.t_end:g} s{start}")
    if cfg.scene.free_surface:
        from parsph.setup.scenes import layer
        return "\n".join([f"{head} -> {out_dir}/{stem}_NNNN.h5"] + layer.describe(cfg))
    return f"{head}; Re = {cfg.reynolds:.4g}, nu = {cfg.nu:.4g} m^2/s -> {out_dir}/{stem}_NNNN.h5"


def max_ranks(cfg):
    """The largest rank count whose slabs hold their ghost rows (what ``parsph run`` accepts)."""
    grid = grid_for(cfg, get_kernel(cfg.kernel, cfg.dim))
    return slabs.max_ranks(cfg.Ly_ring, grid.cutoff, grid.m)


def fits_in_memory(comm, cfg, threads=1):
    """Refuse a run whose particles cannot fit in the memory of the nodes in use (``threads`` per rank)."""
    mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    hosts = dict(comm.allgather((MPI.Get_processor_name(), mem)))
    have = sum(hosts.values())
    need = cfg.n_particles * bytes_per_particle(cfg, threads)
    if need > 0.8 * have:
        raise ConfigError("numerics.Nx", f"{cfg.n_particles:,} particles need about {need / 1e9:.3g} GB, "
                          f"more than 80% of the {have / 1e9:.3g} GB of memory on {len(hosts)} node(s)")


def set_threads(n):
    """numba threads per rank for the prange loops (results do not depend on the count)."""
    most = numba.config.NUMBA_NUM_THREADS
    if not 1 <= n <= most:
        raise UsageError(thread_limit(n, most))
    numba.set_num_threads(n)


def thread_limit(n, most, env=None, usable=None, cores=None):
    """The one line refusing ``--threads n`` above numba's ``most``, saying where the limit comes from:
    NUMBA_NUM_THREADS in the environment, else the cores this process may run on (its CPU affinity, which
    numba counts), naming the launcher's binding and its remedy where that is fewer than the machine's cores
    (Open MPI binds each rank to one core when it starts 2 ranks or fewer). ``env``, ``usable`` and ``cores``
    default to the process's own (the environment's NUMBA_NUM_THREADS, len(os.sched_getaffinity(0)),
    os.cpu_count())."""
    env = os.environ.get("NUMBA_NUM_THREADS") if env is None else env
    if usable is None:
        usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    cores = os.cpu_count() if cores is None else cores
    head = f"--threads {n}: must be between 1 and {most}"
    if env:
        return f"{head}: NUMBA_NUM_THREADS={env} in the environment sets it"
    if n > most and usable < cores:
        return (f"{head}: this process may run on {usable} of the machine's {cores} cores (its CPU affinity: the "
                f"launcher bound it; Open MPI binds each rank to one core by default); start it with "
                f"'mpirun --bind-to none' (Open MPI; or give each rank its cores, '--map-by slot:pe={n}')")
    return f"{head} (the cores this process may run on; NUMBA_NUM_THREADS sets another limit)"


def _refuse_overwrite(out_dir, stem, first, force):
    """Outputs from index ``first`` on are not overwritten without ``force``; unfinished (.part) files
    are debris of a killed run, not outputs."""
    if os.path.isdir(out_dir) and not force:
        taken = [f for f, k in _existing(out_dir, stem) if k >= first and not f.endswith(".part")]
        if taken:
            raise UsageError(f"output {os.path.join(out_dir, taken[0])} exists; "
                             f"pass --force to overwrite, or choose --out")


def _make_dir(comm, out_dir):
    if comm.rank == 0:
        try:
            os.makedirs(out_dir, exist_ok=True)
        except OSError as e:
            raise UsageError(f"cannot create output directory {out_dir}: {e.strerror}") from None


def _writable(out_dir):
    if not os.access(out_dir, os.W_OK):
        raise UsageError(f"output directory {out_dir} is not writable")


def _existing(out_dir, stem):
    """(file name, output index) of the run's outputs in out_dir, unfinished ones too."""
    pat = re.compile(re.escape(stem) + r"_(\d{4,})\.h5(\.part)?$")
    return sorted((f, int(m.group(1))) for f in os.listdir(out_dir) if (m := pat.match(f)))
