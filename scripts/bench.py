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
Python per step. The scalar reference loops (below) time the two pair passes'
arithmetic on the same pair list. Memory: peak resident set size summed over
ranks, per particle. One JSON record per size goes to --json (appended).
"""
import argparse
import json
import os
import platform
import resource
import sys
import time

import numpy as np
from mpi4py import MPI
import numba
from numba import njit

from parsph.studies import cases
from parsph.simulation.solver import PHASES, Simulation
from parsph.sph import pass_data, reference_passes

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def make_config(nx, extra=()):
    return cases.couette(nx, overrides=["output.t_end=1.0", *extra])


@njit(cache=True)
def reference_forces(order, pstart, pj, n, x, y, vx, vy, m, th, ith, pr, irho, fp, c1, c2, ax, ay):
    """The arithmetic of Eq. (5) for fluid pairs, nothing else: each pair once, no branches, no walls.

    A ceiling for the solver's force loop on the same pair list (not part of parsph).
    """
    ax[:n] = 0.0
    ay[:n] = 0.0
    for a in range(n):
        i = order[a]
        xi = x[i]
        yi = y[i]
        vxi = vx[i]
        vyi = vy[i]
        thi = th[i]
        ithi = ith[i]
        pri = pr[i]
        irhoi = irho[i]
        mi = m[i]
        a0 = ax[i]
        a1 = ay[i]
        for p in range(pstart[a], pstart[a + 1]):
            j = pj[p]
            f = fp[p]
            P = c1 * pri * pr[j] * (ithi + ith[j]) * f
            V = (thi + th[j]) * irhoi * irho[j] * f
            rx = xi - x[j]
            ry = yi - y[j]
            ux = vxi - vx[j]
            uy = vyi - vy[j]
            si = c2 * thi * V
            sj = c2 * th[j] * V
            a0 += m[j] * (P * rx + si * ux)
            a1 += m[j] * (P * ry + si * uy)
            ax[j] -= mi * (P * rx + sj * ux)
            ay[j] -= mi * (P * ry + sj * uy)
        ax[i] = a0
        ay[i] = a1


@njit(cache=True)
def reference_forces_rows(order, pstart, pj, n, rows, m, fp, c1, c2, ax, ay):
    """:func:`reference_forces` reading one packed row per particle (x, y, vx, vy, theta, 1/theta,
    pressure factor, 1/rho: 64 bytes, one cache line) instead of eight separate arrays."""
    ax[:n] = 0.0
    ay[:n] = 0.0
    for a in range(n):
        i = order[a]
        xi = rows[i, 0]
        yi = rows[i, 1]
        vxi = rows[i, 2]
        vyi = rows[i, 3]
        thi = rows[i, 4]
        ithi = rows[i, 5]
        pri = rows[i, 6]
        irhoi = rows[i, 7]
        mi = m[i]
        a0 = ax[i]
        a1 = ay[i]
        for p in range(pstart[a], pstart[a + 1]):
            j = pj[p]
            f = fp[p]
            P = c1 * pri * rows[j, 6] * (ithi + rows[j, 5]) * f
            V = (thi + rows[j, 4]) * irhoi * rows[j, 7] * f
            rx = xi - rows[j, 0]
            ry = yi - rows[j, 1]
            ux = vxi - rows[j, 2]
            uy = vyi - rows[j, 3]
            si = c2 * thi * V
            sj = c2 * rows[j, 4] * V
            a0 += m[j] * (P * rx + si * ux)
            a1 += m[j] * (P * ry + si * uy)
            ax[j] -= mi * (P * rx + sj * ux)
            ay[j] -= mi * (P * ry + sj * uy)
        ax[i] = a0
        ay[i] = a1


@njit(cache=True)
def reference_density(order, pstart, pj, n, x, y, m, h, norm, rho, fp):
    """The cubic spline sum of Eq. (3) over the pair list, each pair once, nothing else (2-D)."""
    inv_h = 1.0 / h
    for k in range(n):
        rho[k] = 4.0 * m[k]
    for a in range(n):
        i = order[a]
        xi = x[i]
        yi = y[i]
        s = rho[i]
        mi = m[i]
        for p in range(pstart[a], pstart[a + 1]):
            j = pj[p]
            dx = xi - x[j]
            dy = yi - y[j]
            q = np.sqrt(dx * dx + dy * dy) * inv_h
            a2 = max(2.0 - q, 0.0)
            b1 = max(1.0 - q, 0.0)
            w = a2 * a2 * a2 - 4.0 * b1 * b1 * b1
            fp[p] = w
            s += m[j] * w
            rho[j] += mi * w
        rho[i] = s
    for k in range(n):
        rho[k] *= norm


def reference(sim, repeat=20):
    """ns per unique pair of the two reference loops on the solver's current pair list."""
    R, N, ps, cfg = sim.rates, sim.neighbours, sim.ps, sim.cfg
    n = ps.n
    pairs = N.npairs
    # (dW/dr)/r of every listed pair, which the force loops below read (the solver's serial pass writes only
    # the pairs within 2h, into its compact list): the scalar reference pass fills R.fp
    reference_passes.density_serial(R.list, pass_data.particle_arrays(ps), R.consts, R.switches)
    x, y = ps.pos[:n, 0].copy(), ps.pos[:n, 1].copy()
    vx, vy = ps.vel[:n, 0].copy(), ps.vel[:n, 1].copy()
    th = ps.theta[:n].copy()
    fargs = (N.order, N.pstart, N.pj, n, x, y, vx, vy, ps.mass[:n].copy(), th, 1.0 / th,
             R.fields[:n, 6].copy(), R.fields[:n, 4].copy(), R.fp.copy(), -1.0 / cfg.rho_s ** 2, cfg.k,
             np.zeros(n), np.zeros(n))
    result = {"forces": timed(reference_forces, fargs, repeat) / pairs * 1e9}
    rows = np.ascontiguousarray(np.column_stack([x, y, vx, vy, th, 1.0 / th, R.fields[:n, 6], R.fields[:n, 4]]))
    rargs = (N.order, N.pstart, N.pj, n, rows, ps.mass[:n].copy(), R.fp.copy(), -1.0 / cfg.rho_s ** 2, cfg.k,
             np.zeros(n), np.zeros(n))
    result["forces_rows"] = timed(reference_forces_rows, rargs, repeat) / pairs * 1e9
    dargs = (N.order, N.pstart, N.pj, n, x, y, ps.mass[:n].copy(), cfg.h, sim.kernel.norm(cfg.h, cfg.dim),
             np.zeros(n), np.zeros(len(R.fp)))
    result["density"] = timed(reference_density, dargs, repeat) / pairs * 1e9
    return result


