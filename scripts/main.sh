#!/usr/bin/env bash
# The main job: set up whatever is missing, run the paper's Couette case
# (Table 1) to t = 0.5 s on 2 ranks, print the error table against Eq. (8)
# and write the profile PNG.
#   bash scripts/main.sh [RANKS] [extra parsph run options]
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
bash scripts/setup.sh
source scripts/mpienv.sh
RANKS=${1:-2}
shift || true
OUT=out/couette_paper
mpirun -n "$RANKS" $PARSPH_MPIRUN_FLAGS .venv/bin/parsph run run/couette_paper.toml --out "$OUT" --force "$@"
.venv/bin/parsph plot "$OUT"
.venv/bin/parsph check "$OUT" --tol 0.02
