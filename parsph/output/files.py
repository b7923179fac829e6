"""Finding and reading a run's outputs with serial h5py (no MPI needed): the files, the profiles, a snapshot,
the last restart point."""
import glob
import os
import re

import h5py
import numpy as np

from .layout import PARTICLE_FIELDS, PROFILE_FIELDS, PROFILE_OPTIONAL


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
            row = {key: g[key][()] for key in PROFILE_FIELDS if key in g}
            for key in PROFILE_OPTIONAL:  # a file written before v_x was profiled
                row.setdefault(key, np.full(g["x"].shape, np.nan))
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
