"""The shipped gas run files through ``parsph run`` and ``parsph check`` at its default tolerances: the table of
docs/validation.md ("The shipped gas run files against parsph check").

    .venv/bin/python scripts/check_gas_scenes.py [--out out] [--ranks 1] [--reuse] [--names NAME ...]

Each run file ``run/NAME.toml`` runs to its end (``parsph run run/NAME.toml --out OUT/NAME --force``, under
``mpirun -n RANKS`` where RANKS > 1; the results are the same bit for bit on any rank count), then
``parsph check OUT/NAME`` judges it. ``--reuse`` checks existing outputs without running. Prints a markdown
table: the exit code of check, its verdict's numbers (a layer: the worst height of the mass fractions against
the transient, % of H0, and the worst interior theta at the end state; otherwise the error table's worst max
error) and the run's wall time.
"""
import argparse
import os
import re
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NAMES = ("suspension", "sedimentation", "fluidized_bed", "fluidized_bed_air", "bubbling_bed", "single_bubble",
         "bubbling_bed_3d")


def parsph(*args, ranks=1):
    cmd = [sys.executable, "-m", "parsph", *args]
    if ranks > 1:
        cmd = ["mpirun", "-n", str(ranks), *os.environ.get("PARSPH_MPIRUN_FLAGS", "").split(), *cmd]
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)


def verdict(out):
    """The numbers check printed: (heights % of H0, interior %) for a layer (None where not judged), (the
    time-averaged drop's deviation from the weight %, the bubbles' median rise velocity / c sqrt(g D)) for a
    bubbling bed, else (the error table's worst max error, None)."""
    if "bed check:" in out:
        d = re.search(r"drop/W = [\d.]+ \(([+-][\d.]+)%[);]", out)
        r = re.search(r"u_b / \([\d.]+ sqrt\(g D\)\): median ([\d.e+-]+)", out)
        return (float(d.group(1)) if d else None), (float(r.group(1)) if r else None)
    if "layer:" in out:
        h = re.search(r"heights within ([\d.e+-]+)% of H0", out)
        i = re.search(r"interior theta within ([\d.e+-]+)%", out)
        return (float(h.group(1)) if h else None), (float(i.group(1)) if i else None)
    column = 2 if "amplitude" in out else 1   # (t, [amplitude,] max error, rms error, ...)
    rows = [float(line.split()[column]) for line in out.splitlines() if re.match(r"\s+[\d.]+\s", line)]
    return (max(rows) if rows else None), None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "out"))
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--reuse", action="store_true", help="check existing outputs, do not run")
    ap.add_argument("--names", nargs="+", default=list(NAMES))
    a = ap.parse_args()
    lines = ["| run file | `parsph check` exit | verdict (default tolerances) | run wall time |",
             "| --- | --- | --- | --- |"]
    for name in a.names:
        out = os.path.join(a.out, name)
        wall = "-"
        if not a.reuse:
            t0 = time.perf_counter()
            r = parsph("run", os.path.join("run", name + ".toml"), "--out", out, "--force", "--quiet", ranks=a.ranks)
            if r.returncode != 0:
                sys.exit(f"{name}: parsph run failed ({r.returncode}): {r.stderr.strip()}")
            wall = f"{time.perf_counter() - t0:.0f} s ({a.ranks} rank{'s' if a.ranks > 1 else ''})"
        c = parsph("check", out)
        first, second = verdict(c.stdout)
        if "bed check:" in c.stdout:
            what = (f"drop {first:+.3g}% from the weight (1%)" if first is not None else "drop not judged") + \
                   (f", bubbles' rise {second:.3g} x c sqrt(g D) (c: 0.5 in 2-D, 0.711 in 3-D)" if second is not None else ", no bubble tracked")
        elif "layer:" in c.stdout:
            what = (f"heights within {first:.3g}% of H0 (3%)" if first is not None else "no heights") + \
                   (f", interior theta within {second:.3g}% (2%)" if second is not None else ", interior not judged")
        else:
            what = f"max error {first:.3g} (0.02)" if first is not None else "no reference"
        lines.append(f"| `run/{name}.toml` | {c.returncode} | {what} | {wall} |")
        print(lines[-1], flush=True)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
