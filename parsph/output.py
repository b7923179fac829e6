"""HDF5 output: one file per output time, written collectively through h5py's mpio driver.

Directory layout (docs/output.md has the table with units)::

    DIR/<name>_NNNN.h5     output k = NNNN: profile and particle snapshot at one time
    DIR/<name>.xdmf        ParaView sidecar: the snapshots as a time series of points

Each file is written as ``<name>_NNNN.h5.part`` and renamed when complete and
closed (rank 0 fsyncs the file before the rename and the directory after it),
so a run killed at any moment (even SIGKILL, or a crash of the machine) leaves
every earlier output whole and readable, and every output file with particles
is a restart point. In a file:

    /                      attrs: parsph_version, run_file (TOML), scene, dim, n_particles, ranks,
                                  time, step, index, dt, L, Ly, V_w, nu, integrator state
    /profile/x             (Nx,)          bin centres [m]
    /profile/vy, theta     (Nx,)          mean v_y [m/s] and theta of the fluid particles per bin
    /profile/count         (Nx,)          fluid particles per bin
    /profile/vy_exact, theta_exact (Nx,)  the scene's reference (NaN where it has none)
    /profile attrs         err_max, err_rms: |f - f_exact| / scale of the scene's error field
                           (root attrs error_field, error_scale), max and RMS over bins
    /particles/{id, kind, mass, position, velocity, theta}   (N,), (N,), (N,), (N, dim), (N, dim), (N,)
                           mass in kg/m in 2-D (per metre of z), kg in 3-D (MASS_UNITS)
    /particles/velocity_xyz (N, 3) f4      2-D only: (v_x, v_y, 0) for ParaView's glyphs
    /layout/offset         (P+1,)         rows offset[r] .. offset[r+1]-1 hold writer rank r's particles
    /layout/y_range        (P, 2)         min and max y of those particles (NaN: none)
    /layout/bin_start      (P, B+1)       first row of each of B equal y-bins of [y_min, y_max] per rank
    /layout/memory_index   (N,) i4        each row's place in the writer rank's memory (restored on restart)
    /restart/position      (N, dim)       the solver's positions as it holds them: wrapped into the box
                                          only at its last neighbour-list build, so they may lie up to
                                          that build's drift outside it [m]
    /restart/ref           (N, dim)       the positions at that build (in the box) [m]: a restart builds
                                          the same list from them and continues bit for bit

Writing: every rank writes its particles as one hyperslab at the offset given
by a scan of the particle counts, in one collective H5Dwrite per dataset; a
rank with no particles takes part with an empty selection. Within its rows a
rank's particles are ordered by y-bin (a stable sort, O(n)), so that a restart
on P' ranks reads only the rows of the bins that overlap its own slab
(``read_particles``): O(N/P') memory and I/O per rank, whatever P and P'.
When h5py lacks MPI, rank 0 gathers and writes instead (one warning line
saying whether h5py lacks MPI or ``PARSPH_SERIAL_HDF5`` forced it), and each
rank of a restart reads its rows with serial h5py.
"""
import glob
import json
import os
import re
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import h5py
import numpy as np
from h5py import h5fd, h5p, h5s

from . import __version__

SERIAL_ENV = "PARSPH_SERIAL_HDF5"  # set to 1 to force the gather-to-rank-0 path
PARTICLE_FIELDS = ("id", "kind", "mass", "position", "velocity", "theta")
RESTART_FIELDS = ("id", "kind", "mass", "position", "velocity")
FILE_DTYPES = {"id": np.int64, "kind": np.int8, "mass": np.float64, "position": np.float64,
               "velocity": np.float64, "theta": np.float64}
