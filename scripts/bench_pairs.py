"""ns per unique pair of the density and momentum passes against today's scalar reference loops, same pair list.

    .venv/bin/python scripts/bench_pairs.py --nx 50 100 200 [--threads 1 2] [--rounds 15] [--json FILE]

For each N_x the case of scripts/bench.py (Couette, L_y = L, h = 1.25 dx, dt = "auto") is built and stepped
past the impulsive start (--warmup steps). On the pair list of its last step the passes of
:mod:`parsph.sph.equations` and of :mod:`parsph.sph.reference_passes` are first checked to give the same
numbers bit for bit, then timed in alternation: --rounds rounds, in each every pass called for about --seconds;
the minimum time per call over the rounds is kept (the least disturbed by other processes on a shared machine).
One thread: the serial passes, in process CPU time. More threads: the threaded passes, in wall time (their CPU
time, all threads together, is recorded too).
"""
import argparse
import json
import os
import platform
import sys
import time

import numba
import numpy as np
from mpi4py import MPI

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench import make_config  # noqa: E402

from parsph.simulation.solver import Simulation  # noqa: E402
from parsph.sph import equations, pass_data, reference_passes  # noqa: E402


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def threading_layer():
    try:
        return numba.threading_layer()
    except ValueError:  # no parallel region has run
        return "none"


def state(nx, warmup):
    """The benchmark case after ``warmup`` steps, its rates evaluated: (sim, pass arguments, gather)."""
    sim = Simulation(make_config(nx), MPI.COMM_SELF)
    sim.take_steps(warmup)
    R = sim.rates
    return sim, (R.list, pass_data.particle_arrays(sim.ps), R.consts, R.switches), R.gather_arrays()


def outputs(lst, parts, compact=False):
    """Sums of the particles that need them, the pairs of nonzero (dW/dr)/r (j then the bits of f; from the
    compact list the serial density pass writes, or from the full list's fp) and the accelerations."""
    n, n_own = lst.n, parts.n_own
    need = lst.need[:n]
    if compact:
        k = lst.cstart[n]
        j, f = lst.cj[:k], lst.cf[:k]
    else:
        j, f = lst.pj[:lst.npairs], lst.fp[:lst.npairs]
    keep = f != 0
    pairs = np.concatenate([j[keep].astype(np.int64), f[keep].view(np.int64)])
    return (lst.rho_sum[:n][need].copy(), pairs, parts.acc[:n_own].copy())


def check(args, gather, threads):
    """The new passes give the reference's numbers bit for bit on this list (sums of the particles that need
    them, the pairs within 2h with their (dW/dr)/r, accelerations)."""
    lst, parts = args[0], args[1]
    numba.set_num_threads(threads)
    if threads == 1:
        reference_passes.density_serial(*args)
        reference_passes.momentum_serial(*args)
        ref = outputs(lst, parts)
        equations.density_serial(*args)
        equations.momentum_serial(*args)
        new = outputs(lst, parts, compact=True)
    else:
        reference_passes.density_threaded(*args, gather)
        reference_passes.momentum_threaded(*args, gather)
        ref = outputs(lst, parts)
        equations.density_threaded(*args, gather)
        equations.momentum_threaded(*args, gather)
        new = outputs(lst, parts)
    names = ("rho_sum", "pairs", "acc")
    return [name for name, a, b in zip(names, ref, new) if not np.array_equal(a, b)]


def per_call(fn, args, reps):
    """(wall, process CPU) seconds per call."""
    w0, c0 = time.perf_counter(), time.process_time()
    for _ in range(reps):
        fn(*args)
    return (time.perf_counter() - w0) / reps, (time.process_time() - c0) / reps


def timings(args, gather, threads, rounds, seconds):
    """Minimum (wall, CPU) seconds per call of each pass over ``rounds`` alternating rounds."""
    numba.set_num_threads(threads)
    if threads == 1:
        passes = {"density_ref": (reference_passes.density_serial, args),
                  "density_new": (equations.density_serial, args),
                  "forces_ref": (reference_passes.momentum_serial, args),
                  "forces_new": (equations.momentum_serial, args)}
    else:
        targs = args + (gather,)
        passes = {"density_ref": (reference_passes.density_threaded, targs),
                  "density_new": (equations.density_threaded, targs),
                  "forces_ref": (reference_passes.momentum_threaded, targs),
                  "forces_new": (equations.momentum_threaded, targs)}
    reps = {}
    for name, (fn, a) in passes.items():
        fn(*a)
        reps[name] = max(2, int(seconds / max(per_call(fn, a, 3)[0], 1e-7)))
    wall = dict.fromkeys(passes, np.inf)
    cpu = dict.fromkeys(passes, np.inf)
    for _ in range(rounds):
        for name, (fn, a) in passes.items():
            w, c = per_call(fn, a, reps[name])
            wall[name] = min(wall[name], w)
            cpu[name] = min(cpu[name], c)
    return wall, cpu


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
        sim, args, gather = state(nx, a.warmup)
        lst = args[0]
        for threads in a.threads:
            if threads > numba.config.NUMBA_NUM_THREADS:
                print(f"Nx={nx}: {threads} threads: numba allows {numba.config.NUMBA_NUM_THREADS} here, skipped")
                continue
            differ = check(args, gather, threads)
            if differ:
                print(f"Nx={nx} T={threads}: new passes differ from the reference in {', '.join(differ)}")
                status = 1
            load0 = os.getloadavg()[0]
            wall, cpu = timings(args, gather, threads, a.rounds, a.seconds)
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
                with open(a.json, "a") as f:
                    f.write(json.dumps(rec) + "\n")
        numba.set_num_threads(1)
    return status


if __name__ == "__main__":
    sys.exit(main())
