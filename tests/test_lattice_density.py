"""The paper case at t = 0: summation density on the lattice and the initial accelerations,
against an independent brute-force numpy evaluation of Eqs. (3)-(5).

Wall particles hold the density that Eq. (3) gives inside the infinite initial lattice
(``rho_wall = m sum_j W(|r_j|)`` over lattice points), so that the undisturbed lattice is in
equilibrium next to a wall too; the brute force below computes that sum on its own.
"""
import math
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from parsph.sph.particles import GRAIN
from parsph.simulation.solver import Simulation

PAPER_TOML = Path(__file__).resolve().parent.parent / "run" / "couette_paper.toml"


def cubic(q, alpha):
    """Eq. (4) and its derivative in R (numpy, written out again here)."""
    w = np.where(q < 1, 4 - 6 * q ** 2 + 3 * q ** 3, np.where(q < 2, (2 - q) ** 3, 0.0))
    dw = np.where(q < 1, -12 * q + 9 * q ** 2, np.where(q < 2, -3 * (2 - q) ** 2, 0.0))
    return alpha * w, alpha * dw


def lattice_theta(cfg):
    """Eq. (3) at a point of the infinite lattice (dx, dy): m sum_j W(|r_j|) / rho_s, brute force."""
    alpha = 5 / (14 * math.pi * cfg.h * cfg.h)
    reach = math.ceil(2 * cfg.h / min(cfg.dx, cfg.dy)) + 1
    i, j = np.meshgrid(np.arange(-reach, reach + 1), np.arange(-reach, reach + 1), indexing="ij")
    r = np.hypot(i * cfg.dx, j * cfg.dy).ravel()
    return math.fsum(cfg.mass * cubic(r / cfg.h, alpha)[0]) / cfg.rho_s


def reference_row(cfg):
    """Eqs. (3)-(5) for the fluid particles of one lattice row, by brute force.

    Lattice of docs/physics.md, "Walls": x = (c + 1/2) dx for fluid c = 0..Nx-1, wall layers at
    x = -(k + 1/2) dx and L + (k + 1/2) dx; y periodic. Walls hold the lattice's summed theta
    (:func:`lattice_theta`, the solver's choice), the moving plate has v_y = V_w, no-slip
    factor beta = min(1.5, 1 + d_j / d_i).
    Returns (x, theta, a) for the fluid particles of row 0 (every row is the same).
    """
    dx, dy, h, m = cfg.dx, cfg.dy, cfg.h, cfg.mass
    nw, Nx = cfg.layers, cfg.Nx
    alpha = 5 / (14 * math.pi * h * h)
    cols = np.arange(-nw, Nx + nw)
    xc = (cols + 0.5) * dx
    # neighbour rows: a few either side of row 0, y taken relative to row 0 (periodicity)
    rows = np.arange(-4, 5)
    X, Yr = np.meshgrid(xc, rows * dy, indexing="ij")
    X, Yr = X.ravel(), Yr.ravel()
    C = np.repeat(cols, rows.size)
    fluid = (C >= 0) & (C < Nx)
    vy = np.where(C >= Nx, cfg.V_w, 0.0)

    # Eq. (3) for each fluid column (row 0); walls: the infinite lattice's summed theta
    theta_col = np.full(cols.size, lattice_theta(cfg))
    for c in range(Nx):
        r = np.hypot(X - (c + 0.5) * dx, Yr)
        theta_col[c + nw] = np.sum(m * cubic(r / h, alpha)[0]) / cfg.rho_s
    theta = theta_col[C + nw]
    rho = cfg.rho_s * theta

    def G(th):
        return 10.0 ** (cfg.G_a * th + cfg.G_b)

    acc = np.zeros((Nx, 2))
    for c in range(Nx):
        xi = (c + 0.5) * dx
        ti = theta_col[c + nw]
        dxv, dyv = xi - X, 0.0 - Yr
        r = np.hypot(dxv, dyv)
        nb = (r > 0) & (r < 2 * h)
        r, dxv, dyv = r[nb], dxv[nb], dyv[nb]
        tj, rj, vj, Cj, Xj = theta[nb], rho[nb], vy[nb], C[nb], X[nb]
        dW = cubic(r / h, alpha)[1] / h
        p = -(m / cfg.rho_s ** 2) * G(0.5 * (ti + tj)) * (1 / ti + 1 / tj) * dW / r
        acc[c, 0] = np.sum(p * dxv)
        di = np.where(Xj < 0, xi, cfg.L - xi)
        dj = np.where(Xj < 0, -Xj, Xj - cfg.L)
        beta = np.where(fluid[nb], 1.0, np.minimum(cfg.beta_max, 1 + dj / di))
        visc = cfg.k * ti * m * (ti + tj) / (cfg.rho_s * ti * rj) * dW / r * beta * (0.0 - vj)
        acc[c, 1] = np.sum(p * dyv) + np.sum(visc)
    return xc[nw:nw + Nx], theta_col[nw:nw + Nx], acc