PROFILE_FIELDS = ("x", "vy", "theta", "count", "vy_exact", "theta_exact")
# a particle's mass per unit of the dimensions the lattice leaves out (2-D: per metre of z)
MASS_UNITS = {1: "kg/m^2", 2: "kg/m", 3: "kg"}
UNITS = {"id": "1", "kind": "1", "position": "m", "velocity": "m/s", "theta": "1"}
BIN_ROWS = 256       # rows per y-bin of the restart layout, on the fullest rank
MAX_BINS = 65535     # bin keys fit uint16, where numpy's stable sort is a radix sort
READ_ROWS = (1 << 16, 1 << 22)  # rows per read round of a restart: ceil(N / P) clipped to this


@dataclass
class Frame:
    """What the writer needs at one output time: ``fields`` are this rank's owned particles
    (id, kind, mass, position wrapped into the box, velocity, theta); ``profile`` is the
    reduced profile (Simulation.profile's dict, with ``err`` = (max, rms))."""
    t: float
    step: int
    dt: float
    profile: dict
    fields: dict


def parallel_hdf5_available():
    return bool(h5py.get_config().mpi) and os.environ.get(SERIAL_ENV, "") in ("", "0")


def collective_dxpl():
    """A transfer property list for collective MPI-IO (every rank calls H5Dread/H5Dwrite)."""
    dxpl = h5p.create(h5p.DATASET_XFER)
    dxpl.set_dxpl_mpio(h5fd.MPIO_COLLECTIVE)
    return dxpl


def write_rows(dset, start, arr, dxpl=None):
    """Write ``arr`` into rows ``start ..`` of ``dset`` in one H5Dwrite.

    With a collective ``dxpl`` every rank must call this once per dataset; a rank
    without rows selects nothing instead of skipping the call. ``arr`` must have the
    dataset's dtype (a conversion would make HDF5 fall back to independent I/O).
    """
    fspace = dset.id.get_space()
    if len(arr):
        arr = np.ascontiguousarray(arr)
        fspace.select_hyperslab((start,) + (0,) * (arr.ndim - 1), arr.shape)
        mspace = h5s.create_simple(arr.shape)
    else:
        fspace.select_none()
        arr = np.zeros((1,) + dset.shape[1:], dset.dtype)
        mspace = h5s.create_simple(arr.shape)
        mspace.select_none()
    dset.id.write(mspace, fspace, arr, dxpl=dxpl)


def read_rows(dset, ranges, dxpl=None):
    """Rows ``a .. b-1`` for each (a, b) in ``ranges`` (ascending, disjoint), in one H5Dread;
    collective like ``write_rows`` (an empty ``ranges`` selects nothing)."""
    rows = sum(b - a for a, b in ranges)
    rest = dset.shape[1:]
    fspace = dset.id.get_space()
    fspace.select_none()
    for a, b in ranges:
        if b > a:
            fspace.select_hyperslab((a,) + (0,) * len(rest), (b - a,) + rest, op=h5s.SELECT_OR)
    out = np.empty((rows,) + rest, dset.dtype)
    buf = out if rows else np.zeros((1,) + rest, dset.dtype)
    mspace = h5s.create_simple(buf.shape)
    if not rows:
        mspace.select_none()
    dset.id.read(mspace, fspace, buf, dxpl=dxpl)
    return out


def y_bins(y, y_min, y_max, nbins):
    """Bin of each y among ``nbins`` equal bins of [y_min, y_max] (clipped to the ends).

    Monotone in y, and the writer and the reader evaluate it alike, so the bins
    of the ends of a y-range bracket the bins of every y inside it.
    """
    y = np.asarray(y, dtype=np.float64)
    span = y_max - y_min
    if not span > 0:
        return np.zeros(y.shape, np.uint16)
    k = y - y_min
    k *= nbins / span
    np.floor(k, out=k)
    np.clip(k, 0, nbins - 1, out=k)
    return k.astype(np.uint16)


