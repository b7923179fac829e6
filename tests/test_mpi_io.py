"""The HDF5 output of a multi-rank run equals that of a one-rank run (read with serial h5py).

Serial pytest launching ``mpirun`` itself (skipped inside an mpirun job):

    .venv/bin/python -m pytest -q tests/test_mpi_io.py

Runs: 2 ranks (parallel HDF5), 3 ranks (parallel HDF5), 1 rank without mpirun,
and 2 ranks with PARSPH_SERIAL_HDF5=1 (the gather-to-rank-0 fallback).
Each run writes one file per output time, ``<stem>_NNNN.h5`` (written as
``.part`` and renamed when complete), and the XDMF sidecar ``<stem>.xdmf``.
The particle data are written with collective I/O (test_mpi_collective_io.py
checks the transfer mode itself) and ordered by y-bin within each rank's rows.
"""
from pathlib import Path

import h5py
import numpy as np
import pytest

from parsph import output

from mpi_helpers import launch  # noqa: E402
from xdmf_check import check_sidecar  # noqa: E402

pytestmark = pytest.mark.skipif(launch.under_mpirun(), reason="launches mpirun itself (nested mpirun fails)")

LY, NY, NX, LAYERS = 0.004, 20, 50, 3
N = NY * (NX + 2 * LAYERS)
SETS = ["output.t_end=0.002", "output.times=[0.001, 0.002]", f"domain.Ly={LY}"]
STEM = "couette_paper"
FILES = [f"{STEM}_0000.h5", f"{STEM}_0001.h5"]  # one per output time
TIMES, STEPS = [0.001, 0.002], [100, 200]
WARNING = "rank 0 gathers and writes the output"
FIELDS = ("id", "kind", "mass", "position", "velocity", "theta")
ROOT_ATTRS = ("parsph_version", "run_file", "scene", "dim", "n_particles", "ranks", "time", "step", "index",
              "dt", "L", "Ly", "V_w", "nu", "kinds", "units", "snapshot", "error_field", "error_scale")
PROFILE = ("x", "vy", "theta", "count", "vy_exact", "theta_exact", "vx", "vx_exact")

RUNS = {  # name: (ranks, extra environment); ranks 0 = no mpirun
    "serial": (0, {}),
    "mpi2": (2, {}),
    "mpi3": (3, {}),
    "mpi2_serial_hdf5": (2, {"PARSPH_SERIAL_HDF5": "1"}),
}


def run_parsph(ranks, out_dir, env=None, extra=(), timeout=120):
    args = ["run", launch.PAPER, "--out", out_dir, "--quiet", *extra]
    for s in SETS:
        args += ["--set", s]
    cmd = launch.parsph_cmd(*args)
    if ranks:
        cmd = launch.mpirun_cmd(ranks, *cmd)
    return launch.run(cmd, timeout=timeout, **(env or {}))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    launch.warm_cache()
    base = tmp_path_factory.mktemp("mpi_io")
    out = {}
    for name, (ranks, env) in RUNS.items():
        d = base / name
        r = run_parsph(ranks, d, env)
        assert r.returncode == 0, r
        out[name] = (d, r)
    return out


def h5(runs, name, k):
    return runs[name][0] / FILES[k]


def read_all(path):
    """{dataset path: array} and {object path: attrs} of a whole file."""
    data, attrs = {}, {}
    with h5py.File(path, "r") as f:
        attrs["/"] = dict(f.attrs)

        def visit(name, obj):
            attrs[name] = dict(obj.attrs)
            if isinstance(obj, h5py.Dataset):
                data[name] = obj[()]
        f.visititems(visit)
    return data, attrs


def sorted_particles(data):
    order = np.argsort(data["particles/id"], kind="stable")
    return {k: data[f"particles/{k}"][order] for k in FIELDS}


@pytest.mark.parametrize("name", list(RUNS))
def test_directory_layout(runs, name):
    """Exactly the two outputs, the sidecar and its connectivity, all complete: no .part left behind."""
    d = runs[name][0]
    assert sorted(p.name for p in d.iterdir()) == sorted(FILES + [f"{STEM}.xdmf", f"{STEM}.cells.h5"])
    assert [Path(f).name for f in output.output_files(str(d))] == FILES
    assert Path(output.last_snapshot(str(d))).name == FILES[-1]


