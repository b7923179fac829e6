"""Smoothing kernels W(r, h) and dW/dr, normalised in 1-, 2- and 3-D.

Each kernel is a pair of numba functions ``w(r, inv_h, norm)`` and
``dwdr(r, inv_h, norm)`` with compact support ``r < 2h``; ``norm`` is the
dimension- and h-dependent constant from :func:`Kernel.norm`. The loops in
:mod:`parsph.sph.density` and :mod:`parsph.sph.momentum` call :func:`kernel_w_f`, a branch-free form of both,
with the kernel's integer id (a function passed as an argument would make
numba's on-disk cache key differ in every process, so nothing would be
reused).
"""
from dataclasses import dataclass
import math

from numba import njit


@njit(cache=True, inline="always")
def cubic_w(r, inv_h, norm):
    """Eq. (4): alpha_d (4 - 6R^2 + 3R^3) for R < 1, alpha_d (2 - R)^3 for R < 2."""
    q = r * inv_h
    if q < 1.0:
        return norm * (4.0 - 6.0 * q * q + 3.0 * q * q * q)
    if q < 2.0:
        t = 2.0 - q
        return norm * t * t * t
    return 0.0


@njit(cache=True, inline="always")
def cubic_dwdr(r, inv_h, norm):
    """dW/dr of Eq. (4)."""
    q = r * inv_h
    if q < 1.0:
        return norm * inv_h * (-12.0 * q + 9.0 * q * q)
    if q < 2.0:
        t = 2.0 - q
        return -3.0 * norm * inv_h * t * t
    return 0.0


@njit(cache=True, inline="always")
def wendland_w(r, inv_h, norm):
    """Wendland C2 on support 2h: (1 - q/2)^4 (2q + 1) in 2-/3-D."""
    q = r * inv_h
    if q < 2.0:
        t = 1.0 - 0.5 * q
        t2 = t * t
        return norm * t2 * t2 * (2.0 * q + 1.0)
    return 0.0


@njit(cache=True, inline="always")
def wendland_dwdr(r, inv_h, norm):
    """dW/dr of the Wendland C2 kernel: -5 q (1 - q/2)^3 / h."""
    q = r * inv_h
    if q < 2.0:
        t = 1.0 - 0.5 * q
        return -5.0 * norm * inv_h * q * t * t * t
    return 0.0


CUBIC, WENDLAND = 0, 1


@njit(cache=True, inline="always")
def kernel_w_f(kid, r, inv_h, norm):
    """``(W, (dW/dr)/r)`` of kernel ``kid`` without branches on r, both exactly zero for r >= 2h.

    For the pair loops: a candidate outside the support adds an exact zero, so
    no branch is mispredicted and sums do not depend on which candidates are
    visited. Cubic spline as ``a^3 - 4 b^3`` with ``a = max(2 - q, 0)``,
    ``b = max(1 - q, 0)`` (Eq. (4) on both pieces), its ``(dW/dr)/r`` as
    ``(9q - 12) / h^2`` or ``-3 a^2 / (q h^2)`` (a select, not a branch);
    Wendland C2 as ``t^4 (2q + 1)`` with ``t = max(1 - q/2, 0)``, whose
    ``(dW/dr)/r = -5 t^3 / h^2``. At r = 0 the second value is its limit (no 0/0).
    """
    q = r * inv_h
    if kid == CUBIC:
        a = max(2.0 - q, 0.0)
        b = max(1.0 - q, 0.0)
        w = norm * (a * a * a - 4.0 * b * b * b)
        f = norm * inv_h * inv_h * (9.0 * q - 12.0 if q < 1.0 else -3.0 * a * a / q)
    else:
        t = max(1.0 - 0.5 * q, 0.0)
        t3 = t * t * t
        w = norm * t3 * t * (2.0 * q + 1.0)
        f = -5.0 * norm * inv_h * inv_h * t3
    return w, f


@dataclass(frozen=True)
class Kernel:
    """A kernel: its numba functions and its normalisation per dimension."""
    name: str
    w: object
    dwdr: object
    alpha: tuple  # alpha_d * h^d for d = 1, 2, 3
    kid: int  # id for kernel_w_f
    support: float = 2.0  # in units of h

    def norm(self, h, dim):
        return self.alpha[dim - 1] / h ** dim


CUBIC_SPLINE = Kernel("cubic_spline", cubic_w, cubic_dwdr,
                      (1.0 / 6.0, 5.0 / (14.0 * math.pi), 1.0 / (4.0 * math.pi)), CUBIC)
_WENDLAND_23 = Kernel("wendland_c2", wendland_w, wendland_dwdr,
                      (math.nan, 7.0 / (4.0 * math.pi), 21.0 / (16.0 * math.pi)), WENDLAND)

KERNEL_NAMES = ("cubic_spline", "wendland_c2")


def get_kernel(name, dim):
    """The kernel called ``name`` in ``dim`` dimensions."""
    if name == "cubic_spline":
        return CUBIC_SPLINE
    if name == "wendland_c2":
        return _WENDLAND_23
    raise KeyError(name)
