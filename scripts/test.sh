#!/usr/bin/env bash
# Set up whatever is missing (with the loops the suite runs compiled) and run the whole test suite:
#   1. serial tests (they also launch small mpirun jobs as subprocesses), in
#      PARSPH_TEST_WORKERS (default: one more than the cores) pytest-xdist
#      workers, one test file per worker at a time (a file's module fixtures run
#      once); 0: in this process. A worker waits part of its time on the
#      processes it launches (MPI's start-up, mpirun's grace before it signals),
#      so one worker more than the cores keeps them busy
#   2. the MPI-marked tests under mpirun -n 2 and -n 3 (pytest-mpi), collected
#      from the files that hold them (every rank imports what it collects)
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
# Python keeps the byte-code of what it imports (parsph's and the tests' modules, in their __pycache__ folders
# beside numba's cache): without it each of the suite's 250-odd processes compiles the sources again
unset PYTHONDONTWRITEBYTECODE
bash scripts/setup.sh --suite  # also compiles what the suite runs in launched processes and under mpirun
source scripts/mpienv.sh
PY=.venv/bin/python
CORES=$(nproc 2>/dev/null || echo 1)
echo "== serial tests"
$PY -m pytest -q -n "${PARSPH_TEST_WORKERS:-$((CORES + 1))}" --dist loadfile tests "$@"
MPI_FILES=$(grep -l 'mark\.mpi' tests/test_*.py)
for n in 2 3; do
    echo "== MPI tests on $n ranks"
    # pytest-mpi: only tests marked mpi; each rank runs them on COMM_WORLD
    NUMBA_NUM_THREADS=1 timeout 900 mpirun -n $n $PARSPH_MPIRUN_FLAGS $PY -m pytest -q --with-mpi -m mpi -p no:cacheprovider $MPI_FILES "$@"
done
