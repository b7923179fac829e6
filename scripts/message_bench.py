"""The cost of the step's messages by route: one ghost round (to and from both neighbours) and one
3-float all-reduce, sent from compiled code (parsph.parallel.native_mpi), through mpi4py's Isend/Irecv/
Waitall, and through mpi4py's persistent requests (Startall/Waitall).

    mpirun -n 2 .venv/bin/python scripts/message_bench.py [--rows 200] [--reps 20000]

Rows of 6 float64 (a 2-D forward row), ``--rows`` to each neighbour. Prints microseconds per round
(the median of 5 timed batches, the slowest rank); the compiled route's loop runs entirely in numba.
"""
import argparse
import time

import numpy as np
from mpi4py import MPI
from numba import njit

from parsph.parallel import native_mpi


@njit(cache=True)
def native_rounds(h, left, right, up, down, below, above, n, reqs, stats, flags, out, reps):
    err = 0
    for _ in range(reps):
        err |= native_mpi.exchange_rows(h, left, right, 31, 32, up, n, down, n, below, n, above, n, reqs, stats)
        err |= native_mpi.allreduce(h, native_mpi.OP_MAX, flags, out)
    return err


def mpi4py_rounds(comm, left, right, up, down, below, above, flags, out, reps):
    D = MPI.DOUBLE
    for _ in range(reps):
        rq = [comm.Irecv([below, D], left, 31), comm.Irecv([above, D], right, 32),
              comm.Isend([up, D], right, 31), comm.Isend([down, D], left, 32)]
        MPI.Request.Waitall(rq)
        comm.Allreduce(flags, out, op=MPI.MAX)


def persistent_rounds(comm, left, right, up, down, below, above, flags, out, reps):
    D = MPI.DOUBLE
    rq = [comm.Recv_init([below, D], left, 31), comm.Recv_init([above, D], right, 32),
          comm.Send_init([up, D], right, 31), comm.Send_init([down, D], left, 32)]
    for _ in range(reps):
        MPI.Prequest.Startall(rq)
        MPI.Request.Waitall(rq)
        comm.Allreduce(flags, out, op=MPI.MAX)
    for r in rq:
        r.Free()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rows", type=int, default=200)
    ap.add_argument("--reps", type=int, default=20000)
    a = ap.parse_args()
    comm = MPI.COMM_WORLD
    r, P = comm.rank, comm.size
    left, right = (r - 1) % P, (r + 1) % P
    n = a.rows
    up, down, below, above = (np.random.default_rng(r).random((n, 6)) for _ in range(4))
    flags, out = np.zeros(3), np.zeros(3)
    routes = {"mpi4py Isend/Irecv/Waitall": lambda k: mpi4py_rounds(comm, left, right, up, down, below, above,
                                                                      flags, out, k),
              "mpi4py persistent requests": lambda k: persistent_rounds(comm, left, right, up, down, below, above,
                                                                        flags, out, k)}
    ok, why = native_mpi.available()
    if ok:
        h = native_mpi.handles(comm)
        reqs, stats = native_mpi.requests(4)
        routes["compiled (native_mpi)"] = lambda k: native_rounds(h, left, right, up, down, below, above, n, reqs,
                                                                 stats, flags, out, k)
    elif r == 0:
        print(f"compiled route unavailable: {why}")
    for name, fn in routes.items():
        fn(10)
        times = []
        for _ in range(5):
            comm.Barrier()
            t0 = time.perf_counter()
            fn(a.reps // 5)
            times.append((time.perf_counter() - t0) / (a.reps // 5))
        worst = comm.allreduce(float(np.median(times)), op=MPI.MAX)
        if r == 0:
            print(f"P={P} rows={n:5d}  {name:30s} {worst * 1e6:7.2f} us per ghost round + all-reduce", flush=True)


if __name__ == "__main__":
    main()
