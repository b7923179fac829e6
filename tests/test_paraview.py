"""ParaView's default XDMF reader on real runs: scripts/paraview_check.py under pvpython.

    .venv/bin/python -m pytest -q tests/test_paraview.py

Skipped when ``pvpython`` is not on PATH (Debian: ``apt-get install paraview
python3-paraview xvfb xauth``; not part of the set-up). Short paper-case runs in
2-D and 3-D (serial parsph), then the script: every step must be one cell per
particle (ParaView draws cells, not bare points), show id, kind, theta,
vx, vy (vz) and the 3-component velocity as the active vectors, the Glyph
filter must accept velocity as its orientation and make arrows, and the error
the script computes from ParaView's points at the last step must equal
``parsph check``'s and an independent recomputation from the HDF5 particles
and Eq. (8) (numpy binning, parsph.physics.analytic). Where ``xvfb-run`` is
present, the script also renders the last step as the GUI does after Apply, and
the picture must not be blank. The structure of the sidecar is tested without
ParaView in test_xdmf.py.
"""
import random
import re
import shutil

import numpy as np
import pytest

from parsph import output
from parsph.physics.analytic import couette_velocity

from mpi_helpers import launch  # noqa: E402

SCRIPT = launch.REPO / "scripts" / "paraview_check.py"
pytestmark = [pytest.mark.skipif(shutil.which("pvpython") is None, reason="pvpython not installed"),
              pytest.mark.skipif(launch.under_mpirun(), reason="launches parsph and pvpython itself")]

CASES = {  # dim: (run-file overrides, output times)
    2: (["domain.Ly=0.004"], [0.001, 0.002]),
    3: (["scene.dim=3", "domain.Ly=0.002", "domain.Lz=0.0006"], [0.0005, 0.001]),
}


def independent_error(h5):
    """Max |mean v_y per x bin - Eq. (8)| / V_w over the fluid particles of one file."""
    snap = output.read_snapshot(h5)
    a = snap["attrs"]
    fluid = snap["kind"] == 0
    x, vy = snap["position"][fluid, 0], snap["velocity"][fluid, 1]
    nb = 50
    edges = np.arange(nb + 1) * (a["L"] / nb)
    b = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, nb - 1)
    mean = np.array([vy[b == k].mean() for k in range(nb)])
    exact = couette_velocity((np.arange(nb) + 0.5) * a["L"] / nb, a["time"], a["nu"], a["L"], a["V_w"])
    return np.max(np.abs(mean - exact)) / abs(a["V_w"])


def pvpython(args, xvfb):
    """Run pvpython ARGS, under a virtual display of its own where ``xvfb`` (a random server number:
    two xvfb-run at once both take :99). About one start in ten on this loaded machine fails to
    connect to the new server ("bad X server connection"), a fault of the display, not of the file:
    up to three tries."""
    for attempt in range(3):
        pre = ["xvfb-run", "-a", "-n", str(random.randrange(100, 30000))] if xvfb else []
        pv = launch.run([*pre, "pvpython", *args], timeout=300)
        if "bad X server connection" not in pv.stderr:
            break
    return pv


