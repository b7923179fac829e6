"""HDF5 output: one file per run, written collectively through h5py's mpio driver.

Layout (README.md, "Output file", has the full table with units):

    /                      attrs: parsph_version, run_file (TOML), scene, dim, n_particles, ranks, ...
    /profile/x             (Nx,)          bin centres [m]
    /profile/time          (n_out,)       output times [s]
    /profile/step          (n_out,)       step numbers
    /profile/vy            (n_out, Nx)    simulated v_y per bin [m/s]
    /profile/count         (n_out, Nx)    fluid particles per bin
    /profile/vy_exact      (n_out, Nx)    reference v_y, scenes with one [m/s]
    /profile/err_max, err_rms (n_out,)    |v - v_exact| / V_w, max and RMS over bins
    /snapshots/NNNN/{id, kind, position, velocity, theta}   (N,), (N,), (N, dim), (N, dim), (N,)

``/profile`` attr ``written`` counts complete outputs. Each rank writes its
particles as one hyperslab at the offset given by an exclusive scan of the
particle counts. When h5py lacks MPI, rank 0 gathers and writes instead. An
XDMF sidecar (``<name>.xdmf``) lets ParaView open the snapshots as points.
"""
import os
import sys

import h5py
import numpy as np
from mpi4py import MPI

from . import __version__
from .particles import KIND_NAMES

SERIAL_ENV = "PARSPH_SERIAL_HDF5"  # set to 1 to force the gather-to-rank-0 path


def parallel_hdf5_available():
    return bool(h5py.get_config().mpi) and os.environ.get(SERIAL_ENV, "") in ("", "0")


