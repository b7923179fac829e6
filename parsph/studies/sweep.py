"""The accuracy/speed sweep of the Couette case (docs/accuracy.md): its grids of numerical choices, one run
of a choice set, and the resumable execution of a grid, each run in its own process.

A run is the paper case (Table 1 physics: :func:`parsph.studies.builders.couette`,
square box) with the run's choices of N_x, h/dx, kernel, integrator, dt
("auto" with a safety factor, or fixed), beta_max, wall layers and end time,
on one rank (COMM_SELF) with an in-memory output callback (no HDF5 is
written: the sweep measures the solver, not the file system). Its record:
the choices, particle count, steps, dt, wall and process CPU time of the time
loop (cumulative at each output time, too: a CPU second is the cost, since
on a shared machine wall time also counts other people's work), and the
errors against Eq. (8) at t = 0.01, 0.05, 0.2, 0.5 s (those not past t_end).
Before the timed run a tiny case with the same kernel and integrator is run
once, so that loading numba's on-disk cache (or compiling) is not counted.

Choices (JSON keys): Nx, h_over_dx, kernel, integrator, dt ("auto" or seconds),
dt_safety, beta_max, layers (0: the fewest covering 2h), t_end, and perturb:
if set, one fluid particle of the column next to the moving wall is put at
distance perturb * dx from the wall plane at t = 0 (the robustness probe of
the Morris cap beta_max); set: further "section.key=value" overrides
(diagnostics that change the physics, e.g. a weaker modulus G; such runs are
kept off the frontier).

Each run of a grid is a process of its own (a worker command the caller
gives: scripts/sweep_run.py), so that runs can go side by side and one that
crashes takes nothing else down; finished runs are kept in DIR/runs.jsonl by
the studies' resumable runner (:class:`parsph.studies.runs.Runs`), so a killed
sweep resumes. The first run copies parsph/ to DIR/code and every run imports
that copy, so that edits to the working tree during a sweep do not mix code
versions (each record carries a hash of the code).
"""
import concurrent.futures as cf
import hashlib
import json
import math
import os
import shutil
import subprocess
import time

import numpy as np
from mpi4py import MPI

from parsph.errors import GuardError
from parsph.simulation.solver import Simulation
from parsph.sph.particles import GRAIN
from .builders import couette
from .machine import REPO, commit
from .runs import JsonLines, Runs

TIMES = (0.01, 0.05, 0.2, 0.5)
DEFAULTS = {"h_over_dx": 1.25, "kernel": "cubic_spline", "integrator": "paper", "dt": "auto",
            "dt_safety": 1.0, "beta_max": 1.5, "layers": 0, "t_end": 0.5, "perturb": None, "set": []}
PAPER_CASE = {"Nx": 50, "dt": 1e-5, "t_end": 0.5}  # Table 1: h = 1.25 dx, cubic, Eqs. (6)-(7), dt = 1e-5 s
NO_CAP = 1e6  # beta_max "none": 1 + d_j/d_i never reaches it


def choices(run):
    out = dict(DEFAULTS)
    out.update(run)
    return out


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


def build_config(run):
    """The paper case (Table 1 physics: builders.couette, square box) with the run's numerics."""
    c = choices(run)
    times = [t for t in TIMES if t <= c["t_end"] * (1 + 1e-12)]
    return couette(int(c["Nx"]), h_over_dx=float(c["h_over_dx"]),
                   dt="auto" if c["dt"] == "auto" else float(c["dt"]), overrides=[
        f'numerics.kernel="{c["kernel"]}"', f'numerics.integrator="{c["integrator"]}"',
        f"numerics.dt_safety={float(c['dt_safety'])!r}", f"walls.beta_max={float(c['beta_max'])!r}",
        f"walls.layers={int(c['layers'])}", f"output.t_end={float(c['t_end'])!r}", f"output.times={times!r}",
        "output.snapshots=false", *c["set"]])


# ---- one run --------------------------------------------------------------------------------------
def _warm_up(run):
    """Load (or compile) every numba function the run will call, untimed."""
    c = choices(run)
    small = dict(c, Nx=12, t_end=1e-4, perturb=None)
    small["dt"] = "auto"
    sim = Simulation(build_config(small), MPI.COMM_SELF)
    sim.run(output=lambda s, snapshot=None: s.profile)  # noqa: the profile's numba function too