def _durable_rename(part, final):
    """Rename a closed ``part`` file to ``final`` so that a crash of the machine cannot leave
    ``final`` naming a file whose data never reached the disk: fsync the data, rename, then
    fsync the directory that holds the new name."""
    fd = os.open(part, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
    os.replace(part, final)
    try:
        fd = os.open(os.path.dirname(os.path.abspath(final)), os.O_RDONLY)
    except OSError:  # a file system whose directories cannot be opened: the rename stands
        return
    try:
        os.fsync(fd)
    except OSError:  # some file systems refuse fsync on a directory
        pass
    finally:
        os.close(fd)


def output_name(stem, k):
    return f"{stem}_{k:04d}.h5"


class Output:
    """Writes output k of a run into DIR/<stem>_k.h5; collective on every rank."""

    def __init__(self, comm, out_dir, stem, cfg, n_total, first_index=0):
        self.comm = comm
        self.dir = out_dir
        self.stem = stem
        self.cfg = cfg
        self.N = n_total
        self.parallel = parallel_hdf5_available()
        self.dxpl = collective_dxpl() if self.parallel else None
        self.root = comm.rank == 0
        self.index = first_index
        if not self.parallel and comm.size > 1 and self.root:
            why = (f"{SERIAL_ENV}={os.environ[SERIAL_ENV]} forces serial HDF5" if h5py.get_config().mpi
                   else "h5py has no MPI support")
            print(f"parsph: warning: {why}; rank 0 gathers and writes the output", file=sys.stderr, flush=True)
        # sidecar entries of complete outputs (snapshot_entry); a restart continues
        # the series of the outputs before it
        self.written = []
        if self.root and first_index > 0:
            for fn in output_files(out_dir):
                if fn.endswith(".h5") and os.path.basename(fn).startswith(stem + "_"):
                    with h5py.File(fn, "r") as f:
                        if int(f.attrs["index"]) < first_index:
                            self.written.append(_entry_from_file(f, os.path.basename(fn)))
            self.written.sort(key=lambda w: w["time"])

    def __call__(self, frame, snapshot=None):
        """Write the next output: the profile, and the particles if snapshots are on.

        ``frame`` is a Frame (or anything with the same attributes); an object with a
        ``frame()`` method (a Simulation) is asked for it.
        """
        if callable(getattr(frame, "frame", None)):
            frame = frame.frame()
        cfg, comm = self.cfg, self.comm
        snapshot = cfg.values["output"]["snapshots"] if snapshot is None else snapshot
        prof = frame.profile
        emax, erms = prof["err"]
        name = output_name(self.stem, self.index)
        final = os.path.join(self.dir, name)
        part = final + ".part"
        if self.parallel:
            f = h5py.File(part, "w", driver="mpio", comm=comm)
        else:
            f = h5py.File(part, "w") if self.root else None
        field = cfg.scene.error_field
        scale = cfg.velocity_scale if field == "vy" else cfg.theta0
        if f is not None:
            f.attrs.update({
                "parsph_version": __version__, "run_file": cfg.text,
                "scene": cfg.values["scene"]["name"], "dim": cfg.dim, "n_particles": self.N,
                "ranks": comm.size, "time": frame.t, "step": frame.step, "index": self.index,
                "dt": frame.dt, "L": cfg.L, "Ly": cfg.Ly, "V_w": cfg.V_w, "nu": cfg.nu,
                "kinds": "0 fluid, 1 fixed wall, 2 moving wall", "units": "SI: m, s, kg, m/s",
                "snapshot": bool(snapshot), "error_field": field, "error_scale": scale,
            })
            g = f.create_group("profile")
            g.attrs["err_max"] = emax
            g.attrs["err_rms"] = erms
            for key, unit in (("x", "m"), ("vy", "m/s"), ("theta", "1"), ("count", "1"),
                              ("vy_exact", "m/s"), ("theta_exact", "1")):
                arr = np.asarray(prof[key], dtype=np.float64)
                d = g.create_dataset(key, arr.shape, dtype="f8")
                d.attrs["units"] = unit
                write_rows(d, 0, arr if self.root else arr[:0], self.dxpl)
        if snapshot:
            self._particles(frame.fields, f)
        # No try/finally: closing is collective, and a rank that failed mid-write
        # must reach MPI_Abort instead of waiting in the close for the others.
        if f is not None:
            f.close()
        comm.Barrier()
        if self.root:
            _durable_rename(part, final)
        self.written.append(snapshot_entry(name, frame.t, bool(snapshot), self.N, cfg.dim, field, scale, cfg.L,
                                           prof[field + "_exact"], emax, erms))
        if self.root:
            write_xdmf(os.path.join(self.dir, self.stem + ".xdmf"), self.written)
        self.index += 1
        comm.Barrier()
        return final

    def _particles(self, fields, f):
        """The particles, bin-sorted in y within each rank's rows, and the layout a restart reads."""
        comm, dim = self.comm, self.cfg.dim
        pos = fields["position"]
        n = len(pos)
        counts = np.zeros(comm.size, np.int64)
        comm.Allgather(np.array([n], np.int64), counts)
        offset = np.concatenate([[0], np.cumsum(counts)])
        if offset[-1] != self.N:
            raise RuntimeError(f"{offset[-1]} particles to write, {self.N} expected")
        off = int(offset[comm.rank])
        y = pos[:, 1]
        mine = np.array([y.min(), y.max()] if n else [np.nan, np.nan])
        y_range = np.zeros((comm.size, 2))
        comm.Allgather(mine, y_range)
        nbins = int(min(MAX_BINS, max(1, -(-int(counts.max()) // BIN_ROWS))))
        key = y_bins(y, mine[0], mine[1], nbins)
        bin_start = off + np.concatenate([[0], np.cumsum(np.bincount(key, minlength=nbins))]).astype(np.int64)
        # a stable radix sort; no permutation at all where the rows are in bin order already
        order = None if np.all(key[1:] >= key[:-1]) else np.argsort(key, kind="stable")
        del key

        def ordered(a):
            return a if order is None else np.take(a, order, axis=0)

        def arrays():
            """(group, name, rows of this rank) of every per-particle dataset."""
            for key_ in PARTICLE_FIELDS:
                yield "particles", key_, ordered(fields[key_]).astype(FILE_DTYPES[key_], copy=False)
            if dim == 2:
                v = np.zeros((n, 3), np.float32)
                v[:, :2] = ordered(fields["velocity"])
                yield "particles", "velocity_xyz", v
            if "position_raw" in fields:  # the solver's exact state: what a restart continues from
                yield "restart", "position", ordered(fields["position_raw"]).astype(np.float64, copy=False)
                yield "restart", "ref", ordered(fields["ref"]).astype(np.float64, copy=False)
            # each row's place in the writer's memory: a restart on the same slabs restores that order
            itype = np.int32 if counts.max() < 2 ** 31 else np.int64
            yield "layout", "memory_index", (np.arange(n) if order is None else order).astype(itype)

        units = dict(UNITS, mass=MASS_UNITS[dim], velocity_xyz="m/s", ref="m")
        tables = (("offset", offset, None), ("y_range", y_range, None), ("bin_start", bin_start, comm.rank))
        if self.parallel:
            groups = {"particles": f.create_group("particles"), "layout": f.create_group("layout"),
                      "restart": f.create_group("restart")}
            for grp, key_, arr in arrays():
                d = groups[grp].create_dataset(key_, (self.N,) + arr.shape[1:], dtype=arr.dtype)
                if key_ in units:
                    d.attrs["units"] = units[key_]
                write_rows(d, off, arr, self.dxpl)
            lay = groups["layout"]
            for key_, arr, row in tables:
                shape = (comm.size, nbins + 1) if row is not None else arr.shape
                d = lay.create_dataset(key_, shape, dtype=arr.dtype)
                if row is not None:  # every rank its own row
                    write_rows(d, row, arr[None, :], self.dxpl)
                else:  # rank 0 the whole table
                    write_rows(d, 0, arr if self.root else arr[:0], self.dxpl)
        else:
            groups = {"particles": f.create_group("particles"), "layout": f.create_group("layout"),
                      "restart": f.create_group("restart")} if self.root else None
            for grp, key_, arr in arrays():
                arr = np.ascontiguousarray(arr)
                width = int(np.prod(arr.shape[1:], dtype=np.int64))
                recv = None
                if self.root:
                    full = np.empty((self.N,) + arr.shape[1:], dtype=arr.dtype)
                    recv = [full, counts * width]
                comm.Gatherv(arr, recv, root=0)
                if self.root:
                    d = groups[grp].create_dataset(key_, data=full)
                    if key_ in units:
                        d.attrs["units"] = units[key_]
                    del full
            rows = comm.gather(bin_start, root=0)
            if self.root:
                lay = groups["layout"]
                for key_, arr, row in tables:
                    lay.create_dataset(key_, data=np.array(rows) if row is not None else arr)


# ---- the ParaView sidecar ------------------------------------------------------------
def snapshot_entry(name, time, snapshot, n, dim, field, scale, L, exact, err_max, err_rms):
    """What the sidecar says of one output file (a dict; ``profile`` travels as an Information
    element so that scripts can compare ParaView's view of the particles with parsph's profile)."""
    return {"name": name, "time": float(time), "snapshot": bool(snapshot), "n": int(n), "dim": int(dim),
            "profile": {"field": str(field), "scale": float(scale), "L": float(L), "bins": len(exact),
                        "exact": [float(v) for v in exact], "err_max": float(err_max),
                        "err_rms": float(err_rms)}}


def _entry_from_file(f, name):
    a = f.attrs
    field = str(a.get("error_field", "vy"))
    g = f["profile"]
    return snapshot_entry(name, a["time"], "particles" in f, a["n_particles"], a["dim"], field,
                          a.get("error_scale", a["V_w"]), a["L"], g[field + "_exact"][()],
                          g.attrs["err_max"], g.attrs["err_rms"])


NUMBER_TYPES = {"f": "Float", "i": "Int", "u": "UInt"}


def _data_item(parent, fname, path, shape, dtype, column=None):
    """An HDF DataItem for ``fname:path`` of ``shape``; ``column`` c: that column of an
    (N, k) dataset, as Xdmf3's hyperslab syntax ``path|start:stride:count:dims``
    (ParaView's default reader skips ItemType="HyperSlab" items: their type is unknown
    before they are read)."""
    dtype = np.dtype(dtype)
    ntype = NUMBER_TYPES[dtype.kind]
    if dtype.itemsize == 1:
        ntype = {"Int": "Char", "UInt": "UChar"}[ntype]
    text = f"{fname}:{path}"
    dims = shape
    if column is not None:
        n, k = shape
        text += f"|0 {column}:1 1:{n} 1:{n} {k}"
        dims = (n,)
    item = ET.SubElement(parent, "DataItem", Dimensions=" ".join(map(str, dims)), NumberType=ntype,
                         Precision=str(dtype.itemsize), Format="HDF")
    item.text = text
    return item


def xdmf_grid(entry):
    """One time step: N points with id, kind, theta, the velocity vector and its components."""
    fname, n, dim = entry["name"], entry["n"], entry["dim"]
    grid = ET.Element("Grid", Name=fname, GridType="Uniform")
    ET.SubElement(grid, "Time", Value=repr(entry["time"]))
    # Xdmf3 requires the Value attribute (text content aborts ParaView's default reader)
    ET.SubElement(grid, "Information", Name="parsph.profile", Value=json.dumps(entry["profile"]))
    ET.SubElement(grid, "Topology", TopologyType="Polyvertex", NumberOfElements=str(n), NodesPerElement="1")
    geom = ET.SubElement(grid, "Geometry", GeometryType="XY" if dim == 2 else "XYZ")
    _data_item(geom, fname, "/particles/position", (n, dim), FILE_DTYPES["position"])

    def attribute(name, kind="Scalar"):
        return ET.SubElement(grid, "Attribute", Name=name, AttributeType=kind, Center="Node")

    for key in ("id", "kind", "theta"):
        _data_item(attribute(key), fname, f"/particles/{key}", (n,), FILE_DTYPES[key])
    if dim == 3:
        _data_item(attribute("velocity", "Vector"), fname, "/particles/velocity", (n, 3), np.float64)
    else:
        _data_item(attribute("velocity", "Vector"), fname, "/particles/velocity_xyz", (n, 3), np.float32)
    for c in range(dim):
        _data_item(attribute("v" + "xyz"[c]), fname, "/particles/velocity", (n, dim), np.float64, column=c)
    return grid


def write_xdmf(path, entries):
    """Rewrite the ParaView sidecar: one point set per snapshot, in time order (atomic rename)."""
    root = ET.Element("Xdmf", Version="3.0")
    series = ET.SubElement(ET.SubElement(root, "Domain"), "Grid", Name="particles", GridType="Collection",
                           CollectionType="Temporal")
    for entry in sorted(entries, key=lambda e: e["time"]):
        if entry["snapshot"]:
            series.append(xdmf_grid(entry))
    ET.indent(root)
    with open(path + ".part", "wb") as fh:
        ET.ElementTree(root).write(fh, encoding="utf-8", xml_declaration=True)
        fh.write(b"\n")
    os.replace(path + ".part", path)


# ---- restart: each rank reads the particles of its own slab ---------------------------------
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


def _rows_in(f, comm, lo, hi, parallel):
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
    ranges, offset = _rows_in(f, comm, lo, hi, parallel)
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


# ---- reading (serial h5py, no MPI needed) ------------------------------------------
def output_files(path):
    """Complete output files of a run: ``path`` is a directory or one output file."""
    if os.path.isdir(path):
        files = [f for f in glob.glob(os.path.join(path, "*_[0-9][0-9][0-9][0-9]*.h5"))
                 if re.search(r"_\d{4,}\.h5$", f)]
        stems = {re.sub(r"_\d{4,}\.h5$", "", os.path.basename(f)) for f in files}
        if len(stems) > 1:
            raise ValueError(f"{path} holds outputs of several runs ({', '.join(sorted(stems))}); name one file")
        return sorted(files, key=lambda f: int(re.search(r"_(\d{4,})\.h5$", f).group(1)))
    if os.path.isfile(path):
        return [path]
    raise FileNotFoundError(path)


def read_profile(path):
    """Profiles of all complete outputs of a run (sorted by time) as a dict of arrays."""
    files = output_files(path)
    rows = []
    for fn in files:
        with h5py.File(fn, "r") as f:
            g = f["profile"]
            row = {key: g[key][()] for key in PROFILE_FIELDS}
            row.update(time=f.attrs["time"], step=f.attrs["step"], err_max=g.attrs["err_max"],
                       err_rms=g.attrs["err_rms"], attrs=dict(f.attrs))
            rows.append(row)
    rows.sort(key=lambda r: r["time"])
    if not rows:
        raise FileNotFoundError(f"no complete output in {path}")
    out = {k: np.array([r[k] for r in rows]) for k in ("time", "step", "err_max", "err_rms") + PROFILE_FIELDS}
    out["x"] = rows[0]["x"]
    out["attrs"] = rows[-1]["attrs"]
    return out


def read_snapshot(path):
    """Particles of one output file, sorted by id, with the file's attributes."""
    with h5py.File(path, "r") as f:
        g = f["particles"]
        order = np.argsort(g["id"][()], kind="stable")
        out = {key: g[key][()][order] for key in PARTICLE_FIELDS}
        out["attrs"] = dict(f.attrs)
    return out


def last_snapshot(path):
    """The latest complete output file of a run that holds particles (a restart point)."""
    best = None
    for fn in output_files(path):
        with h5py.File(fn, "r") as f:
            if "particles" in f and (best is None or f.attrs["time"] > best[0]):
                best = (f.attrs["time"], fn)
    if best is None:
        raise FileNotFoundError(f"no output with particles in {path}")
    return best[1]
