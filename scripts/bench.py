"""Benchmark one configuration: particle-steps per second and the per-phase breakdown.

    [mpirun -n P] .venv/bin/python scripts/bench.py --nx 50 200 [--steps N] [--json FILE] [--tag TEXT]

For each N_x the Couette case (L_y = L, h = 1.25 dx, dt = "auto") is built;
one step is taken to compile (numba caches on disk; the first-ever compile is
reported as ``jit_s``), then ``--steps`` steps are timed. Phase times are the
slowest rank's seconds per step (``phases_min_s``: the fastest rank's). A second pass times every numba call: the
rest of the step ("outside numba") is Python orchestration and MPI. Memory: peak resident set size summed over
ranks, per particle. One JSON record per size goes to --json (appended).
"""
import argparse
import json
import os
import platform
import resource
import sys
import time
import tomllib

import numpy as np
from mpi4py import MPI
import numba
from numba import njit

from numba.core.registry import CPUDispatcher

from parsph import config, decomposition, equations, integrate, neighbours, particles, rates, solver
from parsph.solver import PHASES, Simulation

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def make_config(nx, extra=()):
    raw = tomllib.loads(open(os.path.join(ROOT, "run", "couette_paper.toml")).read())
    del raw["numerics"]["h"]
    config.apply_overrides(raw, [f"numerics.Nx={nx}", "numerics.h_over_dx=1.25", 'numerics.dt="auto"',
                                 "output.times=[]", "output.t_end=1.0", *extra])
    return config.build(raw, config.dumps(raw))


class NumbaClock:
    """Wraps every numba function the solver calls to add up the time spent inside them."""

    def __init__(self):
        self.seconds = 0.0
        self._saved = []

    def install(self):
        for mod in (equations, integrate, neighbours, particles, decomposition, rates, solver):
            for name, obj in list(vars(mod).items()):
                if isinstance(obj, CPUDispatcher):
                    self._saved.append((mod, name, obj))
                    setattr(mod, name, self._wrap(obj))

    def _wrap(self, fn):
        def timed(*args):
            t0 = time.perf_counter()
            out = fn(*args)
            self.seconds += time.perf_counter() - t0
            return out
        return timed

    def remove(self):
        for mod, name, obj in self._saved:
            setattr(mod, name, obj)


@njit(cache=True)
def reference_forces(n, sx, sy, svx, svy, sm, sth, sinv_th, shg, sinv_rho, nbr_n, nbr_j, nbr_f, c1, c2,
                     ax, ay):
    """The arithmetic of Eq. (5) for fluid pairs, nothing else: no branches, reciprocals precomputed.

    A ceiling for the solver's force loop on the same neighbour list (not part of parsph).
    """
    for i in range(n):
        a0 = 0.0
        a1 = 0.0
        xi = sx[i]
        yi = sy[i]
        thi = sth[i]
        ith = sinv_th[i]
        irho = sinv_rho[i]
        hgi = shg[i]
        vxi = svx[i]
        vyi = svy[i]
        for p in range(nbr_n[i]):
            j = nbr_j[i, p]
            f = nbr_f[i, p]
            m = sm[j]
            cp = c1 * m * hgi * shg[j] * (ith + sinv_th[j]) * f
            cv = c2 * thi * m * (thi + sth[j]) * irho * sinv_rho[j] * f
            a0 += cp * (xi - sx[j]) + cv * (vxi - svx[j])
            a1 += cp * (yi - sy[j]) + cv * (vyi - svy[j])
        ax[i] = a0
        ay[i] = a1


@njit(cache=True)
def reference_density(n, sx, sy, sm, cell_of, start, ncx, ncy, h, norm, out):
    """Cell search and cubic-spline sum of Eq. (3) for every particle, nothing else (2-D)."""
    inv_h = 1.0 / h
    s2 = 4.0 * h * h
    for i in range(n):
        c0 = cell_of[i]
        cx0 = c0 % ncx
        cy0 = c0 // ncx
        acc = 0.0
        for a in range(max(cx0 - 1, 0), min(cx0 + 2, ncx)):
            for b in range(max(cy0 - 1, 0), min(cy0 + 2, ncy)):
                c = b * ncx + a
                for j in range(start[c], start[c + 1]):
                    dx = sx[i] - sx[j]
                    dy = sy[i] - sy[j]
                    r2 = dx * dx + dy * dy
                    if r2 < s2:
                        q = np.sqrt(r2) * inv_h
                        w = 4.0 - 6.0 * q * q + 3.0 * q * q * q if q < 1.0 else (2.0 - q) ** 3
                        acc += sm[j] * w
        out[i] = acc * norm


def reference(sim, repeat=20):
    """ns per neighbour pair of the two reference loops on the solver's current data.

    The force loop walks the solver's neighbour list of its last evaluation;
    the density loop then re-sorts the particles into cells of side 2h.
    """
    W, ps, cfg = sim.work, sim.ps, sim.cfg
    n = ps.n
    pairs = W.pairs(n)
    ax, ay = np.zeros(n), np.zeros(n)
    sinv_th, sinv_rho = W.sinv[:n, 1].copy(), W.sinv[:n, 0].copy()
    fargs = (n, W.sx, W.sy, W.svx, W.svy, W.sm, W.stheta, sinv_th, W.spress, sinv_rho,
             W.nbr_n, W.nbr_j, W.nbr_f, -1.0 / cfg.rho_s ** 2, cfg.k, ax, ay)
    result = {"forces": timed(reference_forces, fargs, repeat) / pairs * 1e9}
    grid = neighbours.sort_into_cells(
        ps.pos, ps.vel, ps.mass, ps.kind, ps.gid, n, ps.n_own, sim.x0, sim.rates.cell,
        W.order, W.cell_of, W.tmp, W.sx, W.sy, W.sz, W.svx, W.svy, W.svz, W.sm, W.skind, W.owned)
    start, ncx, ncy = grid[:3]
    dargs = (n, W.sx, W.sy, W.sm, W.cell_of, start, ncx, ncy, cfg.h, sim.kernel.norm(cfg.h, cfg.dim), np.zeros(n))
    result["density"] = timed(reference_density, dargs, repeat) / pairs * 1e9
    return result


