"""What ``parsph run`` prints while it runs and when it ends, with compiling kept apart.

numba compiles a loop the first time a process calls it with new argument
types and the disk cache does not hold it yet (first run of this code on this
machine: some seconds per loop). :class:`CompileWatch` listens to numba's
``numba:compile`` events, sums their wall time (the outermost ones: a loop's
compile includes the loops it calls) and says once that it is compiling.
:class:`Progress` is the time loop's ``progress`` callback: the rate and the
time left come from steady steps only, those after the run's first step
(``Simulation.steady``: step, t and clock when it ended; the first step loads
or compiles the loops and builds the first neighbour list), less any compile
among them; before there are any, a line gives no rate and no time left. The
summary splits the command's wall time into compile, set-up (everything else
up to the end of the first step) and the time loop (the steady steps,
outputs and checks included).
"""
import math
import time

COMPILING = "compiling the loops, first run on this machine (numba keeps them on disk for later runs)"


def fmt_time(s):
    s = int(round(s))
    return f"{s // 3600}h{s % 3600 // 60:02d}m" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"


class CompileWatch:
    """While installed (``with``), the spans of numba's outermost compilations; ``note()`` once, at the
    first compilation after :meth:`arm` (or at ``arm`` where one came before: the banner goes first)."""

    def __init__(self, note=None):
        self.note = note
        self.spans = []    # (start, end) perf_counter seconds of each outermost compilation
        self._depth = 0
        self._start = 0.0
        self._armed = False

    def arm(self):
        self._armed = True
        if self.spans or self._depth:
            self._say()

    def _say(self):
        if self.note is not None:
            self.note()
            self.note = None

    def __enter__(self):
        from numba.core import event

        class Listener(event.Listener):
            on_start, on_end = self._on_start, self._on_end
        self._event, self._listener = event, Listener()
        event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc):
        self._event.unregister("numba:compile", self._listener)
        return False

    def _on_start(self, ev):
        if self._depth == 0:
            if self._armed:
                self._say()
            self._start = time.perf_counter()
        self._depth += 1

    def _on_end(self, ev):
        self._depth -= 1
        if self._depth == 0:
            self.spans.append((self._start, time.perf_counter()))

    def seconds(self, since=-math.inf, until=math.inf):
        """Compiling time within [since, until]."""
        return sum(max(0.0, min(b, until) - max(a, since)) for a, b in self.spans)


class Progress:
    """The time loop's progress callback (``sim.run(progress=...)``) and the run's summary line.

    ``say`` prints on rank 0; ``watch`` is the run's CompileWatch; ``started``
    (``Progress.clock()``, default now) is the command's start, after its imports.
    """

    clock = staticmethod(time.perf_counter)

    def __init__(self, cfg, n_total, say, watch, started=None):
        self.cfg, self.n_total, self.say, self.watch = cfg, n_total, say, watch
        self.started = time.perf_counter() if started is None else started

    def steady_rate(self, sim, now):
        """(steps per second, simulated seconds per second) over the steady steps up to ``now``; None before any."""
        steady = getattr(sim, "steady", None)
        if steady is None or sim.step <= steady[0]:
            return None
        step0, t0, clock0 = steady
        wall = now - clock0 - self.watch.seconds(clock0, now)
        if wall <= 0:
            return None
        return (sim.step - step0) / wall, (sim.t - t0) / wall

    def line(self, sim, now=None):
        cfg = self.cfg
        now = time.perf_counter() if now is None else now
        of = "" if cfg.dt_auto else f"/{cfg.nsteps}"
        head = f"  step {sim.step:>7d}{of}  t = {sim.t:.5f} s"
        rates = self.steady_rate(sim, now)
        if rates is None:
            c = self.watch.seconds(self.started, now)
            what = f"compiling took {c:.0f} s" if c >= 0.5 else "loading the loops"
            return f"{head}  first step ({what}): no rate yet"
        steps_s, sim_s = rates
        if cfg.dt_auto:
            left = (cfg.t_end - sim.t) / sim_s if sim_s > 0 else math.inf
        else:
            left = (cfg.nsteps - sim.step) / steps_s
        eta = fmt_time(left) if math.isfinite(left) else "unknown"
        return f"{head}  {self.n_total * steps_s:.3g} particle-steps/s  left {eta}"

    def __call__(self, sim, *_):
        """Print a progress line (the solver may pass its own rate and time left: not used)."""
        self.say(self.line(sim))

    def summary(self, sim, steps_done):
        """``done: N steps in T s: time loop L s (R particle-steps/s), set-up S s, compile C s; ...`` (and with
        the solved gas, its solve's seconds and share of the time loop)."""
        end = sim.loop_started + sim.wall_time
        total = end - self.started
        compile_s = self.watch.seconds(self.started, end)
        steady = getattr(sim, "steady", None)
        loop = 0.0
        rate = ""
        if steady is not None and sim.step > steady[0]:
            loop = end - steady[2] - self.watch.seconds(steady[2], end)
            rate = f" ({self.n_total * (sim.step - steady[0]) / loop:.3g} particle-steps/s)" if loop > 0 else ""
        setup = total - compile_s - loop
        gas = ""
        if getattr(sim, "gas", None) is not None and loop > 0:  # the solved gas: its share of the time loop
            seconds = sim.timers["gas"] - getattr(sim, "steady_timers", {}).get("gas", 0.0)  # the loop's steps
            gas = f"; the gas solve {seconds:.1f} s ({100 * seconds / loop:.0f}% of the loop)"
        return (f"done: {steps_done} steps in {total:.1f} s: time loop {loop:.1f} s{rate}, set-up and first step "
                f"{setup:.1f} s, compile {compile_s:.1f} s; neighbour list built {sim.rebuilds} times{gas}")
