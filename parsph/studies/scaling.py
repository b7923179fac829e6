"""Strong and weak scaling measured (scripts/scaling.py, docs/scaling.md): what one rank records while the
benchmarks' case steps under ``mpirun -n P``, and the per-P summary of those records.

Each rank runs every size given in one process, their timed blocks in turn
(a drift of the machine's speed then hits all sizes alike), and records:
wall time per step (the mean, and the fastest block: on a shared machine the
least disturbed one) and CPU time (``time.process_time``; MPI waits spin and
count as CPU); the solver's phases (``Simulation(clock=time.process_time)``:
the Python ones in CPU seconds, the compiled blocks' in wall seconds, their
waits included); every send and all-reduce with its bytes: the step's
(``forward``, ``refresh``, ``step``) from the sizes of the ghost rounds, the
list builds' (``migrate``, ``exchange_ghosts``) and the CPU seconds waiting
in them from ``SlabRing.stats``; owned, ghost and image particles, list
pairs, list builds; and one ghost round and one 3-float all-reduce alone (the
fastest of ``reps``), through the route the step takes (compiled code where
native MPI loads). The counts are what the scaling model
(:mod:`parsph.studies.scaling_model`) predicts from the lattice.
"""
import csv
import json
import os
import platform
import time
from types import SimpleNamespace

import numba
import numpy as np
from mpi4py import MPI

from parsph.parallel import native_halo, native_mpi, slabs
from parsph.physics import kernels
from parsph.simulation.solver import Simulation
from parsph.sph import cells
from .builders import bench
from .machine import cpu_model


def machine():
    """The machine, as the scaling records name it."""
    return f"{platform.node()}: {os.cpu_count()} cores, {cpu_model()}"


def slabs_refused(p, nx, sets):
    """Why ``p`` ranks do not fit the benchmarks' case at N_x = ``nx`` with ``sets`` (None: they fit)."""
    cfg = bench(nx, sets)
    grid = cells.grid_for(cfg, kernels.get_kernel(cfg.kernel, cfg.dim))
    cut = grid.cutoff
    if slabs.fits(cfg.Ly_ring, p, grid.axes[1].side, grid.axes[1].n, grid.m):
        return None
    return (f"{p} ranks do not fit N_x = {nx}, L_y = {cfg.Ly:g} m (slabs of at least about 1.5 x the cutoff "
            f"{cut:g} m): at most {slabs.max_ranks(cfg.Ly_ring, cut, cells.CELLS_PER_CUTOFF)}")


# ---- one rank, under mpirun ------------------------------------------------------------------------
def _lone_rounds(sim, reps):
    """Seconds of one ghost round, one rho round and one 3-float all-reduce alone (the fastest of reps),
    through the route the step uses (compiled code where native MPI loads, else mpi4py)."""
    ring, ps, comm = sim.ring, sim.ps, sim.comm
    buf, out = np.zeros(3), np.zeros(3)
    best = {"forward": np.inf, "refresh": np.inf, "allreduce": np.inf}
    plan = ring.plan(ps.dim) if sim.native else None
    if plan is not None:
        args = (plan, ps.pos, ps.vel, ps.disp, ps.n_own)
        native_halo.forward(*args), native_halo.refresh(plan, ps.rho, ps.n_own)  # compile or load first
    h = native_mpi.handles(comm) if plan is not None else None
    for _ in range(reps):
        comm.Barrier()
        t0 = time.perf_counter()
        native_halo.forward(*args) if plan is not None else ring.forward(ps)
        t1 = time.perf_counter()
        native_halo.refresh(plan, ps.rho, ps.n_own) if plan is not None else ring.refresh(ps, ps.rho)
        t2 = time.perf_counter()
        native_mpi.allreduce(h, native_mpi.OP_MAX, buf, out) if plan is not None else \
            comm.Allreduce(buf, out, op=MPI.MAX)
        t3 = time.perf_counter()
        for k, v in (("forward", t1 - t0), ("refresh", t2 - t1), ("allreduce", t3 - t2)):
            best[k] = min(best[k], v)
    return best


