"""The writer and the restart reader on synthetic particle sets, on one rank (no mpirun).

    .venv/bin/python -m pytest -q tests/test_xdmf.py

Frames are built directly (random particles in the box, a Couette reference
profile), so every check compares the files with the arrays that went in:
the particle datasets, the y-bin layout a restart reads, read_particles on
slabs that differ from the writer's, and the XDMF sidecar (structure checked
against the HDF5 files by xdmf_check.check_sidecar). ParaView itself:
test_paraview.py (skipped without pvpython).
"""
import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np
import pytest
from mpi4py import MPI

from parsph.setup import config
from parsph import output
from parsph.output.restart import rows_in
from parsph.physics.analytic import couette_velocity

from xdmf_check import check_sidecar

PAPER = str(Path(__file__).resolve().parent.parent / "run" / "couette_paper.toml")
SEDIMENTATION = str(Path(__file__).resolve().parent.parent / "run" / "sedimentation.toml")
FIELDS = ("id", "kind", "mass", "position", "velocity", "theta")


def make_cfg(dim):
    extra = ["scene.dim=3", "domain.Lz=0.0006"] if dim == 3 else []
    return config.load(PAPER, ["domain.Ly=0.004", *extra])


def make_frame(cfg, n, t, seed, y_lo=0.0, y_hi=None):
    """n random particles with y in [y_lo, y_hi) and the Couette profile at t (exact from Eq. (8))."""
    rng = np.random.default_rng(seed)
    y_hi = cfg.Ly if y_hi is None else y_hi
    dim = cfg.dim
    pos = rng.uniform(0.0, 1.0, (n, dim)) * ([cfg.L, 1.0, cfg.Lz][:dim])
    pos[:, 1] = y_lo + (y_hi - y_lo) * rng.uniform(0.0, 1.0, n)
    fields = {"id": rng.permutation(10 * n + 1)[:n].astype(np.int64), "kind": rng.integers(0, 3, n),
              "mass": rng.uniform(1e-5, 2e-5, n), "position": pos, "velocity": rng.normal(size=(n, dim)),
              "theta": rng.uniform(0.3, 0.4, n)}
    x = (np.arange(cfg.Nx) + 0.5) * cfg.L / cfg.Nx
    exact = couette_velocity(x, t, cfg.nu, cfg.L, cfg.V_w)
    vy = exact + 0.01 * np.sin(x / cfg.L * 7)
    e = np.abs(vy - exact) / cfg.V_w
    profile = {"x": x, "vy": vy, "theta": np.full(cfg.Nx, 0.35), "count": np.full(cfg.Nx, 3.0), "vy_exact": exact,
               "theta_exact": np.full(cfg.Nx, np.nan), "err": (e.max(), math.sqrt(np.mean(e * e)))}
    return output.Frame(t, int(round(t / cfg.dt)), cfg.dt, profile, fields)


def by_id(d):
    order = np.argsort(d["id"], kind="stable")
    return {k: np.asarray(d[k])[order] for k in d if k in FIELDS}


@pytest.mark.parametrize("dim", [2, 3])
def test_sidecar_and_files_from_frames(tmp_path, dim):
    """Two outputs from frames: the files hold the frames' particles, and the sidecar (with a run
    name that XML must escape) describes them as ParaView's default reader needs."""
    cfg = make_cfg(dim)
    stem = "a&b <c> 'd\""
    frames = [make_frame(cfg, 500, t, seed) for seed, t in enumerate((0.001, 0.002))]
    out = output.Output(MPI.COMM_SELF, str(tmp_path), stem, cfg, 500)
    names = [Path(out(fr, snapshot=True)).name for fr in frames]
    assert names == [f"{stem}_0000.h5", f"{stem}_0001.h5"]
    for name, fr in zip(names, frames):
        got = output.read_snapshot(str(tmp_path / name))
        want = by_id(fr.fields)
        for k in FIELDS:
            assert np.array_equal(got[k], np.asarray(want[k]).astype(output.FILE_DTYPES[k])), k
    grids = check_sidecar(tmp_path / f"{stem}.xdmf", names, 500, dim)
    prof = json.loads(grids[1].find("Information").get("Value"))
    assert prof["exact"] == frames[1].profile["vy_exact"].tolist()
    assert prof["err_max"] == frames[1].profile["err"][0]
    # the text is escaped, not spliced: the raw file holds &amp; and &lt;, never a bare '<c>'
    raw = (tmp_path / f"{stem}.xdmf").read_text()
    assert "a&amp;b &lt;c&gt;" in raw and "<c>" not in raw


