"""The studies' case builders and fits (parsph/studies/builders.py, stability_cases.py, fits.py): a column's
Reynolds number gives back its k, the stability map's prediction is the limit of parsph.physics.limits for
the column's material and lattice (what the records in docs/ were run against), the settling column is
run/settling.toml with the map's box, and the shared fits recover what they were given. No solver runs.
"""
import math

import numpy as np
import pytest

from parsph.physics import limits, table1
from parsph.physics.closures import G_A, G_B
from parsph.setup import config
from parsph.setup.runfile import RunFile
from parsph.setup.schema import SCHEMA
from parsph.studies import builders, fits
from parsph.studies.stability_cases import LY_IN_H, prediction


@pytest.mark.parametrize("theta0, re", [(0.35, 57.0), (0.05, 2000.0), (0.7, 1.0)])
def test_couette_k_gives_the_columns_reynolds_number(theta0, re):
    cfg = builders.couette(10, ly_in_h=LY_IN_H, theta0=theta0, re=re)
    assert cfg.theta0 == theta0
    assert cfg.reynolds == pytest.approx(re, rel=1e-12)
    assert builders.couette_k(table1.V_W * table1.L * table1.RHO_S / (table1.K * table1.THETA0)) == \
        pytest.approx(table1.K, rel=1e-15)


@pytest.mark.parametrize("theta0, re, nx, integrator", [(0.35, 57.0, 10, "paper"), (0.7, 400.0, 50, "paper"),
                                                         (0.64, 10.0, 50, "midpoint")])
def test_prediction_is_the_limit_of_the_columns_material_and_lattice(theta0, re, nx, integrator):
    """The limits the map's runs were made against, written out from their parts (bit for bit)."""
    k = abs(table1.V_W) * table1.L * table1.RHO_S / (re * theta0)
    dx = table1.L / nx
    lim = limits.limits(theta0, abs(table1.V_W), 0.0, limits.Material(table1.RHO_S, k, G_A, G_B),
                        limits.Lattice(table1.H_OVER_DX * dx, (dx, dx), beta_max=SCHEMA["walls"]["beta_max"].default),
                        integrator=integrator)
    p = prediction(theta0, re, nx, integrator)
    assert p.k == k and p.limits == lim and p.dt == min(lim.values())
    c2 = limits.sound_speed(theta0, table1.RHO_S, G_A, G_B, "paper") ** 2
    assert p.acoustic_damping == 2.0 * k * theta0 / table1.RHO_S / c2


def test_settling_column_is_the_run_file_in_the_maps_box():
    rf = RunFile.read(builders.SETTLING_RUN)
    nx, theta0 = 20, 0.6
    lim = builders.settling_limits(nx, theta0, ly_in_h=LY_IN_H)
    cfg = builders.settling(nx, theta0, ly_in_h=LY_IN_H, dt=2.0 * min(lim.values()), t_end=1e-3,
                         overrides=["checks.every=1"])
    h = rf.get("numerics", "h_over_dx") * rf.get("domain", "L") / nx
    assert (cfg.Nx, cfg.theta0, cfg.Ly, cfg.t_end, cfg.output_times) == (nx, theta0, LY_IN_H * h, 1e-3, ())
    assert cfg.dt == 2.0 * min(lim.values()) and not cfg.dt_auto
    assert cfg.get("checks.every") == 1 and cfg.get("numerics.pressure_form") == rf.get("numerics", "pressure_form")
    auto = config.build(builders.settling_run_file(nx, theta0, ly_in_h=LY_IN_H).set("numerics", dt="auto"))
    assert lim == auto.limits   # at theta_0: the limits config.build takes
    assert min(builders.settling_limits(nx, theta0, ly_in_h=LY_IN_H, theta=0.7).values()) < min(lim.values())


def test_fits_recover_a_power_law_and_a_line():
    dx = np.array([0.1, 0.05, 0.025, 0.0125])
    err = 3.0 * dx ** 1.5
    assert fits.loglog_slope(dx, err) == pytest.approx(1.5, rel=1e-12)
    assert fits.local_orders(dx, err) == pytest.approx([1.5] * 3, rel=1e-12)
    assert math.isnan(fits.loglog_slope(dx[:1], err[:1]))
    x = np.array([1e2, 1e3, 1e4, 1e5])
    slope, b = fits.relative_line(x, 2e-9 * x + 5e-6)
    assert (slope, b) == (pytest.approx(2e-9, rel=1e-9), pytest.approx(5e-6, rel=1e-9))
    slope, b = fits.relative_line(x, 2e-9 * x + 5e-6, intercept=5e-6)
    assert b == 5e-6 and slope == pytest.approx(2e-9, rel=1e-12)
