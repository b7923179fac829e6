"""parsph.physics.limits against independent references.

- the sound speed of each pressure form: a finite difference of the effective pressure built from
  closures.modulus, and the ratio c_eff / c = sqrt(1 + G_a ln10 theta) of docs/physics.md;
- the linearised operator (lattice sums): the eigenvalues of a dense Jacobian of the package's own
  right-hand side (``Simulation.compute_rates``, finite differences) on a tiny periodic patch;
- the per-mode limits: the spectral radius of the integrators' amplification matrices, written here
  from Eqs. (6)-(7) and the midpoint rule, on either side of the predicted dt, for single modes and
  for the whole patch's Jacobian;
- the classical limits from their formulas;
- the walls' term (``wall_gamma_max``): the largest eigenvalue of a dense Jacobian of the real rates
  with respect to velocity on short channels with walls, 2-D and 3-D.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from parsph.physics import closures, limits
from parsph.setup import config
from parsph.setup.runfile import RunFile
from parsph.simulation.solver import Simulation
from parsph.sph.particles import GRAIN

from conftest import ROOT

RHO_S, GA, GB = 2000.0, 8.76, -1.183
N, L = 8, 0.01          # 8 x 8 periodic patch: wave vectors 2 pi n / (8 dx) hit the quarter zone's grid of 5
DX = L / N


def patch(theta, form="paper", k=1.0, kernel="cubic_spline", h_over_dx=1.25):
    raw = {"scene": {"name": "periodic_box", "amplitude": 0.0}, "terms": {"pressure": True, "viscosity": True},
           "domain": {"L": L, "Ly": L}, "material": {"rho_s": RHO_S, "theta0": theta, "k": k},
           "numerics": {"Nx": N, "h_over_dx": h_over_dx, "dt": 1e-12, "pressure_form": form, "kernel": kernel,
                        "allow_unstable_dt": True},
           "output": {"t_end": 1e-11}}
    return Simulation(config.build(RunFile(raw)), MPI.COMM_SELF)


def jacobian(sim):
    """d acc / d pos and d acc / d vel of the fluid (2n x 2n each) by finite differences of compute_rates."""
    ps = sim.ps
    n = ps.n_own
    sim.compute_rates()
    a0 = ps.acc[:n].reshape(-1).copy()
    x0, v0 = ps.pos[:n].copy(), ps.vel[:n].copy()
    jx, jv = np.zeros((2 * n, 2 * n)), np.zeros((2 * n, 2 * n))
    eps = 1e-5 * DX  # central differences: truncation ~eps^2, round-off ~1e-16/eps, both below 1e-10
    for i in range(n):
        for d in range(2):
            for sgn in (1.0, -1.0):
                ps.pos[:n] = x0
                ps.pos[i, d] += sgn * eps
                ps.n = n
                sim.compute_rates()
                jx[:, 2 * i + d] += sgn * ps.acc[:n].reshape(-1) / (2 * eps)
            ps.pos[:n] = x0
            ps.vel[:n] = v0
            ps.vel[i, d] += 1e-3           # the viscous term is linear in v: one-sided is exact
            ps.n = n
            sim.compute_rates()
            jv[:, 2 * i + d] = (ps.acc[:n].reshape(-1) - a0) / 1e-3
            ps.vel[:n] = v0
    return jx, jv, float(ps.theta[:n].mean())


def patch_modes(sim, theta, form, k, kernel="cubic_spline"):
    """omega^2 and gamma of limits.modes on the patch's own wave vectors, each counted as often as it occurs."""
    w2, g, kap = limits.modes(theta, limits.Material(RHO_S, k, GA, GB), limits.Lattice(sim.cfg.h, (DX, DX), kernel),
                              limits.Terms(form=form), nkappa=N // 2 + 1)
    idx = np.rint(kap * DX / (2 * math.pi / N)).astype(int)
    w_all, g_all = [], []
    for (kx, ky), w, gg in zip(idx, w2, g):
        mult = (1 if kx in (0, N // 2) else 2) * (1 if ky in (0, N // 2) else 2)
        w_all += list(w) * mult
        g_all += [gg] * (2 * mult)
    return np.sort(w_all), np.sort(g_all)


# ---- the sound speed -----------------------------------------------------------------------------------
@pytest.mark.parametrize("theta", [0.05, 0.35, 0.6, 0.7])
def test_sound_speed_is_the_derivative_of_the_effective_pressure(theta):
    """paper: p = G theta; consistent: p = G / (G_a ln 10) (grad p = G grad theta): c^2 = (dp/dtheta) / rho_s."""
    e = 1e-6
    p_paper = lambda t: closures.modulus(t, GA, GB) * t                       # noqa: E731
    p_cons = lambda t: closures.modulus(t, GA, GB) / (GA * math.log(10.0))    # noqa: E731
    for form, p in (("paper", p_paper), ("consistent", p_cons)):
        c2 = (p(theta + e) - p(theta - e)) / (2 * e) / RHO_S
        assert limits.sound_speed(theta, RHO_S, GA, GB, form) == pytest.approx(math.sqrt(c2), rel=1e-8)
    # docs/physics.md: c_eff / c = sqrt(1 + G_a ln10 theta): 2.84 at 0.35, 3.62 at 0.6, 3.89 at 0.7
    ratio = limits.sound_speed(theta, RHO_S, GA, GB, "paper") / limits.sound_speed(theta, RHO_S, GA, GB, "consistent")
    assert ratio == pytest.approx(math.sqrt(1 + 8.76 * 2.302585092994046 * theta), rel=1e-12)
    expected = {0.35: 2.84, 0.6: 3.62, 0.7: 3.89}
    if theta in expected:
        assert ratio == pytest.approx(expected[theta], abs=0.005)


def test_classical_limits_follow_their_formulas():
    h, theta, k, v, a = 2.5e-4, 0.35, 1.0, 1.0, 30.0
    G = 10 ** (GA * theta + GB)
    c_eff = math.sqrt(G * (1 + GA * math.log(10) * theta) / RHO_S)
    material, lattice = limits.Material(RHO_S, k, GA, GB), limits.Lattice(h, (h / 1.25, h / 1.25))
    lim = limits.classical_limits(theta, v, material, lattice, limits.Terms(form="paper"), a)
    assert lim["cfl"] == pytest.approx(0.25 * h / (c_eff + v), rel=1e-12)
    assert lim["viscous"] == pytest.approx(0.125 * h * h / (k * theta / RHO_S), rel=1e-12)
    assert lim["force"] == pytest.approx(0.25 * math.sqrt(h / a), rel=1e-12)
    # docs/physics.md, "Stability limits", Table 1 (paper form): CFL 4.0e-5 s with c_eff, 5.2e-5 s with c
    assert lim["cfl"] == pytest.approx(4.0e-5, rel=0.02)
    assert limits.classical_limits(theta, v, material, lattice, limits.Terms(form="consistent"))["cfl"] == \
        pytest.approx(5.2e-5, rel=0.02)


# ---- the linearised operator against the Jacobian of the real loops ------------------------------------
JACOBIAN_CASES = [(0.35, "paper", "cubic_spline", 1.25), (0.05, "consistent", "cubic_spline", 1.25),
                  (0.6, "paper", "wendland_c2", 1.5)]


@pytest.mark.parametrize("theta0, form, kernel, hdx", JACOBIAN_CASES,
                         ids=[f"{t}-{f}-{k}-{h}" for t, f, k, h in JACOBIAN_CASES])
def test_lattice_modes_are_the_eigenvalues_of_the_rates_jacobian(theta0, form, kernel, hdx):
    """-d acc/d pos has the eigenvalues omega^2 of K(kappa), -d acc/d vel those of gamma(kappa)."""
    sim = patch(theta0, form, k=0.7, kernel=kernel, h_over_dx=hdx)
    jx, jv, theta = jacobian(sim)
    w2, g = patch_modes(sim, theta, form, 0.7, kernel)
    ex = np.sort(np.linalg.eigvals(-jx).real)
    ev = np.sort(np.linalg.eigvals(-jv).real)
    assert np.abs(ex - w2).max() <= 1e-6 * np.abs(w2).max(), (ex[:4], w2[:4], ex[-2:], w2[-2:])
    assert np.abs(ev - g).max() <= 1e-9 * g.max(), (ev[-3:], g[-3:])
    assert w2.max() > 0 and g.max() > 0


# ---- the per-mode limits against the amplification matrices ---------------------------------------------
def amplification(omega2, gamma, dt, integrator):
    """One step of x'' = -omega2 x - gamma x' as a 2x2 matrix on (x, v)."""
    if integrator == "paper":   # Eqs. (6)-(7): x += dt v + dt^2 a / 2, v += dt a, a = -omega2 x - gamma v
        return np.array([[1 - omega2 * dt * dt / 2, dt - gamma * dt * dt / 2], [-omega2 * dt, 1 - gamma * dt]])
    J = np.array([[0.0, 1.0], [-omega2, -gamma]]) * dt
    return np.eye(2) + J + J @ J / 2


@pytest.mark.parametrize("integrator", ["paper", "midpoint"])
@pytest.mark.parametrize("omega2, gamma", [(1e10, 1e3), (1e10, 1e5), (1e6, 1e5), (0.0, 1e4), (4e8, 4e4)])
def test_mode_limit_is_where_the_amplification_leaves_the_unit_disk(integrator, omega2, gamma):
    dt, _ = limits.mode_limits(np.array([omega2]), np.array([gamma]), integrator)
    dt = float(dt[0])
    radius = lambda t: max(abs(np.linalg.eigvals(amplification(omega2, gamma, t, integrator))))  # noqa: E731
    assert radius(0.999 * dt) <= 1 + 1e-12
    assert radius(1.001 * dt) > 1 + 1e-9
    if integrator == "paper":     # the closed form: min(2 gamma / omega^2, 2 / gamma)
        assert dt == pytest.approx(min(2 * gamma / omega2 if omega2 else math.inf, 2 / gamma), rel=1e-12)


@pytest.mark.parametrize("integrator, theta0, k", [("paper", 0.6, 0.05), ("paper", 0.2, 1.0), ("midpoint", 0.6, 0.05)])
def test_patch_amplification_leaves_the_unit_disk_at_the_predicted_dt(integrator, theta0, k):
    """The whole patch: the integrator's amplification matrix built from the Jacobian of the rates
    (paper: x += dt v + dt^2 a / 2, v += dt a; midpoint: I + dt J + (dt J)^2 / 2)."""
    sim = patch(theta0, "paper", k=k)
    jx, jv, theta = jacobian(sim)
    dt, term = limits.linear_limit(theta, limits.Material(RHO_S, k, GA, GB), limits.Lattice(sim.cfg.h, (DX, DX)),
                                   integrator=integrator, nkappa=N // 2 + 1)
    n2 = jx.shape[0]
    J = np.block([[np.zeros((n2, n2)), np.eye(n2)], [jx, jv]])
    def radius(t):
        if integrator == "paper":
            A = np.block([[np.eye(n2) + 0.5 * t * t * jx, t * np.eye(n2) + 0.5 * t * t * jv], [t * jx, np.eye(n2) + t * jv]])
        else:
            A = np.eye(2 * n2) + t * J + 0.5 * (t * J) @ (t * J)
        lam = np.linalg.eigvals(A)
        # the lattice's own instability (omega^2 < 0, limits.lattice_growth) is a real root above 1 at
        # every dt: leave it out; the time-step modes are complex pairs (acoustic) or real negative (viscous)
        lam = lam[~((np.abs(lam.imag) <= 1e-9 * np.abs(lam)) & (lam.real > 0))]
        return max(abs(lam))
    # Empirical margin: for the weakly damped cases (k = 0.05) the patch's largest |lambda| at 0.97x
    # has been seen up to 1 + 4e-8 (a fresh process; 1 + 6e-9 in others), the same order as their
    # growth at 1.05x (1 + 7e-8): the prediction holds to ~1e-7 there, and the check is that the
    # radius crosses 1 between 0.97x and 1.05x and grows with dt
    below, above = radius(0.97 * dt), radius(1.05 * dt)
    assert below <= 1 + 1e-7, (term, below)
    assert above > 1 + 1e-9 and above > below, (term, below, above)


# ---- the wall term of the limit against the Jacobian of a channel with walls ----------------------------
WALL_CASES = [  # (dim, N_x, rows along y (and z), kernel, h / dx, beta_max)
    (2, 12, 8, "cubic_spline", 1.25, 1.5),   # the paper's: beta capped at 1.5 for every wall row
    (2, 24, 8, "cubic_spline", 1.25, 1.5),   # a wider channel than wall_gamma_max's 12 rows
    (2, 12, 8, "cubic_spline", 1.25, 8.0),   # no cap: beta = 1 + d_j / d_i (2, 4, 6 for the first row)
    (2, 12, 8, "wendland_c2", 2.5, 8.0),     # run/couette_accurate.toml's kernel (5 wall layers)
    (3, 12, 4, "cubic_spline", 1.25, 1.5),   # 3-D: modes along y and z
]


def channel_velocity_jacobian(dim, nx, rows, kernel, h_over_dx, beta_max):
    """d a_y / d v_y of the fluid of a Couette channel at rest at t = 0 (finite differences of
    ``Simulation.compute_rates``), the largest |d a_x / d v_y|, |d a_z / d v_y|, and the run."""
    dx = 2e-4
    over = [f"numerics.Nx={nx}", f"domain.L={nx * dx!r}", f"domain.Ly={rows * dx!r}", f"numerics.h={h_over_dx * dx!r}",
            f'numerics.kernel="{kernel}"', f"walls.beta_max={beta_max!r}", "output.times=[]", "output.t_end=1e-5"]
    if dim == 3:
        over.append(f"domain.Lz={rows * dx!r}")
    cfg = config.load(ROOT / "run" / ("couette_3d.toml" if dim == 3 else "couette_paper.toml"), over)
    sim = Simulation(cfg, MPI.COMM_SELF)
    sim.compute_rates()
    ps, n = sim.ps, sim.ps.n_own
    fluid = np.flatnonzero(ps.kind[:n] == GRAIN)
    a0, v0 = ps.acc[:n].copy(), ps.vel[:n].copy()
    dv = 1e-3  # the viscous term is linear in v: one-sided differences are exact to rounding
    jac = np.zeros((len(fluid), len(fluid)))
    cross = 0.0
    for col, i in enumerate(fluid):
        ps.vel[i, 1] += dv
        sim.compute_rates()
        da = (ps.acc[:n][fluid] - a0[fluid]) / dv
        jac[:, col] = da[:, 1]
        cross = max(cross, float(np.abs(np.delete(da, 1, axis=1)).max()))
        ps.vel[:n] = v0
    assert sim.rebuilds == 1  # velocities only: the list and the particles' order stayed
    return jac, cross, cfg


@pytest.mark.parametrize("dim, nx, rows, kernel, h_over_dx, beta_max", WALL_CASES,
                         ids=[f"{d}d-nx{n}-{k}-{h}-beta{b}" for d, n, _, k, h, b in WALL_CASES])
def test_wall_damping_limit_is_the_channels_largest_eigenvalue(dim, nx, rows, kernel, h_over_dx, beta_max):
    """limits.wall_gamma_max, scaled by 2 k m / rho_s^2 h^-(dim+2), against the largest eigenvalue of
    -d a / d v of the real rates in a channel with walls, within 1e-8 relative either way (measured:
    1e-13 on 12 rows, 5e-10 on 24: its 12 rows stand for any wider channel). The periodic lattice's
    largest damping rate (limits.modes) is 8 to 18 % below: the walls' term is what binds."""
    jac, cross, cfg = channel_velocity_jacobian(dim, nx, rows, kernel, h_over_dx, beta_max)
    scale = float(np.abs(jac).max())
    assert cross <= 1e-12 * scale  # each velocity component is damped by itself
    assert np.abs(jac - jac.T).max() <= 1e-12 * scale
    eig = np.linalg.eigvalsh(-0.5 * (jac + jac.T))
    assert eig.min() > -1e-9 * scale  # damping only (the uniform mode is held by the walls)
    spacing = tuple(round(s / cfg.h, 12) for s in cfg.spacing)
    predicted = limits.wall_gamma_max(kernel, dim, spacing, beta_max) * 2 * cfg.k * cfg.mass / cfg.rho_s ** 2 \
        / cfg.h ** (dim + 2)
    assert predicted == pytest.approx(eig.max(), rel=1e-8), (predicted, eig.max())
    periodic = limits.modes(cfg.theta0, limits.Material(cfg.rho_s, cfg.k, cfg.G_a, cfg.G_b),
                            limits.Lattice(cfg.h, tuple(cfg.spacing), kernel))[1].max()
    assert eig.max() > 1.05 * periodic, (eig.max(), periodic)