class Output:
    """The run's HDF5 file; collective calls on every rank, data from each."""

    def __init__(self, comm, path, cfg, sim):
        self.comm = comm
        self.path = path
        self.cfg = cfg
        self.dim = cfg.dim
        self.N = sim.n_total
        self.parallel = parallel_hdf5_available()
        self.root = comm.rank == 0
        if not self.parallel and comm.size > 1 and self.root:
            print("parsph: warning: h5py has no MPI support; rank 0 gathers and writes the output",
                  file=sys.stderr, flush=True)
        if self.parallel:
            self.f = h5py.File(path, "w", driver="mpio", comm=comm)
        else:
            self.f = h5py.File(path, "w") if self.root else None
        self.writes = self.parallel or self.root
        nout = len(cfg.output_times)
        nb = sim.nbins
        if self.writes:
            f = self.f
            f.attrs.update({
                "parsph_version": __version__, "run_file": cfg.text,
                "scene": cfg.values["scene"]["name"], "dim": cfg.dim, "n_particles": self.N,
                "ranks": comm.size, "dt": cfg.dt, "L": cfg.L, "Ly": cfg.Ly, "V_w": cfg.V_w,
                "nu": cfg.nu, "kinds": "0 fluid, 1 fixed wall, 2 moving wall",
                "units": "SI: m, s, kg, m/s",
            })
            g = f.create_group("profile")
            g.attrs["written"] = 0
            for name, shape, dt, unit in (("x", (nb,), "f8", "m"), ("time", (nout,), "f8", "s"),
                                          ("step", (nout,), "i8", "1"), ("vy", (nout, nb), "f8", "m/s"),
                                          ("count", (nout, nb), "f8", "1"),
                                          ("vy_exact", (nout, nb), "f8", "m/s"),
                                          ("err_max", (nout,), "f8", "1"), ("err_rms", (nout,), "f8", "1")):
                d = g.create_dataset(name, shape, dtype=dt, fillvalue=np.nan if dt == "f8" else 0)
                d.attrs["units"] = unit
            f.create_group("snapshots")
        self._snaps = []

    # -- writing ----------------------------------------------------------------
    def __call__(self, sim, k):
        """Write output number k: the profile, and a particle snapshot if enabled."""
        x, vy, counts, exact, (emax, erms) = sim.profile()
        if self.cfg.values["output"]["snapshots"]:
            self._snapshot(sim, k)
        if self.writes:
            g = self.f["profile"]
            if self.root:
                g["x"][:] = x
                g["time"][k] = sim.t
                g["step"][k] = sim.step
                g["vy"][k] = vy
                g["count"][k] = counts
                if exact is not None:
                    g["vy_exact"][k] = exact
                g["err_max"][k] = emax
                g["err_rms"][k] = erms
            g.attrs["written"] = k + 1
            self.f.flush()
        if self.root:
            self._write_xdmf()

    def _snapshot(self, sim, k):
        ps, comm, N, dim = sim.ps, self.comm, self.N, self.dim
        n = ps.n_own
        fields = {
            "id": (ps.gid[:n], "i8", "1"),
            "kind": (ps.kind[:n].astype(np.int8), "i1", "1"),
            "position": (ps.pos[:n], "f8", "m"),
            "velocity": (ps.vel[:n], "f8", "m/s"),
            "theta": (ps.theta[:n], "f8", "1"),
        }
        name = f"snapshots/{k:04d}"
        if self.parallel:
            off = np.zeros(1, np.int64)
            comm.Exscan(np.array([n], np.int64), off)
            off = int(off[0]) if comm.rank > 0 else 0
            grp = self.f.create_group(name)
            for key, (arr, dt, unit) in fields.items():
                d = grp.create_dataset(key, (N,) + arr.shape[1:], dtype=dt)
                d.attrs["units"] = unit
                if n:
                    d[off:off + n] = arr
        else:
            counts = np.zeros(comm.size, np.int64)
            comm.Allgather(np.array([n], np.int64), counts)
            grp = self.f.create_group(name) if self.root else None
            for key, (arr, dt, unit) in fields.items():
                arr = np.ascontiguousarray(arr)
                width = int(np.prod(arr.shape[1:], dtype=np.int64))
                recv = None
                if self.root:
                    full = np.empty((N,) + arr.shape[1:], dtype=arr.dtype)
                    recv = [full, counts * width]
                comm.Gatherv(arr, recv, root=0)
                if self.root:
                    d = grp.create_dataset(key, data=full)
                    d.attrs["units"] = unit
        if self.writes:
            grp.attrs["time"] = sim.t
            grp.attrs["step"] = sim.step
        self._snaps.append((name, sim.t))

    def _write_xdmf(self):
        """Rewrite the ParaView sidecar: one point set per snapshot, in time order."""
        h5name = os.path.basename(self.path)
        N, dim = self.N, self.dim
        geom = "XY" if dim == 2 else "XYZ"

        def item(path, dims, ntype="Float", prec=8):
            return (f'<DataItem Dimensions="{dims}" NumberType="{ntype}" Precision="{prec}" '
                    f'Format="HDF">{h5name}:/{path}</DataItem>')

        def column(path, c):
            return (f'<DataItem ItemType="HyperSlab" Dimensions="{N} 1">'
                    f'<DataItem Dimensions="3 2" Format="XML">0 {c} 1 1 {N} 1</DataItem>'
                    f'{item(path, f"{N} {dim}")}</DataItem>')

        grids = []
        for name, t in self._snaps:
            attrs = [f'<Attribute Name="id" Center="Node">{item(name + "/id", N, "Int")}</Attribute>',
                     f'<Attribute Name="kind" Center="Node">{item(name + "/kind", N, "Char", 1)}</Attribute>',
                     f'<Attribute Name="theta" Center="Node">{item(name + "/theta", N)}</Attribute>']
            for c, comp in enumerate("xyz"[:dim]):
                attrs.append(f'<Attribute Name="v{comp}" Center="Node">{column(name + "/velocity", c)}</Attribute>')
            grids.append(
                f'<Grid Name="{name}" GridType="Uniform"><Time Value="{t!r}"/>'
                f'<Topology TopologyType="Polyvertex" NumberOfElements="{N}"/>'
                f'<Geometry GeometryType="{geom}">{item(name + "/position", f"{N} {dim}")}</Geometry>'
                + "".join(attrs) + "</Grid>")
        text = ('<?xml version="1.0" ?>\n<Xdmf Version="3.0"><Domain>'
                '<Grid Name="particles" GridType="Collection" CollectionType="Temporal">\n'
                + "\n".join(grids) + "\n</Grid></Domain></Xdmf>\n")
        xdmf = os.path.splitext(self.path)[0] + ".xdmf"
        tmp = xdmf + ".tmp"
        with open(tmp, "w") as fh:
            fh.write(text)
        os.replace(tmp, xdmf)

    def close(self):
        if self.f is not None:
            self.f.close()
            self.f = None


def read_profile(path):
    """The /profile group of an output file as a dict of arrays (complete outputs only)."""
    with h5py.File(path, "r") as f:
        g = f["profile"]
        n = int(g.attrs["written"])
        out = {k: g[k][()] if k == "x" else g[k][:n] for k in g}
        out["attrs"] = dict(f.attrs)
    return out


def read_snapshot(path, k=-1):
    """Particles of snapshot k (default: the last), sorted by id."""
    with h5py.File(path, "r") as f:
        names = sorted(f["snapshots"])
        g = f["snapshots"][names[k]]
        order = np.argsort(g["id"][()])
        out = {key: g[key][()][order] for key in g}
        out["time"] = g.attrs["time"]
    return out
