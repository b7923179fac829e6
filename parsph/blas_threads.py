"""One BLAS thread per process, unless the environment says otherwise (``OPENBLAS_NUM_THREADS``).

parsph's dense linear algebra is the solved gas's banded Cholesky factor and its solves (LAPACK through
scipy; a grid of a few thousand cells), too small for OpenBLAS's threads to pay: on the 2-core machine
of docs/performance.md a factorisation of the bubbling bed's 80 x 40 grid took 6.2 ms with the default
threads and 1.3 ms with one, and 16 ms beside another busy process (its threads spin-wait for a core);
under ``mpirun`` every rank is such a process. OpenBLAS reads the setting when numpy first loads it, so
this must run before numpy is imported (parsph's ``__init__`` runs it; a script that imports numpy first
keeps the default).
"""
import os

ENV = "OPENBLAS_NUM_THREADS"


def apply():
    os.environ.setdefault(ENV, "1")
