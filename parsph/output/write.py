"""Writing one output: the profile and the particles of every rank into one HDF5 file (collective).

Every rank writes its particles as one hyperslab at the offset given by a
scan of the particle counts; within its rows a rank's particles are ordered
by y-bin, so that a restart reads only the bins of its slab
(:mod:`.restart`). Without MPI in h5py rank 0 gathers and writes.
"""
import os
import sys
from dataclasses import dataclass

import h5py
import numpy as np

from .. import __version__
from .files import output_files
from .hdf5 import SERIAL_ENV, collective_dxpl, durable_rename, parallel_hdf5_available, write_rows, y_bins
from .layout import (BIN_ROWS, FILE_DTYPES, MASS_UNITS, MAX_BINS, PARTICLE_FIELDS, PROFILE_FIELDS, PROFILE_OPTIONAL,
                     PROFILE_UNITS, UNITS)
from .xdmf import UPRIGHT, VECTORS, entry_from_file, snapshot_entry, write_xdmf


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
    grid: dict = None  # the solved gas's grid: {name: array} (rank-independent) and "attrs"; None without it


def _scales(cfg):
    """The scene's own scales among a file's root attributes: what the scene says of itself where it says
    (``cfg.scene.file_attributes``: a layer on the floor's H0 [m], U, U_mf [m/s] and dp_bed [Pa]), else a
    channel's or a box's V_w [m/s] and nu [m^2/s]. The scene is the run's value: this layer imports none."""
    own = getattr(cfg.scene, "file_attributes", None)
    if own is not None:
        return own(cfg)
    return {"V_w": cfg.V_w, "nu": cfg.nu}


