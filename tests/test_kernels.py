"""Smoothing kernels: normalisation by quadrature, derivative by finite differences,
compact support, positivity, the cubic spline's Eq. (4) constants and Wendland C2's."""
import math

import numpy as np
import pytest

from parsph.physics import kernels
from parsph.physics.kernels import get_kernel

H = 2.5e-4  # the paper's h [m]; a non-unit h exercises the h^-d scaling
# the cubic spline of Eq. (4) has constants for 1-, 2- and 3-D; Wendland C2 is used in 2-D and 3-D only
KERNELS = [("cubic_spline", 1)] + [(name, dim) for name in ("cubic_spline", "wendland_c2") for dim in (2, 3)]
IDS = [f"{n}-{d}d" for n, d in KERNELS]


def w_vec(k, r, h, dim):
    norm = k.norm(h, dim)
    return np.array([k.w(float(x), 1.0 / h, norm) for x in np.ravel(r)])


def dw_vec(k, r, h, dim):
    norm = k.norm(h, dim)
    return np.array([k.dwdr(float(x), 1.0 / h, norm) for x in np.ravel(r)])


def gauss_legendre(a, b, npts, nsub):
    """Nodes and weights of a composite Gauss-Legendre rule on [a, b]."""
    x, w = np.polynomial.legendre.leggauss(npts)
    edges = np.linspace(a, b, nsub + 1)
    lo, hi = edges[:-1, None], edges[1:, None]
    nodes = 0.5 * (hi - lo) * x[None, :] + 0.5 * (hi + lo)
    weights = 0.5 * (hi - lo) * w[None, :]
    return nodes.ravel(), weights.ravel()


def simpson(f, a, b, n):
    """Composite Simpson rule with n (even) intervals."""
    x = np.linspace(a, b, n + 1)
    y = f(x)
    return (b - a) / (3 * n) * (y[0] + y[-1] + 4 * y[1:-1:2].sum() + 2 * y[2:-1:2].sum())


def measure(r, dim):
    """The radial measure: 1-D handled by doubling the half line."""
    return {1: 2.0 * np.ones_like(r), 2: 2 * math.pi * r, 3: 4 * math.pi * r * r}[dim]


@pytest.mark.parametrize("name,dim", KERNELS, ids=IDS)
def test_normalisation_gauss(name, dim):
    """int W dV = 1: pieces [0, h] and [h, 2h] separately (the cubic spline has a knot at R = 1)."""
    k = get_kernel(name, dim)
    total = 0.0
    for a, b in ((0.0, H), (H, 2 * H)):
        r, wt = gauss_legendre(a, b, 8, 16)
        total += np.sum(wt * measure(r, dim) * w_vec(k, r, H, dim))
    assert total == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("name,dim", KERNELS, ids=IDS)
def test_normalisation_simpson_1d_line(name, dim):
    """The same with a plain Simpson rule on the full interval (1-D: over (-2h, 2h))."""
    k = get_kernel(name, dim)
    if dim == 1:
        val = simpson(lambda x: w_vec(k, np.abs(x), H, dim), -2 * H, 2 * H, 4000)
    else:
        val = simpson(lambda r: measure(r, dim) * w_vec(k, r, H, dim), 0.0, 2 * H, 4000)
    assert val == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize("name,dim", KERNELS, ids=IDS)
def test_normalisation_scales_with_h(name, dim):
    """norm(h) = alpha_d / h^d: the integral stays 1 for another h."""
    k = get_kernel(name, dim)
    h = 1.7
    total = 0.0
    for a, b in ((0.0, h), (h, 2 * h)):
        r, wt = gauss_legendre(a, b, 8, 8)
        total += np.sum(wt * measure(r, dim) * w_vec(k, r, h, dim))
    assert total == pytest.approx(1.0, abs=1e-6)
    assert k.norm(2 * h, dim) == pytest.approx(k.norm(h, dim) / 2 ** dim, rel=1e-14)


@pytest.mark.parametrize("name,dim", KERNELS, ids=IDS)
def test_derivative_matches_finite_difference(name, dim):
    k = get_kernel(name, dim)
    R = np.linspace(0.013, 1.987, 151)
    R = R[np.abs(R - 1.0) > 0.02]  # keep the stencil off the cubic spline's knot
    r = R * H
    eps = 1e-6 * H
    fd = (w_vec(k, r + eps, H, dim) - w_vec(k, r - eps, H, dim)) / (2 * eps)
    an = dw_vec(k, r, H, dim)
    scale = np.max(np.abs(an))
    assert scale > 0
    np.testing.assert_allclose(an, fd, rtol=0, atol=1e-6 * scale)
    # and a kernel decreases monotonically inside its support
    assert np.all(an < 0)


