"""The table of validated cases in docs/validation.md, the short-box study and the cost of the pressure term.

    .venv/bin/python scripts/validate_scenes.py [--out results] [--ranks 2] [--quick]
                                                [--scenes NAME ...] [--parts 1 2 3]

1. Each scene's run file on ``--ranks`` ranks (mpirun): particles, wall time,
   error against its reference at the last output (settling: theta(x) averaged
   over the outputs from t >= 0.4 s, and also against the balance that the
   paper's pressure form converges to).
2. Couette with L_y = N_y dx for N_y = 50, 25, 10, 5, 3 to t = 0.05 s: the
   largest difference of the profile from the square box's, the error against
   Eq. (8), the particle count and the largest rank count (``parsph.simulation.case.max_ranks``: what
   ``parsph run`` accepts, slabs that hold their ghost rows).
3. Couette (N_x = 50, L_y = L) with and without the pressure term: CPU time per
   step (one rank, to t = 0.05 s), and the whole run on ``--ranks`` ranks: the
   profile error at t = 0.01, 0.05 and 0.5 s and the spread of the particles'
   theta at the end (how far the lattice left its order).
Writes OUTDIR/scenes.md and prints it.
"""
import argparse
import os
import subprocess
import sys
import time

import numpy as np

from parsph.output import read_profile
from parsph.setup import config
from parsph.simulation.case import max_ranks
from parsph.studies.validation import in_process, scene_error, theta_spread

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


def scene_row(name, a):
    """Run one run file on a.ranks ranks; its row of the validated-cases table."""
    extra = []
    if a.quick:
        cfg0 = config.load(os.path.join(RUN, name + ".toml"))
        extra = ["--set", f"output.t_end={cfg0.t_end / 10}", "--set",
                 f"output.times=[{cfg0.t_end / 20}, {cfg0.t_end / 10}]"]
    wall = run_scene(name, a.ranks, a.out, extra)
    cmd = f"`mpirun -n {a.ranks} parsph run run/{name}.toml`"
    n, msg = scene_error(os.path.join(a.out, name))
    return f"| {name} | {cmd} | {n} | {wall:.1f} | {msg} |"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="results")
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="short runs (t_end / 10) to check the script")
    ap.add_argument("--scenes", nargs="*", default=list(SCENES), help="run files to run (default: all)")
    ap.add_argument("--parts", nargs="*", type=int, default=[1, 2, 3], help="which tables (default: all)")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    lines = []
    if 1 in a.parts:
        lines += ["| scene | command | particles | wall time, %d ranks [s] | error |" % a.ranks,
                  "| --- | --- | --- | --- | --- |"]
        lines += [scene_row(name, a) for name in a.scenes]
    paper = open(os.path.join(RUN, "couette_paper.toml")).read()
    t_end = 0.005 if a.quick else 0.05
    if 2 in a.parts:
        lines += ["", "Couette flow in a short box (N_x = 50, t = 0.05 s, one rank):", "",
                  "| L_y | N_y | particles | max \\|v - v(L_y = L)\\| / V_w | max error vs Eq. (8) "
                  "| largest rank count |", "| --- | --- | --- | --- | --- | --- |"]
        base = None
        for ny in (50, 25, 10, 5, 3):
            ly = ny * 2e-4
            cfg, sim, prof = in_process(paper, [f"domain.Ly={ly}", f"output.t_end={t_end}",
                                                f"output.times=[{t_end}]"])
            if base is None:
                base = prof["vy"]
            diff = np.abs(prof["vy"] - base).max() / cfg.V_w
            pmax = max_ranks(cfg)
            lines.append(f"| {ly:g} m | {ny} | {sim.n_total} | {diff:.1e} | {prof['err'][0]:.3e} | {pmax} |")
    if 3 in a.parts:
        lines += ["", "The pressure term in Couette flow (N_x = 50, L_y = L): CPU time per step (one rank, "
                  "to t = 0.05 s), and the whole run on %d ranks:" % a.ranks, "",
                  "| pressure term | CPU ms/step | wall time [s] | max error at t = 0.01 / 0.05 / 0.5 s "
                  "| theta spread (std/mean) at the end |", "| --- | --- | --- | --- | --- |"]
        for on in ("true", "false"):
            c0 = time.process_time()
            cfg, sim, prof = in_process(paper, [f"terms.pressure={on}", f"output.t_end={t_end}",
                                                f"output.times=[{t_end}]"])
            cpu = (time.process_time() - c0) / sim.step * 1e3
            extra = ["--set", f"terms.pressure={on}"]
            if a.quick:
                extra += ["--set", "output.t_end=0.05", "--set", "output.times=[0.01, 0.05]"]
            out = os.path.join(a.out, "pressure_" + on)
            wall = run_scene("couette_paper", a.ranks, out, extra)
            p = read_profile(os.path.join(out, "couette_paper"))
            errs = " / ".join(f"{e:.2e}" for t, e in zip(p["time"], p["err_max"]) if round(t, 6) in (0.01, 0.05, 0.5))
            lines.append(f"| {on} | {cpu:.2f} | {wall:.1f} | {errs} | "
                         f"{theta_spread(os.path.join(out, 'couette_paper')):.2e} |")
    text = "\n".join(lines) + "\n"
    with open(os.path.join(a.out, "scenes.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
