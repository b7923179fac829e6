"""Benchmarks of the step and of its pair passes (scripts/bench.py, bench_pairs.py; docs/performance.md).

:func:`bench` steps the benchmarks' Couette case (:func:`parsph.studies.builders.bench`)
through ``Simulation.take_steps``, the loop ``parsph run`` runs, and records its
rate, the phases of the slowest and the fastest rank, the memory and the
machine. Beside them it times scalar loops over the same pair list that do the
arithmetic of Eqs. (3) and (5) and nothing else (each pair once, no branches,
no walls): a ceiling the solver's passes are measured against, not used by
the solver. :func:`pair_state`, :func:`check_passes` and :func:`time_passes`
compare the passes of :mod:`parsph.sph.density` and :mod:`parsph.sph.momentum` with the scalar reference
passes of :mod:`parsph.sph.reference_passes` on one pair list: first bit for
bit, then timed in alternation (the minimum over rounds: the least disturbed
by other processes on a shared machine).
"""
import os
import platform
import time

import numba
import numpy as np
from mpi4py import MPI
from numba import njit

from parsph.simulation.solver import PHASES, Simulation
from parsph.sph import density, momentum, pass_data, reference_passes
from parsph.sph.pair_terms import pressure_term, viscosity_coefficient, viscous_term
from .builders import bench as bench_case
from .machine import current_rss, peak_rss, threading_layer


PAPER_FORM, OWN_MU = (), ()  # the switches of Eq. (5)'s paper form and mu_i = k theta_i (pass_data.switch)


@njit(cache=True)
def reference_forces(order, pstart, pj, n, x, y, vx, vy, m, th, ith, pr, irho, fp, c1, c2, ax, ay):
    """The arithmetic of Eq. (5) for fluid pairs, nothing else: each pair once, no branches, no walls.

    A ceiling for the solver's force loop on the same pair list (not used by the solver).
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
            P = pressure_term(pri, pr[j], ithi, ith[j], f, c1, PAPER_FORM)
            V = viscous_term(thi, th[j], irhoi, irho[j], f)
            rx = xi - x[j]
            ry = yi - y[j]
            ux = vxi - vx[j]
            uy = vyi - vy[j]
            si = viscosity_coefficient(thi, thi, th[j], c2, OWN_MU) * V
            sj = viscosity_coefficient(th[j], thi, th[j], c2, OWN_MU) * V
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
            P = pressure_term(pri, rows[j, 6], ithi, rows[j, 5], f, c1, PAPER_FORM)
            V = viscous_term(thi, rows[j, 4], irhoi, rows[j, 7], f)
            rx = xi - rows[j, 0]
            ry = yi - rows[j, 1]
            ux = vxi - rows[j, 2]
            uy = vyi - rows[j, 3]
            si = viscosity_coefficient(thi, thi, rows[j, 4], c2, OWN_MU) * V
            sj = viscosity_coefficient(rows[j, 4], thi, rows[j, 4], c2, OWN_MU) * V
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


def bench(comm, nx, steps=None, extra=(), budget=5.0, warmup=200):
    """One size's record: ``steps`` timed steps (None: as many as fit in ``budget`` seconds) of the
    benchmarks' case at N_x = ``nx`` (``extra``: run-file overrides) after one step to compile and
    ``warmup`` more past the impulsive start (whose first steps rebuild the neighbour list often)."""
    cfg = bench_case(nx, extra)
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
    rss = comm.allreduce(peak_rss(), op=MPI.SUM)
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


# ---- the pair passes against the reference passes ------------------------------------------------------
def pair_state(nx, warmup):
    """The benchmarks' case after ``warmup`` steps, its rates evaluated: (sim, pass arguments, gather)."""
    sim = Simulation(bench_case(nx), MPI.COMM_SELF)
    sim.take_steps(warmup)
    R = sim.rates
    return sim, (R.list, pass_data.particle_arrays(sim.ps), R.consts, R.switches), R.gather_arrays()


def _outputs(lst, parts, compact=False):
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


def check_passes(args, gather, threads):
    """The names of what the new passes give differently from the reference on this list (sums of the
    particles that need them, the pairs within 2h with their (dW/dr)/r, accelerations): none, bit for bit."""
    lst, parts = args[0], args[1]
    numba.set_num_threads(threads)
    if threads == 1:
        reference_passes.density_serial(*args)
        reference_passes.momentum_serial(*args)
        ref = _outputs(lst, parts)
        density.density_serial(*args)
        momentum.momentum_serial(*args)
        new = _outputs(lst, parts, compact=True)
    else:
        reference_passes.density_threaded(*args, gather)
        reference_passes.momentum_threaded(*args, gather)
        ref = _outputs(lst, parts)
        density.density_threaded(*args, gather)
        momentum.momentum_threaded(*args, gather)
        new = _outputs(lst, parts)
    names = ("rho_sum", "pairs", "acc")
    return [name for name, a, b in zip(names, ref, new) if not np.array_equal(a, b)]


def _per_call(fn, args, reps):
    """(wall, process CPU) seconds per call."""
    w0, c0 = time.perf_counter(), time.process_time()
    for _ in range(reps):
        fn(*args)
    return (time.perf_counter() - w0) / reps, (time.process_time() - c0) / reps


def time_passes(args, gather, threads, rounds, seconds):
    """Minimum (wall, CPU) seconds per call of each pass over ``rounds`` alternating rounds."""
    numba.set_num_threads(threads)
    if threads == 1:
        passes = {"density_ref": (reference_passes.density_serial, args),
                  "density_new": (density.density_serial, args),
                  "forces_ref": (reference_passes.momentum_serial, args),
                  "forces_new": (momentum.momentum_serial, args)}
    else:
        targs = args + (gather,)
        passes = {"density_ref": (reference_passes.density_threaded, targs),
                  "density_new": (density.density_threaded, targs),
                  "forces_ref": (reference_passes.momentum_threaded, targs),
                  "forces_new": (momentum.momentum_threaded, targs)}
    reps = {}
    for name, (fn, a) in passes.items():
        fn(*a)
        reps[name] = max(2, int(seconds / max(_per_call(fn, a, 3)[0], 1e-7)))
    wall = dict.fromkeys(passes, np.inf)
    cpu = dict.fromkeys(passes, np.inf)
    for _ in range(rounds):
        for name, (fn, a) in passes.items():
            w, c = _per_call(fn, a, reps[name])
            wall[name] = min(wall[name], w)
            cpu[name] = min(cpu[name], c)
    return wall, cpu