def _step_messages(sim, steps):
    """The step's messages (calls, bytes) by phase over ``steps`` steps, from the plan's sizes: each step
    sends one ghost round (pos, vel, disp) and one rho round to the two neighbours and all-reduces the
    three flags (the midpoint integrator: twice; auto dt: the maxima too)."""
    ring, d = sim.ring, sim.ps.dim
    ghosts_sent = len(ring.send_up) + len(ring.send_down)
    evals = 2 if sim.cfg.integrator == "midpoint" else 1
    out = {"forward.send": {"calls": 2 * evals * steps, "bytes": 8 * 3 * d * ghosts_sent * evals * steps},
           "refresh.send": {"calls": 2 * evals * steps, "bytes": 8 * ghosts_sent * evals * steps},
           "step.allreduce": {"calls": (evals + int(sim.cfg.dt_auto)) * steps,
                              "bytes": 24 * (evals + int(sim.cfg.dt_auto)) * steps}}
    st = ring.stats
    for method, (calls, nbytes) in st["sends"].items():
        if method in ("migrate", "exchange_ghosts"):
            out[f"{method}.send"] = {"calls": calls, "bytes": nbytes}
    for method, calls in st["allreduces"].items():
        out[f"{method}.allreduce"] = {"calls": calls, "bytes": 8 * calls}
    return out


def measure(nxs, sets, warmup, blocks, block, reps, threads, tag):
    """Every size of ``nxs`` in this process on COMM_WORLD, their timed blocks in turn (the machine's
    speed drifts): one JSON record per size, on rank 0 (None on the other ranks)."""
    numba.set_num_threads(threads)
    world = MPI.COMM_WORLD
    runs = []
    for nx in nxs:
        # the solver's Python phase timers and the ring's message statistics in CPU seconds
        sim = Simulation(bench(nx, sets), world, clock=time.process_time)
        sim.take_steps(1 + warmup)
        sim.timers.clear()
        for part in sim.ring.stats.values():
            part.clear()
        runs.append(SimpleNamespace(nx=nx, sim=sim, r0=sim.rebuilds, s0=sim.step, walls=[], cpus=[], rebuilds=[]))
    for _ in range(blocks):
        for run in runs:
            sim = run.sim
            world.Barrier()
            b0, w0, c0 = sim.rebuilds, time.perf_counter(), time.process_time()
            sim.take_steps(block)
            run.cpus.append(time.process_time() - c0)
            world.Barrier()
            run.walls.append(time.perf_counter() - w0)
            run.rebuilds.append(sim.rebuilds - b0)
    lines = []
    for run in runs:
        sim, ring, ps = run.sim, run.sim.ring, run.sim.ps
        steps = sim.step - run.s0
        st = ring.stats
        waits = sum(st["waiting"].values())
        mine = {
            "rank": world.rank, "own": ps.n_own, "ghosts_below": ring.n_below, "ghosts_above": ring.n_above,
            "images": ring.n_images, "local": ps.n, "pairs": sim.neighbours.npairs,
            "cpu_s_per_step": sum(run.cpus) / steps, "wall_block_s": run.walls, "rebuilds_per_block": run.rebuilds,
            # waits in the Python-side messages (list builds; every step on the mpi4py path); the compiled
            # step's waits are inside its sync and halo phases
            "blocked_cpu_s_per_step": waits / steps, "blocked_wall_s_per_step": waits / steps,
            "blocked_cpu_by_phase_s": {k: v / steps for k, v in st["waiting"].items()},
            "ring_cpu_s": {k: v / steps for k, v in st["seconds"].items()},
            "phases_cpu_s": {k: v / steps for k, v in sim.timers.items()},
            "messages": _step_messages(sim, steps),
            "native_mpi": sim.native, "returns_per_step": sim.block_calls / max(sim.step, 1),
        }
        mine["alone_s"] = _lone_rounds(sim, reps)
        mine["alone_blocked_s"] = sum(mine["alone_s"].values())
        ranks = world.gather(mine, root=0)
        if world.rank == 0:
            nreb = sim.rebuilds - run.r0
            lines.append(json.dumps({
                "mode": tag, "nx": run.nx, "set": sets, "ranks": world.size, "threads": threads,
                "particles": sim.n_total, "dt": sim.cfg.dt, "steps": steps, "warmup": warmup,
                "step_s": sum(run.walls) / steps, "step_best_block_s": min(run.walls) / block,
                "cpu_s_per_step_max": max(r["cpu_s_per_step"] for r in ranks),
                "rebuilds": nreb, "steps_per_rebuild": steps / max(nreb, 1),
                "cutoff": sim.grid.cutoff, "Ly": sim.cfg.Ly, "per_rank": ranks, "machine": machine()}))
    return lines if world.rank == 0 else None


