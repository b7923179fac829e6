#!/usr/bin/env bash
# Set up whatever is missing and run the whole test suite:
#   1. serial tests (they also launch small mpirun jobs as subprocesses)
#   2. the MPI-marked tests under mpirun -n 2 and -n 3 (pytest-mpi)
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
bash scripts/setup.sh
source scripts/mpienv.sh
PY=.venv/bin/python
echo "== serial tests"
$PY -m pytest -q tests "$@"
for n in 2 3; do
    echo "== MPI tests on $n ranks"
    # pytest-mpi: only tests marked mpi; each rank runs them on COMM_WORLD
    NUMBA_NUM_THREADS=1 timeout 900 mpirun -n $n $PARSPH_MPIRUN_FLAGS $PY -m pytest -q --with-mpi -m mpi -p no:cacheprovider tests "$@"
done
