"""MPI called from numba code: the few functions the compiled step needs, bound to the libmpi that mpi4py loaded.

The functions are declared as external symbols (``numba.types.ExternalFunction``)
that LLVM resolves in the process when a compiled function is loaded, so the
callers keep ``cache=True``; the library is made visible to LLVM with
``llvmlite.binding.load_library_permanently``. Handles (communicator, datatype,
operation) come from mpi4py (``MPI._handleof``) as integers, so the compiled
code works on whatever communicator parsph is handed, not only COMM_WORLD.

The bindings pass every handle and address as a pointer-sized integer. That
is Open MPI's ABI (handles are pointers); MPICH's handles are C ``int``, which
the x86-64 and AArch64 calling conventions pass in the same registers, but the
bindings are used only where :func:`available` has checked the library and
the handle sizes: elsewhere the solver sends its messages through mpi4py, the
same arithmetic by another route.

Requests and statuses live in int64 arrays sized from mpi4py's
``MPI._sizeof`` (never MPI_STATUSES_IGNORE, a macro with no symbol).
"""
import os

import numpy as np
from numba import njit, types

ENV = "PARSPH_NATIVE_MPI"  # "0": send from Python through mpi4py even where the bindings load

_i32, _ip, _f64 = types.int32, types.intp, types.float64
# int MPI_Isend(const void *buf, int count, MPI_Datatype, int dest, int tag, MPI_Comm, MPI_Request *)
mpi_isend = types.ExternalFunction("MPI_Isend", _i32(_ip, _i32, _ip, _i32, _i32, _ip, _ip))
mpi_irecv = types.ExternalFunction("MPI_Irecv", _i32(_ip, _i32, _ip, _i32, _i32, _ip, _ip))
mpi_waitall = types.ExternalFunction("MPI_Waitall", _i32(_i32, _ip, _ip))
# int MPI_Allreduce(const void *send, void *recv, int count, MPI_Datatype, MPI_Op, MPI_Comm)
mpi_allreduce = types.ExternalFunction("MPI_Allreduce", _i32(_ip, _ip, _i32, _ip, _ip, _ip))
# int MPI_Iallreduce(const void *send, void *recv, int count, MPI_Datatype, MPI_Op, MPI_Comm, MPI_Request *)
mpi_iallreduce = types.ExternalFunction("MPI_Iallreduce", _i32(_ip, _ip, _i32, _ip, _ip, _ip, _ip))
mpi_wait = types.ExternalFunction("MPI_Wait", _i32(_ip, _ip))
mpi_wtime = types.ExternalFunction("MPI_Wtime", _f64())

# the handles array of a communicator (Handles.h): its columns
COMM, DOUBLE, OP_MAX, OP_SUM = 0, 1, 2, 3
REQUEST_WORDS = 1  # int64 words per MPI_Request (checked in available())
_STATE = {}


def _libmpi_path():
    """The libmpi shared object this process has mapped (the one mpi4py loaded)."""
    try:
        with open("/proc/self/maps") as f:
            for line in f:
                path = line.split()[-1]
                if "/libmpi.so" in path or "/libmpich.so" in path:
                    return path
    except OSError:
        pass
    return None


def load():
    """Load the libmpi that mpi4py mapped into LLVM's symbol table (once): "" where it is there, else why not.
    Every MPI has MPI_Wtime, the compiled stages' clock (:func:`wtime`); the handle-taking bindings need
    :func:`available` besides."""
    if "loaded" not in _STATE:
        from mpi4py import MPI  # noqa: F401 - maps libmpi
        path, why = _libmpi_path(), ""
        if path is None:
            why = "no libmpi mapped in this process"
        else:
            try:
                import llvmlite.binding as llvm
                llvm.load_library_permanently(path)
            except Exception as e:  # noqa: BLE001 - reported: the bindings are then not used
                why = f"cannot load {path} into LLVM: {e}"
        _STATE["loaded"] = why
    return _STATE["loaded"]


def available():
    """(True, "") where compiled code can call MPI here; else (False, why) and the caller uses mpi4py."""
    if "ok" in _STATE:
        return _STATE["ok"], _STATE["why"]
    ok, why = False, ""
    if os.environ.get(ENV, "1") == "0":
        why = f"{ENV}=0"
    else:
        from mpi4py import MPI
        sizes = [MPI._sizeof(t) for t in (MPI.Comm, MPI.Datatype, MPI.Op, MPI.Request)]
        why = load()
        if not why and any(s != 8 for s in sizes):
            why = f"handle sizes {sizes} (the bindings know pointer-sized handles, Open MPI's)"
        ok = not why
    _STATE.update(ok=ok, why=why)
    return ok, why


def handles(comm):
    """The int64 handles of ``comm`` and of the datatype and operations the compiled code uses."""
    from mpi4py import MPI
    return np.array([MPI._handleof(comm), MPI._handleof(MPI.DOUBLE), MPI._handleof(MPI.MAX),
                     MPI._handleof(MPI.SUM)], np.int64)


def requests(n):
    """Room for n requests and n statuses (int64 words)."""
    from mpi4py import MPI
    words = -(-MPI._sizeof(MPI.Status) // 8)
    return np.zeros(n * REQUEST_WORDS, np.int64), np.zeros(n * words + 1, np.int64)


@njit(cache=True)
def exchange_rows(h, left, right, tag_up, tag_down, up, n_up, down, n_down, below, n_below, above, n_above,
                  reqs, stats):
    """One round with both neighbours: the first n_up rows of ``up`` to the right (tag_up), n_down of ``down``
    to the left (tag_down); n_below rows from the left into ``below``, n_above from the right into ``above``.

    C-contiguous 2-D float64 buffers of one width. Returns MPI's error code (0: success)."""
    w = up.shape[1]
    comm, dbl = h[COMM], h[DOUBLE]
    r = reqs.ctypes.data
    err = mpi_irecv(below.ctypes.data, n_below * w, dbl, left, tag_up, comm, r)
    err |= mpi_irecv(above.ctypes.data, n_above * w, dbl, right, tag_down, comm, r + 8)
    err |= mpi_isend(up.ctypes.data, n_up * w, dbl, right, tag_up, comm, r + 16)
    err |= mpi_isend(down.ctypes.data, n_down * w, dbl, left, tag_down, comm, r + 24)
    err |= mpi_waitall(4, r, stats.ctypes.data)
    return err


@njit(cache=True)
def allreduce(h, op, values, out):
    """out = the element-wise reduction (h[OP_MAX] or h[OP_SUM]) of the float64 ``values`` over the ranks."""
    return mpi_allreduce(values.ctypes.data, out.ctypes.data, values.size, h[DOUBLE], h[op], h[COMM])


@njit(cache=True)
def iallreduce(h, op, values, out, req):
    """:func:`allreduce` started, not waited for: ``values`` and ``out`` must stay untouched until
    :func:`wait` on ``req`` (one request of :func:`requests`) returns."""
    return mpi_iallreduce(values.ctypes.data, out.ctypes.data, values.size, h[DOUBLE], h[op], h[COMM],
                          req.ctypes.data)


@njit(cache=True)
def wait(req, stat):
    """Wait for the one request in ``req`` (its status into ``stat``); returns MPI's error code."""
    return mpi_wait(req.ctypes.data, stat.ctypes.data)


@njit(cache=True)
def wtime():
    """Seconds of MPI's wall clock (MPI_Wtime): the compiled step's phase timers."""
    return mpi_wtime()
