"""``parsph converge``'s runs: a scene at several resolutions, and estimates of each one's error.

Level l of a family is the run file with N_x R^l particles across (h / dx
fixed; dt ~ dx^2 from the coarsest level's, or each level at its own limit
with --dt-scaling limit: :func:`parsph.studies.levels.level_run_file`), written as an ordinary
run file DIR/<family>/nx<N_x>/<name>.toml and run by the same library call as
``parsph run`` (:func:`parsph.simulation.case.run_case`), on the same
communicator, one level after another, without particle snapshots. Two more
runs complete a study: the coarsest level with the viscosity k / (1 + b), b
the kernel's viscosity bias at this h / dx (its effect is an error every
level shares: DIR/<family>/nx<N_x>_bias), and, with a target, the finest
level at its stability limit (the time error's share:
DIR/<family>/nx<N_x>_dtlimit). The estimates are
:mod:`parsph.studies.estimates`'; the cost of a level is the process CPU time
of its time loop summed over ranks, up to each output time. A level whose
``level.json`` records the same run file is reused, so a stopped study
resumes (:class:`parsph.studies.runs.Runs`, the studies' one resumable
runner). The command (options, exit codes, the report's files) is
:mod:`parsph.cli.converge`.
"""
from dataclasses import dataclass, fields
import os
from typing import NamedTuple, Optional

import numpy as np

from parsph.errors import UsageError, agree
from parsph.setup import config
from parsph.simulation.case import run_case, set_threads
from parsph.simulation.solver import Simulation
from .levels import BIAS_MIN, bias_of, bias_run_file
from .runs import RunDirs, Runs


@dataclass
class LevelRun:
    """One run of a study (a level, the bias run or the time-step run): what its level.json records."""
    family: str
    Nx: int
    dir: str
    run_file: str    # the run file as written, with its header: a level is reused where it is the same
    particles: int
    time: list       # the output times [s]
    steps: list      # the step of each
    cpu_s: list      # process CPU seconds of the time loop to each, summed over ranks
    ranks: int
    threads: int
    level: Optional[int] = None    # its place among the levels (0: coarsest); None for the other runs
    bias: Optional[float] = None   # the bias run's b

    def record(self):
        """As JSON holds it (level and bias only where set)."""
        rec = {f.name: getattr(self, f.name) for f in fields(self)}
        return {k: v for k, v in rec.items() if v is not None or k not in ("level", "bias")}


class FamilyRuns(NamedTuple):
    """A family's runs: its levels (coarsest first), its bias run and its time-step run (None: not run)."""
    family: str
    levels: list
    bias: Optional[LevelRun]
    time: Optional[LevelRun]


