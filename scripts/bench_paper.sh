#!/usr/bin/env bash
# Wall time of the paper case (Table 1, run/couette_paper.toml, to t = 0.5 s)
# on 1 and on 2 ranks, one thread per rank, with the error table of each run.
#   bash scripts/bench_paper.sh [OUTDIR]      (default results/paper)
# Writes OUTDIR/bench_paper.md: the two runs' wall time, particle-steps/s and
# speed-up, then each run's error table against Eq. (8). The wall time is the
# time loop's as the run prints it (the steady steps after the first, output writes included);
# the process start, the set-up, the first step and any compiling are not in it.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
bash scripts/setup.sh
source scripts/mpienv.sh
OUT=${1:-results/paper}
mkdir -p "$OUT"
for n in 1 2; do
    echo "== paper case on $n rank(s)"
    NUMBA_NUM_THREADS=1 mpirun -n $n $PARSPH_MPIRUN_FLAGS .venv/bin/parsph run run/couette_paper.toml \
        --out "$OUT/ranks$n" --force --quiet | tee "$OUT/ranks$n.log"
done
.venv/bin/python - "$OUT" <<'PY'
import re, subprocess, sys, platform, os
out = sys.argv[1]
rows = {}
for n in (1, 2):
    m = re.search(r"done: (\d+) steps in [\d.]+ s: time loop ([\d.]+) s \(([\d.e+]+) particle-steps/s", open(f"{out}/ranks{n}.log").read())
    rows[n] = (int(m.group(1)), float(m.group(2)), float(m.group(3)))
rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
lines = [f"Paper case to t = 0.5 s, commit {rev}, {platform.node()} ({os.cpu_count()} cores)", "",
         "| ranks | steps | wall time [s] | particle-steps/s | speed-up |", "| --- | --- | --- | --- | --- |"]
for n, (steps, wall, rate) in rows.items():
    lines.append(f"| {n} | {steps} | {wall:.1f} | {rate:.3g} | {rows[1][1] / wall:.2f} |")
for n in (1, 2):
    table = subprocess.run([".venv/bin/parsph", "check", f"{out}/ranks{n}"], capture_output=True, text=True).stdout
    lines += ["", f"{n} rank(s):", "```", table.rstrip(), "```"]
open(f"{out}/bench_paper.md", "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
