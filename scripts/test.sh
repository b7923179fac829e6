#!/usr/bin/env bash
# Set up whatever is missing (with the loops the suite runs compiled) and run the whole test suite:
#   1. serial tests (they also launch small mpirun jobs as subprocesses), in
#      PARSPH_TEST_WORKERS (default 2) pytest-xdist workers, one test file per
#      worker at a time (a file's module fixtures run once); 0: in this process
#   2. the MPI-marked tests under mpirun -n 2 and -n 3 (pytest-mpi)
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
bash scripts/setup.sh --suite  # also compiles what the suite runs in launched processes and under mpirun
source scripts/mpienv.sh
PY=.venv/bin/python
echo "== serial tests"
$PY -m pytest -q -n "${PARSPH_TEST_WORKERS:-2}" --dist loadfile tests "$@"
for n in 2 3; do
    echo "== MPI tests on $n ranks"
    # pytest-mpi: only tests marked mpi; each rank runs them on COMM_WORLD
    NUMBA_NUM_THREADS=1 timeout 900 mpirun -n $n $PARSPH_MPIRUN_FLAGS $PY -m pytest -q --with-mpi -m mpi -p no:cacheprovider tests "$@"
done