@pytest.mark.parametrize("dim", [2, 3])
def test_a_layer_opens_upright(tmp_path, dim):
    """A layer's sidecar (its files carry H0) puts the height along ParaView's Y: its geometry is the files'
    display copy of the positions, (y, x[, z]) (xdmf_check), the glyphs' vector (v_y, v_x, v_z); the position
    keeps the files' frame."""
    extra = ["scene.dim=3", "domain.Lz=0.0024", 'body_force.g=[-9.81, 0.0, 0.0]'] if dim == 3 else []
    cfg = config.load(SEDIMENTATION, extra)
    frames = [make_frame(cfg, 400, t, seed) for seed, t in enumerate((0.1, 0.2))]
    out = output.Output(MPI.COMM_SELF, str(tmp_path), "sed", cfg, 400)
    names = [Path(out(fr, snapshot=True)).name for fr in frames]
    grids = check_sidecar(tmp_path / "sed.xdmf", names, 400, dim)
    assert all(g.find("Geometry/DataItem").text.endswith(":/particles/position_view") for g in grids)
    prof = json.loads(grids[0].find("Information").get("Value"))
    assert prof["axis"] == 1  # the file's x is ParaView's Y: a script bins the points' Y
    with h5py.File(tmp_path / names[1]) as f:
        assert np.array_equal(f["particles/position"][()][np.argsort(f["particles/id"][()])],
                              by_id(frames[1].fields)["position"])  # the file's own frame
        v = f["particles/velocity_xyz"][()]
        vel = f["particles/velocity"][()]
    assert np.array_equal(v[:, 0], vel[:, 1].astype(np.float32)) and np.array_equal(v[:, 1],
                                                                                   vel[:, 0].astype(np.float32))


def test_profile_only_outputs_and_restart_continue_the_sidecar(tmp_path):
    """Outputs without particles are not grids; an Output continuing at index 2 keeps the grids
    of the files before it (read back from them) and appends its own. The restart finds no
    connectivity file (as beside the outputs of a parsph that wrote none) and writes it."""
    cfg = make_cfg(2)
    out = output.Output(MPI.COMM_SELF, str(tmp_path), "run", cfg, 300)
    out(make_frame(cfg, 300, 0.001, 1), snapshot=True)
    out(make_frame(cfg, 300, 0.002, 2), snapshot=False)
    check_sidecar(tmp_path / "run.xdmf", ["run_0000.h5"], 300, 2)
    before = ET.parse(tmp_path / "run.xdmf").getroot()
    (tmp_path / "run.cells.h5").unlink()
    again = output.Output(MPI.COMM_SELF, str(tmp_path), "run", cfg, 300, first_index=2)
    again(make_frame(cfg, 300, 0.003, 3), snapshot=True)
    grids = check_sidecar(tmp_path / "run.xdmf", ["run_0000.h5", "run_0002.h5"], 300, 2)
    old = [g for g in before.iter("Grid") if g.get("GridType") == "Uniform"][0]
    old.tail = grids[0].tail = None  # indentation differs with the position in the file
    assert ET.tostring(grids[0]) == ET.tostring(old)  # the earlier step reads back identically


def test_layout_orders_each_ranks_rows_by_y_bin(tmp_path):
    """/layout: offset, y_range and bin_start describe the rows; every row of bin k has y in bin k."""
    cfg = make_cfg(2)
    n = 5000
    path = output.Output(MPI.COMM_SELF, str(tmp_path), "run", cfg, n)(make_frame(cfg, n, 0.001, 7), snapshot=True)
    with h5py.File(path, "r") as f:
        y = f["particles/position"][:, 1]
        offset, y_range, starts = (f[f"layout/{k}"][()] for k in ("offset", "y_range", "bin_start"))
    assert offset.tolist() == [0, n]
    assert y_range.tolist() == [[y.min(), y.max()]]
    nbins = starts.shape[1] - 1
    assert nbins == math.ceil(n / output.BIN_ROWS)
    assert starts[0, 0] == 0 and starts[0, -1] == n and np.all(np.diff(starts[0]) >= 0)
    # bins are equal slices of [y_min, y_max]: recompute each row's bin from y independently
    width = (y.max() - y.min()) / nbins
    for k in range(nbins):
        rows = y[starts[0, k]:starts[0, k + 1]]
        assert np.all((rows >= y.min() + k * width * (1 - 1e-12)) & (rows <= y.min() + (k + 1) * width * (1 + 1e-12)))


