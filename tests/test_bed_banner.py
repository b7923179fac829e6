"""What a layer on the floor says about itself (issue 45): the banner of ``parsph run`` for the sedimentation and
fluidized_bed scenes (theta0, H0, u_t, tau, U, U_mf, Wallis's margin), the warning for a bed past Wallis's
bound in the one-dimensional gas, theta0 past random close packing, and the output files' root attributes.

In process, no run: the banner is :func:`parsph.simulation.case.banner` of the validated run file (a stand-in
for the simulation's particle count, time and step), the warning :func:`parsph.setup.scenes.layer.wallis_warnings`
that ``run_case`` says before it, the attributes those :class:`parsph.output.Output` writes. Every number is
checked against one worked out here from the run file's values: Stokes's u_t, tau and theta* (Richardson &
Zaki) in closed form, Ergun's U_mf solved by scipy.optimize.brentq, c_k = 4.65 theta u_t eps^3.65 and
c_d = sqrt(G(theta) / rho_s) (the consistent pressure form: p_s' = G).

    .venv/bin/python -m pytest -q tests/test_bed_banner.py
"""
import math
import re
from types import SimpleNamespace

import h5py
import numpy as np
import pytest
from scipy.optimize import brentq

from parsph.setup import config
from parsph.setup.scenes import layer
from parsph.simulation.case import banner

BED, SEDIMENT, AIR, COUETTE = ("run/fluidized_bed.toml", "run/sedimentation.toml", "run/fluidized_bed_air.toml",
                               "run/couette_paper.toml")
REL = 1e-3  # the banner prints 4 significant digits


def text(cfg):
    sim = SimpleNamespace(n_total=cfg.n_particles, t=0.0, step=0)
    return banner(cfg, sim, SimpleNamespace(size=2), None, "out/x", "x")


def value(line, name):
    """The number after ``name = `` in the banner."""
    m = re.search(rf"(?<![\w/]){re.escape(name)} = ([-+0-9.e]+|inf)", line)
    assert m, (name, line)
    return float(m.group(1))


def hand(cfg):
    """The scales worked out by hand from the run file's values (Stokes drag, the consistent form)."""
    gas, g = cfg.gas, abs(cfg.g[0])
    rho_s, rho_g, mu, d, t0 = cfg.rho_s, gas.rho, gas.mu, gas.d, cfg.theta0
    u_t = (rho_s - rho_g) * g * d * d / (18.0 * mu)
    e0 = 1.0 - t0

    def ergun(U):  # the packed bed's Ergun pressure drop less its buoyant weight, per unit height
        return (150.0 * mu * t0 ** 2 * U / (e0 ** 3 * d * d) + 1.75 * rho_g * t0 * U * U / (e0 ** 3 * d)
                - t0 * (rho_s - rho_g) * g)

    U_mf = brentq(ergun, 0.0, 10.0, xtol=1e-15, rtol=1e-14)
    theta = 1.0 - (gas.U / u_t) ** (1.0 / 4.65) if gas.U > 0 else t0  # Richardson & Zaki's theta*
    return dict(u_t=u_t, tau=rho_s * d * d * e0 ** 4.65 / (18.0 * mu), U_mf=U_mf, theta=theta,
                c_k=4.65 * theta * u_t * (1.0 - theta) ** 3.65,
                c_d=math.sqrt(10.0 ** (cfg.G_a * theta + cfg.G_b) / rho_s),
                dp=t0 * (rho_s - rho_g) * g * cfg.get("scene.height"))


@pytest.mark.parametrize("path", [BED, SEDIMENT])
def test_banner_names_the_layers_scales(path):
    """theta0, H0, u_t, tau, U, U_mf, U/U_mf and both of Wallis's speeds, each at its value; no Re, no nu."""
    cfg = config.load(path)
    assert cfg.get("gas.drag") == "stokes" and cfg.get("numerics.pressure_form") == "consistent"
    out = text(cfg)
    first, layer_line, wallis = out.split("\n")
    assert first.startswith(f"parsph {cfg.scene.name}: ") and first.endswith("-> out/x/x_NNNN.h5")
    assert "Re = " not in out and "nu = " not in out
    h = hand(cfg)
    assert value(layer_line, "theta0") == cfg.theta0
    assert value(layer_line, "H0") == pytest.approx(cfg.get("scene.height"), rel=REL)
    assert value(layer_line, "u_t") == pytest.approx(h["u_t"], rel=REL)
    assert value(layer_line, "tau") == pytest.approx(h["tau"], rel=REL)
    assert value(layer_line, "U") == pytest.approx(cfg.gas.U, rel=REL, abs=0.0)
    assert value(layer_line, "U_mf") == pytest.approx(h["U_mf"], rel=REL)
    assert value(layer_line, "U/U_mf") == pytest.approx(cfg.gas.U / h["U_mf"], rel=REL, abs=0.0)
    where = "theta*" if cfg.gas.U > 0 else "theta0"
    assert value(wallis, f"Wallis at {where}") == pytest.approx(h["theta"], rel=REL)
    assert value(wallis, "c_d") == pytest.approx(h["c_d"], rel=2 * REL)
    assert value(wallis, "c_k") == pytest.approx(h["c_k"], rel=REL)
    assert value(wallis, "c_d/c_k") == pytest.approx(h["c_d"] / h["c_k"], rel=2 * REL)
    assert ("past Wallis's bound" in wallis) == (h["c_k"] > h["c_d"])
    assert "random close packing" not in out