@pytest.mark.parametrize("name", list(RUNS))
def test_root_attributes(runs, name):
    for k in range(len(FILES)):
        _, a1 = read_all(h5(runs, "serial", k))
        _, a = read_all(h5(runs, name, k))
        a1, a = a1["/"], a["/"]
        assert set(a) >= set(ROOT_ATTRS), set(ROOT_ATTRS) - set(a)
        assert a["run_file"] == a1["run_file"]
        assert a["parsph_version"] == a1["parsph_version"]
        for key in ("scene", "dim", "n_particles", "time", "step", "index", "dt", "L", "Ly", "V_w", "nu",
                    "kinds", "units", "snapshot", "error_field", "error_scale"):
            assert a[key] == a1[key], key
        assert a["error_field"] == "vy" and a["error_scale"] == 1.0  # Couette: v_y errors / V_w
        assert a1["ranks"] == 1 and a["ranks"] == max(1, RUNS[name][0])
        assert a["n_particles"] == N
        assert a["index"] == k and a["step"] == STEPS[k] and bool(a["snapshot"])
        assert a["time"] == pytest.approx(TIMES[k], rel=1e-12)
        assert "Ly = 0.004" in a["run_file"] and "t_end = 0.002" in a["run_file"]


@pytest.mark.parametrize("name", [n for n in RUNS if n != "serial"])
def test_profile_matches_one_rank(runs, name):
    for k in range(len(FILES)):
        d1, at1 = read_all(h5(runs, "serial", k))
        d, at = read_all(h5(runs, name, k))
        names = sorted(key for key in d1 if key.startswith("profile/"))
        assert names == sorted(key for key in d if key.startswith("profile/"))
        assert names == sorted(f"profile/{key}" for key in PROFILE)
        for key in ("profile/x", "profile/count", "profile/vy_exact", "profile/theta_exact", "profile/vx_exact"):
            assert np.array_equal(d[key], d1[key], equal_nan=True), key
        for key in PROFILE:
            assert d1[f"profile/{key}"].shape == (NX,), key
        assert np.all(d1["profile/count"] == NY)
        assert np.all(np.isnan(d1["profile/theta_exact"]))  # Couette has no theta reference
        assert np.all(np.isfinite(d1["profile/vy_exact"]))
        for key in ("profile/vy", "profile/theta", "profile/vx"):
            assert np.all(np.isfinite(d[key])), key
            # bin sums are all-reduced over ranks, so the order of the additions differs
            np.testing.assert_allclose(d[key], d1[key], rtol=1e-14, atol=1e-15, err_msg=key)
        for key in ("err_max", "err_rms"):
            assert np.isfinite(at["profile"][key])
            np.testing.assert_allclose(at["profile"][key], at1["profile"][key], rtol=1e-14, atol=1e-15,
                                       err_msg=key)
        for key in names:
            assert at[key].get("units") == at1[key].get("units") and "units" in at1[key], key


@pytest.mark.parametrize("name", list(RUNS))
def test_read_profile(runs, name):
    """read_profile over the directory stacks the files in time order, with the files' numbers."""
    d = runs[name][0]
    p = output.read_profile(str(d))
    np.testing.assert_allclose(p["time"], TIMES, rtol=1e-12)
    assert p["step"].tolist() == STEPS
    for key in PROFILE[1:]:
        assert p[key].shape == (len(FILES), NX), key
    for k in range(len(FILES)):
        data, attrs = read_all(d / FILES[k])
        one = output.read_profile(str(d / FILES[k]))
        for key in PROFILE[1:]:
            assert np.array_equal(p[key][k], data[f"profile/{key}"], equal_nan=True), key
            assert np.array_equal(one[key][0], data[f"profile/{key}"], equal_nan=True), key
        assert p["err_max"][k] == attrs["profile"]["err_max"]
        assert p["err_rms"][k] == attrs["profile"]["err_rms"]
    assert np.array_equal(p["x"], read_all(d / FILES[0])[0]["profile/x"])


