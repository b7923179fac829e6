"""Benchmark one configuration: particle-steps per second and the per-phase breakdown.

    [mpirun -n P] .venv/bin/python scripts/bench.py --nx 50 200 [--steps N] [--json FILE] [--tag TEXT]

For each N_x the Couette case (L_y = L, h = 1.25 dx, dt = "auto", recomputed every
step from the state as ``parsph run`` does) is built and stepped through
``Simulation.take_steps``, the loop ``parsph run`` runs (compiled blocks, the
auto rule, the run-time checks; no outputs): one step to compile (numba
caches on disk; the first-ever compile is reported as ``jit_s``), 200 more
past the impulsive start (whose first steps rebuild the neighbour list often),
then ``--steps`` steps timed. Phase times are the slowest rank's seconds per
step (``phases_min_s``: the fastest rank's): the compiled blocks' phases
(sync, density, halo, forces, integrate) in wall seconds, the Python ones
(rebuild, checks) too; ``outside_phases_share`` is the rest of the wall time
(Python between blocks). ``returns_per_step``: returns from compiled code to
Python per step. The scalar reference loops (parsph.studies.benchmark,
which takes these measurements) time the two pair passes' arithmetic on the
same pair list. Memory: peak resident set size summed over
ranks, per particle. One JSON record per size goes to --json (appended).
"""
import argparse
import sys

import numba
from mpi4py import MPI

from parsph.simulation.solver import Simulation
from parsph.studies import builders
from parsph.studies.benchmark import bench
from parsph.studies.runs import append_json


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nx", type=int, nargs="+", default=[50])
    ap.add_argument("--steps", type=int, default=0,
                    help="timed steps (default: as many as fit in --budget seconds)")
    ap.add_argument("--budget", type=float, default=5.0, help="seconds of timed steps per size")
    ap.add_argument("--json", help="append results as JSON lines to this file")
    ap.add_argument("--tag", default="", help="label stored with each record")
    ap.add_argument("--set", action="append", default=[], help="extra run-file overrides")
    ap.add_argument("--threads", type=int, default=1, help="numba threads per rank (NUMBA_NUM_THREADS caps it)")
    a = ap.parse_args()
    numba.set_num_threads(a.threads)
    comm = MPI.COMM_WORLD
    Simulation(builders.bench(10), comm).take_steps(2)  # load the compiled loops before any RSS is taken
    for nx in a.nx:
        r = bench(comm, nx, a.steps or None, a.set, a.budget)
        r["tag"] = a.tag
        if comm.rank == 0:
            ph = " ".join(f"{k} {v * 1e3:.3f}" for k, v in r["phases_s"].items())
            print(f"Nx={nx:4d} P={r['ranks']} N={r['particles']:7d} {r['step_s'] * 1e3:9.3f} ms/step "
                  f"(CPU {r['cpu_s_per_step'] * 1e3 / r['ranks']:.3f} ms per rank: "
                  f"{r['particles'] / r['cpu_s_per_step']:.3g} particle-steps per CPU-second) "
                  f"T={r['threads']} {r['particle_steps_per_s']:.3g} particle-steps/s  outside the phases {100 * r['outside_phases_share']:.1f}%  "
                  f"{r['ns_per_pair_density']:.1f}/{r['ns_per_pair_forces']:.1f} ns/pair (density/forces)  "
                  f"RSS {r['rss_bytes_per_particle']:.0f} B/particle "
                  f"({r['rss_added_bytes_per_particle']:.0f} B above the {r['rss_before_bytes'] / 2**20:.0f} MiB before)  jit+setup {r['jit_s']:.1f} s {a.tag}",
                  flush=True)
            print(f"    ms/step: {ph}; {r['steps_per_rebuild']:.1f} steps per list rebuild, "
                  f"{r['returns_per_step']:.3f} returns to Python per step (native MPI: {r['native_mpi']})",
                  flush=True)
            print(f"    reference loops (CPU time): {r['ns_per_pair_reference_density']:.1f}/"
                  f"{r['ns_per_pair_reference_forces']:.1f} ns/pair (density/forces; forces reading one packed "
                  f"row per particle: {r['ns_per_pair_reference_forces_rows']:.1f})", flush=True)
            if a.json:
                append_json(a.json, r)
    return 0


if __name__ == "__main__":
    sys.exit(main())