def timed(fn, args, repeat):
    """Seconds per call (after one warm-up call)."""
    fn(*args)
    t0 = time.perf_counter()
    for _ in range(repeat):
        fn(*args)
    return (time.perf_counter() - t0) / repeat


def threading_layer():
    try:
        return numba.threading_layer()
    except ValueError:  # no parallel region has run
        return "none"


def current_rss():
    """Resident set size of this process now [bytes]."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def bench(comm, nx, steps=None, extra=(), budget=5.0):
    cfg = make_config(nx, extra)
    rss0 = comm.allreduce(current_rss(), op=MPI.SUM)
    comm.Barrier()
    t0 = time.perf_counter()
    sim = Simulation(cfg, comm)
    sim.compute_rates()
    sim.advance(cfg.dt)
    jit = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    if steps is None:
        t1 = time.perf_counter()
        for _ in range(3):
            sim.compute_rates()
            sim.advance(cfg.dt)
        per = comm.allreduce((time.perf_counter() - t1) / 3, op=MPI.MAX)
        steps = max(10, int(budget / per))
    sim.timers.clear()
    comm.Barrier()
    c0, t0 = time.process_time(), time.perf_counter()
    for _ in range(steps):
        sim.compute_rates()
        sim.advance(cfg.dt)
    comm.Barrier()
    wall = time.perf_counter() - t0
    phases = {k: comm.allreduce(sim.timers.get(k, 0.0), op=MPI.MAX) / steps for k in PHASES}
    # the rank that reaches an exchange last waits least: its time is the message cost without the imbalance
    phases_min = {k: comm.allreduce(sim.timers.get(k, 0.0), op=MPI.MIN) / steps for k in PHASES}
    # a second, shorter pass with every numba call timed: the rest is Python and MPI
    clock = NumbaClock()
    clock.install()
    n2 = max(10, steps // 4)
    t1 = time.perf_counter()
    for _ in range(n2):
        sim.compute_rates()
        sim.advance(cfg.dt)
    wall2 = time.perf_counter() - t1
    clock.remove()
    outside = comm.allreduce((wall2 - clock.seconds) / wall2, op=MPI.MAX)
    cpu = comm.allreduce(time.process_time() - c0, op=MPI.SUM)
    pairs = comm.allreduce(sim.work.pairs(sim.ps.n), op=MPI.SUM)
    rss = comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, op=MPI.SUM)
    ref = reference(sim)
    step = wall / steps
    return {
        "nx": nx, "ranks": comm.size, "particles": sim.n_total, "steps": steps, "dt": cfg.dt,
        "step_s": step, "particle_steps_per_s": sim.n_total * steps / wall,
        "cpu_s_per_step": cpu / steps, "pairs_per_step": pairs,
        "ns_per_pair_density": phases["density"] * comm.size / pairs * 1e9,
        "ns_per_pair_forces": phases["forces"] * comm.size / pairs * 1e9,
        "ns_per_pair_reference_density": ref["density"], "ns_per_pair_reference_forces": ref["forces"],
        "jit_s": jit, "phases_s": phases, "phases_min_s": phases_min, "outside_numba_share": outside,
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
    warm = Simulation(make_config(10), comm)  # load the compiled loops before any RSS is taken
    warm.compute_rates()
    warm.advance(warm.cfg.dt)
    del warm
    for nx in a.nx:
        r = bench(comm, nx, a.steps or None, a.set, a.budget)
        r["tag"] = a.tag
        if comm.rank == 0:
            ph = " ".join(f"{k} {v * 1e3:.3f}" for k, v in r["phases_s"].items())
            print(f"Nx={nx:4d} P={r['ranks']} N={r['particles']:7d} {r['step_s'] * 1e3:9.3f} ms/step "
                  f"T={r['threads']} {r['particle_steps_per_s']:.3g} particle-steps/s  outside numba {100 * r['outside_numba_share']:.1f}%  "
                  f"{r['ns_per_pair_density']:.1f}/{r['ns_per_pair_forces']:.1f} ns/pair (density/forces)  "
                  f"RSS {r['rss_bytes_per_particle']:.0f} B/particle "
                  f"({r['rss_added_bytes_per_particle']:.0f} B above the {r['rss_before_bytes'] / 2**20:.0f} MiB before)  jit+setup {r['jit_s']:.1f} s {a.tag}",
                  flush=True)
            print(f"    ms/step: {ph}", flush=True)
            print(f"    reference loops: {r['ns_per_pair_reference_density']:.1f}/"
                  f"{r['ns_per_pair_reference_forces']:.1f} ns/pair (density/forces)", flush=True)
            if a.json:
                with open(a.json, "a") as f:
                    f.write(json.dumps(r) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
