"""One run of the accuracy/speed sweep (scripts/sweep.py), in its own process.

    .venv/bin/python scripts/sweep_run.py '{"Nx": 50, "kernel": "cubic_spline", ...}' [--profiles DIR] [--code DIR]

Builds the Couette case of run/couette_paper.toml (Table 1 physics) with the
run's numerical choices, runs it on one rank (COMM_SELF) with an in-memory
output callback (no HDF5 is written: the sweep measures the solver, not the
file system), and prints one JSON line: the choices, particle count, steps,
dt, wall and process CPU time of the time loop (cumulative at each output
time, too), and the errors against Eq. (8) at t = 0.01, 0.05, 0.2, 0.5 s
(those not past t_end).

Before the timed run a tiny case with the same kernel and integrator is run
once, so that loading numba's on-disk cache (or compiling) is not counted.

Choices (JSON keys): Nx, h_over_dx, kernel, integrator, dt ("auto" or seconds),
dt_safety, beta_max, layers (0: the fewest covering 2h), t_end, and perturb:
if set, one fluid particle of the column next to the moving wall is put at
distance perturb * dx from the wall plane at t = 0 (the robustness probe of
the Morris cap beta_max); set: further "section.key=value" overrides (diagnostics
that change the physics, e.g. a weaker modulus G; such runs are kept off the frontier).
"""
import hashlib
import json
import math
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
if "--code" in sys.argv:  # a snapshot of parsph (scripts/sweep.py makes one), ahead of the working tree
    sys.path.insert(0, os.path.abspath(sys.argv[sys.argv.index("--code") + 1]))

from mpi4py import MPI  # noqa: E402

from parsph.studies import cases  # noqa: E402
from parsph.sph.particles import FLUID  # noqa: E402
from parsph.errors import GuardError  # noqa: E402
from parsph.simulation.solver import Simulation  # noqa: E402

TIMES = (0.01, 0.05, 0.2, 0.5)
DEFAULTS = {"h_over_dx": 1.25, "kernel": "cubic_spline", "integrator": "paper", "dt": "auto",
            "dt_safety": 1.0, "beta_max": 1.5, "layers": 0, "t_end": 0.5, "perturb": None, "set": []}


def choices(run):
    out = dict(DEFAULTS)
    out.update(run)
    return out


def build_config(run):
    """The paper case (Table 1 physics: cases.couette, square box) with the run's numerics."""
    c = choices(run)
    times = [t for t in TIMES if t <= c["t_end"] * (1 + 1e-12)]
    return cases.couette(int(c["Nx"]), h_over_dx=float(c["h_over_dx"]),
                         dt="auto" if c["dt"] == "auto" else float(c["dt"]), overrides=[
        f'numerics.kernel="{c["kernel"]}"', f'numerics.integrator="{c["integrator"]}"',
        f"numerics.dt_safety={float(c['dt_safety'])!r}", f"walls.beta_max={float(c['beta_max'])!r}",
        f"walls.layers={int(c['layers'])}", f"output.t_end={float(c['t_end'])!r}", f"output.times={times!r}",
        "output.snapshots=false", *c["set"]])


def warm_up(run):
    """Load (or compile) every numba function the run will call, untimed."""
    c = choices(run)
    small = dict(c, Nx=12, t_end=1e-4, perturb=None)
    small["dt"] = "auto"
    sim = Simulation(build_config(small), MPI.COMM_SELF)
    sim.run(output=lambda s, snapshot=None: s.profile)  # noqa: the profile's numba function too


def perturb(sim, cfg, eps):
    """Move the fluid particle of the wall-adjacent column with the smallest y to d = eps dx."""
    ps = sim.ps
    n = ps.n_own
    fluid = np.flatnonzero(ps.kind[:n] == FLUID)
    last = fluid[np.abs(ps.pos[fluid, 0] - (cfg.L - 0.5 * cfg.dx)) < 1e-9 * cfg.L]
    k = last[np.argmin(ps.pos[last, 1])]
    ps.pos[k, 0] = cfg.L - eps * cfg.dx
    return int(ps.gid[k])


