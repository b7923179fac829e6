"""Lattice sums of parsph.physics.lattice_sums against independent references.

* a brute-force pair sum in plain Python with the kernels typed here from their
  formulas (Eq. (4); Wendland C2 on support 2h), enumerating the sheared lattice
  as (i, j + i s) without the reduction mod 1 that the module uses;
* the continuum values, by Gauss-Legendre quadrature of the kernels typed here:
  the viscous sum's second moment -pi int r^2 W'(r) dr and int W dA, both 1;
  the lattice sums tend to them as h/dx grows;
* the symmetry of the sheared lattices: the shift s and 1 - s are mirror images (y -> -y);
* in 3-D and on lattices with dy, dz != dx: the numpy brute force of ``lattice_brute.py`` (kernels
  typed there in 2-D and 3-D, every lattice point enumerated).
"""
import math

import numpy as np
import pytest

from parsph.physics.lattice_sums import sheared_lattice_bias, sheared_lattice_sums, viscosity_bias
from parsph.physics.kernels import KERNEL_NAMES, get_kernel
from parsph.physics.lattice_sums import lattice_sum

import lattice_brute


def cubic(q):
    """Eq. (4) in 2-D with h = 1: (W, dW/dr)."""
    a = 5.0 / (14.0 * math.pi)
    if q < 1.0:
        return a * (4 - 6 * q * q + 3 * q ** 3), a * (-12 * q + 9 * q * q)
    if q < 2.0:
        return a * (2 - q) ** 3, -3 * a * (2 - q) ** 2
    return 0.0, 0.0


def wendland(q):
    """Wendland C2 in 2-D on support 2h, h = 1: 7/(4 pi) (1 - q/2)^4 (2q + 1), and its derivative."""
    a = 7.0 / (4.0 * math.pi)
    if q < 2.0:
        t = 1 - q / 2
        return a * t ** 4 * (2 * q + 1), a * (-2 * t ** 3 * (2 * q + 1) + 2 * t ** 4)
    return 0.0, 0.0


FORMULA = {"cubic_spline": cubic, "wendland_c2": wendland}


def brute_force(kernel, h_over_dx, s, reach=12):
    """(nu_eff / nu, dx^2 sum W) summed pair by pair over columns i shifted by i s (dx = 1)."""
    f = FORMULA[kernel]
    h = h_over_dx
    lap = dens = 0.0
    for i in range(-reach, reach + 1):
        for j in range(-reach - abs(i), reach + abs(i) + 1):
            y = j + i * s  # column i shifted by i s, not reduced mod 1
            r = math.hypot(i, y)
            w, dw = f(r / h)
            dens += w / h ** 2
            if r > 0:
                lap += -0.5 * i * i * (dw / h ** 3) / r
    return 2.0 * lap, dens


CASES = [(k, hr) for k in KERNEL_NAMES for hr in (1.0, 1.25, 2.0, 2.5)]


def test_the_formulas_typed_here_are_the_kernels():
    """The brute force's kernels are those of the package (values at a few radii)."""
    for name in KERNEL_NAMES:
        k = get_kernel(name, 2)
        for q in (0.0, 0.3, 1.0, 1.7, 2.0):
            w, dw = FORMULA[name](q)
            assert k.w(q, 1.0, k.norm(1.0, 2)) == pytest.approx(w, rel=1e-13, abs=1e-16)
            assert k.dwdr(q, 1.0, k.norm(1.0, 2)) == pytest.approx(dw, rel=1e-13, abs=1e-16)


@pytest.mark.parametrize("kernel, h_over_dx", CASES)
@pytest.mark.parametrize("s", [0.0, 0.05, 0.3, 0.5, 0.85])
def test_sums_equal_a_brute_force_pair_sum(kernel, h_over_dx, s):
    nu, dens = sheared_lattice_sums(kernel, h_over_dx, s)
    ref_nu, ref_dens = brute_force(kernel, h_over_dx, s)
    assert nu == pytest.approx(ref_nu, rel=1e-12)
    assert dens == pytest.approx(ref_dens, rel=1e-12)


@pytest.mark.parametrize("kernel, h_over_dx", CASES)
def test_square_lattice(kernel, h_over_dx):
    """Shift 0 is the square lattice: viscosity_bias, and lattice_sums.lattice_sum's density (dx = 1)."""
    nu, dens = sheared_lattice_sums(kernel, h_over_dx, 0.0)
    assert viscosity_bias(kernel, h_over_dx) == pytest.approx(brute_force(kernel, h_over_dx, 0.0)[0], rel=1e-12)
    assert dens == pytest.approx(lattice_sum(get_kernel(kernel, 2), h_over_dx, (1.0, 1.0)), rel=1e-13)