@pytest.mark.parametrize("name", [n for n in RUNS if n != "serial"])
def test_particles_match_one_rank_bit_for_bit(runs, name):
    for k in range(len(FILES)):
        d1, _ = read_all(h5(runs, "serial", k))
        d, _ = read_all(h5(runs, name, k))
        a, b = sorted_particles(d), sorted_particles(d1)
        for key in FIELDS:
            assert a[key].dtype == b[key].dtype and a[key].shape == b[key].shape, key
            assert np.array_equal(a[key], b[key]), f"{name} output {k}: {key} differs from the 1-rank run"
        # read_snapshot sorts by id and gives the same arrays
        snap = output.read_snapshot(str(h5(runs, name, k)))
        for key in FIELDS:
            assert np.array_equal(snap[key], b[key]), key


@pytest.mark.parametrize("name", list(RUNS))
def test_particle_contents(runs, name):
    for k in range(len(FILES)):
        data, at = read_all(h5(runs, name, k))
        snap = sorted_particles(data)
        assert snap["id"].dtype == np.int64 and snap["kind"].dtype == np.int8
        assert snap["mass"].dtype == np.float64 and snap["mass"].shape == (N,)
        assert snap["position"].shape == (N, 2) and snap["velocity"].shape == (N, 2)
        assert snap["theta"].shape == (N,)
        assert np.array_equal(snap["id"], np.arange(N))            # every particle once, no gaps
        kinds, counts = np.unique(snap["kind"], return_counts=True)
        assert kinds.tolist() == [0, 1, 2]
        assert counts.tolist() == [NY * NX, NY * LAYERS, NY * LAYERS]
        # m = rho_s theta0 dx dy, dx = L / Nx = 2e-4 m, dy = Ly / Ny = 2e-4 m
        np.testing.assert_allclose(snap["mass"], 2000.0 * 0.35 * 2e-4 * 2e-4, rtol=1e-12)
        assert np.all(np.isfinite(snap["position"])) and np.all(np.isfinite(snap["velocity"]))
        y = snap["position"][:, 1]
        assert np.all((y >= 0) & (y < LY))
        fluid = snap["kind"] == 0
        assert np.all((snap["position"][fluid, 0] > 0) & (snap["position"][fluid, 0] < 0.01))
        assert np.all(snap["velocity"][snap["kind"] == 2, 1] == 1.0)
        assert np.all(snap["velocity"][snap["kind"] == 1] == 0.0)
        assert np.all((snap["theta"][fluid] > 0.2) & (snap["theta"][fluid] < 0.5))
        # walls hold the summed density of the initial lattice: theta0 (1 - 5.5e-4), all alike
        walls = ~fluid
        assert np.ptp(snap["theta"][walls]) == 0.0
        assert snap["theta"][walls][0] / 0.35 - 1 == pytest.approx(-5.515e-4, rel=1e-3)
        for key, unit in (("position", "m"), ("velocity", "m/s"), ("mass", "kg/m"), ("theta", "1")):
            assert at[f"particles/{key}"]["units"] == unit, key


@pytest.mark.parametrize("name", list(RUNS))
def test_xdmf_sidecar(runs, name):
    """The sidecar names one grid per output file, in time order, and every HDF item it names
    exists in that file with the shape and number type it states (xdmf_check.check_sidecar)."""
    d = runs[name][0]
    assert not (d / f"{STEM}.xdmf.part").exists()
    check_sidecar(d / f"{STEM}.xdmf", FILES, N, 2)


@pytest.mark.parametrize("name", list(RUNS))
def test_layout_describes_the_writer_ranks(runs, name):
    """/layout: rank r's rows are offset[r] .. offset[r+1]-1, their y lie in y_range[r], their y at the
    last build of the neighbour list (/restart/ref, when particles last migrated) in [r Ly / P,
    (r+1) Ly / P) (the slab it owned), and bin_start splits them into y-bins."""
    P = max(1, RUNS[name][0])
    for k in range(len(FILES)):
        with h5py.File(h5(runs, name, k), "r") as f:
            y = f["particles/position"][:, 1]
            y_ref = f["restart/ref"][:, 1]
            offset, y_range, starts = (f[f"layout/{key}"][()] for key in ("offset", "y_range", "bin_start"))
        assert offset[0] == 0 and offset[-1] == N and len(offset) == P + 1 and starts.shape[0] == P
        for r in range(P):
            rows = y[offset[r]:offset[r + 1]]
            assert rows.size and y_range[r].tolist() == [rows.min(), rows.max()]
            owned = y_ref[offset[r]:offset[r + 1]]
            assert np.all((owned >= r * LY / P * (1 - 1e-12)) & (owned < (r + 1) * LY / P * (1 + 1e-12)))
            assert starts[r, 0] == offset[r] and starts[r, -1] == offset[r + 1]
            assert np.all(np.diff(starts[r]) >= 0)


