"""`parsph check` on a decaying flow: errors relative to what is left of the wave (in a stream, plus the stream)."""
import math

import numpy as np
import pytest


def test_check_reports_the_periodic_box_relative_to_the_current_amplitude(tmp_path, cli):
    out = tmp_path / "box"
    rc, so, se = cli("run", "run/periodic_box.toml", "--out", out, "--quiet", "--set", "numerics.Nx=16",
                     "--set", "output.t_end=0.04", "--set", "output.times=[0.02, 0.04]", timeout=300)
    assert rc == 0, se
    rc, so, se = cli("check", out, "--tol", "0.5")
    assert rc == 0, se
    from parsph.output import read_profile
    p = read_profile(str(out))
    U, L, nu = 0.1, 0.01, 1.0 * 0.35 / 2000.0
    k = 2 * math.pi / L
    rows = [line.split() for line in so.splitlines() if line.strip()[:1].isdigit()]
    assert len(rows) == 2
    for i, row in enumerate(rows):
        t = float(row[0])
        amp = U * math.exp(-nu * k * k * t)  # independent of the scene's code: the decay rate nu k^2
        exact = U * np.sin(k * p["x"]) * math.exp(-nu * k * k * t)
        assert float(row[1]) == float(f"{amp:.4g}")
        emax = np.max(np.abs(p["vy"][i] - exact)) / amp
        assert float(row[2]) == float(f"{emax:.3e}")
        # the last column is the same error relative to the initial amplitude U
        assert float(row[4]) == float(f"{emax * amp / U:.3e}")
    # the amplitude left at 0.04 s is exp(-nu k^2 0.04) = 0.76 of U: the relative errors are larger
    assert float(rows[1][2]) > float(rows[1][4])
    # and --tol applies to the relative error
    rc, _, _ = cli("check", out, "--tol", f"{float(rows[1][2]) * 0.99:.6g}")
    assert rc == 1


def test_a_box_in_a_stream_is_measured_against_stream_and_wave():
    """run/suspension.toml (Stokes drag, a stream w = 0.02 m/s, a wave U = 0.01 m/s): errors are relative to the
    wave left plus the whole stream, U exp(-(nu k^2 + 1/tau) t) + |w| (the drag's error in time is a share of
    the slip still to relax, |w| exp(-t/tau), which the mean reached alone, |w| (1 - exp(-t/tau)), leaves out);
    tau = rho_s d^2 eps0^3.65 / (18 mu_g) written out here."""
    from parsph.setup.config import load
    cfg = load("run/suspension.toml")
    rho_s, d, mu, theta0, w, U, L = 2500.0, 3e-4, 1e-3, 0.3, 0.02, 0.01, 0.004
    tau = rho_s * d * d * (1 - theta0) ** 3.65 / (18 * mu)
    nu = 0.1 * theta0 / rho_s                     # mu_s / rho_s, mu_s = k theta0 (docs/physics.md, Eq. (5))
    k = 2 * math.pi / L
    for t in (0.0, 0.001, 0.002, 0.005, 0.02):
        assert cfg.error_scale(t) == pytest.approx(U * math.exp(-(nu * k * k + 1 / tau) * t) + w, rel=1e-9)
