"""A run's time: t, dt and the step count, the output times still due, the end, and the progress clock."""
import time


class Timeline:
    """t, dt and the step of a run (zero, or a restart's ``attrs``), and the rules that read them."""

    def __init__(self, cfg, attrs=None):
        self.cfg = cfg
        self.step = 0 if attrs is None else int(attrs["step"])
        self.t = 0.0 if attrs is None else float(attrs["time"])
        self.dt = cfg.dt if attrs is None else float(attrs["dt"])

    def count(self, dt):
        """One step of ``dt`` taken: with a fixed dt, t = step dt (no sum of roundings); with auto, the sum."""
        self.step += 1
        self.t = self.step * self.cfg.dt if not self.cfg.dt_auto else self.t + dt

    def output_due(self, t_out):
        if not self.cfg.dt_auto:
            return self.step == round(t_out / self.cfg.dt)
        return self.t >= t_out * (1 - 1e-12) - 1e-300

    def at_end(self):
        cfg = self.cfg
        return self.t >= cfg.t_end * (1 - 1e-12) if cfg.dt_auto else self.step >= cfg.nsteps

    def pending_outputs(self):
        """The output times still to write (a restart's own state was written already)."""
        pending = [t for t in self.cfg.output_times if t >= self.t * (1 + 1e-12) or (self.step == 0 and t == 0)]
        if self.step > 0:
            pending = [t for t in pending if not self.output_due(t)]
        return pending

    def target(self, pending):
        """The time the auto rule lands on next: the next output or the end."""
        return min(pending[0], self.cfg.t_end) if pending else self.cfg.t_end

    def stop_step(self, pending, steps):
        """The step a run of ``steps`` steps stops at: with a fixed dt, at the next output or the end first."""
        cfg = self.cfg
        stop = self.step + steps
        if not cfg.dt_auto:
            stop = min(stop, cfg.nsteps)
            if pending:
                stop = min(stop, max(round(pending[0] / cfg.dt), self.step + 1))
        return stop

    def most_steps(self, observe, last_step):
        """The most steps before Python sees the state again: one for an observer, up to ``last_step``."""
        most = 1 if observe is not None else None
        if last_step is not None:
            most = min(most or last_step, last_step - self.step)
        return most


class Ticker:
    """The loop's clock for progress (parsph.cli.progress): ``sim.loop_started``, ``sim.steady`` (step, t,
    clock) once the run's first step, which loads or compiles the loops and builds the first list, is done
    (steps after it are steady) with ``sim.steady_timers``, the stage timers then, and ``progress(sim, rate,
    eta)`` every ``output.progress_interval`` s."""

    def __init__(self, sim, progress):
        self.sim, self.progress = sim, progress
        self.interval = sim.cfg.get("output.progress_interval")
        self.step0, self.t0 = sim.step, sim.t
        sim.loop_started = self.last = time.perf_counter()
        sim.steady = None

    def tick(self):
        sim, now = self.sim, time.perf_counter()
        if sim.steady is None:
            sim.steady = (sim.step, sim.t, now)
            sim.steady_timers = dict(getattr(sim, "timers", {}))  # the stages' seconds so far (with compiling)
        if self.progress is not None and self.interval > 0 and now - self.last >= self.interval:
            self.last = now
            rate = sim.n_total * (sim.step - self.step0) / (now - sim.loop_started)
            eta = (sim.cfg.t_end - sim.t) * (now - sim.loop_started) / max(sim.t - self.t0, 1e-300)
            self.progress(sim, rate, eta)
