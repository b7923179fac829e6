"""The solved gas's cost against the column closure's on a 2-D bed (docs/performance.md, "The solved gas"):
run/fluidized_bed.toml widened to N particles, the same steps with gas.flow = "column" (compiled blocks)
and "solved" (the Python path with the grid's solve), alternated, on one rank; prints ms a step of each,
their ratio and the gas stage's share.

    NUMBA_NUM_THREADS=1 .venv/bin/python scripts/gas_bench.py --particles 20000 --steps 300 --repeat 3 [--gas gas.solve_every=5]
"""
import argparse
import json
import time

from mpi4py import MPI

from parsph.simulation.solver import Simulation
from parsph.studies import layers


def case(flow, rows, extra):
    return layers.load(layers.BED, [f'gas.flow="{flow}"', f"domain.Ly={rows * 2e-4!r}", "output.t_end=1.0",
                                    "output.times=[1.0]", "output.snapshots=false", *extra])


def timed(cfg, steps):
    sim = Simulation(cfg, MPI.COMM_SELF)
    sim.take_steps(20)  # compiled, the list built, the first solves made
    gas0 = sim.timers.get("gas", 0.0)
    t0 = time.perf_counter()
    sim.take_steps(steps)
    wall = time.perf_counter() - t0
    return wall / steps, (sim.timers.get("gas", 0.0) - gas0) / steps, sim.n_total


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=int, default=20000, help="about this many fluid particles (50 per y row)")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--set", action="append", default=[], help="more overrides of both runs (section.key=value)")
    ap.add_argument("--gas", action="append", default=[], help="overrides of the solved run only (gas.solve_every=5)")
    a = ap.parse_args()
    rows = max(12, a.particles // 50)
    rows += rows % 2
    out = {"column": [], "solved": [], "gas": []}
    for _ in range(a.repeat):
        for flow in ("column", "solved"):
            step, gas, n = timed(case(flow, rows, a.set + (a.gas if flow == "solved" else [])), a.steps)
            out[flow].append(step)
            if flow == "solved":
                out["gas"].append(gas)
    med = {k: sorted(v)[len(v) // 2] for k, v in out.items()}
    print(json.dumps({"particles": n, "steps": a.steps, "ms_column": 1e3 * med["column"],
                      "ms_solved": 1e3 * med["solved"], "ratio": med["solved"] / med["column"],
                      "gas_share": med["gas"] / med["solved"], "runs": out}))


if __name__ == "__main__":
    main()
