"""Collective HDF5 I/O on COMM_WORLD with synthetic frames (pytest-mpi, any rank count >= 1).

    mpirun -n 3 .venv/bin/python -m pytest -q --with-mpi -m mpi tests/test_mpi_collective_io.py

The last rank holds no particles when the writer runs: it must still take part
in every collective call. After the writes and reads, HDF5's own record of the
transfer (H5Pget_mpio_actual_io_mode, H5Pget_mpio_no_collective_cause, called
through ctypes on the library h5py loaded) must say collective on every rank,
after every H5Dwrite and H5Dread (test_every_dataset_is_transferred_collectively
records it per dataset), not only the last of a call.
The files are compared with the arrays that went in; read_particles on slabs
other than the writer's with brute-force masks of those arrays. The same checks
run with PARSPH_SERIAL_HDF5=1 (gather to rank 0; serial reads per rank), where
the transfer mode is not checked.
"""
import ctypes
from pathlib import Path

import numpy as np
import pytest

from parsph.setup import config
from parsph import output

pytestmark = pytest.mark.mpi

PAPER = str(Path(__file__).resolve().parent.parent / "run" / "couette_paper.toml")
H5D_MPIO_CONTIGUOUS_COLLECTIVE = 0x4  # H5D_mpio_actual_io_mode_t
LY = 0.004


def hdf5_library():
    """The libhdf5 that h5py uses (already loaded: ctypes shares its state)."""
    import h5py  # noqa: F401 - loads the library
    with open("/proc/self/maps") as f:
        paths = {ln.split()[-1] for ln in f if "/libhdf5" in ln and "_hl" not in ln}
    assert len(paths) == 1, paths
    lib = ctypes.CDLL(paths.pop())
    lib.H5Pget_mpio_actual_io_mode.argtypes = [ctypes.c_int64, ctypes.POINTER(ctypes.c_int)]
    lib.H5Pget_mpio_no_collective_cause.argtypes = [ctypes.c_int64, ctypes.POINTER(ctypes.c_uint32),
                                                     ctypes.POINTER(ctypes.c_uint32)]
    return lib


def io_mode(dxpl):
    """(actual I/O mode, local and global causes of no collective I/O) of the last transfer."""
    lib = hdf5_library()
    mode, local, glob = ctypes.c_int(-1), ctypes.c_uint32(99), ctypes.c_uint32(99)
    assert lib.H5Pget_mpio_actual_io_mode(dxpl.id, ctypes.byref(mode)) >= 0
    assert lib.H5Pget_mpio_no_collective_cause(dxpl.id, ctypes.byref(local), ctypes.byref(glob)) >= 0
    return mode.value, local.value, glob.value


def frame_of_rank(cfg, comm):
    """Rank r: 300 + 40 r particles in its slab [r Ly/P, (r+1) Ly/P); the last rank none (P > 1)."""
    r, P = comm.rank, comm.size
    n = 0 if (P > 1 and r == P - 1) else 300 + 40 * r
    rng = np.random.default_rng(100 + r)
    pos = np.column_stack([rng.uniform(0, cfg.L, n), rng.uniform(r * LY / P, (r + 1) * LY / P, n)])
    fields = {"id": 10_000 * r + rng.permutation(5 * n + 1)[:n], "kind": rng.integers(0, 3, n),
              "mass": rng.uniform(1, 2, n), "position": pos, "velocity": rng.normal(size=(n, 2)),
              "theta": rng.uniform(0.3, 0.4, n)}
    nb = cfg.Nx
    profile = {k: np.linspace(0, 1, nb) for k in ("x", "vy", "theta", "count", "vy_exact", "theta_exact")}
    profile["err"] = (0.5, 0.25)
    return output.Frame(0.001, 100, cfg.dt, profile, fields)


def gathered(comm, fields):
    parts = comm.allgather(fields)
    return {k: np.concatenate([p[k] for p in parts]) for k in fields}


def by_id(d, keys):
    order = np.argsort(d["id"], kind="stable")
    return {k: np.asarray(d[k])[order] for k in keys}


