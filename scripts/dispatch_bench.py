"""The cost of calling each numba pass: CPU time per call on an empty input (no particle, no pair).

    .venv/bin/python scripts/dispatch_bench.py [--calls N] [--rounds R] [--steps N]

With nothing to loop over, a call costs what numba's dispatcher does before
and after the loop: typing the arguments, finding the compiled version,
boxing the result. Each pass gets its arguments from the passes' data
(:class:`parsph.sph.rates.Rates`) of a small Couette case, with n = 0; it is called
through its dispatcher and through the compiled version (:func:`parsph.sph.dispatch.compiled`,
as the Python path calls the evaluation's stages); the median over ``--rounds`` rounds of ``--calls``
calls each, in process CPU time. Then the time of whole steps of the
Couette case at N_x = 10 (160 particles, fixed dt = 1e-5 s, after 300
steps), where the fixed cost of a step weighs most, in compiled blocks and on
the Python path: minimum and median over ``--rounds`` (at most 5) rounds of
``--steps`` steps.
"""
import argparse
import sys
import time

import numba
import numpy as np
from mpi4py import MPI

from parsph.simulation.solver import Simulation
from parsph.sph import cells, density, momentum, pass_data, dispatch
from parsph.studies.builders import bench


def empty_calls(sim):
    """name -> (function, arguments) of every pass, on an empty input."""
    R, N, ps = sim.rates, sim.neighbours, sim.ps
    gather = R.gather_arrays()
    lst = R.list._replace(n=0, npairs=0)
    parts = pass_data.particle_arrays(ps)._replace(n_own=0)
    c, sw = R.consts, R.switches
    empty_box = N.local._replace(size=np.zeros(3, np.int64), centre_hi=N.local.centre_lo - 1)
    return {
        "density_serial": (density.density_serial, (lst, parts, c, sw)),
        "density_threaded": (density.density_threaded, (lst, parts, c, sw, gather)),
        "particle_factors": (momentum.particle_factors, (lst, parts, c, sw, 0, 0)),
        "momentum_serial": (momentum.momentum_serial, (lst, parts, c, sw)),
        "momentum_threaded": (momentum.momentum_threaded, (lst, parts, c, sw, gather)),
        "patch_spread": (cells.patch_spread, (ps.disp, N.cells._replace(n=0), empty_box, N.box, N.work)),
    }


def per_call(fn, args, calls, rounds):
    """Median over ``rounds`` of the CPU microseconds per call."""
    fn(*args)
    times = []
    for _ in range(rounds):
        t0 = time.process_time()
        for _ in range(calls):
            fn(*args)
        times.append((time.process_time() - t0) / calls * 1e6)
    return float(np.median(times))


def per_step(steps, rounds, native):
    """(minimum, median) CPU microseconds per step of the Couette case at N_x = 10 (160 particles,
    dt = 1e-5 s), stepped as parsph run steps (Simulation.take_steps): ``native`` the compiled blocks,
    else the Python path with mpi4py messages."""
    sim = Simulation(bench(10, ["numerics.dt=1e-5"]), MPI.COMM_SELF, native=None if native else False)
    sim.take_steps(300)
    times = []
    for _ in range(rounds):
        t0 = time.process_time()
        sim.take_steps(steps)
        times.append((time.process_time() - t0) / steps * 1e6)
    return min(times), float(np.median(times))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--calls", type=int, default=20000)
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--steps", type=int, default=2000, help="steps per round of the step timing")
    a = ap.parse_args()
    numba.set_num_threads(1)
    sim = Simulation(bench(10), MPI.COMM_SELF)
    sim.compute_rates()
    print(f"{'pass':18s} {'dispatcher':>10s} {'compiled':>10s}  [us per call, CPU, median]")
    for name, (fn, args) in empty_calls(sim).items():
        direct = per_call(fn, args, a.calls, a.rounds)
        version = per_call(dispatch.compiled(fn, *args), args, a.calls, a.rounds)  # after the dispatcher ran
        print(f"{name:18s} {direct:10.2f} {version:10.2f}", flush=True)
    for native, route in ((True, "compiled blocks"), (False, "Python path, mpi4py")):
        lo, mid = per_step(a.steps, min(a.rounds, 5), native)
        print(f"a step at N_x = 10 ({route}): {lo:.1f} us (minimum), {mid:.1f} us (median) CPU", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