@pytest.mark.parametrize("name,dim", KERNELS, ids=IDS)
def test_compact_support(name, dim):
    k = get_kernel(name, dim)
    r = np.array([2.0, 2.0 + 1e-12, 2.1, 2.5, 3.0, 10.0]) * H
    assert np.all(w_vec(k, r, H, dim) == 0.0)
    assert np.all(dw_vec(k, r, H, dim) == 0.0)
    # continuity at the edge: just inside, W and dW/dr are tiny
    r_in = (2.0 - 1e-4) * H
    assert 0 < w_vec(k, [r_in], H, dim)[0] < 1e-8 * w_vec(k, [0.0], H, dim)[0]


@pytest.mark.parametrize("name,dim", KERNELS, ids=IDS)
def test_positive_inside(name, dim):
    k = get_kernel(name, dim)
    r = np.linspace(0.0, 1.999, 400) * H
    assert np.all(w_vec(k, r, H, dim) > 0)
    # dW/dr vanishes at the origin (smooth peak)
    assert dw_vec(k, [0.0], H, dim)[0] == 0.0


@pytest.mark.parametrize("dim,alpha", [(1, 1 / (6 * H)), (2, 5 / (14 * math.pi * H ** 2)),
                                       (3, 1 / (4 * math.pi * H ** 3))])
def test_cubic_spline_eq4_values(dim, alpha):
    """Eq. (4): W(0) = 4 alpha_d; W(h) = alpha_d; W(1.5h) = alpha_d / 8; dW/dr(h) = -3 alpha_d / h."""
    k = get_kernel("cubic_spline", dim)
    assert k.norm(H, dim) == pytest.approx(alpha, rel=1e-14)
    w = w_vec(k, [0.0, H, 1.5 * H, 0.5 * H], H, dim)
    np.testing.assert_allclose(w, [4 * alpha, alpha, alpha / 8, alpha * (4 - 1.5 + 3 / 8)], rtol=1e-13)
    d = dw_vec(k, [H, 0.5 * H], H, dim)
    np.testing.assert_allclose(d, [-3 * alpha / H, alpha / H * (-6 + 9 / 4)], rtol=1e-13)


@pytest.mark.parametrize("dim,alpha,w_h,dw_h", [
    (2, 7 / (4 * math.pi * H ** 2), 3 / 16, -5 / 8),     # (1 - q/2)^4 (2 q + 1)
    (3, 21 / (16 * math.pi * H ** 3), 3 / 16, -5 / 8)])
def test_wendland_c2_values(dim, alpha, w_h, dw_h):
    """Wendland C2 on support 2h: W(0) = alpha_d (7/(4 pi h^2), 21/(16 pi h^3)), W(h) and
    dW/dr(h) from the polynomial at q = 1, zero from 2h on (constants typed here, not read from parsph)."""
    k = get_kernel("wendland_c2", dim)
    assert k.norm(H, dim) == pytest.approx(alpha, rel=1e-14)
    w = w_vec(k, [0.0, H, 2 * H, 2.5 * H], H, dim)
    np.testing.assert_allclose(w[:2], [alpha, w_h * alpha], rtol=1e-13)
    assert w[2] == 0.0 and w[3] == 0.0
    d = dw_vec(k, [0.0, H], H, dim)
    assert d[0] == 0.0
    np.testing.assert_allclose(d[1], dw_h * alpha / H, rtol=1e-13)


@pytest.mark.parametrize("name,dim", KERNELS, ids=IDS)
def test_pair_function_by_kernel_id(name, dim):
    """The loops' branch-free ``kernel_w_f(kid, ...)`` gives the kernel's W and (dW/dr)/r (to round-off),
    exact zeros from 2h on, and a finite (dW/dr)/r at r = 0 (the kernel's limit: no 0/0)."""
    k = get_kernel(name, dim)
    assert isinstance(k.kid, int)
    norm = k.norm(H, dim)
    scale = k.w(0.0, 1.0 / H, norm)
    for x in np.concatenate([np.linspace(0.01, 2.2, 220), [1.0, 2.0, 1.999999]]) * H:
        w, f = kernels.kernel_w_f(k.kid, float(x), 1.0 / H, norm)
        assert w == pytest.approx(k.w(float(x), 1.0 / H, norm), rel=1e-12, abs=1e-14 * scale)
        assert f == pytest.approx(k.dwdr(float(x), 1.0 / H, norm) / x, rel=1e-12, abs=1e-14 * scale / H ** 2)
        if x >= 2 * H:
            assert w == 0.0 and f == 0.0
    w0, f0 = kernels.kernel_w_f(k.kid, 0.0, 1.0 / H, norm)
    assert w0 == k.w(0.0, 1.0 / H, norm)
    tiny = 1e-6 * H
    assert f0 == pytest.approx(k.dwdr(tiny, 1.0 / H, norm) / tiny, rel=1e-5, abs=1e-14 * scale / H ** 2)


def test_kernel_ids_distinct():
    """Every (name, dim) with its own functions has its own id."""
    by_id = {}
    for name, dim in KERNELS:
        k = get_kernel(name, dim)
        by_id.setdefault(k.kid, set()).add((k.w, k.dwdr))
    assert all(len(fns) == 1 for fns in by_id.values()), by_id
    assert len(by_id) == 2  # cubic spline, Wendland C2
