"""Benchmark: particle-steps per second and the per-phase breakdown.

    mpirun -n P .venv/bin/python scripts/bench.py [--nx 50 200 400] [--steps 200] [--json FILE]

For each size the Couette case (L_y = L, square lattice) is built, one step is
taken to compile (the JIT time is reported separately; numba caches it on
disk), then ``--steps`` steps are timed. Phases are the slowest rank's
seconds per step. Output: a table on stdout and, with --json, one record per
size (append-friendly). Results are recorded in README.md ("Performance").
"""
import argparse
import json
import os
import platform
import resource
import sys
import time

from mpi4py import MPI

from parsph import config
from parsph.solver import PHASES, Simulation

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def bench(comm, nx, steps, extra=()):
    over = [f"numerics.Nx={nx}", "numerics.h_over_dx=1.25", f"output.t_end={1e-5 * (steps + 1)}",
            "output.times=[]"] + list(extra)
    raw = config.tomllib.loads(open(os.path.join(ROOT, "run", "couette_paper.toml")).read())
    del raw["numerics"]["h"]
    config.apply_overrides(raw, over)
    cfg = config.build(raw, config.dumps(raw))
    comm.Barrier()
    t0 = time.perf_counter()
    sim = Simulation(cfg, comm)
    sim.compute_rates()
    sim.advance()
    jit = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    sim.timers.clear()
    comm.Barrier()
    t0 = time.perf_counter()
    for _ in range(steps):
        sim.compute_rates()
        sim.advance()
    comm.Barrier()
    wall = time.perf_counter() - t0
    phases = {k: comm.allreduce(sim.timers.get(k, 0.0), op=MPI.MAX) / steps for k in PHASES}
    rss = comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, op=MPI.SUM)
    inside = sum(phases[k] for k in ("neighbours", "density", "forces", "integrate"))
    return {
        "nx": nx, "ranks": comm.size, "particles": sim.n_total, "steps": steps,
        "step_s": wall / steps, "particle_steps_per_s": sim.n_total * steps / wall,
        "jit_and_setup_s": jit, "phases_s": phases,
        "outside_numba_share": max(0.0, 1 - inside / (wall / steps)),
        "peak_rss_bytes_per_particle": rss / sim.n_total,
        "machine": f"{platform.node()} {platform.processor() or platform.machine()} {os.cpu_count()} cores",
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nx", type=int, nargs="+", default=[50])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--json", help="append results as JSON lines to this file")
    ap.add_argument("--set", action="append", default=[], help="extra run-file overrides")
    a = ap.parse_args()
    comm = MPI.COMM_WORLD
    for nx in a.nx:
        r = bench(comm, nx, a.steps, a.set)
        if comm.rank == 0:
            ph = " ".join(f"{k}={v * 1e3:.3f}" for k, v in r["phases_s"].items())
            print(f"Nx={nx:4d} P={r['ranks']} N={r['particles']:7d}  {r['step_s'] * 1e3:8.3f} ms/step  "
                  f"{r['particle_steps_per_s']:.3g} particle-steps/s  jit+setup {r['jit_and_setup_s']:.1f} s  "
                  f"outside numba {100 * r['outside_numba_share']:.1f}%  RSS {r['peak_rss_bytes_per_particle']:.0f} B/particle",
                  flush=True)
            print(f"    ms/step: {ph}", flush=True)
            if a.json:
                with open(a.json, "a") as f:
                    f.write(json.dumps(r) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
