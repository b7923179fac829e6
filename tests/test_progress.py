"""Progress lines and the run's summary (parsph.cli.progress): compiling is said and kept out of the figures.

    .venv/bin/python -m pytest -q tests/test_progress.py

The arithmetic is checked on made-up clocks against sums done by hand here;
CompileWatch on a real numba compilation; the solver's ``steady`` mark on a
short in-process run. A cold-cache run under mpirun, which says it compiles,
is in test_mpi_numba_cache.py (it shares that module's fresh cache).
"""
from types import SimpleNamespace

import numba
import pytest

from parsph.cli.progress import COMPILING, CompileWatch, Progress, fmt_time


class FakeWatch:
    def __init__(self, spans):
        self.spans = spans

    seconds = CompileWatch.seconds


def cfg(nsteps=10_000, t_end=0.1, auto=False):
    return SimpleNamespace(nsteps=nsteps, t_end=t_end, dt_auto=auto)


def sim(step, t, steady, loop_started=0.0, wall=None, rebuilds=3):
    return SimpleNamespace(step=step, t=t, steady=steady, loop_started=loop_started, wall_time=wall, rebuilds=rebuilds)


def test_rate_and_time_left_come_from_the_steady_steps_less_compiling():
    """Steady since step 1 at clock 100 s; at 110 s step 801, with 2 s of compiling inside (103-105 s)
    and 50 s before (the first step): 800 steps in 8 s -> 100 steps/s, 9199 steps left -> 92 s."""
    p = Progress(cfg(), 2800, print, FakeWatch([(40.0, 90.0), (103.0, 105.0)]), started=30.0)
    line = p.line(sim(801, 801e-5, (1, 1e-5, 100.0)), now=110.0)
    assert f"{2800 * 100:.3g} particle-steps/s" in line, line
    assert line.endswith(f"left {fmt_time(92)}"), line
    assert "step     801/10000" in line


def test_dt_auto_time_left_from_simulated_time_per_second():
    """dt auto: 0.01 s simulated in 8 steady seconds; 0.1 - 0.02 s left -> 64 s."""
    p = Progress(cfg(auto=True), 1000, print, FakeWatch([]), started=0.0)
    line = p.line(sim(500, 0.02, (10, 0.01, 100.0)), now=108.0)
    assert line.endswith(f"left {fmt_time(64)}") and "step     500  t" in line, line


def test_no_rate_and_no_time_left_before_a_steady_step():
    """Before the solver marks its first step done, and just at it: no rate, no time left; compiling named."""
    p = Progress(cfg(), 2800, print, FakeWatch([(1.0, 14.0)]), started=0.0)
    for s in (sim(0, 0.0, None), sim(1, 1e-5, (1, 1e-5, 15.0))):
        line = p.line(s, now=15.0)
        assert "particle-steps/s" not in line and "left" not in line, line
        assert "compiling took 13 s" in line, line


def test_summary_splits_compile_set_up_and_time_loop():
    """Command from 0 s, loop 5-65 s, first step done at 25 s, compiling 6-24 s and 30-32 s:
    total 65, compile 20, time loop 65 - 25 - 2 = 38 s for 99 steady steps, set-up 65 - 20 - 38 = 7."""
    p = Progress(cfg(nsteps=100), 1000, print, FakeWatch([(6.0, 24.0), (30.0, 32.0)]), started=0.0)
    text = p.summary(sim(100, 1e-3, (1, 1e-5, 25.0), loop_started=5.0, wall=60.0, rebuilds=7), 100)
    assert text == (f"done: 100 steps in 65.0 s: time loop 38.0 s ({1000 * 99 / 38:.3g} particle-steps/s), "
                    f"set-up and first step 7.0 s, compile 20.0 s; neighbour list built 7 times"), text


def test_compile_watch_times_real_compilations_and_says_so_once():
    """Two new signatures of a fresh function: two spans, the note once (after arm), nothing for a call
    that needs no compilation."""
    said = []
    with CompileWatch(note=lambda: said.append(COMPILING)) as w:
        @numba.njit
        def f(x):
            return x + 1
        f(1)
        assert said == [] and len(w.spans) == 1  # before arm: timed, not said
        w.arm()
        assert said == [COMPILING]
        f(2.0)
        f(3)
    assert said == [COMPILING] and len(w.spans) == 2
    assert all(b > a for a, b in w.spans) and w.seconds() == pytest.approx(sum(b - a for a, b in w.spans))
    f(4.0)  # outside the watch: not recorded
    assert len(w.spans) == 2


def test_solver_marks_the_end_of_its_first_step(paper_cfg):
    """Simulation.run sets steady = (step0 + 1, its t, a clock within the loop) after its first step."""
    from mpi4py import MPI
    from parsph.simulation.solver import Simulation
    c = paper_cfg("domain.Ly=0.002", "output.t_end=3e-5", "output.times=[]", "output.progress_interval=0")
    s = Simulation(c, MPI.COMM_SELF).run()
    assert s.step == 3 and s.steady[0] == 1 and s.steady[1] == pytest.approx(1e-5)
    assert s.loop_started < s.steady[2] <= s.loop_started + s.wall_time