@pytest.mark.parametrize("with_layout", [True, False])
def test_read_particles_returns_exactly_the_slab(tmp_path, with_layout):
    """read_particles(lo, hi) on cuts that differ from the writer's equals a brute-force mask of the
    input, also for a slab with no particles; a file without /layout (older files) reads alike."""
    cfg = make_cfg(3)
    n = 4000
    fr = make_frame(cfg, n, 0.001, 11)
    path = output.Output(MPI.COMM_SELF, str(tmp_path), "run", cfg, n)(fr, snapshot=True)
    if not with_layout:
        with h5py.File(path, "a") as f:
            del f["layout"]
    y = fr.fields["position"][:, 1]
    cuts = np.concatenate([[0.0], np.sort(np.random.default_rng(3).uniform(0, cfg.Ly, 6)), [cfg.Ly]])
    cuts = np.concatenate([cuts, [cfg.Ly, cfg.Ly + 1e-3]])  # an empty slab beyond the particles
    seen = []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        got = output.read_particles(path, MPI.COMM_SELF, lo, hi)
        mask = (y >= lo) & (y < hi)
        want = by_id({k: fr.fields[k][mask] for k in output.RESTART_FIELDS})
        got = by_id(got)
        for k in output.RESTART_FIELDS:
            assert got[k].shape[1:] == want[k].shape[1:], k
            assert np.array_equal(got[k], np.asarray(want[k]).astype(output.FILE_DTYPES[k])), (lo, hi, k)
        seen.append(got["id"])
    assert np.array_equal(np.sort(np.concatenate(seen)), np.sort(fr.fields["id"]))


def test_the_writers_own_slab_comes_back_in_its_memory_order(tmp_path):
    """Rows are y-bin sorted in the file; /layout/memory_index restores the writer's order, so a
    restart on the same slabs holds its particles exactly as the run that wrote them did."""
    cfg = make_cfg(2)
    n = 3000
    fr = make_frame(cfg, n, 0.001, 9)
    path = output.Output(MPI.COMM_SELF, str(tmp_path), "run", cfg, n)(fr, snapshot=True)
    with h5py.File(path, "r") as f:
        assert not np.array_equal(f["particles/id"][()], fr.fields["id"])  # the file order is another
    got = output.read_particles(path, MPI.COMM_SELF, 0.0, cfg.Ly)
    for k in output.RESTART_FIELDS:
        assert np.array_equal(got[k], np.asarray(fr.fields[k]).astype(output.FILE_DTYPES[k])), k
    # a sub-slab: the same order, filtered
    mask = (fr.fields["position"][:, 1] >= 0.001) & (fr.fields["position"][:, 1] < 0.003)
    got = output.read_particles(path, MPI.COMM_SELF, 0.001, 0.003)
    assert np.array_equal(got["id"], fr.fields["id"][mask])


def test_a_narrow_slab_reads_only_nearby_rows(tmp_path):
    """The layout bounds what a slab reads: its own particles plus at most its two end bins."""
    cfg = make_cfg(2)
    n = 20000
    fr = make_frame(cfg, n, 0.001, 5)
    path = output.Output(MPI.COMM_SELF, str(tmp_path), "run", cfg, n)(fr, snapshot=True)
    y = fr.fields["position"][:, 1]
    with h5py.File(path, "r") as f:
        widest = int(np.diff(f["layout/bin_start"][0]).max())
        for lo, hi in ((0.001, 0.0011), (0.0, 0.0001), (0.0039, 0.004), (0.002, 0.002)):
            rows = sum(b - a for a, b in rows_in(f, MPI.COMM_SELF, lo, hi, False)[0])
            inside = int(((y >= lo) & (y < hi)).sum())
            assert inside <= rows <= inside + 2 * widest, (lo, hi, rows, inside)


def test_read_state_reads_attributes_only(tmp_path):
    cfg = make_cfg(2)
    path = output.Output(MPI.COMM_SELF, str(tmp_path), "run", cfg, 100)(make_frame(cfg, 100, 0.002, 1),
                                                                        snapshot=True)
    state = output.read_state(path)
    assert set(state) == {"attrs", "path"} and state["path"] == path
    assert state["attrs"]["step"] == 200 and state["attrs"]["time"] == 0.002 and state["attrs"]["index"] == 0
    with h5py.File(path, "a") as f:
        del f["particles/velocity"]
    with pytest.raises(ValueError, match="velocity"):
        output.read_state(path)