def test_serial_hdf5_fallback_warns_once(runs):
    _, r = runs["mpi2_serial_hdf5"]
    assert launch.count_lines(r.output, WARNING) == 1, r
    line = next(ln for ln in r.output.splitlines() if WARNING in ln)
    assert line.startswith("parsph: warning:")
    # the reason given is the true one: forced by the environment here, or h5py built without MPI
    assert ("PARSPH_SERIAL_HDF5=1 forces serial HDF5" if h5py.get_config().mpi else "h5py has no MPI support") in line


@pytest.mark.skipif(not h5py.get_config().mpi, reason="h5py without MPI: the fallback warning is expected")
@pytest.mark.parametrize("name", ["serial", "mpi2", "mpi3"])
def test_no_warning_with_parallel_hdf5(runs, name):
    _, r = runs[name]
    assert WARNING not in r.output, r
    assert "warning" not in r.output.lower(), r


def test_serial_hdf5_files_equal_parallel_files(runs):
    """Gathered and hyperslab-written files agree dataset for dataset, attribute for attribute.

    Both put the ranks' particles in rank order, so even the unsorted arrays agree."""
    for k in range(len(FILES)):
        dp, atp = read_all(h5(runs, "mpi2", k))
        ds, ats = read_all(h5(runs, "mpi2_serial_hdf5", k))
        assert sorted(dp) == sorted(ds)
        for key in dp:
            assert dp[key].dtype == ds[key].dtype, key
            assert np.array_equal(dp[key], ds[key], equal_nan=dp[key].dtype.kind == "f"), key
        a, b = sorted_particles(dp), sorted_particles(ds)
        for key in a:
            assert np.array_equal(a[key], b[key]), (k, key)
        assert sorted(atp) == sorted(ats)
        for key in atp:
            assert atp[key] == ats[key], key


@pytest.mark.parametrize("name", ["mpi2", "serial"])
def test_check_exit_codes(runs, name):
    d = runs[name][0]
    ok = launch.run(launch.parsph_cmd("check", d, "--tol", "10"), timeout=60)
    assert ok.returncode == 0, ok
    assert "within" in ok.stdout
    bad = launch.run(launch.parsph_cmd("check", d, "--tol", "1e-9"), timeout=60)
    assert bad.returncode == 1, bad
    assert launch.count_lines(bad.stderr, "above tolerance") == 1, bad
    # one output file works too
    assert launch.run(launch.parsph_cmd("check", h5(runs, name, 1), "--tol", "10"), timeout=60).returncode == 0


def test_rerun_without_force_refused_then_force_overwrites(runs, tmp_path):
    """Existing outputs under mpirun -n 2: exit 2 without --force (the files untouched), 0 with it."""
    d = runs["mpi2"][0]
    before = {f: (d / f).read_bytes() for f in FILES + [f"{STEM}.xdmf", f"{STEM}.cells.h5"]}
    r = run_parsph(2, d)
    assert r.returncode == 2, r
    assert launch.count_lines(r.stderr, "parsph: error") == 1, r
    assert "--force" in r.stderr and FILES[0] in r.stderr, r
    assert {f: (d / f).read_bytes() for f in before} == before
    # with --force the run replaces them with the same physics (same particles, bit for bit)
    copy = tmp_path / "forced"
    copy.mkdir()
    for f, data in before.items():
        (copy / f).write_bytes(data)
    r = run_parsph(2, copy, extra=("--force",))
    assert r.returncode == 0, r
    assert sorted(p.name for p in copy.iterdir()) == sorted(before)
    for k, f in enumerate(FILES):
        new = output.read_snapshot(str(copy / f))
        old = output.read_snapshot(str(d / f))
        for key in FIELDS:
            assert np.array_equal(new[key], old[key]), (f, key)
