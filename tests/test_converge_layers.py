"""`parsph converge` on a layer scene (sedimentation): scene.height stays fixed in metres at every level, the
empty bins above the free top (NaN in the profiles) are left out of the comparison, and a height that is not
a whole number of the coarsest dx (the levels' layers would differ) is refused in one line naming it.

A tiny study: N_x = 15, 30, 60 in a 6 mm box, a 4 mm layer, to 0.02 s (a few seconds).
"""
import json
import math

from parsph.setup.runfile import RunFile

SETS = ["--set", "domain.L=0.006", "--set", "numerics.Nx=15", "--set", "output.t_end=0.02",
        "--set", "output.times=[0.01, 0.02]"]


def test_converge_on_sedimentation(tmp_path, cli):
    out = tmp_path / "conv"
    rc, so, se = cli("converge", "run/sedimentation.toml", "--levels", "3", "--out", out, *SETS,
                     "--set", "scene.height=0.004", timeout=600)
    assert rc == 0, se
    assert "Traceback" not in se
    rep = json.loads((out / "converge.json").read_text())
    fam = rep["families"][0]
    assert fam["scene"] == "sedimentation" and fam["field"] == "theta" and fam["Nx"] == [15, 30, 60]
    for level in fam["levels"]:
        text = level["run_file"].split("\n", 1)[1]
        assert RunFile.parse(text).get("scene", "height") == 0.004
    # the layer fills 10, 20, 40 columns of 6, 12, 24 rows, with 3 wall layers (2h / dx = 2.5) at floor and lid
    assert fam["particles"] == [(c + 2 * 3) * n for c, n in zip((10, 20, 40), (6, 12, 24))]
    for row in fam["times"]:
        bins = row["estimate"]["bins"]
        assert 0 < bins <= 10, bins  # the 5 bins above the 4 mm layer are empty at every level: left out
        assert all(math.isfinite(v) for v in row["true_max"] + row["check_max"])
    assert "bins have data in every level" in so


def test_converge_refuses_a_height_between_lattice_columns(tmp_path, cli):
    rc, so, se = cli("converge", "run/sedimentation.toml", "--levels", "3", "--out", tmp_path / "x", *SETS,
                     "--set", "scene.height=0.0043")
    assert rc == 2
    lines = [ln for ln in se.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in se
    assert lines[0].startswith("parsph: error: scene.height:") and "0.0004 m" in lines[0]
