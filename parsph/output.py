"""HDF5 output: one file per output time, written collectively through h5py's mpio driver.

Directory layout (README.md, "Output files", has the table with units)::

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

Each rank writes its particles as one hyperslab at the offset given by an
exclusive scan of the particle counts. When h5py lacks MPI, rank 0 gathers
and writes instead (one warning line saying whether h5py lacks MPI or
``PARSPH_SERIAL_HDF5`` forced it).
"""
import glob
import os
import re
import sys

import h5py
import numpy as np

from . import __version__

SERIAL_ENV = "PARSPH_SERIAL_HDF5"  # set to 1 to force the gather-to-rank-0 path
PARTICLE_FIELDS = ("id", "kind", "mass", "position", "velocity", "theta")
PROFILE_FIELDS = ("x", "vy", "theta", "count", "vy_exact", "theta_exact")
# a particle's mass per unit of the dimensions the lattice leaves out (2-D: per metre of z)
MASS_UNITS = {1: "kg/m^2", 2: "kg/m", 3: "kg"}


def parallel_hdf5_available():
    return bool(h5py.get_config().mpi) and os.environ.get(SERIAL_ENV, "") in ("", "0")


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
        self.root = comm.rank == 0
        self.index = first_index
        if not self.parallel and comm.size > 1 and self.root:
            why = (f"{SERIAL_ENV}={os.environ[SERIAL_ENV]} forces serial HDF5" if h5py.get_config().mpi
                   else "h5py has no MPI support")
            print(f"parsph: warning: {why}; rank 0 gathers and writes the output", file=sys.stderr, flush=True)
        # (file name, time, has particles) of complete outputs, for the XDMF sidecar;
        # a restart continues the series of the outputs before it
        self.written = []
        if self.root and first_index > 0:
            for fn in output_files(out_dir):
                if fn.endswith(".h5") and os.path.basename(fn).startswith(stem + "_"):
                    with h5py.File(fn, "r") as f:
                        if int(f.attrs["index"]) < first_index:
                            self.written.append((os.path.basename(fn), float(f.attrs["time"]), "particles" in f))
            self.written.sort(key=lambda w: w[1])

    def __call__(self, sim, snapshot=None):
        """Write the next output from ``sim`` (t, step, dt, profile, fields): the profile, and the particles
        if snapshots are on."""
        cfg, comm = self.cfg, self.comm
        snapshot = cfg.values["output"]["snapshots"] if snapshot is None else snapshot
        prof = sim.profile
        emax, erms = prof["err"]
        name = output_name(self.stem, self.index)
        final = os.path.join(self.dir, name)
        part = final + ".part"
        if self.parallel:
            f = h5py.File(part, "w", driver="mpio", comm=comm)
        else:
            f = h5py.File(part, "w") if self.root else None
        if f is not None:
            f.attrs.update({
                "parsph_version": __version__, "run_file": cfg.text,
                "scene": cfg.values["scene"]["name"], "dim": cfg.dim, "n_particles": self.N,
                "ranks": comm.size, "time": sim.t, "step": sim.step, "index": self.index,
                "dt": sim.dt, "L": cfg.L, "Ly": cfg.Ly, "V_w": cfg.V_w, "nu": cfg.nu,
                "kinds": "0 fluid, 1 fixed wall, 2 moving wall", "units": "SI: m, s, kg, m/s",
                "snapshot": bool(snapshot), "error_field": cfg.scene.error_field,
                "error_scale": cfg.velocity_scale if cfg.scene.error_field == "vy" else cfg.theta0,
            })
            g = f.create_group("profile")
            g.attrs["err_max"] = emax
            g.attrs["err_rms"] = erms
            for key, unit in (("x", "m"), ("vy", "m/s"), ("theta", "1"), ("count", "1"),
                              ("vy_exact", "m/s"), ("theta_exact", "1")):
                arr = prof[key]
                d = g.create_dataset(key, arr.shape, dtype="f8")
                d.attrs["units"] = unit
                if self.root:
                    d[...] = arr
        if snapshot:
            self._particles(sim, f)
        # No try/finally: closing is collective, and a rank that failed mid-write
        # must reach MPI_Abort instead of waiting in the close for the others.
        if f is not None:
            f.close()
        comm.Barrier()
        if self.root:
            _durable_rename(part, final)
        self.written.append((name, sim.t, bool(snapshot)))
        if self.root:
            self._write_xdmf()
        self.index += 1
        comm.Barrier()
        return final

    def _particles(self, sim, f):
        comm, N = self.comm, self.N
        src = sim.fields
        n = len(src["id"])
        fields = {
            "id": (src["id"], "i8", "1"),
            "kind": (np.asarray(src["kind"]).astype(np.int8), "i1", "1"),
            "mass": (src["mass"], "f8", MASS_UNITS[self.cfg.dim]),
            "position": (src["position"], "f8", "m"),
            "velocity": (src["velocity"], "f8", "m/s"),
            "theta": (src["theta"], "f8", "1"),
        }
        if self.parallel:
            off = np.zeros(1, np.int64)
            comm.Exscan(np.array([n], np.int64), off)
            off = int(off[0]) if comm.rank > 0 else 0
            grp = f.create_group("particles")
            for key, (arr, dt, unit) in fields.items():
                d = grp.create_dataset(key, (N,) + arr.shape[1:], dtype=dt)
                d.attrs["units"] = unit
                if n:
                    d[off:off + n] = arr
        else:
            counts = np.zeros(comm.size, np.int64)
            comm.Allgather(np.array([n], np.int64), counts)
            grp = f.create_group("particles") if self.root else None
            for key, (arr, dt, unit) in fields.items():
                arr = np.ascontiguousarray(arr)
                width = int(np.prod(arr.shape[1:], dtype=np.int64))
                recv = None
                if self.root:
                    full = np.empty((N,) + arr.shape[1:], dtype=arr.dtype)
                    recv = [full, counts * width]
                comm.Gatherv(arr, recv, root=0)
                if self.root:
                    grp.create_dataset(key, data=full).attrs["units"] = unit

    def _write_xdmf(self):
        """Rewrite the ParaView sidecar: one point set per snapshot, in time order."""
        N, dim = self.N, self.cfg.dim
        geom = "XY" if dim == 2 else "XYZ"

        def item(fname, path, dims, ntype="Float", prec=8):
            return (f'<DataItem Dimensions="{dims}" NumberType="{ntype}" Precision="{prec}" '
                    f'Format="HDF">{fname}:/particles/{path}</DataItem>')

        grids = []
        for fname, t, snap in self.written:
            if not snap:
                continue
            attrs = [f'<Attribute Name="id" Center="Node">{item(fname, "id", N, "Int")}</Attribute>',
                     f'<Attribute Name="kind" Center="Node">{item(fname, "kind", N, "Char", 1)}</Attribute>',
                     f'<Attribute Name="theta" Center="Node">{item(fname, "theta", N)}</Attribute>']
            for c, comp in enumerate("xyz"[:dim]):
                attrs.append(
                    f'<Attribute Name="v{comp}" Center="Node"><DataItem ItemType="HyperSlab" Dimensions="{N} 1">'
                    f'<DataItem Dimensions="3 2" Format="XML">0 {c} 1 1 {N} 1</DataItem>'
                    f'{item(fname, "velocity", f"{N} {dim}")}</DataItem></Attribute>')
            grids.append(
                f'<Grid Name="{fname}" GridType="Uniform"><Time Value="{t!r}"/>'
                f'<Topology TopologyType="Polyvertex" NumberOfElements="{N}"/>'
                f'<Geometry GeometryType="{geom}">{item(fname, "position", f"{N} {dim}")}</Geometry>'
                + "".join(attrs) + "</Grid>")
        text = ('<?xml version="1.0" ?>\n<Xdmf Version="3.0"><Domain>'
                '<Grid Name="particles" GridType="Collection" CollectionType="Temporal">\n'
                + "\n".join(grids) + "\n</Grid></Domain></Xdmf>\n")
        xdmf = os.path.join(self.dir, self.stem + ".xdmf")
        with open(xdmf + ".part", "w") as fh:
            fh.write(text)
        os.replace(xdmf + ".part", xdmf)


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


def read_state(path):
    """Everything a restart needs from one output file: particles (file order) and attributes."""
    with h5py.File(path, "r") as f:
        if "particles" not in f:
            raise ValueError(f"{path} holds no particles (output.snapshots was false)")
        g = f["particles"]
        out = {key: g[key][()] for key in PARTICLE_FIELDS}
        out["attrs"] = dict(f.attrs)
    return out
