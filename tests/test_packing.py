"""The packing limit (``material.theta_max``): the frictional pressure against Johnson & Jackson's closed form
written out here, its derivative against a central difference, its tangent past theta_c; the walls' mirror
with it against the total pressure; the keys' refusals; and a bed below minimum fluidisation resting on it
against the steady column (scipy's ODE) with the same pressure."""
import math

import pytest

from parsph.errors import ConfigError
from parsph.physics import closures, limits
from parsph.setup import config
from parsph.sph import walls
from parsph.sph.pass_data import ON
from parsph.studies import layers

LO, HI = 0.5, 0.64
G_A, G_B, RHO_S = 8.76, -2.0, 2000.0


def johnson_jackson(theta):
    """0.05 Pa (theta - theta_min)^2 / (theta_max - theta)^5 (Johnson & Jackson 1987), 0 below theta_min."""
    return 0.05 * max(theta - LO, 0.0) ** 2 / (HI - theta) ** 5


@pytest.mark.parametrize("theta", [0.3, 0.5, 0.52, 0.58, 0.6, 0.62])
def test_frictional_pressure_is_johnson_and_jacksons_below_theta_c(theta):
    p, dp = closures.packing_pressure(theta, LO, HI)
    assert p == pytest.approx(johnson_jackson(theta), rel=1e-13, abs=0.0)
    if theta <= LO:
        assert dp == 0.0  # (theta - theta_min)^2: no kink where it starts
        return
    e = 1e-6
    fd = (johnson_jackson(theta + e) - johnson_jackson(theta - e)) / (2 * e)
    assert dp == pytest.approx(fd, rel=1e-6)


def test_frictional_pressure_continues_on_its_tangent_past_theta_c():
    tc = closures.packing_limit(LO, HI)
    assert tc == pytest.approx(HI - 0.1 * (HI - LO))
    p_c = johnson_jackson(tc)
    slope = p_c * (2 / (tc - LO) + 5 / (HI - tc))
    for theta in (tc + 1e-3, HI, 0.9):
        p, dp = closures.packing_pressure(theta, LO, HI)
        assert p == pytest.approx(p_c + slope * (theta - tc), rel=1e-12)
        assert dp == pytest.approx(slope, rel=1e-12)


@pytest.mark.parametrize("theta", [0.3, 0.55, 0.6, 0.62])
@pytest.mark.parametrize("rise", [1e-4, 1e-1, 30.0])
def test_mirror_theta_has_the_extrapolated_total_pressure(theta, rise):
    """p(theta_w) = p(theta_i) + rho_s theta_i rise with p = G / (G_a ln 10) + p_f, over six decades."""
    def p(t):
        return closures.modulus(t, G_A, G_B) / (G_A * math.log(10.0)) + closures.packing_pressure(t, LO, HI)[0]
    th_w = walls.mirror_theta(theta, rise, G_A, G_B, RHO_S, ON, ON, LO, HI)
    assert th_w >= theta
    assert p(th_w) == pytest.approx(p(theta) + RHO_S * theta * rise, rel=1e-9)


def test_sound_speed_has_the_frictional_stiffness():
    theta = 0.6
    G = closures.modulus(theta, G_A, G_B)
    want = math.sqrt((G + closures.packing_pressure(theta, LO, HI)[1]) / RHO_S)
    assert limits.sound_speed(theta, RHO_S, G_A, G_B, "consistent", (LO, HI)) == pytest.approx(want, rel=1e-14)


@pytest.mark.parametrize("sets,key", [
    (["material.theta_max=0.64", 'numerics.pressure_form="paper"'], "material.theta_max"),
    (["material.theta_min=0.5"], "material.theta_min"),
    (["material.theta_max=0.45"], "material.theta_max"),
    (["material.theta_max=0.61"], "material.theta0"),
])
def test_bad_packing_keys_are_refused(sets, key):
    with pytest.raises(ConfigError) as e:
        config.load(layers.BED_AIR, sets)
    assert e.value.key == key


def test_a_bed_below_minimum_fluidisation_rests_on_its_packing_limit():
    """The air bed at U = 0.04 m/s (0.45 U_mf) with theta_max = 0.64 from theta0 = 0.57: by 0.1 s the
    particles' theta in the interior within 2% of the steady column's with p = G / (G_a ln 10) + p_f (theta
    0.571 at its floor, where p_f is 76% of p; without p_f 0.625, 9% off), its top within 2h."""
    r = layers.bed(Ly=8e-4, t_end=0.1, n_times=2, path=layers.BED_AIR,
                   extra=["gas.U=0.04", "material.theta_max=0.64", "material.theta0=0.57"])
    assert r["U"] < 0.5 * r["U_mf"]
    assert r["errors"][-1] < 0.02, r["errors"]
    assert abs(r["tops"][-1] - r["top_ref"]) < 2 * 2.5e-4, (r["tops"], r["top_ref"])


def test_the_banner_names_the_packing_limit_and_its_pressure_at_theta0():
    from parsph.setup.scenes import layer
    cfg = config.load(layers.BED_AIR, ["material.theta_max=0.64"])
    head = layer.describe(cfg)[0]
    p_f = f"{johnson_jackson(0.6):.4g}"
    assert "packing limit theta_max = 0.64 from theta_min = 0.5" in head and f"p_f = {p_f} Pa" in head, head
    assert "packing limit" not in layer.describe(config.load(layers.BED_AIR))[0]
