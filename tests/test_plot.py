"""`parsph plot`: the profile PNG is named after the run's stem, whatever the width of the output index;
`parsph plot --particles` draws one PNG per output with particles.

Output files are ``<stem>_NNNN.h5`` with an index of four digits or more, so a
run with 10,000 outputs or more has five-digit names. The outputs here are
written in process from made-up frames (test_xdmf.make_frame: random particles,
the Couette reference profile), and the command runs in process (no MPI).
"""
import os
import shutil

import numpy as np
import pytest
from mpi4py import MPI

from parsph import output
from parsph.cli import main
from parsph.cli.report import profile_png
from parsph.cli.particles_plot import middle_layer

from test_xdmf import make_cfg, make_frame


@pytest.mark.parametrize("name, stem", [
    ("couette_paper_0000.h5", "couette_paper"),
    ("couette_paper_9999.h5", "couette_paper"),
    ("couette_paper_10000.h5", "couette_paper"),    # five digits
    ("couette_paper_123456.h5", "couette_paper"),   # six
    ("run_2_0001.h5", "run_2"),                      # digits and underscores in the stem stay
    ("a_0003_0004.h5", "a_0003"),                    # only the last index is the output's
])
def test_profile_png_name(name, stem):
    assert profile_png(os.path.join("d", "e", name)) == os.path.join("d", "e", f"{stem}_profile.png")


def write_outputs(out, dim=2, times=(0.001, 0.002), snapshots=(True, True), n=400, frames=None):
    cfg = make_cfg(dim)
    w = output.Output(MPI.COMM_SELF, str(out), "couette_paper", cfg, n)
    frames = frames or [make_frame(cfg, n, t, seed) for seed, t in enumerate(times)]
    return cfg, [w(fr, snapshot=s) for fr, s in zip(frames, snapshots)]


def test_plot_of_a_run_with_a_five_digit_index(tmp_path, capsys):
    """A one-output run whose file is renamed to index 10000: the plot is <stem>_profile.png beside it."""
    pytest.importorskip("matplotlib")
    out = tmp_path / "out"
    out.mkdir()
    write_outputs(out, times=(2e-5,), snapshots=(True,))
    shutil.move(out / "couette_paper_0000.h5", out / "couette_paper_10000.h5")
    assert main(["plot", str(out)]) == 0
    png = out / "couette_paper_profile.png"
    assert png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", sorted(os.listdir(out))
    assert f"wrote {png}" in capsys.readouterr().out


def colours(png):
    import matplotlib.image
    img = matplotlib.image.imread(png)[:, :, :3]
    return img.reshape(-1, 3)


def near(pixels, rgb, tol=0.02):
    return int((np.abs(pixels - np.asarray(rgb)[:3]).max(axis=1) < tol).sum())