class Study:
    """The runs of a plan (:class:`parsph.studies.levels.FamilyPlan` per family), one after another on
    ``comm``; ``running`` names the run in hand, for a message if it fails.

    ``name``: the run file's path as given (the levels' header); ``stem``: its name without .toml;
    ``time_runs``: run the time-step run of a family where its levels allow one (``--target``).
    """

    def __init__(self, comm, plans, name, stem, out_dir, *, time_runs=False, dt_scaling="dx2", threads=1,
                 force=False, say=None, stop_requested=None):
        self.comm, self.plans, self.name, self.stem, self.out_dir = comm, plans, name, stem, out_dir
        self.time_runs, self.dt_scaling, self.threads, self.force = time_runs, dt_scaling, threads, force
        self.say = say or (lambda msg: None)
        self.stop_requested = stop_requested
        self.running = None
        self._warm = False
        self._runs = Runs(RunDirs("level.json"), comm)

    def run(self):
        """Every family's runs: a list of :class:`FamilyRuns`."""
        out = []
        for plan in self.plans:
            self._warm = False
            out.append(self._family(plan))
        return out

    def _family(self, plan):
        fam, levels = plan.family, plan.levels
        runs = []
        for l, (nx, rf) in enumerate(levels):
            rec = self._level(plan, nx, rf, f"level {l + 1}/{len(levels)}", f"nx{nx}")
            rec.level = l
            runs.append(rec)
        nx0, rf0 = levels[0]
        b = agree(self.comm, lambda: bias_of(rf0))
        bias = None
        if b is not None and abs(b) > BIAS_MIN:
            # the coarsest level again with k / (1 + b): its difference from the coarsest level is the
            # effect of the kernel's viscosity bias, which every level shares and no difference shows
            bias = self._level(plan, nx0, bias_run_file(rf0, b), f"bias run (k / (1 + b), b = {b:+.2e})",
                               f"nx{nx0}_bias")
            bias.bias = b
        time_run = None
        nxf, rff = levels[-1]
        s0 = rf0.get("numerics", "dt_safety", 1.0)
        if (self.time_runs and self.dt_scaling == "dx2" and rff.get("numerics", "dt") == "auto"
                and rff.get("numerics", "dt_safety") < s0 * (1 - 1e-6)):
            # the finest level again at the base level's margin below its own limit: the difference is the
            # time error's share, which --target uses to trade a larger dt against a finer N_x
            time_run = self._level(plan, nxf, rff.set("numerics", dt_safety=s0), f"time-step run (dt_safety {s0:g})",
                                   f"nx{nxf}_dtlimit")
        return FamilyRuns(fam, runs, bias, time_run)

    def _level(self, plan, nx, rf, what, sub):
        """Run one level (or reuse it): its LevelRun."""
        comm, fam, root = self.comm, plan.family, self.comm.rank == 0
        ldir = os.path.join(self.out_dir, fam, sub)
        # the header names no level index, so a study from another base N_x can reuse this level
        text = f"# parsph converge: {self.name}, family {fam}, N_x = {nx}\n" + rf.dump()
        rec = _level_run(self._runs.done((ldir, text)))
        if rec is not None:
            self.say(f"parsph converge: family {fam}, {what}: N_x = {nx}, reusing {ldir}")
            return rec
        if not self._warm:  # a coarse level too small for the rank count is bad input on every rank alike
            self.running = f"the warm-up of N_x = {plan.levels[0].nx} ({fam})"
            agree(comm, lambda: _warm_up(comm, plan.levels[0].run_file, self.threads))
            self._warm = True
        path = os.path.join(ldir, self.stem + ".toml")
        agree(comm, lambda: _write(root, ldir, path, text))
        comm.Barrier()
        self.say(f"parsph converge: family {fam}, {what}: N_x = {nx}")
        self.running = f"N_x = {nx} ({fam}, {what})"
        res = run_case(comm, config.load(path), ldir, self.stem, force=self.force, threads=self.threads,
                       stop_requested=self.stop_requested, say=self.say)
        cpu = np.zeros(len(res.outputs))
        comm.Allreduce(np.array([o.cpu_s for o in res.outputs], dtype=float), cpu)
        rec = LevelRun(fam, nx, ldir, text, int(res.sim.n_total), [float(o.t) for o in res.outputs],
                       [int(o.step) for o in res.outputs], cpu.tolist(), comm.size, self.threads)
        self._runs.add((ldir, text), rec.record())
        return rec


def _warm_up(comm, run_file, threads):
    """A few steps of a level and an output's frame of them, on the levels' threads, untimed, so that loading
    (or compiling) numba's code of the step and of the outputs is not counted as cost."""
    set_threads(threads)  # before it, the process's default: the threaded versions, which the levels do not run
    cfg = config.build(run_file)
    sim = Simulation(config.build(run_file.set("output", t_end=2.5 * cfg.dt, times=[])), comm).run()
    sim.frame(True)


def _write(root, ldir, path, text):
    if root:
        try:
            os.makedirs(ldir, exist_ok=True)
            with open(path, "w") as f:
                f.write(text)
        except OSError as e:
            raise UsageError(f"cannot write {path}: {e.strerror}") from None


def _level_run(rec):
    """A kept level's record as a LevelRun (None: none kept, or a record of another form)."""
    try:
        return None if rec is None else LevelRun(**rec)
    except TypeError:
        return None
