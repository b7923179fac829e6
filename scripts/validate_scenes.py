"""The README's table of validated cases, the short-box study and the cost of the pressure term.

    .venv/bin/python scripts/validate_scenes.py [--out results] [--ranks 2] [--quick]

1. Each scene's run file on ``--ranks`` ranks (mpirun): particles, wall time,
   error against its reference at the last output (settling: theta(x) averaged
   over the outputs from t >= 0.4 s, and also against the balance that the
   paper's pressure form converges to).
2. Couette with L_y = N_y dx for N_y = 50, 25, 10, 5, 3 to t = 0.05 s: the
   largest difference of the profile from the square box's, the error against
   Eq. (8), the particle count and the largest rank count (slabs >= 2h).
3. Couette (N_x = 50, L_y = L) with and without the pressure term: CPU time per
   step and the profile error at t = 0.05 s.
Writes OUTDIR/scenes.md and prints it.
"""
import argparse
import math
import os
import subprocess
import sys
import time

import numpy as np
from mpi4py import MPI

from parsph import config
from parsph.analytic import settling_equilibrium
from parsph.output import output_files, read_profile, read_snapshot
from parsph.particles import FLUID
from parsph.solver import Simulation

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RUN = os.path.join(ROOT, "run")
SCENES = ("couette_paper", "couette_3d", "poiseuille", "periodic_box", "settling")


def run_scene(name, ranks, out, extra=()):
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = ["mpirun", "-n", str(ranks), "--oversubscribe", sys.executable, "-m", "parsph", "run",
           os.path.join(RUN, name + ".toml"), "--out", os.path.join(out, name), "--force", "--quiet", *extra]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def settling_time(outdir, tol=1e-4):
    """The first output time from which the fluid's largest |v_x| stays below ``tol`` [m/s] (None: never)."""
    settled = None
    for f in output_files(outdir):
        snap = read_snapshot(f)
        vx = np.abs(snap["velocity"][snap["kind"] == FLUID, 0]).max()
        if vx < tol:
            settled = settled if settled is not None else float(snap["attrs"]["time"])
        else:
            settled = None
    return settled


def in_process(text, over):
    cfg = config.loads(text, over)
    sim = Simulation(cfg, MPI.COMM_SELF)
    last = {}
    sim.run(output=lambda s, snapshot=None: last.update(s.profile()))
    return cfg, sim, last


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="results")
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="short runs (t_end / 10) to check the script")
    ap.add_argument("--scenes", nargs="*", default=list(SCENES), help="run files to run (default: all)")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    lines = ["| scene | command | particles | wall time, %d ranks [s] | error at the last output |" % a.ranks,
             "| --- | --- | --- | --- | --- |"]
    for name in a.scenes:
        extra = []
        if a.quick:
            cfg0 = config.load(os.path.join(RUN, name + ".toml"))
            extra = ["--set", f"output.t_end={cfg0.t_end / 10}", "--set",
                     f"output.times=[{cfg0.t_end / 20}, {cfg0.t_end / 10}]"]
        wall = run_scene(name, a.ranks, a.out, extra)
        p = read_profile(os.path.join(a.out, name))
        at = p["attrs"]
        n = at["n_particles"]
        cmd = f"`mpirun -n {a.ranks} parsph run run/{name}.toml`"
        if at["error_field"] == "theta":
            late = p["time"] >= 0.4 * p["time"][-1]
            theta = np.nanmean(p["theta"][late], axis=0)
            ref = p["theta_exact"][-1]
            cfg = config.loads(at["run_file"])
            paper = settling_equilibrium(p["x"], cfg.theta0, cfg.L, cfg.rho_s, -cfg.g[0], cfg.G_a, cfg.G_b,
                                         form="paper")
            err = np.abs(theta - ref) / cfg.theta0
            errp = np.abs(theta - paper) / cfg.theta0
            settled = settling_time(os.path.join(a.out, name))
            when = f"settled (max \\|v_x\\| < 1e-4 m/s) from t = {settled:g} s" if settled is not None \
                else "not settled (max \\|v_x\\| >= 1e-4 m/s at the last output)"
            msg = (f"{when}; theta(x) averaged over t >= {p['time'][late][0]:g} s: max {err.max():.2e}, "
                   f"RMS {math.sqrt((err ** 2).mean()):.2e} of theta_0 (floor {theta[0]:.4f} vs "
                   f"{ref[0]:.4f}); against the paper form's balance: max {errp.max():.2e}")
        else:
            msg = (f"t = {p['time'][-1]:g} s: max {p['err_max'][-1]:.2e}, RMS {p['err_rms'][-1]:.2e} "
                   f"of {at['error_scale']:.3g} m/s")
        lines.append(f"| {name} | {cmd} | {n} | {wall:.1f} | {msg} |")
    lines += ["", "Couette flow in a short box (N_x = 50, t = 0.05 s, one rank):", "",
              "| L_y | N_y | particles | max \\|v - v(L_y = L)\\| / V_w | max error vs Eq. (8) | largest rank count |",
              "| --- | --- | --- | --- | --- | --- |"]
    paper = open(os.path.join(RUN, "couette_paper.toml")).read()
    t_end = 0.005 if a.quick else 0.05
    base = None
    for ny in (50, 25, 10, 5, 3):
        ly = ny * 2e-4
        cfg, sim, prof = in_process(paper, [f"domain.Ly={ly}", f"output.t_end={t_end}", f"output.times=[{t_end}]"])
        if base is None:
            base = prof["vy"]
        diff = np.abs(prof["vy"] - base).max() / cfg.V_w
        pmax = int(math.floor(ly / (2 * cfg.h) * (1 + 1e-12)))
        lines.append(f"| {ly:g} m | {ny} | {sim.n_total} | {diff:.1e} | {prof['err'][0]:.3e} | {pmax} |")
    lines += ["", "The pressure term in Couette flow (N_x = 50, L_y = L, t = 0.05 s, one rank):", "",
              "| pressure term | CPU ms/step | max error | RMS error |", "| --- | --- | --- | --- |"]
    for on in ("true", "false"):
        c0 = time.process_time()
        cfg, sim, prof = in_process(paper, [f"terms.pressure={on}", f"output.t_end={t_end}",
                                            f"output.times=[{t_end}]"])
        cpu = (time.process_time() - c0) / sim.step * 1e3
        lines.append(f"| {on} | {cpu:.2f} | {prof['err'][0]:.3e} | {prof['err'][1]:.3e} |")
    text = "\n".join(lines) + "\n"
    with open(os.path.join(a.out, "scenes.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