def test_the_3d_formulas_of_the_brute_force_are_the_kernels():
    """lattice_brute's kernels are the package's in 2-D and 3-D (values and derivatives at a few radii)."""
    q = np.array([0.0, 0.3, 1.0, 1.7, 2.0, 2.5])
    for name in KERNEL_NAMES:
        k = get_kernel(name, 3)
        for dim in (2, 3):
            w, dw = lattice_brute.kernel(name, dim, q)
            norm = k.norm(1.0, dim)
            np.testing.assert_allclose(w, [k.w(x, 1.0, norm) for x in q], rtol=1e-13, atol=1e-16)
            np.testing.assert_allclose(dw, [k.dwdr(x, 1.0, norm) for x in q], rtol=1e-13, atol=1e-16)


SPACINGS = [(1.0, 1.0), (16 / 15, 0.9)]  # (dy, dz) in units of dx


@pytest.mark.parametrize("kernel, h_over_dx", [(k, hr) for k in KERNEL_NAMES for hr in (1.25, 2.0, 2.5)])
@pytest.mark.parametrize("s", [0.0, 0.3, 0.85])
@pytest.mark.parametrize("dy, dz", SPACINGS)
def test_3d_sums_equal_a_brute_force_sum(kernel, h_over_dx, s, dy, dz):
    """The 3-D (sheared) lattice sums, and kernels.lattice_sum (the walls' held density), against the
    brute force; 2-D with dy != dx too."""
    for dim in (2, 3):
        nu, dens = sheared_lattice_sums(kernel, h_over_dx, s, dim, dy, dz)
        ref_nu, ref_dens = lattice_brute.sheared_sums(kernel, h_over_dx, s, dim, dy, dz)
        assert nu == pytest.approx(ref_nu, rel=1e-12), dim
        assert dens == pytest.approx(ref_dens, rel=1e-12), dim
    if s == 0.0:
        total = lattice_sum(get_kernel(kernel, 3), h_over_dx, (1.0, dy, dz))
        assert total * dy * dz == pytest.approx(ref_dens, rel=1e-12)


@pytest.mark.parametrize("kernel, h_over_dx", CASES)
@pytest.mark.parametrize("s", [0.05, 0.3, 0.45])
def test_shift_and_its_mirror_agree(kernel, h_over_dx, s):
    a = sheared_lattice_sums(kernel, h_over_dx, s)
    b = sheared_lattice_sums(kernel, h_over_dx, 1.0 - s)
    assert a == pytest.approx(b, rel=1e-12)


@pytest.mark.parametrize("kernel, h_over_dx", CASES)
def test_sheared_range_brackets_every_shift(kernel, h_over_dx):
    """(min, max) over s = k/20 contain the square lattice's values and those of the shifts sampled."""
    lo_nu, hi_nu, lo_d, hi_d = sheared_lattice_bias(kernel, h_over_dx, offsets=20)
    for s in (0.0, 0.25, 0.5, 0.95):
        nu, dens = sheared_lattice_sums(kernel, h_over_dx, s)
        assert lo_nu <= nu <= hi_nu and lo_d <= dens <= hi_d
    assert lo_nu < hi_nu and lo_d < hi_d  # the shift does change both sums


def gauss_legendre(a, b, n=20, pieces=40):
    x, w = np.polynomial.legendre.leggauss(n)
    edges = np.linspace(a, b, pieces + 1)
    lo, hi = edges[:-1, None], edges[1:, None]
    return (0.5 * (hi - lo) * x + 0.5 * (hi + lo)).ravel(), (0.5 * (hi - lo) * w).ravel()


@pytest.mark.parametrize("kernel", KERNEL_NAMES)
def test_continuum_values_are_one(kernel):
    """By quadrature (knot at r = h kept at a piece edge): 2 pi int r W dr = 1 (the normalisation)
    and 2 int (-x^2 / 2) W'(r) / r dA = -pi int r^2 W'(r) dr = 1, the value nu_eff / nu tends to."""
    f = FORMULA[kernel]
    r, w = gauss_legendre(0.0, 2.0)
    W, dW = np.array([f(q) for q in r]).T
    assert 2 * math.pi * np.sum(w * r * W) == pytest.approx(1.0, abs=1e-12)
    assert -math.pi * np.sum(w * r ** 2 * dW) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("kernel", KERNEL_NAMES)
@pytest.mark.parametrize("h_over_dx", [4.0, 8.0, 16.0])
def test_lattice_sums_tend_to_the_continuum(kernel, h_over_dx):
    """At every shift both sums approach 1 as h/dx grows. By Poisson summation the deviation is the
    summand's Fourier transform at the reciprocal lattice, which falls at least as (dx/h)^3 (the
    summand x^2 W'(r)/r of the cubic spline has a jump in its second derivative at r = h); the
    constant 1 is not derived but loose (measured: 0.1 (dx/h)^4 at most)."""
    bound = (1.0 / h_over_dx) ** 3
    lo_nu, hi_nu, lo_d, hi_d = sheared_lattice_bias(kernel, h_over_dx, offsets=10)
    assert max(abs(lo_nu - 1), abs(hi_nu - 1), abs(lo_d - 1), abs(hi_d - 1)) <= bound
