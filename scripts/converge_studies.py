"""The studies of docs/accuracy.md's "Estimated against true errors": run them and print the table.

    NUMBA_NUM_THREADS=1 .venv/bin/python scripts/converge_studies.py [--only NAME ...] [--out DIR] [--report-only]

Each study is one `parsph converge` call on one rank (levels reused when their run
file is unchanged, so a second call only reports). Printed per study and output time:
observed order(s) and shape residual(s), what converge says, estimated over true max
error for the second-finest and the finest level, the bias's effect, the finest
level's true error (and `parsph check`'s on its own bins), and the CPU time of the
levels and of the bias run.
"""
import argparse
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

COUETTE_T = ["--set", "output.t_end=0.05", "--set", "output.times=[0.01, 0.02, 0.05]"]
STUDIES = {
    "couette_paper": ["run/couette_fast.toml", "--family", "paper", *COUETTE_T],
    "couette_accurate": ["run/couette_fast.toml", "--family", "accurate", *COUETTE_T],
    # the same three with each level at its own stability limit (--dt-scaling limit), for comparison
    "couette_paper_limit": ["run/couette_fast.toml", "--family", "paper", "--dt-scaling", "limit", *COUETTE_T],
    "couette_accurate_limit": ["run/couette_fast.toml", "--family", "accurate", "--dt-scaling", "limit", *COUETTE_T],
    "couette_fast_limit": ["run/couette_fast.toml", "--family", "fast", "--dt-scaling", "limit", *COUETTE_T],
    "couette_fast": ["run/couette_fast.toml", "--family", "fast", *COUETTE_T],
    "couette_fast_4": ["run/couette_fast.toml", "--family", "fast", "--levels", "4",
                       "--set", "output.t_end=0.02", "--set", "output.times=[0.01, 0.02]"],
    "couette_3d": ["run/couette_3d.toml", "--family", "paper", "--set", "numerics.Nx=16",
                   "--set", "domain.Ly=0.002", "--set", "domain.Lz=0.002", *COUETTE_T],
    "poiseuille": ["run/poiseuille.toml", "--set", "numerics.Nx=16", "--set", "numerics.dt=\"auto\"",
                   "--set", "output.t_end=0.2", "--set", "output.times=[0.01, 0.05, 0.2]"],
    "box_cubic": ["run/periodic_box.toml", "--set", "numerics.Nx=16", "--set", "numerics.dt=\"auto\""],
    "box_cubic_4": ["run/periodic_box.toml", "--set", "numerics.Nx=16", "--set", "numerics.dt=\"auto\"",
                    "--levels", "4", "--set", "output.t_end=0.01", "--set", "output.times=[0.01]"],
    "box_accurate": ["run/periodic_box.toml", "--family", "accurate", "--set", "numerics.Nx=32",
                     "--set", "domain.Ly=0.004"],
    "settling": ["run/settling.toml", "--set", "numerics.Nx=12", "--set", "domain.Ly=0.0025",
                 "--set", "output.t_end=0.6", "--set", "output.times=[0.2, 0.4, 0.6]"],
}


def fmt(v, spec=".2e"):
    return "-" if v is None else format(v, spec)


def report(name, path):
    rep = json.load(open(path))
    lines = []
    for fam in rep["families"]:
        cost = sum(lv["cpu_s"][-1] for lv in fam["levels"])
        bcost = fam["bias_run"]["cpu_s"][-1] if fam.get("bias_run") else 0.0
        lines.append(f"## {name}: family {fam['family']}, N_x {fam['Nx']}, bias b = {fmt(fam.get('bias'), '+.2e')}; "
                     f"CPU s of the levels {cost:.1f}, bias run {bcost:.2f}")
        for row in fam["times"]:
            e = row["estimate"]
            orders = ", ".join(fmt(p, ".2f") for p in e["orders"])
            shapes = ", ".join(fmt(s, ".2f") for s in e["shapes"])
            says = "asymptotic" if e["asymptotic"] else "NOT: " + "; ".join(r.split(":")[0] for r in e["reasons"])
            tm = row.get("true_max")
            if e["err_max"] is not None and tm:
                ratios = "; ".join(fmt(a / b, ".2f") for a, b in zip(e["err_max"][-2:], tm[-2:]))
                rich = "; ".join(fmt(a / b, ".2f") for a, b in zip(e["richardson_max"][-2:], tm[-2:]))
            else:
                ratios = rich = "-"
            true = f"{fmt(tm[-1])} ({fmt(row['check_max'][-1])}); all: {', '.join(fmt(v) for v in tm)}" if tm else "-"
            lines.append(f"| t {row['t']:g} | {orders} ({shapes}) | {says} | est/true {ratios} | "
                         f"Richardson alone {rich} | bias {fmt(e.get('bias_max'))} | true {true} |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", action="append")
    ap.add_argument("--out", default=os.path.join(ROOT, "results", "converge"))
    ap.add_argument("--report-only", action="store_true")
    args = ap.parse_args()
    for name, cargs in STUDIES.items():
        if args.only and name not in args.only:
            continue
        out = os.path.join(args.out, name)
        if not args.report_only:
            cmd = [sys.executable, "-m", "parsph", "converge", *cargs, "--out", out]
            p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
            with open(out + ".log", "w") as f:
                f.write(p.stdout + p.stderr)
            if p.returncode != 0:
                print(f"## {name}: exit {p.returncode}: {p.stderr.strip()[-300:]}", flush=True)
                continue
        path = os.path.join(out, "converge.json")
        if os.path.exists(path):
            print(report(name, path), flush=True)


if __name__ == "__main__":
    main()
