"""Restart: each rank reads the particles of its own slab from an output file, whatever the rank count that
wrote it: only the rows of the y-bins that overlap its slab, in rounds of bounded size, in the memory order
of the writer.
"""
import h5py
import numpy as np

from .hdf5 import collective_dxpl, parallel_hdf5_available, read_rows, y_bins
from .layout import FILE_DTYPES, RESTART_FIELDS

READ_ROWS = (1 << 16, 1 << 22)  # rows per read round of a restart: ceil(N / P) clipped to this


def read_state(path):
    """What a restart needs before it sets up: the attributes of one output file with particles
    (no particle arrays) and its path, for ``read_particles``."""
    with h5py.File(path, "r") as f:
        if "particles" not in f:
            raise ValueError(f"{path} holds no particles (output.snapshots was false)")
        g, n = f["particles"], f.attrs["n_particles"]
        for key in RESTART_FIELDS:
            if key not in g or g[key].shape[:1] != (n,):
                raise ValueError(f"{path}: /particles/{key} is missing or not {n} rows long")
        return {"attrs": dict(f.attrs), "path": path}


def read_grid(path):
    """An output's /grid (the solved gas's cells, :class:`parsph.output.Frame`'s ``grid``) as {name: array,
    "attrs": dict}, subgroups' names with a "/"; None where the file has none. Small: every rank reads it."""
    with h5py.File(path, "r") as f:
        if "grid" not in f:
            return None
        out = {"attrs": dict(f["grid"].attrs)}
        f["grid"].visititems(lambda name, obj: out.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset)
                             else None)
        return out


def rows_in(f, comm, lo, hi, parallel):
    """Ascending, disjoint row ranges (a, b) of the file that hold every particle with
    lo <= y < hi (the bins of the writer ranks' rows that overlap [lo, hi)), and the
    writer ranks' row offsets (None for a file without /layout)."""
    g = f["particles"]
    n = g["id"].shape[0]
    if "layout" not in f:  # a file without the layout: every row, read in rounds and filtered
        return [(0, n)], None
    lay = f["layout"]
    tables = None
    if comm.rank == 0 or not parallel:
        tables = lay["offset"][()], lay["y_range"][()]
    if parallel:
        tables = comm.bcast(tables, root=0)
    offset, y_range = tables
    nbins = lay["bin_start"].shape[1] - 1
    ranges = []
    for r in range(len(y_range)):
        y0, y1 = y_range[r]
        if offset[r + 1] == offset[r] or y1 < lo or y0 >= hi:
            continue
        k0, k1 = y_bins([max(lo, y0), min(hi, y1)], y0, y1, nbins)
        starts = lay["bin_start"][r, int(k0):int(k1) + 2]
        ranges.append((int(starts[0]), int(starts[-1])))
    return ranges, offset


def _rounds(ranges, size):
    """Split row ranges into rounds of at most ``size`` rows each."""
    rounds, cur, room = [], [], size
    for a, b in ranges:
        while b > a:
            take = min(b - a, room)
            cur.append((a, a + take))
            a += take
            room -= take
            if room == 0:
                rounds.append(cur)
                cur, room = [], size
    if cur:
        rounds.append(cur)
    return rounds


def read_particles(path, comm, lo, hi, dxpl=None):
    """The particles of one output file with lo <= y < hi (id, kind, mass, position, velocity, and the
    solver's exact state position_raw, ref where the file has them).

    Collective on ``comm`` under the mpio driver (every rank the same number of
    collective reads, empty where it has nothing left to read); with serial HDF5
    each rank opens the file itself. A rank reads only the rows of the file's
    y-bins that overlap [lo, hi), in rounds of at most ceil(N / P) rows (clipped to
    READ_ROWS), so its memory is O(N / P) whatever the rank count that wrote the file.
    Particles come in writer-rank order and, within a writer's rows, in the order the
    writer held them (/layout/memory_index), so a restart on the same slabs continues
    with the same memory order as the run that wrote the file (and adds the profile's
    per-bin sums in the same order). ``dxpl``: the collective transfer list to use
    (default a new one; tests pass theirs to inspect the I/O mode HDF5 used).
    """
    parallel = parallel_hdf5_available()
    f = h5py.File(path, "r", driver="mpio", comm=comm) if parallel else h5py.File(path, "r")
    dxpl = (dxpl or collective_dxpl()) if parallel else None
    g = f["particles"]
    n = g["id"].shape[0]
    ranges, offset = rows_in(f, comm, lo, hi, parallel)
    size = int(np.clip(-(-n // comm.size), *READ_ROWS))
    rounds = _rounds(ranges, size)
    count = comm.allreduce(len(rounds), op=_mpi_max()) if parallel else len(rounds)
    shapes = {key: g[key].shape[1:] for key in RESTART_FIELDS}
    dtypes = dict(FILE_DTYPES)
    sources = {key: g[key] for key in RESTART_FIELDS}
    if "restart" in f and "ref" in f["restart"]:  # the solver's exact state (see the module docstring)
        for key, name in (("position_raw", "position"), ("ref", "ref")):
            sources[key] = f["restart"][name]
            shapes[key], dtypes[key] = f["restart"][name].shape[1:], np.float64
    if offset is not None and "memory_index" in f["layout"]:  # (writer rank << 32) + place in its memory
        sources["order"] = f["layout/memory_index"]
        shapes["order"], dtypes["order"] = (), np.int64
    pieces = {key: [] for key in sources}
    for i in range(count):
        sel = rounds[i] if i < len(rounds) else []
        pos = read_rows(g["position"], sel, dxpl)
        keep = (pos[:, 1] >= lo) & (pos[:, 1] < hi)
        every = bool(keep.all())  # inner bins: no filtering copy
        pieces["position"].append(pos if every else pos[keep])
        del pos
        for key, dset in sources.items():
            if key == "position":
                continue
            rows = read_rows(dset, sel, dxpl)
            if key == "order":
                rank = np.searchsorted(offset, np.concatenate([np.arange(a, b) for a, b in sel] or [[]]),
                                       side="right") - 1
                rows = (rank.astype(np.int64) << 32) + rows
                del rank
            pieces[key].append(rows if every else rows[keep])
            del rows
    # no try/finally: the close is collective (see Output.__call__)
    f.close()
    out = {key: (parts[0] if len(parts) == 1 else np.concatenate(parts)) if parts
           else np.zeros((0,) + shapes[key], dtypes[key]) for key, parts in pieces.items()}
    order = out.pop("order", None)
    if order is not None and not np.all(order[1:] >= order[:-1]):
        perm = _memory_order(order, offset)
        del order
        for key in out:
            out[key] = np.take(out[key], perm, axis=0)
    return out


def _memory_order(keys, offset):
    """The permutation that sorts ``keys`` ((writer rank << 32) + place in its memory; grouped by
    writer rank, ascending): O(n) by scatter for a writer whose rows are all here (a restart on
    the same slabs), a sort for a writer of which only some rows are."""
    ranks = keys >> 32
    cuts = np.flatnonzero(np.diff(ranks)) + 1
    perm = np.empty(len(keys), np.int64)
    for s, e in zip(np.concatenate([[0], cuts]), np.concatenate([cuts, [len(keys)]])):
        place = keys[s:e] & 0xFFFFFFFF
        r = int(ranks[s])
        if e - s == offset[r + 1] - offset[r]:  # a permutation of 0 .. n_r - 1: invert it
            perm[s + place] = np.arange(s, e)
        else:
            perm[s:e] = s + np.argsort(place, kind="stable")
    return perm


def _mpi_max():
    from mpi4py import MPI
    return MPI.MAX