def _perturb(sim, cfg, eps):
    """Move the fluid particle of the wall-adjacent column with the smallest y to d = eps dx."""
    ps = sim.ps
    n = ps.n_own
    fluid = np.flatnonzero(ps.kind[:n] == GRAIN)
    last = fluid[np.abs(ps.pos[fluid, 0] - (cfg.L - 0.5 * cfg.dx)) < 1e-9 * cfg.L]
    k = last[np.argmin(ps.pos[last, 1])]
    ps.pos[k, 0] = cfg.L - eps * cfg.dx
    return int(ps.gid[k])


def run_choices(run, prof_dir=None):
    """One run of the choices ``run`` in this process: its record (and, with ``prof_dir``, its profiles
    as PROF_DIR/<run_id>.npz)."""
    c = choices(run)
    cfg = build_config(run)
    _warm_up(run)
    sim = Simulation(cfg, MPI.COMM_SELF)
    moved = _perturb(sim, cfg, float(c["perturb"])) if c["perturb"] else None
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
    xf = sim.ps.pos[:sim.ps.n_own, 0][sim.ps.kind[:sim.ps.n_own] == GRAIN]
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
    return rec


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


# ---- grids ----------------------------------------------------------------------------------------
def default_grid():
    """(run, groups) pairs of the default grid: 7.1 CPU-minutes of time loops measured at 9a54ef1 (8.6 with start-up)."""
    runs = []

    def add(groups, **run):
        runs.append((run, set(groups.split())))

    # Convergence at fixed h/dx, dt = "auto" (safety 1): (kernel, h/dx, integrator, beta_max,
    # N_x run to t = 0.5 s, N_x run to t = 0.05 s only). The finest resolutions stop at 0.05 s.
    for kernel, hr, integ, beta, nx_long, nx_short in (
            ("cubic_spline", 1.25, "paper", 1.5, (20, 30, 50, 70), (100,)),
            ("cubic_spline", 1.25, "midpoint", 1.5, (20,), (30, 50, 70)),
            ("wendland_c2", 1.25, "paper", 1.5, (20, 30, 50), (70,)),
            ("wendland_c2", 1.25, "midpoint", 1.5, (), (20, 30, 50)),
            ("wendland_c2", 1.5, "paper", 1.5, (20, 30), (50, 70)),
            ("wendland_c2", 2.0, "paper", 1.5, (20, 30), (50, 70)),
            ("cubic_spline", 1.25, "paper", NO_CAP, (20, 30, 50), (70, 100)),
            ("cubic_spline", 1.25, "midpoint", NO_CAP, (20,), (30, 50, 70)),
            ("wendland_c2", 1.25, "paper", NO_CAP, (20, 30, 50), (70,)),
            ("wendland_c2", 2.0, "paper", NO_CAP, (20, 30, 50), (70, 100)),
            ("wendland_c2", 2.0, "midpoint", NO_CAP, (), (20, 30, 50)),
            ("cubic_spline", 2.0, "paper", NO_CAP, (20, 30), (50, 70))):
        for nx in nx_long + nx_short:
            add("conv", Nx=nx, kernel=kernel, h_over_dx=hr, integrator=integ, beta_max=beta,
                t_end=0.5 if nx in nx_long else 0.05)
    # Coarser still, for the cheap end of the frontier (not in the order fits).
    for nx in (12, 16):
        add("coarse", Nx=nx, beta_max=NO_CAP, t_end=0.5)
        add("coarse", Nx=nx, kernel="wendland_c2", h_over_dx=2.0, beta_max=NO_CAP, t_end=0.5)
    # The settings of run/couette_fast.toml and of run/couette_accurate.toml as first chosen
    # (h/dx 2; the preset now uses h/dx 2.5, beta_max 8, measured with scripts/sweep_preset.py), to t = 0.5 s.
    add("preset", Nx=12, beta_max=6.0, t_end=0.5)
    # Coarser than the fast preset, to bracket the cheapest setting with 1 % max error at t = 0.05 s
    # (added after the first sweep, run on the same copy of the code).
    for nx in (6, 8, 10):
        add("coarse", Nx=nx, beta_max=6.0, t_end=0.5)
    add("wall", Nx=20, beta_max=6.0, t_end=0.5)
    add("preset", Nx=100, kernel="wendland_c2", h_over_dx=2.0, beta_max=6.0, t_end=0.5)
    # Time step: the paper case itself (fixed dt = 1e-5 s) and smaller auto steps.
    add("paper dt", **PAPER_CASE)
    add("dt", Nx=50, dt_safety=0.25, t_end=0.05)
    for nx, s in ((50, 0.5), (50, 0.25), (70, 0.5)):
        add("dt", Nx=nx, dt_safety=s, beta_max=NO_CAP, t_end=0.05)
    for nx, s in ((30, 0.25), (50, 0.5), (50, 0.25)):
        add("dt", Nx=nx, dt_safety=s, kernel="wendland_c2", h_over_dx=2.0, beta_max=NO_CAP, t_end=0.05)
    # Wall treatment: the Morris cap between 1 (no amplification) and none, more layers than needed.
    for b in (1.0, 3.0, 6.0):
        add("wall", Nx=50, beta_max=b, t_end=0.05)
    add("wall", Nx=30, beta_max=6.0, t_end=0.5)
    add("wall", Nx=50, layers=5, beta_max=NO_CAP, t_end=0.05)
    # Diagnostic (not on the frontier: it changes the physics): the cubic 1.25 floor with a
    # 400x weaker modulus G (G_b = -1.183 -> -3.8), which removes the pressure noise.
    for nx in (20, 50):
        add("diag", Nx=nx, beta_max=NO_CAP, t_end=0.05, set=["material.G_b=-3.8"])
    # Robustness of the cap: one fluid particle put at d = eps dx from the moving wall,
    # the paper's time step, to t = 0.01 s.
    for eps in (0.1, 0.02, 0.005):
        for b in (1.5, 3.0, 6.0, NO_CAP):
            add("probe", Nx=50, dt=1e-5, beta_max=b, perturb=eps, t_end=0.01)
    return runs