# ---- the records of every P ------------------------------------------------------------------------------
def summary(r):
    """One CSV row: times per step, and per-rank means (max where it matters) of counts and messages."""
    pr = r["per_rank"]
    P = r["ranks"]
    steps, nreb = r["steps"], max(r["rebuilds"], 1)

    row = {"ranks": P, "particles": r["particles"], "step_s": r["step_s"], "step_best_block_s": r["step_best_block_s"],
           "cpu_s_per_step_max": r["cpu_s_per_step_max"], "steps_per_rebuild": r["steps_per_rebuild"],
           "own_max": max(x["own"] for x in pr), "ghosts_max": max(x["ghosts_below"] + x["ghosts_above"] for x in pr),
           "ghosts_mean": sum(x["ghosts_below"] + x["ghosts_above"] for x in pr) / P,
           "images_max": max(x["images"] for x in pr), "pairs_max": max(x["pairs"] for x in pr),
           "pairs_sum": sum(x["pairs"] for x in pr)}
    for ph, div, lab in (("forward", steps, "step"), ("refresh", steps, "step"), ("step", steps, "step"),
                         ("migrate", nreb, "rebuild"), ("exchange_ghosts", nreb, "rebuild")):
        for op in ("send", "allreduce"):
            calls = max(x["messages"].get(f"{ph}.{op}", {}).get("calls", 0) for x in pr) / div
            nbytes = max(x["messages"].get(f"{ph}.{op}", {}).get("bytes", 0) for x in pr) / div
            if calls:
                row[f"{ph}_{op}s_per_{lab}"] = calls
                row[f"{ph}_{op}_bytes_per_{lab}"] = nbytes
    for k in ("forward", "refresh", "allreduce"):
        row[f"alone_{k}_s"] = max(x["alone_s"][k] for x in pr)
    # CPU outside blocking MPI calls (waits spin and count as CPU), and that plus one lone step's blocking:
    # the time per step on cores of one's own, without the waits that other processes' load causes here
    row["cpu_busy_s_per_step_max"] = max(x["cpu_s_per_step"] - x["blocked_cpu_s_per_step"] for x in pr)
    row["blocked_wall_s_per_step_max"] = max(x["blocked_wall_s_per_step"] for x in pr)
    row["alone_blocked_s"] = max(x["alone_blocked_s"] for x in pr)
    row["own_cores_estimate_s"] = row["cpu_busy_s_per_step_max"] + row["alone_blocked_s"]
    return row


def write_table(records, mode, nx, sets, base):
    """BASE.csv (one row per P, the busiest rank: :func:`summary`, with the efficiency against P = 1:
    T_1 / (P T_P) strong, T_1 / T_P weak) and BASE.png (where matplotlib is present); the rows."""
    rows = [summary(r) for r in records]
    t1 = rows[0]["step_best_block_s"]
    for o in rows:
        p = o["ranks"]
        o["efficiency"] = t1 / (p * o["step_best_block_s"]) if mode == "strong" else t1 / o["step_best_block_s"]
    desc = machine()
    with open(base + ".csv", "w", newline="") as f:
        f.write(f"# {mode} scaling, N_x = {nx} {' '.join(sets)}, {desc}\n")
        keys = list(dict.fromkeys(k for o in rows for k in o))
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.8))
        P = [o["ranks"] for o in rows]
        ax1.loglog(P, [o["step_best_block_s"] * 1e3 for o in rows], "o-", label="fastest block")
        ax1.loglog(P, [o["cpu_s_per_step_max"] * 1e3 for o in rows], "s:", label="CPU, busiest rank")
        if mode == "strong":
            ax1.loglog(P, [t1 * 1e3 / p for p in P], "k--", lw=0.8, label="ideal")
        ax1.legend()
        ax1.set_xlabel("ranks P")
        ax1.set_ylabel("time per step [ms]")
        ax2.plot(P, [o["efficiency"] for o in rows], "o-")
        ax2.axhline(1.0, color="k", lw=0.8, ls="--")
        ax2.set_ylim(0, 1.1)
        ax2.set_xlabel("ranks P")
        ax2.set_ylabel("parallel efficiency")
        fig.suptitle(f"{mode} scaling, N_x = {nx}\n{desc}", fontsize=9)
        fig.tight_layout()
        fig.savefig(base + ".png", dpi=110)
    except ImportError:
        pass
    return rows
