"""Eq. (8), the transient Couette solution (series from n = 1), against its limits,
the diffusion equation and the method-of-images solution."""
import math

import numpy as np
import pytest

from parsph.physics.analytic import couette_terms, couette_velocity, couette_velocity_images

NU, L, VW = 1.75e-4, 0.01, 1.0  # Table 1


def v(x, t):
    return couette_velocity(np.asarray(x, float), t, NU, L, VW)


@pytest.mark.parametrize("t", [1e-9, 1e-6])
def test_small_time_interior_at_rest(t):
    """Impulsive start: at t -> 0+ the fluid away from the moving plate has not moved.

    The diffusion length sqrt(nu t) is 4e-7 m (1e-9 s) and 1.3e-5 m (1e-6 s); x <= 0.95 L is
    >= 5e-4 m from the plate, i.e. >= 38 diffusion lengths, where the exact v is ~erfc(19) ~ 0.
    """
    x = np.linspace(0.05 * L, 0.95 * L, 37)
    assert np.max(np.abs(v(x, t))) < 1e-6
    # ... while the plate itself moves and the layer next to it is being dragged
    assert v([L], t)[0] == pytest.approx(VW, abs=1e-10)
    ell = math.sqrt(NU * t)
    assert v([L - ell], t)[0] == pytest.approx(math.erfc(0.5), rel=1e-3)


def test_large_time_linear():
    x = np.linspace(0.0, L, 41)
    np.testing.assert_allclose(v(x, 5.0), VW * x / L, rtol=0, atol=1e-12)


@pytest.mark.parametrize("t", [1e-3, 5e-3, 0.02, 0.2])
def test_diffusion_equation(t):
    """dv/dt = nu d2v/dx2 by 4th-order central differences, at points within a few
    diffusion lengths of the moving plate (where both sides are O(V_w / t))."""
    ell = math.sqrt(NU * t)
    xs = np.array([L - 0.5 * ell, L - ell, L - 2 * ell, 0.5 * L])
    xs = xs[(xs > 0.05 * L) & (xs < L - 1e-4)]
    ht = 1e-3 * t
    hx = 0.02 * ell
    for x in xs:
        vt = v([x], t - 2 * ht)[0], v([x], t - ht)[0], v([x], t + ht)[0], v([x], t + 2 * ht)[0]
        dvdt = (vt[0] - 8 * vt[1] + 8 * vt[2] - vt[3]) / (12 * ht)
        vx = v(x + hx * np.array([-2, -1, 0, 1, 2]), t)
        d2v = (-vx[0] + 16 * vx[1] - 30 * vx[2] + 16 * vx[3] - vx[4]) / (12 * hx * hx)
        scale = VW / t  # the size of each term near the plate
        assert abs(dvdt - NU * d2v) <= 1e-5 * scale, (x, t, dvdt, NU * d2v)
        if x >= L - 2.01 * ell:
            assert abs(dvdt) > 1e-2 * scale  # the terms are not trivially zero


@pytest.mark.parametrize("t", [1e-4, 1e-3, 1e-2])
def test_agrees_with_images(t):
    x = np.linspace(0.0, L, 101)
    a = v(x, t)
    b = couette_velocity_images(x, t, NU, L, VW)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-10)
    assert np.max(np.abs(a)) > 0.5  # not both zero


def test_images_against_erfc_half_space():
    """Independent of both: near the plate at small t the flow is Stokes' first problem,
    v = V_w erfc((L - x) / (2 sqrt(nu t)))."""
    t = 1e-4
    x = L - np.linspace(0.0, 5.0, 11) * math.sqrt(NU * t)
    ref = VW * np.array([math.erfc((L - xi) / (2 * math.sqrt(NU * t))) for xi in x])
    np.testing.assert_allclose(v(x, t), ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("t", [1e-6, 1e-4, 1e-2, 0.1, 1.0])
def test_boundary_values(t):
    b = v([0.0, L], t)
    assert abs(b[0]) < 1e-10
    assert abs(b[1] - VW) < 1e-10


def test_terms_truncated_by_tolerance():
    assert couette_terms(1e-4, NU, L) > 100
    # more terms as t -> 0, fewer later; it is not a fixed count
    n = [couette_terms(t, NU, L) for t in (1e-6, 1e-4, 1e-2, 1.0)]
    assert n[0] > n[1] > n[2] > n[3] >= 1
    # the last term kept is below the tolerance relative to V_w, i.e. below 1e-17
    a = math.pi ** 2 * NU * 1e-4 / L ** 2
    N = couette_terms(1e-4, NU, L)
    assert 2 / (N * math.pi) * math.exp(-N * N * a) < 1e-17


def test_initial_state():
    x = np.array([0.0, 0.3 * L, 0.999 * L, L])
    np.testing.assert_array_equal(v(x, 0.0), [0.0, 0.0, 0.0, VW])
    with pytest.raises(ValueError):
        couette_terms(0.0, NU, L)
