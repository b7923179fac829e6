"""parsph.sph.projected: Eq. (3) averaged over the cross directions, and a layer's top from it.

References: Wp integrates to 1 (quadrature over x); theta_bar at a height equals Eq. (3) summed directly over
a lattice's particles (the kernel of parsph.physics.kernels at each point, no projection) and averaged over
y (and z) by the midpoint rule on many points; a sharp lattice top at H: the rows below H are half of a
lattice symmetric about H, so theta_bar(H) is half the full lattice's theta_bar there.
"""
import math

import numpy as np
import pytest
from scipy.integrate import quad

from parsph.physics.kernels import get_kernel
from parsph.setup import config
from parsph.sph import projected
from conftest import ROOT

SED = ROOT / "run" / "sedimentation.toml"


def cfg_of(dim, kernel="cubic_spline"):
    sets = [f"scene.dim={dim}", f'numerics.kernel="{kernel}"', "domain.Ly=0.0012"]
    if dim == 3:
        sets += ["domain.Lz=0.0012", "body_force.g=[-9.81, 0.0, 0.0]"]
    return config.load(SED, sets)


def lattice(cfg, top, rows=40):
    """Rows at top - dx/2, top - 3dx/2, ...: the fluid lattice's x and masses."""
    per_row = cfg.Ny * cfg.Nz
    x = np.repeat(top - (np.arange(rows) + 0.5) * cfg.dx, per_row)
    return x, np.full(x.size, cfg.mass)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("kernel", ["cubic_spline", "wendland_c2"])
def test_projected_kernel_integrates_to_one(dim, kernel):
    cfg = cfg_of(dim, kernel)
    h = cfg.h
    total = quad(lambda x: float(projected.projected_kernel(cfg, x)), -2 * h, 2 * h, points=[-h, 0.0, h],
                 epsabs=1e-15, epsrel=1e-13, limit=200)[0]
    assert abs(total - 1.0) < 1e-10
    assert projected.projected_kernel(cfg, np.array([2 * h, -2.5 * h])).tolist() == [0.0, 0.0]


def direct_average(cfg, x0, px, n=64):
    """Eq. (3) at (x0, y, z) summed over the lattice's particles (rows at heights px, columns at (j + 1/2) dy
    and periodic images), averaged over y (and z) at n midpoints per cross direction."""
    kern = get_kernel(cfg.kernel, cfg.dim)
    norm = kern.norm(cfg.h, cfg.dim)
    cross = [(cfg.Ly, cfg.Ny)] + ([(cfg.Lz, cfg.Nz)] if cfg.dim == 3 else [])
    samples = [(np.arange(n) + 0.5) * L / n for L, _ in cross]
    sites = [(np.arange(-N, 2 * N) + 0.5) * L / N for L, N in cross]     # the box and one image each side
    total = 0.0
    pts = np.stack(np.meshgrid(*samples, indexing="ij"), -1).reshape(-1, len(cross))
    grid = np.stack(np.meshgrid(*sites, indexing="ij"), -1).reshape(-1, len(cross))
    for xr in np.unique(px):
        d2 = (x0 - xr) ** 2 + ((pts[:, None, :] - grid[None, :, :]) ** 2).sum(-1)
        r = np.sqrt(d2).ravel()
        total += sum(kern.w(float(ri), 1.0 / cfg.h, norm) for ri in r[r < 2 * cfg.h])
    return total * cfg.mass / cfg.rho_s / len(pts)


@pytest.mark.parametrize("dim", [2, 3])
def test_uniform_lattice_is_eq3_averaged_across(dim):
    """theta_bar inside a lattice (on a row, between rows, and a quarter step off) is Eq. (3) averaged over
    y (and z), and theta0 to the lattice sum's accuracy (2e-3 for the cubic spline at h = 1.25 dx)."""
    cfg = cfg_of(dim)
    x, m = lattice(cfg, 0.0, rows=30)
    for x0 in (-15 * cfg.dx, -15.5 * cfg.dx, -15.25 * cfg.dx):
        got = float(projected.projected_theta(cfg, x0, x, m))
        want = direct_average(cfg, x0, x, n=48 if dim == 2 else 24)
        assert abs(got - want) < 2e-5 * cfg.theta0, (x0, got, want)
        assert abs(got / cfg.theta0 - 1.0) < 2e-3


def test_sharp_top_is_at_h():
    """A lattice cut at H: theta_bar(H) is half of the full lattice's there (symmetry), and the theta0 / 2
    crossing is H within 1e-3 dx (the full lattice's sum at a midpoint is theta0 to 1e-3 with the cubic
    spline at h = 1.25 dx); at half the full lattice's own value there, H to round-off."""
    cfg = cfg_of(2)
    H = 0.01 + 0.3 * cfg.dx
    x, m = lattice(cfg, H)
    full_x = np.concatenate([x, 2 * H - x])                      # the rows mirrored above H
    full = float(projected.projected_theta(cfg, H, full_x, np.concatenate([m, m])))
    half = float(projected.projected_theta(cfg, H, x, m))
    assert abs(half - 0.5 * full) < 1e-12 * full
    assert abs(projected.interface_height(cfg, x, m) - H) < 1e-3 * cfg.dx
    assert abs(projected.interface_height(cfg, x, m, level=0.5 * full) - H) < 1e-9 * cfg.dx


def test_interface_is_the_highest_crossing():
    """Two layers apart: the top one's crossing, not the lower one's; below the level everywhere: an error."""
    cfg = cfg_of(2)
    lo, m_lo = lattice(cfg, 0.004, rows=20)
    hi, m_hi = lattice(cfg, 0.01, rows=20)
    top = projected.interface_height(cfg, np.concatenate([lo, hi]), np.concatenate([m_lo, m_hi]))
    assert abs(top - 0.01) < 1e-3 * cfg.dx
    with pytest.raises(ValueError):
        projected.interface_height(cfg, hi, m_hi, level=2 * cfg.theta0)
    assert math.isfinite(projected.interface_height(cfg, hi, m_hi, level=0.01 * cfg.theta0))