def quick_grid():
    """A few minutes: coarse convergence of both kernels and integrators to t = 0.05 s, one probe pair."""
    runs = []
    for kernel in ("cubic_spline", "wendland_c2"):
        for integ in ("paper", "midpoint"):
            for nx in (16, 24, 32):
                runs.append(({"Nx": nx, "kernel": kernel, "integrator": integ, "t_end": 0.05}, {"conv"}))
    for nx in (16, 24, 32):
        runs.append(({"Nx": nx, "beta_max": NO_CAP, "t_end": 0.05}, {"conv", "wall"}))
    runs.append(({"Nx": 50, "dt": 1e-5, "t_end": 0.05}, {"paper", "dt"}))
    for b in (1.5, NO_CAP):
        runs.append(({"Nx": 24, "dt": 2e-5, "beta_max": b, "perturb": 0.005, "t_end": 0.01}, {"probe"}))
    return runs


def merge(grid):
    """{run_id: (choices, groups)}: one entry per distinct run, groups united."""
    out = {}
    for r, groups in grid:
        key = run_id(r)
        if key in out:
            out[key][1].update(groups)
        else:
            out[key] = (choices(r), set(groups))
    return out


def estimate_cpu(run):
    """Rough CPU seconds of a run on this machine (for ordering and --max-cost only)."""
    c = choices(run)
    nx, hr = c["Nx"], c["h_over_dx"]
    L, nu, v = 0.01, 1.75e-4, 1.0
    h = hr * L / nx
    if c["dt"] == "auto":  # parsph.physics.limits at theta_0: advection, and the derived viscous limit (~0.32 h^2 / nu)
        dt = c["dt_safety"] * min(0.5 * h / v, 0.32 * h * h / nu)
    else:
        dt = float(c["dt"])
    layers = c["layers"] or math.ceil(2 * hr - 1e-9)
    n = (nx + 2 * layers) * nx
    per_step = (0.3e-3 + 0.65e-6 * n * (hr / 1.25) ** 2) * (2 if c["integrator"] == "midpoint" else 1)
    return c["t_end"] / dt * per_step + 2.0