def test_the_shipped_bed_in_water():
    """run/fluidized_bed.toml: U = 4.36 U_mf, c_d/c_k = 2.48 at theta* = 0.30 (stable), and no warning."""
    cfg = config.load(BED)
    out = text(cfg)
    assert value(out, "U/U_mf") == pytest.approx(4.363, abs=1e-3)
    assert value(out, "Wallis at theta*") == pytest.approx(0.30, abs=1e-4)
    assert "(stable)" in out
    assert layer.wallis_warnings(cfg) == []


def test_a_bed_past_wallis_is_warned_about_in_one_line():
    """run/fluidized_bed_air.toml with G_b = -3.0: c_k = 0.45 m/s against c_d = 0.19 m/s at theta* = 0.5545; one
    line naming the bound, both speeds and the way out (gas.flow = "solved"). Not refused: it still validates."""
    cfg = config.load(AIR, ["material.G_b=-3.0"])
    (line,) = layer.wallis_warnings(cfg)
    assert "\n" not in line and line.startswith("parsph: warning: ")
    assert "Wallis's bound" in line and 'gas.flow = "solved"' in line and 'gas.flow = "column"' in line
    theta = value(line, "theta*")
    assert theta == pytest.approx(0.5545, abs=1e-4)  # the file's comment: theta* = 0.5545
    c_k, c_d = value(line, "c_k"), value(line, "elastic c_d")
    assert c_d == pytest.approx(math.sqrt(10.0 ** (cfg.G_a * theta - 3.0) / cfg.rho_s), rel=2 * REL)
    assert c_k == pytest.approx(0.4514, rel=REL)  # the Gidaspow closure's, by finite differences
    assert c_k > c_d
    assert "past Wallis's bound" in text(cfg)
    # the solved gas is the way out: no warning there
    assert layer.wallis_warnings(config.load(AIR, ["material.G_b=-3.0", 'gas.flow="solved"'])) == []


def test_the_shipped_bed_in_air_is_not_warned_about():
    """At G_b = -2.0 the file's own numbers: c_d = 0.60 against c_k = 0.45 m/s."""
    cfg = config.load(AIR)
    assert layer.wallis_warnings(cfg) == []
    out = text(cfg)
    assert value(out, "c_d") == pytest.approx(0.6002, rel=REL) and value(out, "c_k") == pytest.approx(0.4514, rel=REL)
    assert value(out, "U/U_mf") == pytest.approx(1.472, rel=REL)  # the file's comment: 1.5 U_mf, U_mf = 0.068 m/s


@pytest.mark.parametrize("path", [BED, SEDIMENT])
def test_theta0_past_random_close_packing_is_named(path):
    cfg = config.load(path, ["material.theta0=0.7"])
    out = text(cfg)
    assert value(out, "theta0") == 0.7
    assert "past random close packing, 0.64" in out and "outside the physical range" in out


def test_couette_keeps_its_banner():
    cfg = config.load(COUETTE)
    out = text(cfg)
    assert "\n" not in out
    assert out == (f"parsph couette: {cfg.n_particles} particles on 2 rank(s), dt = 1e-05 s, 50000 steps to "
                   f"t = 0.5 s; Re = 57.14, nu = 0.000175 m^2/s -> out/x/x_NNNN.h5")


def write_one(tmp_path, cfg):
    """One output file (no particles) of ``cfg`` through the real writer on one rank; its root attributes."""
    from mpi4py import MPI
    from parsph.output import PROFILE_FIELDS, Frame, Output
    n = 4
    prof = {key: np.zeros(n) for key in PROFILE_FIELDS}
    prof["err"] = (0.0, 0.0)
    path = Output(MPI.COMM_SELF, str(tmp_path), "x", cfg, 10)(Frame(0.0, 0, cfg.dt, prof, {}), snapshot=False)
    with h5py.File(path, "r") as f:
        return dict(f.attrs)


def test_a_layers_file_carries_its_own_scales(tmp_path):
    """H0, U, U_mf and the pressure drop at the buoyant weight, theta0 (rho_s - rho_g) |g| H0; no V_w, no nu."""
    cfg = config.load(BED)
    a = write_one(tmp_path, cfg)
    h = hand(cfg)
    assert "V_w" not in a and "nu" not in a
    assert a["H0"] == pytest.approx(0.01, rel=1e-12)
    assert a["U"] == cfg.gas.U
    assert a["U_mf"] == pytest.approx(h["U_mf"], rel=1e-10)
    assert a["dp_bed"] == pytest.approx(h["dp"], rel=1e-12)
    assert a["dp_bed"] == pytest.approx(0.45 * 1000.0 * 9.81 * 0.01, rel=1e-12)


def test_a_couette_file_keeps_v_w_and_nu(tmp_path):
    cfg = config.load(COUETTE)
    a = write_one(tmp_path, cfg)
    assert a["V_w"] == cfg.V_w and a["nu"] == cfg.nu
    assert not {"H0", "U", "U_mf", "dp_bed"} & set(a)