def main(argv):
    run = json.loads(argv[1])
    prof_dir = argv[argv.index("--profiles") + 1] if "--profiles" in argv else None
    c = choices(run)
    cfg = build_config(run)
    warm_up(run)
    sim = Simulation(cfg, MPI.COMM_SELF)
    moved = perturb(sim, cfg, float(c["perturb"])) if c["perturb"] else None
    outs = []
    t_wall0 = time.perf_counter()
    t_cpu0 = time.process_time()
    support = 2.0 * cfg.h  # both kernels have support 2h

    def output(s, snapshot=None):
        wall, cpu = time.perf_counter() - t_wall0, time.process_time() - t_cpu0
        prof = s.profile
        x, vy, exact = prof["x"], prof["vy"], prof["vy_exact"]
        emax, erms = prof["err"]
        e = np.abs(vy - exact) / abs(cfg.V_w)
        interior = (x >= support) & (x <= cfg.L - support)
        k = int(np.nanargmax(e))
        outs.append({"t": float(s.t), "step": int(s.step), "err_max": float(emax), "err_rms": float(erms),
                     "err_int": float(np.nanmax(e[interior])) if interior.any() else math.nan,
                     "x_at_max": float(x[k] / cfg.L), "cpu_s": cpu, "wall_s": wall,
                     "vy": vy.tolist(), "exact": exact.tolist(), "x": x.tolist()})

    status = "ok"
    try:
        sim.run(output=output)
        wall = sim.wall_time
    except GuardError as e:
        status = f"failed: {e}"
        wall = time.perf_counter() - t_wall0
    except Exception as e:  # noqa: BLE001 - a blown-up state can fail elsewhere (e.g. numerics); record it
        status = f"failed: {type(e).__name__}: {e}"
        wall = time.perf_counter() - t_wall0
    cpu = time.process_time() - t_cpu0
    steps = sim.step
    xf = sim.ps.pos[:sim.ps.n_own, 0][sim.ps.kind[:sim.ps.n_own] == FLUID]
    rec = {
        "choices": c, "status": status, "n_particles": sim.n_total, "n_fluid": cfg.Nx * cfg.Ny,
        "layers_used": cfg.layers, "dx": cfg.dx, "h": cfg.h, "dt_first": cfg.dt,
        "dt_mean": sim.t / steps if steps else math.nan, "t_reached": sim.t, "steps": steps,
        "wall_s": wall, "cpu_s": cpu,
        "particle_steps_per_s": sim.n_total * steps / wall if wall > 0 else math.nan,
        "particle_steps_per_cpu_s": sim.n_total * steps / cpu if cpu > 0 else math.nan,
        "final_min_wall_distance_dx": float(min(xf.min(), (cfg.L - xf).min()) / cfg.dx) if xf.size else math.nan,
        "moved_particle": moved,
        "process_cpu_total_s": time.process_time(),
        "code": code_hash(),
        "outputs": [{k: v for k, v in o.items() if k not in ("vy", "exact", "x")} for o in outs],
    }
    if prof_dir and outs:
        os.makedirs(prof_dir, exist_ok=True)
        np.savez_compressed(os.path.join(prof_dir, run_id(c) + ".npz"), t=[o["t"] for o in outs],
                            x=np.array(outs[0]["x"]), vy=np.array([o["vy"] for o in outs]),
                            exact=np.array([o["exact"] for o in outs]))
    print(json.dumps(rec), flush=True)
    return 0


def run_id(c):
    """A file-name-safe key of a run's choices."""
    c = choices(c)
    dt = f"auto{c['dt_safety']:g}" if c["dt"] == "auto" else f"dt{float(c['dt']):g}"
    s = (f"{c['kernel']}-{c['integrator']}-h{c['h_over_dx']:g}-nx{int(c['Nx'])}-{dt}"
         f"-b{c['beta_max']:g}-l{int(c['layers'])}-t{c['t_end']:g}")
    if c["perturb"]:
        s += f"-p{float(c['perturb']):g}"
    for item in c["set"]:
        s += "-" + "".join(ch if ch.isalnum() or ch in ".=+-" else "_" for ch in item)
    return s


def code_hash():
    """SHA-1 of the parsph sources, so that the sweep can tell runs of different code apart."""
    import parsph
    h = hashlib.sha1()
    pkg = os.path.dirname(os.path.abspath(parsph.__file__))
    for dirpath, dirnames, files in sorted(os.walk(pkg)):
        dirnames.sort()
        for f in sorted(files):
            if f.endswith(".py"):
                with open(os.path.join(dirpath, f), "rb") as fh:
                    h.update(f.encode() + b"\0" + fh.read())
    return h.hexdigest()[:12]


if __name__ == "__main__":
    sys.exit(main(sys.argv))
