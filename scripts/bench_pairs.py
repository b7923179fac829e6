"""ns per unique pair of the density and momentum passes against today's scalar reference loops, same pair list.

    .venv/bin/python scripts/bench_pairs.py --nx 50 100 200 [--threads 1 2] [--rounds 15] [--json FILE]

For each N_x the case of scripts/bench.py (Couette, L_y = L, h = 1.25 dx, dt = "auto") is built and stepped
past the impulsive start (--warmup steps). On the pair list of its last step the passes of
:mod:`parsph.sph.density`, :mod:`parsph.sph.momentum` and of :mod:`parsph.sph.reference_passes` are first checked to give the same
numbers bit for bit, then timed in alternation: --rounds rounds, in each every pass called for about --seconds;
the minimum time per call over the rounds is kept (the least disturbed by other processes on a shared machine).
One thread: the serial passes, in process CPU time. More threads: the threaded passes, in wall time (their CPU
time, all threads together, is recorded too).
"""
import argparse
import os
import platform
import sys

import numba

from parsph.studies.benchmark import check_passes, pair_state, time_passes
from parsph.studies.machine import cpu_model, threading_layer
from parsph.studies.runs import append_json


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nx", type=int, nargs="+", default=[50, 100, 200])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--seconds", type=float, default=0.05, help="time per pass per round")
    ap.add_argument("--warmup", type=int, default=200)
    ap.add_argument("--json", help="append one JSON record per size and thread count to this file")
    a = ap.parse_args()
    machine = f"{platform.node()}: {cpu_model()}, {os.cpu_count()} cores"
    print(f"# {machine}; numba {numba.__version__}", flush=True)
    status = 0
    for nx in a.nx:
        sim, args, gather = pair_state(nx, a.warmup)
        lst = args[0]
        for threads in a.threads:
            if threads > numba.config.NUMBA_NUM_THREADS:
                print(f"Nx={nx}: {threads} threads: numba allows {numba.config.NUMBA_NUM_THREADS} here, skipped")
                continue
            differ = check_passes(args, gather, threads)
            if differ:
                print(f"Nx={nx} T={threads}: new passes differ from the reference in {', '.join(differ)}")
                status = 1
            load0 = os.getloadavg()[0]
            wall, cpu = time_passes(args, gather, threads, a.rounds, a.seconds)
            load1 = os.getloadavg()[0]
            ns = {k: v / lst.npairs * 1e9 for k, v in (cpu if threads == 1 else wall).items()}
            rec = {"nx": nx, "particles": lst.n, "pairs": lst.npairs, "threads": threads,
                   "clock": "process CPU" if threads == 1 else "wall",
                   **{f"ns_per_pair_{k}": v for k, v in ns.items()},
                   **{f"cpu_ns_per_pair_{k}": v / lst.npairs * 1e9 for k, v in cpu.items()},
                   "density_ratio": ns["density_new"] / ns["density_ref"],
                   "forces_ratio": ns["forces_new"] / ns["forces_ref"],
                   "identical": not differ, "load": [load0, load1], "machine": machine,
                   "threading_layer": threading_layer()}
            print(f"Nx={nx:4d} n={lst.n:7d} pairs={lst.npairs:8d} T={threads}  density {ns['density_ref']:.2f} -> "
                  f"{ns['density_new']:.2f} ns/pair ({rec['density_ratio']:.2f}x)  forces {ns['forces_ref']:.2f} -> "
                  f"{ns['forces_new']:.2f} ns/pair ({rec['forces_ratio']:.2f}x)  "
                  f"{'bit-identical' if not differ else 'DIFFERENT'}  load {load0:.1f}-{load1:.1f}", flush=True)
            if a.json:
                append_json(a.json, rec)
        numba.set_num_threads(1)
    return status


if __name__ == "__main__":
    sys.exit(main())