def timed(fn, args, repeat):
    """CPU seconds per call (after one warm-up call): process time, not disturbed by other processes."""
    fn(*args)
    t0 = time.process_time()
    for _ in range(repeat):
        fn(*args)
    return (time.process_time() - t0) / repeat


def threading_layer():
    try:
        return numba.threading_layer()
    except ValueError:  # no parallel region has run
        return "none"


def current_rss():
    """Resident set size of this process now [bytes]."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def bench(comm, nx, steps=None, extra=(), budget=5.0, warmup=200):
    cfg = make_config(nx, extra)
    rss0 = comm.allreduce(current_rss(), op=MPI.SUM)
    comm.Barrier()
    t0 = time.perf_counter()
    sim = Simulation(cfg, comm)
    sim.take_steps(1)
    jit = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    sim.take_steps(warmup)  # past the impulsive start, whose first steps rebuild the list often
    if steps is None:
        t1, s1 = time.perf_counter(), sim.step
        sim.take_steps(20)
        per = comm.allreduce((time.perf_counter() - t1) / max(sim.step - s1, 1), op=MPI.MAX)
        steps = max(10, int(budget / per))
    sim.timers.clear()
    rebuilds0, calls0, step0 = sim.rebuilds, sim.block_calls, sim.step
    comm.Barrier()
    c0, t0 = time.process_time(), time.perf_counter()
    sim.take_steps(steps)
    cpu = comm.allreduce(time.process_time() - c0, op=MPI.SUM)  # all ranks' CPU seconds in the timed steps
    comm.Barrier()
    wall = time.perf_counter() - t0
    steps = sim.step - step0
    rebuilds = sim.rebuilds - rebuilds0
    phases = {k: comm.allreduce(sim.timers.get(k, 0.0), op=MPI.MAX) / steps for k in PHASES}
    # the rank that reaches an exchange last waits least: its time is the message cost without the imbalance
    phases_min = {k: comm.allreduce(sim.timers.get(k, 0.0), op=MPI.MIN) / steps for k in PHASES}
    inside = sum(sim.timers.get(k, 0.0) for k in PHASES)
    outside = comm.allreduce(max(wall - inside, 0.0) / wall, op=MPI.MAX)
    pairs = comm.allreduce(sim.neighbours.npairs, op=MPI.SUM)
    rss = comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, op=MPI.SUM)
    ref = reference(sim)
    step = wall / steps
    return {
        "nx": nx, "ranks": comm.size, "particles": sim.n_total, "steps": steps, "dt": sim.dt,
        "step_s": step, "particle_steps_per_s": sim.n_total * steps / wall,
        "cpu_s_per_step": cpu / steps, "pairs_per_step": pairs,
        "ns_per_pair_density": phases["density"] * comm.size / pairs * 1e9,
        "ns_per_pair_forces": phases["forces"] * comm.size / pairs * 1e9,
        "ns_per_pair_reference_density": ref["density"], "ns_per_pair_reference_forces": ref["forces"],
        "ns_per_pair_reference_forces_rows": ref["forces_rows"],
        "steps_per_rebuild": steps / max(rebuilds, 1), "returns_per_step": (sim.block_calls - calls0) / steps,
        "native_mpi": sim.native, "jit_s": jit, "phases_s": phases, "phases_min_s": phases_min,
        "outside_phases_share": outside,
        "rss_bytes_per_particle": rss / sim.n_total,
        "rss_before_bytes": rss0, "rss_added_bytes_per_particle": (rss - rss0) / sim.n_total,
        "threads": numba.get_num_threads(), "threading_layer": threading_layer(),
        "machine": f"{platform.node()}, {os.cpu_count()} cores, {platform.processor() or platform.machine()}",
    }


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
    Simulation(make_config(10), comm).take_steps(2)  # load the compiled loops before any RSS is taken
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
                with open(a.json, "a") as f:
                    f.write(json.dumps(r) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