@pytest.mark.parametrize("serial", [False, True], ids=["mpio", "serial_hdf5"])
def test_collective_write_and_slab_reads(mpi_tmp_path, monkeypatch, serial):
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    if serial:
        monkeypatch.setenv(output.SERIAL_ENV, "1")
    elif not output.parallel_hdf5_available():
        pytest.skip("h5py without MPI")
    cfg = config.load(PAPER, [f"domain.Ly={LY}"])
    fr = frame_of_rank(cfg, comm)
    everything = gathered(comm, fr.fields)
    N = len(everything["id"])
    out = output.Output(comm, str(mpi_tmp_path), "serial" if serial else "mpio", cfg, N)
    path = out(fr, snapshot=True)
    if not serial:
        modes = comm.allgather(io_mode(out.dxpl))
        assert modes == [(H5D_MPIO_CONTIGUOUS_COLLECTIVE, 0, 0)] * comm.size, modes

    # the file holds every rank's particles (serial h5py, sorted by id)
    snap = output.read_snapshot(path)
    want = by_id(everything, output.PARTICLE_FIELDS)
    for k in output.PARTICLE_FIELDS:
        assert np.array_equal(snap[k], want[k].astype(output.FILE_DTYPES[k])), k

    # read back on slabs shifted from the writer's; the last rank's is empty; a few rows per round
    # so that ranks need different numbers of rounds and the short ones read empty selections
    monkeypatch.setattr(output.restart, "READ_ROWS", (37, 37))
    P = comm.size
    cuts = [min(LY, (r + 0.37) * LY / P) if r else 0.0 for r in range(P)] + [LY]
    lo, hi = cuts[comm.rank], cuts[comm.rank + 1]
    if P > 1 and comm.rank == P - 1:
        lo = hi = LY
    if P > 1 and comm.rank == P - 2:
        hi = LY
    dxpl = None if serial else output.collective_dxpl()
    got = output.read_particles(path, comm, lo, hi, dxpl=dxpl)
    if not serial:
        modes = comm.allgather(io_mode(dxpl))
        assert modes == [(H5D_MPIO_CONTIGUOUS_COLLECTIVE, 0, 0)] * comm.size, modes
    y = everything["position"][:, 1]
    mask = (y >= lo) & (y < hi)
    want = by_id({k: everything[k][mask] for k in output.RESTART_FIELDS}, output.RESTART_FIELDS)
    got = by_id(got, output.RESTART_FIELDS)
    for k in output.RESTART_FIELDS:
        assert np.array_equal(got[k], want[k].astype(output.FILE_DTYPES[k])), k
    assert comm.allreduce(len(got["id"])) == N

    # on the writer's own slabs every rank gets its particles back in the order it held them
    mine = output.read_particles(path, comm, comm.rank * LY / P, (comm.rank + 1) * LY / P)
    for k in output.RESTART_FIELDS:
        assert np.array_equal(mine[k], np.asarray(fr.fields[k]).astype(output.FILE_DTYPES[k])), k


def test_every_dataset_is_transferred_collectively(mpi_tmp_path, monkeypatch):
    """HDF5's record after every H5Dwrite and H5Dread of an output and a restart read, not only the
    last: each must have been collective on every rank, the writes must cover every dataset of the
    file (the profile, which rank 0 writes and the others select nothing of, included) and the reads
    every dataset read_particles returns rows of. The only other reads are high-level reads of the
    small layout tables (offset and y_range on rank 0, a few bin_start entries per rank)."""
    import h5py
    from mpi4py import MPI
    from parsph.output import restart, write
    comm = MPI.COMM_WORLD
    if not output.parallel_hdf5_available():
        pytest.skip("h5py without MPI")
    cfg = config.load(PAPER, [f"domain.Ly={LY}"])
    fr = frame_of_rank(cfg, comm)
    n = len(fr.fields["id"])
    fr.fields["position_raw"] = fr.fields["position"] + 1e-9   # the solver's state: /restart/*
    fr.fields["ref"] = fr.fields["position"].copy()
    N = comm.allreduce(n)
    records = []

    def recording(fn):
        def wrapped(dset, *args):
            out = fn(dset, *args)
            dxpl = args[-1]  # both pass the transfer list last: (dset, start, arr, dxpl), (dset, ranges, dxpl)
            records.append((dset.name, io_mode(dxpl) if dxpl is not None else "independent: no transfer list"))
            return out
        return wrapped

    monkeypatch.setattr(write, "write_rows", recording(output.hdf5.write_rows))
    monkeypatch.setattr(restart, "read_rows", recording(output.hdf5.read_rows))
    path = output.Output(comm, str(mpi_tmp_path), "io", cfg, N)(fr, snapshot=True)
    written, records[:] = list(records), []
    high_level = set()
    getitem = h5py.Dataset.__getitem__

    def noting(self, key):
        high_level.add(self.name)
        return getitem(self, key)

    monkeypatch.setattr(h5py.Dataset, "__getitem__", noting)
    P = comm.size
    got = output.read_particles(path, comm, comm.rank * LY / P, (comm.rank + 1) * LY / P)
    monkeypatch.setattr(h5py.Dataset, "__getitem__", getitem)
    read = list(records)
    assert np.array_equal(got["ref"], fr.fields["ref"])

    collective = (H5D_MPIO_CONTIGUOUS_COLLECTIVE, 0, 0)
    for what, recs in (("write", written), ("read", read)):
        everyone = comm.allgather(recs)
        assert all(len(r) == len(recs) for r in everyone), f"ranks made different numbers of {what}s"
        bad = [(rank, name, mode) for rank, r in enumerate(everyone) for name, mode in r if mode != collective]
        assert not bad, f"{what}s that were not collective (rank, dataset, mode): {bad}"
    with h5py.File(path, "r", driver="mpio", comm=comm) as f:
        datasets = set()
        f.visititems(lambda name, obj: datasets.add("/" + name) if isinstance(obj, h5py.Dataset) else None)
    assert {name for name, _ in written} == datasets
    assert len(written) == len(datasets)  # each dataset in one call
    want_read = {f"/particles/{k}" for k in output.RESTART_FIELDS} | {"/restart/position", "/restart/ref",
                                                                       "/layout/memory_index"}
    assert {name for name, _ in read} == want_read
    assert high_level <= {"/layout/offset", "/layout/y_range", "/layout/bin_start"}, high_level