def roundoff_bound_ax(cfg):
    """An a-priori bound on |a_x| of a fluid particle of the initial lattice, from round-off only.

    At t = 0 only the pressure term of Eq. (5) has an x part (v_ij is along y), and on the exact
    lattice its pair terms t_j = c f(theta_i, theta_j) F(r_j) X_j (F = (dW/dr)/r, X_j = x_i - x_j,
    c = m / rho_s^2) cancel in mirror pairs -- next to a wall too, since the wall particles
    hold the lattice's own summed density. In floating point (u = eps/2) three things break the
    cancellation:

    1. positions: every coordinate is rounded, |dx| <= u D with D the largest |x| or |y| (the
       y of a periodic halo copy is shifted by Ly and rounded again), so each X_j, Y_j is off by
       at most delta = 4 u D, and t_j by delta (|dt_j/dX| + |dt_j/dY|), where
       dt/dX = c f (F + F' X^2 / r) and dt/dY = c f F' X Y / r, F' = (W'' - W'/r) / r;
    2. theta: every particle's summed theta (and the walls' rho_wall / rho_s) is off the exact
       lattice value by at most dlt = [sum_j m |W'(r_j)| sqrt(2) 2 delta + (N + 2) u sum_j m W] /
       sum_j m W relative (moved positions, then N + 1 rounded additions); theta_i is common to
       all terms (it scales a sum that vanishes), theta_j changes t_j by s dlt relative with
       s = |d ln f / d ln theta_j| <= G_a ln(10) theta / 2 + 1/2;
    3. arithmetic: about 16 rounded operations per term and an N-term sum: (N + 16) u S_x,

    with S_x = sum_j |t_j| and N = 20 neighbours (h = 1.25 dx). Returns (bound, S_x).
    """
    u = np.finfo(float).eps / 2
    dx, dy, h, m = cfg.dx, cfg.dy, cfg.h, cfg.mass
    alpha = 5 / (14 * math.pi * h * h)
    th = lattice_theta(cfg)
    i, j = np.meshgrid(np.arange(-4, 5), np.arange(-4, 5), indexing="ij")
    X, Y = (i * dx).ravel(), (j * dy).ravel()
    r = np.hypot(X, Y)
    nb = (r > 0) & (r < 2 * h)
    N = int(nb.sum())
    X, Y, r = X[nb], Y[nb], r[nb]
    q = r / h
    W, dW = cubic(q, alpha)
    dW = dW / h
    d2W = alpha / h ** 2 * np.where(q < 1, -12 + 18 * q, 6 * (2 - q))
    F = dW / r
    Fp = (d2W - F) / r
    cf = m / cfg.rho_s ** 2 * 10.0 ** (cfg.G_a * th + cfg.G_b) * 2 / th
    t = cf * F * X
    S_x = float(np.sum(np.abs(t)))
    D = max(cfg.L + cfg.layers * dx, cfg.Ly)
    delta = 4 * u * D
    pos = delta * np.sum(np.abs(cf * (F + Fp * X * X / r)) + np.abs(cf * Fp * X * Y / r))
    rho_sum = m * (np.sum(W) + 4 * alpha)  # + the particle itself (W(0) = 4 alpha)
    dlt = (np.sum(m * np.abs(dW)) * math.sqrt(2) * 2 * delta + (N + 2) * u * rho_sum) / rho_sum
    s = cfg.G_a * math.log(10) * th / 2 + 0.5
    return float(pos + s * dlt * S_x + (N + 16) * u * S_x), S_x


@pytest.fixture(scope="module")
def paper_t0():
    from parsph.setup import config
    cfg = config.load(str(PAPER_TOML))
    sim = Simulation(cfg, MPI.COMM_SELF)
    sim.compute_rates()
    ps = sim.ps
    n = ps.n_own
    f = ps.kind[:n] == GRAIN
    col = np.rint(ps.pos[:n, 0][f] / cfg.dx - 0.5).astype(int)
    return cfg, col, ps.theta[:n][f].copy(), ps.acc[:n][f].copy(), sim


