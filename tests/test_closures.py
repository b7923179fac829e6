"""Closures G(theta), mu(theta) and the paper config's derived quantities (docs/physics.md, "Table 1")."""
import math

import numpy as np
import pytest

from parsph.physics import closures


def test_modulus_at_theta0():
    # 10^(8.76 * 0.35 - 1.183) = 10^1.883 = 76.38 Pa (docs/physics.md: 76.4 Pa)
    assert abs(closures.modulus(0.35) - 76.38) < 0.05


def test_modulus_table_of_extremes():
    """docs/physics.md, "Extremes of theta_0": G at theta0 = 0.05, 0.60, 0.64, 0.70 (to the 3-4 digits printed)."""
    for theta, G in ((0.05, 0.18), (0.60, 11830.0), (0.64, 26510.0), (0.70, 88920.0)):
        assert closures.modulus(theta) == pytest.approx(G, rel=0.03)


def test_modulus_vectorised_and_constants():
    th = np.array([0.1, 0.35, 0.6])
    np.testing.assert_allclose(closures.modulus(th), 10.0 ** (8.76 * th - 1.183), rtol=1e-14)
    # Gidaspow's constants (b = -3.33) give a modulus ~140x smaller
    ratio = closures.modulus(0.35) / closures.modulus(0.35, 8.76, -3.33)
    assert ratio == pytest.approx(10 ** 2.147, rel=1e-12)
    assert 139 < ratio < 141


@pytest.mark.parametrize("a,b", [(8.76, -1.183), (8.76, -3.33), (3.0, 0.5)])
def test_pair_mean_factorisation(a, b):
    rng = np.random.default_rng(1)
    for ti, tj in rng.uniform(0.01, 0.7, size=(50, 2)):
        lhs = 10.0 ** b * closures.half_modulus(ti, a) * closures.half_modulus(tj, a)
        rhs = closures.modulus(0.5 * (ti + tj), a, b)
        assert abs(lhs - rhs) <= 1e-12 * abs(rhs)


def test_viscosity():
    assert closures.viscosity(0.35, 1.0) == pytest.approx(0.35, rel=1e-15)
    assert closures.viscosity(0.5, 2.0) == pytest.approx(1.0, rel=1e-15)


@pytest.mark.parametrize("source", ["run file", "package"])
def test_paper_derived(paper_cfg, source):
    """run/couette_paper.toml and the package's Table 1 (studies.builders.paper_run_file) are the same case."""
    from parsph.setup import config
    from parsph.studies import builders
    cfg = paper_cfg() if source == "run file" else config.build(builders.paper_run_file())
    assert cfg.nu == pytest.approx(1.75e-4, rel=1e-12)
    assert cfg.reynolds == pytest.approx(57.142857, rel=1e-4)
    assert cfg.dx == pytest.approx(2e-4, rel=1e-12)
    assert cfg.dy == pytest.approx(2e-4, rel=1e-12)
    assert cfg.Ny == 50
    assert cfg.mass == pytest.approx(2.8e-5, rel=1e-12)  # rho_s theta0 dx^2 [kg/m]
    assert cfg.layers == 3  # n_w dx >= 2h = 5e-4 m with dx = 2e-4 m
    assert cfg.h == pytest.approx(2.5e-4, rel=1e-12)
    assert cfg.dt == 1e-5 and cfg.nsteps == 50000
    assert cfg.output_times == (0.01, 0.02, 0.05, 0.1, 0.2, 0.5)
    # with a fixed dt, output k happens at step round(t_k / dt) (Simulation._output_due)
    assert tuple(round(t / cfg.dt) for t in cfg.output_times) == (1000, 2000, 5000, 10000, 20000, 50000)


def test_paper_stability_limits(paper_cfg):
    from parsph.physics import limits
    cfg = paper_cfg()
    # Monaghan's limits with the closure's c (consistent form) and with the paper form's c_eff (docs/physics.md)
    material, lattice, _ = limits.groups(cfg)
    cons = limits.classical_limits(cfg.theta0, 1.0, material, lattice, limits.Terms(form="consistent"))
    assert cons["cfl"] == pytest.approx(5.2e-5, rel=0.02)
    assert cons["viscous"] == pytest.approx(4.5e-5, rel=0.02)
    assert cons["force"] == math.inf  # no body force in the paper case
    # independent: c = sqrt(G / rho_s) = 0.195 m/s; dt <= 0.25 h / (c + V_w); dt <= 0.125 h^2 / nu
    c = math.sqrt(76.38 / 2000.0)
    assert c == pytest.approx(0.195, rel=0.01)
    assert cons["cfl"] == pytest.approx(0.25 * 2.5e-4 / (c + 1.0), rel=1e-3)
    assert cons["viscous"] == pytest.approx(0.125 * 2.5e-4 ** 2 / 1.75e-4, rel=1e-12)
    paper = limits.classical_limits(cfg.theta0, 1.0, material, lattice, limits.Terms(form="paper"))
    assert paper["cfl"] == pytest.approx(4.0e-5, rel=0.02)
    # the run's limit (von Neumann, viscous here) accepts the paper's dt
    assert min(cfg.limits, key=cfg.limits.get) == "viscous" and min(cfg.limits.values()) > cfg.dt


@pytest.mark.parametrize("theta0,dtcfl", [(0.05, 6.2e-5), (0.35, 4.0e-5), (0.60, 6.4e-6),
                                          (0.64, 4.3e-6), (0.70, 2.3e-6)])
def test_cfl_limits_table(paper_cfg, theta0, dtcfl):
    """docs/physics.md, "Extremes of theta_0": CFL limits with c_eff, k = 1, V_w = 1 (printed to 2 digits)."""
    from parsph.physics import limits
    cfg = paper_cfg(f"material.theta0={theta0}", "numerics.dt=\"auto\"")
    material, lattice, _ = limits.groups(cfg)
    cfl = limits.classical_limits(theta0, 1.0, material, lattice, limits.Terms(form="paper"))["cfl"]
    assert float(f"{cfl:.2g}") == dtcfl
    assert cfg.dt_auto and cfg.dt == pytest.approx(min(cfg.limits.values()), rel=1e-12)