def test_particles_one_png_per_snapshot_coloured_by_the_field(tmp_path, capsys):
    """Three outputs, the middle one without particles: two PNGs, named by their outputs' index. The
    fluid is half at v_y = 0, half at 1 (and the colour scale spans them): both ends of viridis are
    drawn; wall particles (kind 1 and 2) are tan; --times picks one output; a time without one is
    bad input naming the times there are."""
    pytest.importorskip("matplotlib")
    import matplotlib
    cfg = make_cfg(2)
    n = 400
    frames = [make_frame(cfg, n, t, seed) for seed, t in enumerate((0.001, 0.002, 0.003))]
    for fr in frames:
        f = fr.fields
        f["kind"] = np.where(f["position"][:, 0] < 0.1 * cfg.L, 1, np.where(f["position"][:, 0] > 0.9 * cfg.L, 2, 0))
        f["velocity"][:, 1] = (f["position"][:, 0] > 0.5 * cfg.L).astype(float)
    write_outputs(tmp_path, frames=frames, snapshots=(True, False, True), n=n)
    assert main(["plot", str(tmp_path), "--particles"]) == 0
    pngs = [tmp_path / f"couette_paper_vy_{k:04d}.png" for k in (0, 2)]
    assert capsys.readouterr().out.splitlines() == [f"wrote {p}" for p in pngs]
    assert not (tmp_path / "couette_paper_vy_0001.png").exists()
    viridis = matplotlib.colormaps["viridis"]
    for png in pngs:
        px = colours(png)
        assert near(px, viridis(0.0)) > 200 and near(px, viridis(1.0)) > 200, png
        assert near(px, matplotlib.colors.to_rgb('tan')) > 200, png  # the wall particles
    for p in pngs:
        p.unlink()
    assert main(["plot", str(tmp_path), "--particles", "--field", "theta", "--times", "0.003"]) == 0
    assert sorted(p.name for p in tmp_path.glob("*.png")) == ["couette_paper_theta_0002.png"]
    (tmp_path / "couette_paper_theta_0002.png").unlink()
    assert main(["plot", str(tmp_path), "--field", "vx", "--times", "0.001"]) == 0  # no grid: the particles'
    assert sorted(p.name for p in tmp_path.glob("*.png")) == ["couette_paper_vx_0000.png"]
    capsys.readouterr()
    assert main(["plot", str(tmp_path), "--animate", str(tmp_path / "a.gif")]) == 2  # no grid to animate
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no output holds the gas's grid" in err[0], err
    capsys.readouterr()
    assert main(["plot", str(tmp_path), "--particles", "--times", "0.002"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--times 0.002" in err[0] and "0.001, 0.003" in err[0], err


def test_particles_without_walls_have_no_wall_colour(tmp_path):
    """Only fluid (a periodic box has no walls): nothing is drawn in the walls' colour."""
    pytest.importorskip("matplotlib")
    import matplotlib
    cfg = make_cfg(2)
    fr = make_frame(cfg, 300, 0.001, 4)
    fr.fields["kind"] = np.zeros(300, np.int64)
    write_outputs(tmp_path, frames=[fr], snapshots=(True,), n=300)
    assert main(["plot", str(tmp_path), "--particles"]) == 0
    assert near(colours(tmp_path / "couette_paper_vy_0000.png"), matplotlib.colors.to_rgb('tan')) == 0


def test_3d_slice_is_the_middle_layer():
    """middle_layer picks exactly the particles of the z-level nearest the middle of the z range
    (brute force over a lattice of 5 levels with jitter below 1e-13)."""
    rng = np.random.default_rng(2)
    levels = np.array([0.1, 0.3, 0.5, 0.7, 0.9]) * 1e-3
    z = rng.choice(levels, 1000) + rng.uniform(-1e-16, 1e-16, 1000)
    keep, mid = middle_layer(z)
    assert mid == pytest.approx(0.5e-3) and np.array_equal(keep, np.abs(z - 0.5e-3) < 1e-12)


def layer_snapshot(scene="sedimentation", run_file=None, t=0.0):
    """A made-up 2-D layer on the floor of a box 30 mm tall, 2.4 mm wide: fluid 12 rows across up to 20 mm,
    wall rows below the floor and above the lid."""
    L, Ly, dx = 0.03, 0.0024, 2e-4
    xs = np.concatenate([np.arange(-3, 0) + 0.5, np.arange(100) + 0.5, 150 + np.arange(3) + 0.5]) * dx
    X, Y = np.meshgrid(xs, (np.arange(12) + 0.5) * dx, indexing="ij")
    pos = np.column_stack([X.ravel(), Y.ravel()])
    kind = np.where(pos[:, 0] < 0, 1, np.where(pos[:, 0] > L, 1, 0)).astype(np.int8)
    attrs = {"scene": scene, "dim": 2, "L": L, "Ly": Ly, "time": t, "V_w": 0.0}
    if run_file is not None:
        attrs["run_file"] = run_file
    n = len(kind)
    return {"id": np.arange(n), "kind": kind, "mass": np.full(n, 1e-6), "position": pos,
            "velocity": np.zeros((n, 2)), "theta": np.full(n, 0.2), "attrs": attrs}


@pytest.mark.parametrize("scene", ["sedimentation", "fluidized_bed"])
def test_a_layer_is_drawn_upright(scene):
    """A layer's picture: the height (x, from below the floor to above the lid) on the vertical axis in mm,
    the periodic y across, the floor and lid horizontal lines; a Couette picture keeps x across."""
    pytest.importorskip("matplotlib")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from parsph.cli.particles_plot import figure
    snap = layer_snapshot(scene)
    fig = figure(snap, "theta", (0.0, 0.6), heights=(0.019, 0.0185))
    ax = fig.axes[0]
    assert "height" in ax.get_ylabel() and "mm" in ax.get_ylabel() and "gravity down" in ax.get_ylabel()
    assert "y" in ax.get_xlabel() and "height" not in ax.get_xlabel()
    lo, hi = ax.get_ylim()
    assert lo == pytest.approx(-0.5) and hi == pytest.approx(30.5)   # the wall rows' centres, in mm
    assert ax.get_xlim() == pytest.approx((0.0, 2.4))
    fig.canvas.draw()
    bbox = ax.get_window_extent()
    assert bbox.height > 5 * bbox.width        # a tall, narrow column (to scale: 31 mm by 2.4 mm)
    horizontal = sorted(round(line.get_ydata()[0], 6) for line in ax.get_lines()
                        if line.get_ydata()[0] == line.get_ydata()[1])
    assert horizontal == [0.0, 18.5, 19.0, 30.0]   # floor, the SPH's and the reference's 95% heights, lid
    plt.close(fig)
    couette = figure({**snap, "attrs": {**snap["attrs"], "scene": "couette"}}, "theta", (0.0, 0.6))
    ax = couette.axes[0]
    assert ax.get_ylabel() == "y (streamwise) [mm]" and ax.get_xlabel() == "x (wall-normal) [mm]"
    assert ax.get_ylim() == pytest.approx((0.0, 2.4))
    plt.close(couette)


def test_layer_reference_height_from_the_run_file():
    """At t = 0 the reference's 95% height is 0.95 H0 (the run file's layer, 20 mm); no run file, no lines."""
    from parsph.cli.particles_plot import layer_reference_heights
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    with open(os.path.join(root, "run", "sedimentation.toml")) as fh:
        snap = layer_snapshot(run_file=fh.read())
    (t, (ref, sph)), = layer_reference_heights([snap]).items()
    assert t == 0.0 and ref == pytest.approx(0.019) and 0.0185 < sph < 0.0195
    assert layer_reference_heights([layer_snapshot()]) == {}
    assert layer_reference_heights([layer_snapshot(scene="couette")]) == {}


def test_3d_slice_keeps_a_level_drifted_by_round_off():
    """A settled 3-D layer's particles drift in z by round-off (1e-10 m here, beyond 12 decimals): the slice
    is still the whole middle level, not the one particle that kept its z exactly."""
    rng = np.random.default_rng(3)
    levels = np.array([0.1, 0.3, 0.5, 0.7, 0.9]) * 1e-3
    lv = rng.choice(levels, 1000)
    z = lv + rng.uniform(-1e-10, 1e-10, 1000)
    keep, mid = middle_layer(z)
    assert mid == pytest.approx(0.5e-3, abs=1e-9) and np.array_equal(keep, lv == 0.5e-3)


def test_3d_slice_of_grains_that_move_across_z_is_half_a_layer_about_the_walls_middle_level():
    """A 3-D bed: the walls keep their lattice levels, the grains have left theirs: the slice is every particle
    within half a level's spacing of the walls' middle level (brute force)."""
    rng = np.random.default_rng(4)
    levels = (np.arange(21) + 0.5) * 1e-3
    walls = rng.choice(levels, 300)
    grains = rng.uniform(0.0, 0.021, 3000)
    z = np.concatenate([walls, grains])
    keep, mid = middle_layer(z, walls)
    assert mid == levels[10]                             # the middle level, 10.5 mm
    assert np.array_equal(keep, np.abs(z - levels[10]) < 0.5e-3)
    assert 100 < keep[300:].sum() < 190                  # about a 21st of the grains
