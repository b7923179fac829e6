"""Lattice sums of a kernel in 2-D and 3-D: the summation density of a lattice, and how far the discrete
operators are from their continuum values. :func:`lattice_points` is the one builder of a lattice's
neighbour offsets (here and in :mod:`parsph.physics.limits`).

At a fixed ratio h/dx the SPH sums over a lattice do not converge to the
continuum integrals as dx -> 0; their ratio to the continuum value depends on
the kernel and h/dx only. Two such sums matter for the Couette case:

* the Morris viscous operator. In a uniform state Eq. (5)'s viscous term is
  2 nu dx^2 sum_j (v_i - v_j) (dW/dr)(r_ij) / r_ij (per unit nu: m_j
  (theta_i + theta_j) / (rho_i rho_j) = 2 dx^2 / rho_s). For v = x^2 / 2,
  whose Laplacian is 1, that is nu_eff with
  nu_eff / nu = 2 sum_j (-x_j^2 / 2) (dW/dr)(r_j) / r_j   (dx = 1),
  and its continuum value, -pi int_0^2h r^2 W'(r) dr = 2 pi int_0^2h r W dr, is 1;
* the summation density, Eq. (3): rho / (rho_s theta_0) = dx^2 sum_j W(r_j),
  whose continuum value is int W dA = 1.

In a Couette flow each lattice column slides along y past its neighbours, so
a particle sees column i shifted by i s dx (mod dx): the sheared lattices,
on which both sums vary with s.

Pure numpy on the kernels of :mod:`parsph.physics.kernels` (their numba functions are
called as plain functions); no MPI.
"""

import numpy as np

from .kernels import get_kernel


def lattice_points(spacing, reach):
    """Integer indices [n, dim] of a rectangular lattice's points around one of them: every point within
    ``reach`` (in the units of ``spacing``, the step per dimension) and a margin, the box -m_d .. m_d with
    m_d = int(reach / s_d) + 1, in C order (the first axis slowest). Times ``spacing``: the offsets."""
    axes = [np.arange(-int(reach / s) - 1, int(reach / s) + 2) for s in spacing]
    return np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")], axis=1)


def lattice_sum(kernel, h, spacing):
    """sum_j W(|r_j|, h) over the points of an infinite rectangular lattice around one of them.

    ``kernel``: a :class:`parsph.physics.kernels.Kernel`; ``spacing`` the lattice step per dimension.
    Times the particle mass this is the summation density Eq. (3) of a particle inside the lattice.
    """
    R = lattice_points(spacing, kernel.support * h) * np.asarray(spacing, dtype=float)
    r = np.sqrt((R * R).sum(axis=1))
    norm = kernel.norm(h, len(spacing))
    return float(sum(kernel.w(float(x), 1.0 / h, norm) for x in np.sort(r)))


def sheared_lattice_sums(kernel, h_over_dx, shift=0.0, dim=2, dy=1.0, dz=1.0):
    """(nu_eff / nu, dx dy (dz) sum_j W_ij) at a particle of the lattice whose column i is shifted by
    i*shift lattice spacings along y.

    ``kernel``: a name of :data:`parsph.physics.kernels.KERNEL_NAMES`; lengths in units of dx, ``dy``
    and ``dz`` the other spacings (a run whose L_y is not a multiple of dx has dy != dx);
    ``shift`` in units of dy (0: the unsheared lattice). The points are
    (i, (j + frac(i * shift)) dy) and in 3-D (i, (j + frac(i * shift)) dy, l dz): the columns
    normal to x slide along y, z is not sheared. Each particle's volume is dy (dz), so the
    Morris sum is -dy dz sum_j x_j^2 (dW/dr)(r_j) / r_j, whose continuum value is 1 in 2-D and
    3-D alike (int x^2 W'/r dV = -int W dV by parts, with x^2 -> r^2 / dim).
    """
    k = get_kernel(kernel, dim)
    h = float(h_over_dx)  # in units of dx
    norm = k.norm(h, dim)
    reach = k.support * h
    # the unsheared box covers the sheared points within reach: a shift of y by frac < 1 rows needs no more
    idx = lattice_points((1.0, dy, dz)[:dim], reach)
    x = idx[:, 0].astype(float)
    y = (idx[:, 1] + (x * shift - np.floor(x * shift))) * dy
    r = np.sqrt(x * x + y * y + ((idx[:, 2] * dz) ** 2 if dim == 3 else 0.0))
    vol = dy * (dz if dim == 3 else 1.0)
    inside = r < reach
    x, r = x[inside], r[inside]
    w = np.array([k.w(float(q), 1.0 / h, norm) for q in r])
    off = r > 0
    dwdr = np.array([k.dwdr(float(q), 1.0 / h, norm) for q in r[off]])
    nu_ratio = vol * 2.0 * float(np.sum(-0.5 * x[off] ** 2 * dwdr / r[off]))
    return nu_ratio, vol * float(np.sum(w))


def viscosity_bias(kernel, h_over_dx):
    """nu_eff / nu of the Morris viscous operator on the infinite square lattice (uniform theta).

    Depends on the kernel and h/dx only: at fixed h/dx it does not go away as dx -> 0.
    """
    return sheared_lattice_sums(kernel, h_over_dx, 0.0)[0]


def sheared_lattice_bias(kernel, h_over_dx, offsets=20):
    """(min, max) of nu_eff / nu, then (min, max) of dx^2 sum W, over the shifts s = 0, 1/offsets, ...

    The Couette flow passes through every shift s in [0, 1) as the columns slide.
    """
    sums = np.array([sheared_lattice_sums(kernel, h_over_dx, s) for s in np.arange(offsets) / offsets])
    return float(sums[:, 0].min()), float(sums[:, 0].max()), float(sums[:, 1].min()), float(sums[:, 1].max())