# ---- a grid, each run in its own process ----------------------------------------------------------------
def snapshot_code(out_dir, fresh):
    """Copy parsph/ to DIR/code/parsph (once; again with ``fresh``), so that every run of the sweep
    uses the same code even if the working tree changes while the sweep runs."""
    import parsph
    code = os.path.join(out_dir, "code")
    if fresh and os.path.isdir(code):
        shutil.rmtree(code)
    if not os.path.isdir(os.path.join(code, "parsph")):
        shutil.copytree(os.path.dirname(os.path.abspath(parsph.__file__)), os.path.join(code, "parsph"),
                        ignore=shutil.ignore_patterns("__pycache__"))
        head = commit(describe=True)
        with open(os.path.join(code, "SOURCE"), "w") as f:
            f.write(f"parsph/ of {REPO} at git {head or '?'}, copied {time.strftime('%Y-%m-%d %H:%M:%S')}\n")
    return code


def _run_one(worker, key, run, out_dir, code=None):
    cmd = [*worker, json.dumps(run), "--profiles", os.path.join(out_dir, "profiles")]
    env = None
    if code:  # the snapshot's parsph ahead of the installed one (an editable install's finder comes after the path)
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [code, os.environ.get("PYTHONPATH")])))
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, env=env)
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
    if p.returncode != 0 or not lines:
        return key, None, f"exit {p.returncode}: {p.stderr.strip()[-500:]}", time.perf_counter() - t0
    return key, json.loads(lines[-1]), None, time.perf_counter() - t0


def runs_file(out_dir, fresh=False):
    """The sweep's finished runs, DIR/runs.jsonl (``fresh``: set aside as runs.jsonl.old, none kept)."""
    return Runs(JsonLines(os.path.join(out_dir, "runs.jsonl"), fresh=fresh))


def execute(grid, out_dir, worker, jobs=1, rerun=False, max_cost=0.0, snapshot=True):
    """Run every run of ``grid`` ({run_id: (choices, groups)}) not yet in DIR/runs.jsonl, cheapest first,
    ``jobs`` at once, each as ``worker + [choices as JSON, --profiles DIR]`` with DIR/code first on PYTHONPATH (a process that
    prints its record as its last JSON line); the keys skipped by ``max_cost`` (estimated CPU s)."""
    os.makedirs(out_dir, exist_ok=True)
    runs = runs_file(out_dir, fresh=rerun)
    code = snapshot_code(out_dir, rerun) if snapshot else None
    if code:
        with open(os.path.join(code, "SOURCE")) as f:
            print(f"sweep: code: {f.read().strip()}", flush=True)
    todo = [(k, r) for k, (r, _) in grid.items() if runs.done(k) is None]
    skipped = [k for k, r in todo if max_cost and estimate_cpu(r) > max_cost]
    todo = [(k, r) for k, r in todo if k not in skipped]
    todo.sort(key=lambda kr: estimate_cpu(kr[1]))
    est = sum(estimate_cpu(r) for _, r in todo)
    print(f"sweep: {len(grid)} runs, {len(grid) - len(todo) - len(skipped)} done already, {len(todo)} to run "
          f"(estimated {est / 60:.1f} CPU-minutes), {len(skipped)} skipped by --max-cost", flush=True)
    t_start = time.perf_counter()
    with cf.ThreadPoolExecutor(jobs) as pool:
        futs = [pool.submit(_run_one, worker, k, r, out_dir, code) for k, r in todo]
        for i, f in enumerate(cf.as_completed(futs), 1):
            key, rec, err, wall = f.result()
            if rec is None:
                print(f"  [{i}/{len(todo)}] {key}: ERROR {err}", flush=True)
                continue
            runs.add(key, rec)
            e = {o["t"]: o["err_max"] for o in rec["outputs"]}
            errs = " ".join(f"{t:g}:{e[t]:.2e}" for t in sorted(e))
            print(f"  [{i}/{len(todo)}] {key}: {rec['status'][:60]}, {rec['steps']} steps, "
                  f"cpu {rec['cpu_s']:.1f} s, wall {rec['wall_s']:.1f} s, max err {errs} "
                  f"({time.perf_counter() - t_start:.0f} s elapsed)", flush=True)
    print(f"sweep: ran {len(todo)} runs in {time.perf_counter() - t_start:.0f} s wall", flush=True)
    return skipped