def test_wall_density_is_the_lattice_sum(paper_t0):
    """rho_wall = m sum_j W over the infinite lattice (brute force), and the walls' theta is that over rho_s."""
    cfg, _, _, _, sim = paper_t0
    theta_lat = lattice_theta(cfg)
    assert sim.rho_wall == pytest.approx(cfg.rho_s * theta_lat, rel=1e-14)
    ps = sim.ps
    n = ps.n_own
    walls = ps.kind[:n] != GRAIN
    assert walls.sum() == 2 * cfg.layers * cfg.Ny
    np.testing.assert_allclose(ps.theta[:n][walls], theta_lat, rtol=1e-14)
    # the wall holds the fluid's summed lattice density, which is not theta0: the lattice sum of the
    # cubic spline at h = 1.25 dx is theta0 (1 - 5.5e-4)
    assert theta_lat / cfg.theta0 - 1 == pytest.approx(-5.515e-4, rel=1e-3)


def test_every_column_at_theta0(paper_t0):
    cfg, col, theta, _, _ = paper_t0
    assert np.bincount(col, minlength=cfg.Nx).tolist() == [cfg.Ny] * cfg.Nx
    for c in range(cfg.Nx):  # wall-adjacent columns included
        th = theta[col == c]
        assert np.all(np.abs(th / cfg.theta0 - 1) < 5e-3), c
    # the wall layers continue the lattice, so the sum is the same in every column
    assert np.ptp(theta) <= 1e-12 * cfg.theta0


def test_density_matches_brute_force(paper_t0):
    cfg, col, theta, _, _ = paper_t0
    _, theta_ref, _ = reference_row(cfg)
    np.testing.assert_allclose(theta, theta_ref[col], rtol=1e-12)
    # the lattice sum of the cubic spline at h = 1.25 dx: theta0 (1 - 5.5e-4)
    assert theta_ref[cfg.Nx // 2] / cfg.theta0 - 1 == pytest.approx(-5.515e-4, rel=1e-3)


def test_initial_accelerations(paper_t0):
    """What is asserted, and why:

    - a_x (only the pressure term has an x part at t = 0: v_ij is along y): on the uniform
      lattice the pair terms cancel by mirror symmetry, in every column. Next to the walls this
      holds because the wall particles carry the lattice's summed density. Walls held at theta0
      would not do: the fluid's summation density is theta0 (1 - 5.5e-4), and such walls push
      the fluid away with a_x = 0.29 m/s^2 (6.7e-5 of the viscous scale a_v = nu V_w / dx^2 =
      4375 m/s^2) in the first column. |a_x| must stay below the round-off bound of
      :func:`roundoff_bound_ax` (1.7e-10 m/s^2, i.e. 4e-14 a_v; measured: 3.5e-12 m/s^2)
      in every column, wall-adjacent ones included, and equal the brute-force Eq. (5) (~0).
    - a_y: zero except within 2h of the moving plate, where the viscous term drags the fluid
      along +y; compared with the brute-force Eq. (5) (beta = 1.5 there) to 1e-9.
    """
    cfg, col, theta, acc, _ = paper_t0
    a_v = cfg.nu * cfg.V_w / cfg.dx ** 2
    _, _, a_ref = reference_row(cfg)
    ax = np.abs(acc[:, 0])
    bound, S_x = roundoff_bound_ax(cfg)
    # the bound is round-off relative to both the pressure terms' size and the viscous scale ...
    assert bound < 1e-11 * S_x and bound < 1e-13 * a_v, (bound, S_x, a_v)
    # ... and the push of walls held at theta0 (0.29 m/s^2, 2.7e-2 m/s^2 in the second column) is far above it
    assert 0.02 > 1e6 * bound
    near_wall = (col < 2) | (col > cfg.Nx - 3)
    assert ax[near_wall].max() <= bound, (ax[near_wall].max(), bound)
    assert ax.max() <= bound, (ax.max(), bound)
    np.testing.assert_allclose(acc, a_ref[col], rtol=0, atol=1e-9 * a_v)
    np.testing.assert_allclose(acc[:, 0], a_ref[col][:, 0], rtol=0, atol=2 * bound)
    # moving plate side: columns Nx-1 and Nx-2 are dragged forward, the rest are at rest
    ay = acc[:, 1]
    assert np.all(ay[col == cfg.Nx - 1] > 1.0 * a_v)
    assert np.all(ay[col == cfg.Nx - 2] > 0.03 * a_v)
    assert np.abs(ay[col < cfg.Nx - 2]).max() < 1e-9 * a_v
