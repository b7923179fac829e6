"""`parsph check` and `parsph plot` on the layer scenes (sedimentation, fluidized_bed), through the CLI: the
error table and, besides it, the interface against Kynch's line (sedimentation) or the bed's interior theta and
top against the steady column; the plots of theta(x) and v_x(x) over the reference and of the interface (the
bed's top and interior) in time; the profile's v_x in the output files.

Tiny runs (a 30-column box, 12 rows): the sedimentation of a 4 mm layer past Kynch's meeting time (0.12 s),
the bed to 0.3 s, about 15 s together.
"""
import math
import re

import numpy as np
import pytest

from conftest import ROOT

SMALL = ["--set", "domain.L=0.006", "--set", "numerics.Nx=30"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    from conftest import run_cli
    base = tmp_path_factory.mktemp("layers")
    out = {"sedimentation": base / "sed", "fluidized_bed": base / "bed"}
    sets = {"sedimentation": ["--set", "scene.height=0.004", "--set", "output.t_end=0.2",
                              "--set", "output.times=[0.05, 0.1, 0.2]"],
            "fluidized_bed": ["--set", "scene.height=0.002", "--set", "output.t_end=0.3",
                              "--set", "output.times=[0.1, 0.3]"]}
    for name, d in out.items():
        rc, _, err = run_cli("run", ROOT / "run" / f"{name}.toml", "--out", d, "--quiet", *SMALL, *sets[name],
                             timeout=300)
        assert rc == 0, err
    return out


def test_profile_has_v_x(runs):
    """/profile/vx: the fluid's mean v_x per bin (NaN in the empty bins above the top); vx_exact Kynch's v0 in
    the suspension before the meeting, 0 in the sediment, NaN above the top."""
    from parsph.output import read_profile
    from parsph.setup.config import load
    from parsph.setup.scenes import layer
    p = read_profile(str(runs["sedimentation"]))
    cfg = load(ROOT / "run" / "sedimentation.toml", ["domain.L=0.006", "numerics.Nx=30", "scene.height=0.004"])
    k = layer.sedimentation(cfg)
    assert p["vx"].shape == p["vy"].shape == (3, 30)
    first = p["vx"][0]
    filled = p["count"][0] > 0
    assert np.isfinite(first[filled]).all() and np.isnan(first[~filled]).all()
    # at t = 0.05 s the suspension settles at about v0 (< 0) in its middle
    mid = (p["x"] > 0.4 * 4e-3) & (p["x"] < 0.6 * 4e-3)
    assert np.all(first[mid] < 0.0)
    assert abs(np.mean(first[mid]) / k.settling_velocity - 1.0) < 0.3
    ex = p["vx_exact"][0]
    assert set(np.unique(ex[np.isfinite(ex)])) <= {0.0, k.settling_velocity}
    assert np.isnan(ex[p["x"] > 4e-3]).all()


def numbers(line):
    return [float(v) for v in re.findall(r"[-+]?\d+\.?\d*(?:e[-+]?\d+)?", line)]


def test_check_sedimentation_prints_the_interface_against_kynch(runs, cli):
    rc, out, err = cli("check", runs["sedimentation"], "--tol", "2")
    assert rc == 0, err
    assert "errors of theta against the reference" in out
    assert "against Kynch's line" in out and "t_m =" in out
    rows = [ln for ln in out.splitlines() if ln.strip().startswith("t = ")]
    assert len(rows) == 3  # one per output with particles
    for row in rows:
        t, top, ref, diff = numbers(row)[:4]
        assert top > 0 and ref > 0
        assert abs(diff) < 5.0, row  # percent of H0
    # before the meeting (t_m = 0.12 s) the reference falls on Kynch's line: 4 mm - 17.4 mm/s t
    assert numbers(rows[0])[2] == pytest.approx(4.0 - 17.38 * 0.05, abs=0.02)
    # a tolerance the table fails: exit 1, the interface lines still printed
    rc, out, _ = cli("check", runs["sedimentation"], "--tol", "1e-6")
    assert rc == 1 and "against Kynch's line" in out


def test_check_bed_prints_interior_and_top(runs, cli):
    rc, out, err = cli("check", runs["fluidized_bed"], "--tol", "2")
    assert rc == 0, err
    assert "theta* = 0.3" in out and "steady column" in out
    rows = [ln for ln in out.splitlines() if ln.strip().startswith("t = ")]
    assert len(rows) == 2
    last = numbers(rows[-1])
    assert last[1] == pytest.approx(0.30, rel=0.03)  # the interior at t = 0.3 s against theta* = 0.30
    steady = numbers(re.search(r"steady column's ([\d.]+) mm", out).group(0))[0]
    assert last[3] == pytest.approx(steady, abs=0.05 * 2.0)  # the top within 5% of H0 = 2 mm


@pytest.mark.parametrize("name", ["sedimentation", "fluidized_bed"])
def test_plot_layer(runs, cli, name):
    pytest.importorskip("matplotlib")
    rc, out, err = cli("plot", runs[name])
    assert rc == 0, err
    for png in (runs[name] / f"{name}_profile.png", runs[name] / f"{name}_interface.png"):
        assert f"wrote {png}" in out
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the particles coloured by v_x, the floor and the lid marked
    rc, out, err = cli("plot", runs[name], "--particles", "--field", "vx")
    assert rc == 0, err
    assert (runs[name] / f"{name}_vx_0000.png").is_file()


def test_layer_lines_without_snapshots(tmp_path, cli):
    """Outputs without particles: check says the interface is not measured, and still checks the table."""
    d = tmp_path / "sed"
    rc, _, err = cli("run", ROOT / "run" / "sedimentation.toml", "--out", d, "--quiet", *SMALL,
                     "--set", "scene.height=0.004", "--set", "output.t_end=0.02", "--set", "output.times=[0.02]",
                     "--set", "output.snapshots=false", timeout=300)
    assert rc == 0, err
    rc, out, err = cli("check", d, "--tol", "2")
    assert rc == 0, err
    assert "not measured" in out and math.isfinite(numbers(out.splitlines()[2])[1])
