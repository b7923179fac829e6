"""`parsph check` and `parsph plot` on the layer scenes (sedimentation, fluidized_bed), through the CLI: the
verdict on the heights of the layer's mass fractions against its transient (and the interior theta against the
end state once it is reached), the pointwise table beside it for information; the plots of theta(x) and v_x(x)
over the reference and of the heights in time; the profile's v_x in the output files.

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
    printed = {}
    for name, d in out.items():
        rc, printed[name], err = run_cli("run", ROOT / "run" / f"{name}.toml", "--out", d, "--quiet", *SMALL,
                                         *sets[name], timeout=300)
        assert rc == 0, err
    out["printed"] = printed
    return out


@pytest.mark.parametrize("name", ["sedimentation", "fluidized_bed"])
def test_run_ends_with_the_layer_check(runs, cli, name):
    """`parsph run` ends with what `parsph check` prints: the pointwise table for information, the layer's
    table of heights and interior theta."""
    _, checked, _ = cli("check", runs[name])
    printed = runs["printed"][name]
    assert "for information, not the verdict" in printed and "layer check:" in printed
    assert table(printed) == table(checked) and table(printed)


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


def table(out):
    """The layer table's rows: (t, [(SPH, SPH - reference) per fraction, % of H0], max |diff| %, interior)."""
    rows = []
    for line in out.splitlines():
        m = re.match(r"\s+([\d.e+-]+)\s+((?:[\d.]+ \([+-][\d.]+\)\s+){5})\s*([\d.]+)%(?: > tol)?\s+(.*)$", line)
        if m:
            pairs = [(float(a), float(b)) for a, b in re.findall(r"([\d.]+) \(([+-][\d.]+)\)", m.group(2))]
            rows.append((float(m.group(1)), pairs, float(m.group(3)), m.group(4)))
    return rows


def particle_heights(path, t):
    """The heights below which 5, 25, 50, 75, 95% of the fluid's mass lies at output time t, written out here:
    the particles sorted by x, each one's mass cumulated to its middle, linear between them."""
    import h5py
    from parsph.output import output_files
    for fn in output_files(str(path)):
        with h5py.File(fn, "r") as f:
            if "particles" in f and abs(float(f.attrs["time"]) - t) < 1e-12:
                fluid = f["particles/kind"][()] == 0
                x, m = f["particles/position"][()][fluid, 0], f["particles/mass"][()][fluid]
    order = np.argsort(x)
    x, m = x[order], m[order]
    return np.interp(np.array([0.05, 0.25, 0.5, 0.75, 0.95]) * m.sum(), np.cumsum(m) - 0.5 * m, x)


def test_check_sedimentation_judges_the_heights_against_the_transient(runs, cli):
    """The verdict: the heights of the mass fractions at every output against the sedimentation-consolidation
    transient (independent numbers: the particles' heights written out here, the transient solved here from the
    run's values), in % of H0 = 4 mm; the pointwise table printed for information, unflagged."""
    from parsph.physics import consolidation, gas_references as gr
    rc, out, err = cli("check", runs["sedimentation"])
    assert rc == 0, err
    assert "for information, not the verdict" in out and "> tol" not in out
    assert "against the layer's transient" in out and "tolerance 3% of H0" in out
    rows = table(out)
    assert [r[0] for r in rows] == [0.05, 0.1, 0.2]
    H0 = 0.004
    ph = gr.Phases(2000.0, 1000.0, 1e-3, 3e-4, 9.81, "stokes")
    tr = consolidation.solve(0.2, H0, ph, [0.05, 0.1, 0.2], 0.006, 0.0, 8.76, -2.0, "consistent")
    for t, pairs, worst, inner in rows:
        sph = particle_heights(runs["sedimentation"], t) / H0 * 100
        ref = tr.quantiles(t) / H0 * 100
        for (s, d), s_ref, r_ref in zip(pairs, sph, ref):
            assert s == pytest.approx(s_ref, abs=0.006)
            assert d == pytest.approx(s_ref - r_ref, abs=0.011)
        assert worst == pytest.approx(max(abs(d) for _, d in pairs), abs=0.011)
        assert worst < 3.0
    # before 0.2 s the layer is in transit: its interior is not judged; at 0.2 s the transient has settled
    assert rows[0][3].startswith("in transit") and not rows[2][3].startswith("in transit")
    # a tolerance the heights fail: exit 1, one line saying which measure
    rc, out, err = cli("check", runs["sedimentation"], "--tol", "1e-6")
    assert rc == 1 and "a height of the layer's mass" in err and "above the tolerance" in err


def test_check_bed_heights_and_interior(runs, cli):
    """The bed's heights against its transient (which ends as the steady column, theta* = 0.30)."""
    rc, out, err = cli("check", runs["fluidized_bed"])
    assert rc == 0, err
    assert "theta* = 0.3" in out and "steady column" in out
    rows = table(out)
    assert len(rows) == 2
    for t, pairs, worst, inner in rows:
        assert worst < 3.0
        assert pairs[-1][0] > 100.0          # the bed has expanded past H0 = 2 mm
    # the interior against the end state, judged at an output where the transient has reached it
    rc, out, err = cli("check", runs["fluidized_bed"], "--tol", "1e-6")
    assert rc == 1


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
    """Outputs without particles: check says the heights are not measured and, the layer in transit, that
    nothing is judged; the pointwise table is still printed."""
    d = tmp_path / "sed"
    rc, _, err = cli("run", ROOT / "run" / "sedimentation.toml", "--out", d, "--quiet", *SMALL,
                     "--set", "scene.height=0.004", "--set", "output.t_end=0.02", "--set", "output.times=[0.02]",
                     "--set", "output.snapshots=false", timeout=300)
    assert rc == 0, err
    rc, out, err = cli("check", d, "--tol", "2")
    assert rc == 0, err
    assert "not measured" in out and math.isfinite(numbers(out.splitlines()[3])[1])
    assert "nothing to judge" in out
