"""`parsph plot`: the PNG is named after the run's stem, whatever the width of the output index.

Output files are ``<stem>_NNNN.h5`` with an index of four digits or more, so a
run with 10,000 outputs or more has five-digit names.
"""
import os
import shutil

import pytest

from parsph.cli.report import profile_png

from conftest import PAPER_TOML, run_cli


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


def test_plot_of_a_run_with_a_five_digit_index(tmp_path):
    """A one-output run whose file is renamed to index 10000: the plot is <stem>_profile.png beside it."""
    pytest.importorskip("matplotlib")
    out = tmp_path / "out"
    rc, _, err = run_cli("run", PAPER_TOML, "--out", out, "--quiet", "--set", "domain.Ly=0.002",
                         "--set", "output.t_end=2e-5", "--set", "output.times=[2e-5]", timeout=600)
    assert rc == 0, err
    shutil.move(out / "couette_paper_0000.h5", out / "couette_paper_10000.h5")
    rc, stdout, err = run_cli("plot", out, timeout=600)
    assert rc == 0, err
    png = out / "couette_paper_profile.png"
    assert png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", sorted(os.listdir(out))
    assert f"wrote {png}" in stdout