@pytest.mark.parametrize("dim", [2, 3])
def test_default_reader_shows_every_array_and_the_error(tmp_path, dim):
    sets, times = CASES[dim]
    out = tmp_path / "run"
    args = ["run", launch.PAPER, "--out", out, "--quiet", "--set", f"output.t_end={times[-1]}",
            "--set", f"output.times={times}"]
    for s in sets:
        args += ["--set", s]
    r = launch.run(launch.parsph_cmd(*args), timeout=300, shared_cache=True)
    assert r.returncode == 0, r
    n = output.read_state(output.last_snapshot(out))["attrs"]["n_particles"]
    png = tmp_path / "last.png"
    xvfb = shutil.which("xvfb-run") is not None
    pv = pvpython([SCRIPT, "--screenshot", png, out] if xvfb else [SCRIPT, out], xvfb)
    assert pv.returncode == 0, pv
    text = pv.stdout
    assert text.startswith("reader: Xdmf3ReaderS"), pv
    steps = [ln for ln in text.splitlines() if ln.startswith("t = ")]
    assert len(steps) == len(times), pv
    want = ["id (1)", "kind (1)", "theta (1)", "velocity (3, vectors)"] + [f"v{c} (1)" for c in "xyz"[:dim]]
    for t, line in zip(times, steps):
        assert line.startswith(f"t = {t!r} s: {n} points, {n} cells;"), (n, line)
        for w in want:
            assert w in line, (w, line)
    assert "all arrays present on every step" in text
    if xvfb:  # the picture a person sees: particles, not an empty view (N one-pixel points or more)
        m = re.search(r"screenshot of t = (\S+) s: .*: (\S+) of the pixels differ from the background", text)
        assert m and float(m[1]) == times[-1], pv
        assert float(m[2]) > 0.5 * n / (640 * 480) and png.read_bytes()[:4] == b"\x89PNG", pv
    m = re.search(r"Glyph filter oriented by velocity at t = \S+ s: (\d+) points of arrows", text)
    assert m and int(m[1]) > 0, pv

    m = re.search(r"at t = (\S+) s \(last step\).*: max (\S+), rms (\S+) from ParaView's points; "
                  r"parsph: max (\S+), rms (\S+)", text)
    assert m, pv
    t_last, emax, erms, pmax, prms = float(m[1]), *map(float, m.groups()[1:])
    assert t_last == times[-1]
    # parsph check's table: its last row, as printed (three significant digits)
    chk = launch.run(launch.parsph_cmd("check", out, "--tol", "10"), timeout=120)
    assert chk.returncode == 0, chk
    row = re.compile(r"\s*[0-9.e-]+\s+[0-9.e+-]+\s+[0-9.e+-]+$")
    last = [ln.split() for ln in chk.stdout.splitlines() if row.match(ln)][-1]
    assert float(last[0]) == pytest.approx(times[-1])
    assert f"{emax:.3e}" == last[1] and f"{erms:.3e}" == last[2], (emax, erms, last)
    # the same numbers to rounding: ParaView's points against the recorded profile and an independent sum
    assert emax == pytest.approx(pmax, rel=1e-6) and erms == pytest.approx(prms, rel=1e-6)
    assert emax == pytest.approx(independent_error(out / f"{launch.PAPER.stem}_0001.h5"), rel=1e-6)


def test_a_layer_opens_upright(tmp_path):
    """A sedimentation layer: ParaView's points have the width along X and the height along Y (the walls'
    rows above the lid and below the floor on Y), the velocity vector is (vy, vx, 0), and the profile error
    binned on ParaView's Y equals parsph's."""
    out = tmp_path / "run"
    r = launch.run(launch.parsph_cmd("run", launch.REPO / "run" / "sedimentation.toml", "--out", out, "--quiet",
                                     "--set", "output.t_end=0.02", "--set", "output.times=[0.02]"),
                   timeout=300, shared_cache=True)
    assert r.returncode == 0, r
    snap = output.read_snapshot(output.last_snapshot(out))
    a = snap["attrs"]
    pv = pvpython([launch.REPO / "tests" / "paraview_points.py", out], False)
    assert pv.returncode == 0, pv
    bounds = [float(v) for v in pv.stdout.split("bounds")[1].split()[:4]]
    x, y = snap["position"][:, 0], snap["position"][:, 1]
    assert bounds == pytest.approx([y.min(), y.max(), x.min(), x.max()], rel=1e-12)
    assert a["L"] > 4 * a["Ly"] and bounds[3] - bounds[2] > 4 * (bounds[1] - bounds[0])  # standing up
    check = pvpython([SCRIPT, out], False)
    assert check.returncode == 0, check
    assert "velocity = (vy, vx, .) on every point: True" in check.stdout, check
    m = re.search(r"max (\S+), rms (\S+) from ParaView's points; parsph: max (\S+), rms (\S+)", check.stdout)
    assert m and m[1] == m[3] and m[2] == m[4], check
