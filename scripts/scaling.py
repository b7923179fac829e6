"""Strong and weak scaling: time per step and parallel efficiency against the rank count.

    .venv/bin/python scripts/scaling.py strong --nx 200 --max-ranks 16 [--out results]
    .venv/bin/python scripts/scaling.py weak --nx 100 --ly-per-rank 0.0025 --max-ranks 16

strong: the same problem (N_x, L_y = L) on P = 1, 2, ... ranks; efficiency
T_1 / (P T_P). weak: L_y = P * ly-per-rank, so every rank keeps the same
particles; efficiency T_1 / T_P. Each P runs ``scripts/bench.py`` under
``mpirun -n P`` (with --oversubscribe where ranks exceed cores, which measures
correctness, not speed). Writes OUTDIR/scaling_<mode>.csv and .png, the
machine described in both.
"""
import argparse
import csv
import json
import os
import platform
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def machine():
    model = "unknown cpu"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{platform.node()}: {os.cpu_count()} cores, {model}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("mode", choices=("strong", "weak"))
    ap.add_argument("--nx", type=int, default=200)
    ap.add_argument("--max-ranks", type=int, default=4)
    ap.add_argument("--ranks", type=int, nargs="*", help="explicit rank counts (default 1, 2, 4, ... max)")
    ap.add_argument("--ly-per-rank", type=float, default=0.0025, help="weak scaling: L_y per rank [m]")
    ap.add_argument("--budget", type=float, default=4.0, help="timed seconds per run")
    ap.add_argument("--out", default="results")
    ap.add_argument("--mpirun", default="mpirun", help="launcher (e.g. 'srun' on a cluster)")
    a = ap.parse_args()
    ranks = a.ranks or sorted({1, *[2 ** k for k in range(1, 10) if 2 ** k <= a.max_ranks], a.max_ranks})
    os.makedirs(a.out, exist_ok=True)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               NUMBA_NUM_THREADS="1", OMP_WAIT_POLICY="passive")
    rows = []
    for p in ranks:
        with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as tmp:
            jpath = tmp.name
        cmd = [a.mpirun, "-n", str(p)]
        if a.mpirun == "mpirun" and p > (os.cpu_count() or 1):
            cmd.append("--oversubscribe")
        cmd += [sys.executable, os.path.join(ROOT, "scripts", "bench.py"), "--nx", str(a.nx),
                "--budget", str(a.budget), "--json", jpath, "--tag", f"{a.mode} P={p}"]
        if a.mode == "weak":
            cmd += ["--set", f"domain.Ly={a.ly_per_rank * p}"]
        print(" ".join(cmd), flush=True)
        subprocess.run(cmd, check=True, env=env)
        r = json.loads(open(jpath).read().splitlines()[-1])
        os.unlink(jpath)
        rows.append(r)
    t1 = rows[0]["step_s"]
    out = []
    for r in rows:
        p = r["ranks"]
        eff = t1 / (p * r["step_s"]) if a.mode == "strong" else t1 / r["step_s"]
        out.append({"ranks": p, "particles": r["particles"], "step_s": r["step_s"],
                    "particle_steps_per_s": r["particle_steps_per_s"], "efficiency": eff,
                    "halo_s": r["phases_s"]["halo"], "migrate_s": r["phases_s"]["migrate"]})
    base = os.path.join(a.out, f"scaling_{a.mode}")
    desc = machine()
    with open(base + ".csv", "w", newline="") as f:
        f.write(f"# {a.mode} scaling, N_x = {a.nx}, {desc}\n")
        w = csv.DictWriter(f, fieldnames=list(out[0]))
        w.writeheader()
        w.writerows(out)
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.8))
        P = [o["ranks"] for o in out]
        ax1.loglog(P, [o["step_s"] * 1e3 for o in out], "o-")
        if a.mode == "strong":
            ax1.loglog(P, [t1 * 1e3 / p for p in P], "k--", lw=0.8, label="ideal")
            ax1.legend()
        ax1.set_xlabel("ranks P")
        ax1.set_ylabel("time per step [ms]")
        ax2.plot(P, [o["efficiency"] for o in out], "o-")
        ax2.axhline(1.0, color="k", lw=0.8, ls="--")
        ax2.set_ylim(0, 1.1)
        ax2.set_xlabel("ranks P")
        ax2.set_ylabel("parallel efficiency")
        fig.suptitle(f"{a.mode} scaling, N_x = {a.nx}\n{desc}", fontsize=9)
        fig.tight_layout()
        fig.savefig(base + ".png", dpi=110)
    except ImportError:
        pass
    for o in out:
        print(f"P={o['ranks']:3d}  {o['step_s'] * 1e3:9.3f} ms/step  efficiency {o['efficiency']:.2f}")
    print(f"wrote {base}.csv and {base}.png ({desc})")


if __name__ == "__main__":
    main()