def _view_vector(a, upright, dtype):
    """A vector field (..., dim) as ParaView draws it: 3 components (zero-padded) in its frame, the file's
    (x, y, z) or, ``upright`` (a layer), (y, x, z)."""
    out = np.zeros(a.shape[:-1] + (3,), dtype)
    for k, c in enumerate(UPRIGHT if upright else (0, 1, 2)):
        if c < a.shape[-1]:
            out[..., k] = a[..., c]
    return out


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
        self.scales = _scales(cfg)
        self.upright = "H0" in self.scales  # a layer: ParaView draws it with its height along Y (xdmf.UPRIGHT)
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
                            self.written.append(entry_from_file(f, os.path.basename(fn)))
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
        scale = cfg.error_scale(frame.t)  # what the profile's errors are relative to
        if f is not None:
            f.attrs.update({
                "parsph_version": __version__, "run_file": cfg.text,
                "scene": cfg.values["scene"]["name"], "dim": cfg.dim, "n_particles": self.N,
                "ranks": comm.size, "time": frame.t, "step": frame.step, "index": self.index,
                "dt": frame.dt, "L": cfg.L, "Ly": cfg.Ly, "side_walls": bool(cfg.sides), **self.scales,
                "kinds": "0 fluid, 1 fixed wall, 2 moving wall", "units": "SI: m, s, kg, m/s",
                "snapshot": bool(snapshot), "error_field": field, "error_scale": scale,
            })
            g = f.create_group("profile")
            g.attrs["err_max"] = emax
            g.attrs["err_rms"] = erms
            for key in PROFILE_FIELDS:
                if key in PROFILE_OPTIONAL and key not in prof:
                    continue
                unit = PROFILE_UNITS[key]
                arr = np.asarray(prof[key], dtype=np.float64)
                d = g.create_dataset(key, arr.shape, dtype="f8")
                d.attrs["units"] = unit
                write_rows(d, 0, arr if self.root else arr[:0], self.dxpl)
        if frame.grid is not None:
            self._grid(frame.grid, f)
        if snapshot:
            self._particles(frame.fields, f)
        # No try/finally: closing is collective, and a rank that failed mid-write
        # must reach MPI_Abort instead of waiting in the close for the others.
        if f is not None:
            f.close()
        comm.Barrier()
        if self.root:
            durable_rename(part, final)
        grid = None
        if frame.grid is not None and "theta" in frame.grid:
            grid = (*frame.grid["theta"].shape, *frame.grid["attrs"]["cell"])
        self.written.append(snapshot_entry(name, frame.t, bool(snapshot), self.N, cfg.dim, field, scale, cfg.L,
                                           prof[field + "_exact"], emax, erms, grid, upright=self.upright))
        if self.root:
            write_xdmf(os.path.join(self.dir, self.stem + ".xdmf"), self.written)
        self.index += 1
        comm.Barrier()
        return final

    def _grid(self, grid, f):
        """/grid: the gas's fields on its cells, the same on every rank (rank 0's rows written); names with a
        "/" go into subgroups (grid/start: what the next solve starts from, for a restart)."""
        if f is None:
            return
        top = f.create_group("grid")
        for key, val in grid.get("attrs", {}).items():
            top.attrs[key] = val
        arrays = {key: arr for key, arr in grid.items() if key != "attrs"}
        for key in VECTORS:  # display copies for ParaView
            if key in arrays:
                arrays[key + "_xyz"] = _view_vector(arrays[key], self.upright, np.float64)
        for key, arr in arrays.items():
            arr = np.ascontiguousarray(arr, np.float64)
            d = f.create_dataset("grid/" + key, arr.shape, dtype="f8")
            write_rows(d, 0, arr if self.root else arr[:0], self.dxpl)

    def _particles(self, fields, f):
        """The particles, bin-sorted in y within each rank's rows, and the layout a restart reads."""
        comm = self.comm
        n = len(fields["position"])
        counts = np.zeros(comm.size, np.int64)
        comm.Allgather(np.array([n], np.int64), counts)
        offset = np.concatenate([[0], np.cumsum(counts)])
        if offset[-1] != self.N:
            raise RuntimeError(f"{offset[-1]} particles to write, {self.N} expected")
        off = int(offset[comm.rank])
        y = fields["position"][:, 1]
        mine = np.array([y.min(), y.max()] if n else [np.nan, np.nan])
        y_range = np.zeros((comm.size, 2))
        comm.Allgather(mine, y_range)
        nbins = int(min(MAX_BINS, max(1, -(-int(counts.max()) // BIN_ROWS))))
        key = y_bins(y, mine[0], mine[1], nbins)
        bin_start = off + np.concatenate([[0], np.cumsum(np.bincount(key, minlength=nbins))]).astype(np.int64)
        # a stable radix sort; no permutation at all where the rows are in bin order already
        order = None if np.all(key[1:] >= key[:-1]) else np.argsort(key, kind="stable")
        del key
        arrays = self._rows(fields, order, counts)
        tables = (("offset", offset, None), ("y_range", y_range, None), ("bin_start", bin_start, comm.rank))
        if self.parallel:
            self._write_collective(f, arrays, tables, off, nbins)
        else:
            self._write_gathered(f, arrays, tables, counts)

    def _rows(self, fields, order, counts):
        """(group, name, rows of this rank) of every per-particle dataset, in the rank's y-bin order."""
        n = len(fields["position"])

        def ordered(a):
            return a if order is None else np.take(a, order, axis=0)

        for key in PARTICLE_FIELDS:
            yield "particles", key, ordered(fields[key]).astype(FILE_DTYPES[key], copy=False)
        if self.upright:  # the display copy of the positions in ParaView's frame (its Xdmf3 reader has no X_Y)
            pos = ordered(fields["position"])
            yield "particles", "position_view", pos[:, list(UPRIGHT[:pos.shape[1]])].astype(np.float64)
        if self.cfg.dim == 2 or self.upright:  # the display copy ParaView's glyphs need
            yield "particles", "velocity_xyz", _view_vector(ordered(fields["velocity"]), self.upright, np.float32)
        if "position_raw" in fields:  # the solver's exact state: what a restart continues from
            yield "restart", "position", ordered(fields["position_raw"]).astype(np.float64, copy=False)
            yield "restart", "ref", ordered(fields["ref"]).astype(np.float64, copy=False)
        # each row's place in the writer's memory: a restart on the same slabs restores that order
        itype = np.int32 if counts.max() < 2 ** 31 else np.int64
        yield "layout", "memory_index", (np.arange(n) if order is None else order).astype(itype)

    def _units(self):
        return dict(UNITS, mass=MASS_UNITS[self.cfg.dim], velocity_xyz="m/s", position_view="m", ref="m")

    def _write_collective(self, f, arrays, tables, off, nbins):
        """Every rank writes its rows of each dataset, and its row of the bin table (mpio driver)."""
        units, size = self._units(), self.comm.size
        groups = {name: f.create_group(name) for name in ("particles", "layout", "restart")}
        for grp, key, arr in arrays:
            d = groups[grp].create_dataset(key, (self.N,) + arr.shape[1:], dtype=arr.dtype)
            if key in units:
                d.attrs["units"] = units[key]
            write_rows(d, off, arr, self.dxpl)
        lay = groups["layout"]
        for key, arr, row in tables:
            shape = (size, nbins + 1) if row is not None else arr.shape
            d = lay.create_dataset(key, shape, dtype=arr.dtype)
            if row is not None:  # every rank its own row
                write_rows(d, row, arr[None, :], self.dxpl)
            else:  # rank 0 the whole table
                write_rows(d, 0, arr if self.root else arr[:0], self.dxpl)

    def _write_gathered(self, f, arrays, tables, counts):
        """Rank 0 gathers each dataset and writes it (serial HDF5)."""
        comm, units = self.comm, self._units()
        groups = {name: f.create_group(name) for name in ("particles", "layout", "restart")} if self.root else None
        for grp, key, arr in arrays:
            arr = np.ascontiguousarray(arr)
            width = int(np.prod(arr.shape[1:], dtype=np.int64))
            recv = None
            if self.root:
                full = np.empty((self.N,) + arr.shape[1:], dtype=arr.dtype)
                recv = [full, counts * width]
            comm.Gatherv(arr, recv, root=0)
            if self.root:
                d = groups[grp].create_dataset(key, data=full)
                if key in units:
                    d.attrs["units"] = units[key]
                del full
        rows = comm.gather(tables[-1][1], root=0)  # every rank's bin_start
        if self.root:
            lay = groups["layout"]
            for key, arr, row in tables:
                lay.create_dataset(key, data=np.array(rows) if row is not None else arr)
