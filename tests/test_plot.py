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
