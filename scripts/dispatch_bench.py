"""The cost of calling each numba pass: CPU time per call on an empty input (no particle, no pair).

    .venv/bin/python scripts/dispatch_bench.py [--calls N] [--rounds R]

With nothing to loop over, a call costs what numba's dispatcher does before
and after the loop: typing the arguments, finding the compiled version,
boxing the result. Each pass is called as :class:`parsph.rates.Rates` calls
it, with the arrays of a small Couette case and n = 0; the median over
``--rounds`` rounds of ``--calls`` calls each, in process CPU time.
"""
import argparse
import os
import sys
import time

import numba
import numpy as np
from mpi4py import MPI

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench import make_config  # noqa: E402

from parsph import equations, neighbours  # noqa: E402
from parsph.solver import Simulation  # noqa: E402


def empty_calls(sim):
    """name -> (function, arguments) of every pass, on an empty input."""
    R, ps = sim.rates, sim.ps
    wp, Pp, Vp, offset, entry = R._threaded_arrays()
    mc = R.momentum_consts
    return {
        "density_serial": (equations.density_serial, (R.order, R.pstart, R.pj, 0, ps.pos, ps.mass, R.kid, R.inv_h,
                                                      R.norm, R.w0, R.three_d, R.rho_sum, R.fp)),
        "density_threaded": (equations.density_threaded, (R.order, R.pstart, R.pi, R.pj, 0, 0, ps.pos, ps.mass,
                                                          R.kid, R.inv_h, R.norm, R.w0, R.three_d, R.rho_sum, R.fp,
                                                          wp, R.need, offset, entry)),
        "particle_factors": (equations.particle_factors, (ps.rho, R.rho_sum, ps.kind, 0, 0, 0, R.rho_s, R.G_a,
                                                          R.G_b, R.pressure, R.consistent, ps.vel, ps.theta,
                                                          R.fields)),
        "momentum_serial": (equations.momentum_serial, (R.order, R.pstart, R.pj, 0, R.fp, ps.pos, ps.mass, ps.kind,
                                                        R.fields, R.need, 0, *mc, ps.acc)),
        "momentum_threaded": (equations.momentum_threaded, (R.order, R.pstart, R.pi, R.pj, 0, 0, R.fp, ps.pos,
                                                            ps.mass, ps.kind, R.fields, R.need, 0, *mc, ps.acc, Pp,
                                                            Vp, offset, entry)),
        "block_spread": (neighbours.block_spread, (ps.disp, 0, R.cell, np.zeros(3, np.int64), R.centre_lo, R.centre_lo - 1, R.box,
                                                   R.work)),
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--calls", type=int, default=20000)
    ap.add_argument("--rounds", type=int, default=15)
    a = ap.parse_args()
    numba.set_num_threads(1)
    sim = Simulation(make_config(10), MPI.COMM_SELF)
    sim.compute_rates()
    for name, (fn, args) in empty_calls(sim).items():
        print(f"{name:18s} {per_call(fn, args, a.calls, a.rounds):6.2f} us per call (CPU, median)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
