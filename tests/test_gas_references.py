"""The gas references of parsph.physics.gas_references (docs/physics.md, "The solid phase in a gas", refs. 1-4),
each against an independent form: closed forms against the general roots and ODEs, the ODEs against
quadratures in the other variable, the discrete solutions against literal loops, the columns against their
mass, their balance by finite differences, a quadrature in theta and analytic.settling_equilibrium."""
import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from parsph.physics import bed_expansion, drag, gas_references as gr, kynch, limits
from parsph.physics.analytic import settling_equilibrium
from parsph.physics.closures import G_A, G_B

LN10 = math.log(10.0)
WATER = gr.Phases(2500.0, 1000.0, 1e-3, 3e-4, 9.81, "stokes")     # glass beads in water, Stokes drag
AIR = {m: gr.Phases(2000.0, 1.2, 1.8e-5, 3e-4, 9.81, m) for m in ("stokes", "wen_yu", "gidaspow")}  # Table 1 grains
SCHEMES = [("paper", "explicit"), ("paper", "implicit"), ("midpoint", "explicit"), ("midpoint", "implicit")]


def beta(ph, theta, slip):
    return drag.beta(drag.MODELS[ph.model], theta, slip, ph.rho_g, ph.mu_g, ph.d)


def rz_flux(theta, ph):
    """Kynch's flux of the Stokes closure written out: F = -u_t theta (1 - theta)^4.65."""
    u_t = (ph.rho_s - ph.rho_g) * ph.g * ph.d ** 2 / (18.0 * ph.mu_g)
    return -u_t * theta * (1.0 - theta) ** 4.65


def profile_integral(col):
    """int_0^inf theta dx of a column: 8-point Gauss-Legendre on each solver step, plus the exponential tail."""
    nodes, weights = np.polynomial.legendre.leggauss(8)
    a, b = col.x[:-1], col.x[1:]
    xs = 0.5 * (b - a)[:, None] * nodes[None, :] + 0.5 * (a + b)[:, None]
    th = col.theta_at(xs.ravel()).reshape(xs.shape)
    return float(np.sum(0.5 * (b - a)[:, None] * weights[None, :] * th)) + col.theta_top * col.tail_length


def balance_error(col, x, U, ph, form, scale):
    """(p_s(theta(x + h)) - p_s(theta(x - h))) / 2h - f(theta(x)), h = 1e-4 of the local length: the smaller of
    ``scale`` and theta p_s' / |f| (theta's e-folding length; at the free top it is microns)."""
    th = float(col.theta_at(x))
    f = bed_expansion.column_rhs(th, U, ph)
    h = 1e-4 * min(scale, th * limits.dpressure(th, G_A, G_B, form) / abs(f), x)
    p = [limits.pressure(float(t), G_A, G_B, form) for t in col.theta_at(np.array([x - h, x + h]))]
    return (p[1] - p[0]) / (2 * h) - f, th


# ---- reference 1: drag relaxation in a stream ----------------------------------------------------------------
def test_stokes_stream_time_is_rho_theta_eps_over_beta():
    """tau = rho_s d^2 eps0^3.65 / (18 mu_g) equals rho_s theta0 eps0 / beta_Stokes (drag.relaxation_time)."""
    for th in (0.05, 0.35, 0.6):
        tau = gr.stokes_stream_time(th, WATER)
        ref = drag.relaxation_time(drag.STOKES, th, 0.3, WATER.rho_s, WATER.rho_g, WATER.mu_g, WATER.d)
        assert tau == pytest.approx(ref, rel=1e-13)


def test_exact_relaxation_solves_the_ode_with_stokes_drag():
    """v = u_g (1 - exp(-t/tau)) per component against the scalar ODE integrated with the Stokes closure,
    a 2-D stream, t from 0.01 to 20 tau: to 1e-11 of |u_g| (6e-13 reached)."""
    th, u = 0.3, np.array([0.04, -0.03])
    tau = gr.stokes_stream_time(th, WATER)
    t = tau * np.array([0.0, 0.01, 0.5, 1.0, 3.0, 20.0])
    exact = gr.relaxation_velocity(t, u, tau)
    assert exact.shape == (6, 2)
    np.testing.assert_allclose(gr.relaxation_ode(t, u, th, WATER), exact, rtol=0, atol=1e-11 * 0.05)
    np.testing.assert_allclose(exact[3], u * (1.0 - math.exp(-1.0)), rtol=1e-14)


@pytest.mark.parametrize("integrator, update", SCHEMES)
def test_discrete_relaxation_against_a_literal_loop(integrator, update):
    """u_g (1 - r^n) against the recursion of parsph.sph.integrators written out with a constant C = 1/tau,
    n = 0..60, z = dt/tau from 0.1 to past each scheme's overshoot (r < 0); and relaxation_steps (the general
    recursion) with the Stokes closure against the same closed form. To 1e-12 |u_g|."""
    u, tau = 0.05, 2.0e-3
    zs = (0.1, 0.5, 1.5) if update == "explicit" else (0.1, 3.0, 30.0)
    if integrator == "midpoint" and update == "explicit":
        zs = (0.1, 0.5, 1.9)
    for z in zs:
        dt, C = z * tau, 1.0 / tau
        v, loop = 0.0, [0.0]
        for _ in range(60):
            if integrator == "paper":
                a = C * (u - v)
                v = v + dt * (a / (1.0 + dt * C) if update == "implicit" else a)
            elif update == "explicit":
                vs = v + 0.5 * dt * C * (u - v)
                v = v + dt * C * (u - vs)
            else:
                vs = v + 0.5 * dt * C * (u - v) / (1.0 + 0.5 * dt * C)
                v = v + dt * (C * (u - vs) + C * (vs - v)) / (1.0 + 0.5 * dt * C)
            loop.append(v)
        closed = gr.relaxation_discrete(np.arange(61), dt, u, tau, integrator, update)
        np.testing.assert_allclose(closed, loop, rtol=0, atol=1e-12 * u)
        th = 0.3
        tau_w = gr.stokes_stream_time(th, WATER)
        steps = gr.relaxation_steps(60, z * tau_w, u, th, WATER, integrator, update)
        np.testing.assert_allclose(steps, gr.relaxation_discrete(np.arange(61), z * tau_w, u, tau_w, integrator,
                                                                 update), rtol=0, atol=1e-12 * u)


@pytest.mark.parametrize("integrator, update", SCHEMES)
def test_discrete_relaxation_converges_at_the_schemes_order(integrator, update):
    """The discrete solution at t = tau tends to the exact one as dt^1 (paper) or dt^2 (midpoint):
    the error ratio from dt = tau/100 to tau/200 is 2 or 4 to 2%."""
    u, tau = 1.0, 1.0
    err = [abs(gr.relaxation_discrete(n, tau / n, u, tau, integrator, update) - gr.relaxation_velocity(tau, u, tau))
           for n in (100, 200)]
    order = math.log2(err[0] / err[1])
    assert order == pytest.approx(1.0 if integrator == "paper" else 2.0, abs=0.02)


@pytest.mark.parametrize("model", ["wen_yu", "gidaspow"])
def test_slip_dependent_relaxation_against_quadrature(model):
    """The ODE rho_s theta0 eps0 dv/dt = beta(theta0, U - v)(U - v) solved for v(t) (solve_ivp) against t(v) =
    int_0^v dv' / rhs(v') (quad), v/U from 0.1 to 0.999, a 2-D stream U = |u_g| = 2.06 m/s in air (Re to 37;
    theta0 = 0.1 for Wen & Yu, 0.3 for Gidaspow's blend): to 1e-9 U, the velocity parallel to u_g. beta is
    1.1 to 2.8x Stokes's over the run (Gidaspow's 1.4 to 2.9x), so the reference is far from the Stokes one:
    Stokes's drag has reached 0.33 U where these reach 0.6 U."""
    ph, th = AIR[model], (0.1 if model == "wen_yu" else 0.3)
    u = np.array([2.0, 0.5])
    U = float(np.hypot(*u))

    def rhs(v):
        return beta(ph, th, U - v) * (U - v) / (ph.rho_s * th * (1.0 - th))

    fracs = np.array([0.1, 0.3, 0.6, 0.9, 0.99, 0.999])
    t = np.array([quad(lambda v: 1.0 / rhs(v), 0.0, f * U, epsabs=0.0, epsrel=1e-13, limit=200)[0] for f in fracs])
    v = gr.relaxation_ode(t, u, th, ph)
    np.testing.assert_allclose(v, np.multiply.outer(fracs, u), rtol=0, atol=1e-9 * U)
    stokes = gr.relaxation_velocity(t[2], u, gr.stokes_stream_time(th, ph))
    assert np.hypot(*stokes) < 0.5 * U        # Stokes's drag would have reached less than 0.5 U, not 0.6 U


@pytest.mark.parametrize("integrator, update", SCHEMES)
def test_wen_yu_recursion_converges_to_the_ode(integrator, update):
    """relaxation_steps (beta frozen over each stage) with Wen & Yu tends to relaxation_ode at T = tau_Stokes
    (1.4 relaxation times of the slip-dependent drag) as dt^1 (paper) or dt^2 (midpoint): ratio 2 or 4 to 5%."""
    ph, th, u = AIR["wen_yu"], 0.1, 2.0
    T = gr.stokes_stream_time(th, ph)
    ref = gr.relaxation_ode(T, u, th, ph)
    err = [abs(gr.relaxation_steps(n, T / n, u, th, ph, integrator, update)[-1] - ref) for n in (100, 200)]
    order = math.log2(err[0] / err[1])
    assert order == pytest.approx(1.0 if integrator == "paper" else 2.0, abs=0.05)


# ---- reference 2: hindered settling ------------------------------------------------------------------------
def test_hindered_settling_stokes_root_is_richardson_zaki():
    """The root of beta(theta0, |v|/eps0) |v| = theta0 eps0^2 (rho_s - rho_g)|g| with Stokes drag against
    -u_t eps0^4.65, theta0 = 0.01 to 0.9: to 1e-12."""
    for th in (0.01, 0.05, 0.2, 0.4, 0.6, 0.9):
        v = gr.hindered_settling_velocity(th, WATER)
        assert v < 0
        assert v == pytest.approx(gr.richardson_zaki_velocity(th, WATER), rel=1e-12)
        assert v == pytest.approx(-0.073575 * (1.0 - th) ** 4.65, rel=1e-12)


@pytest.mark.parametrize("model", ["wen_yu", "gidaspow"])
def test_hindered_settling_balances_drag_and_weight(model):
    """Air, the slip-dependent closures: the root's drag beta |v| / eps0 carries the buoyant weight theta0 eps0
    (rho_s - rho_g)|g| (drag.beta evaluated here) to 1e-12, and is 2.6x (theta0 = 0.05) to 1.1x (0.6) slower
    than Stokes's."""
    ph = AIR[model]
    for th in (0.05, 0.2, 0.4, 0.6):
        s = -gr.hindered_settling_velocity(th, ph)
        eps = 1.0 - th
        weight = th * eps * eps * (ph.rho_s - ph.rho_g) * ph.g
        assert beta(ph, th, s / eps) * s == pytest.approx(weight, rel=1e-12)
        assert s < 0.9 * abs(gr.richardson_zaki_velocity(th, ph))


@pytest.mark.parametrize("ph", [WATER, AIR["wen_yu"], AIR["gidaspow"]], ids=["stokes", "wen_yu", "gidaspow"])
def test_settling_relaxation_time(ph):
    """tau along the column: the steady state has |v| = tau (1 - rho_g/rho_s) |g| (drag/mass = C |v| with
    C = 1/tau), to 1e-12; for Stokes tau = rho_s d^2 eps0^4.65 / (18 mu_g) (docs/physics.md ref. 2)."""
    for th in (0.05, 0.2, 0.4):
        tau = gr.settling_relaxation_time(th, ph)
        v = gr.hindered_settling_velocity(th, ph)
        assert abs(v) == pytest.approx(tau * (1.0 - ph.rho_g / ph.rho_s) * ph.g, rel=1e-12)
        if ph.model == "stokes":
            assert tau == pytest.approx(ph.rho_s * ph.d ** 2 * (1.0 - th) ** 4.65 / (18.0 * ph.mu_g), rel=1e-12)


# ---- reference 3: bed expansion ---------------------------------------------------------------------------
def test_uniform_bed_stokes_root_is_richardson_zaki():
    """theta* with Stokes drag against 1 - (U/u_t)^(1/4.65), U/u_t = 0.01 to 0.9: to 1e-12."""
    for r in (0.01, 0.2, 0.5, 0.9):
        U = r * WATER.u_t
        assert bed_expansion.uniform_bed_fraction(U, WATER) == pytest.approx(1.0 - r ** (1.0 / 4.65), rel=1e-12)
        assert bed_expansion.richardson_zaki_fraction(U, WATER) == pytest.approx(1.0 - r ** (1.0 / 4.65), rel=1e-14)
    with pytest.raises(ValueError):
        bed_expansion.uniform_bed_fraction(1.01 * WATER.u_t, WATER)


@pytest.mark.parametrize("model", ["wen_yu", "gidaspow"])
def test_uniform_bed_balances_drag_and_weight(model):
    """Air at U = 0.3, 0.6, 1.0 m/s: beta(theta*, U/eps*) U = theta* eps*^2 (rho_s - rho_g)|g| to 1e-12, and
    f = dp_s/dx < 0 just below theta* (the smallest root: the profile from the top climbs to it)."""
    ph = AIR[model]
    for U in (0.3, 0.6, 1.0):
        th = bed_expansion.uniform_bed_fraction(U, ph)
        eps = 1.0 - th
        assert beta(ph, th, U / eps) * U == pytest.approx(th * eps * eps * (ph.rho_s - ph.rho_g) * ph.g, rel=1e-12)
        assert all(bed_expansion.column_rhs(t, U, ph) < 0 for t in np.linspace(1e-6, th * (1 - 1e-6), 50))


def test_minimum_fluidization_from_ergun():
    """U_mf of Table 1's grains in air at theta_mf = 0.6, 0.55: against the textbook Ergun equation
    dp/L = 150 mu U (1-eps)^2/(eps^3 d^2) + 1.75 rho_g U^2 (1-eps)/(eps^3 d) = (1-eps)(rho_s - rho_g) g solved
    here (brentq) to 1e-12 (6.79 cm/s at 0.6); the blended Gidaspow closure's balance is within 2e-4 of it
    (its Wen & Yu share phi(0.4) = 0.3%)."""
    ph = AIR["gidaspow"]
    for th in (0.6, 0.55):
        eps = 1.0 - th

        def ergun(U):
            return (150.0 * ph.mu_g * U * th ** 2 / (eps ** 3 * ph.d ** 2) + 1.75 * ph.rho_g * U * U * th
                    / (eps ** 3 * ph.d) - th * (ph.rho_s - ph.rho_g) * ph.g)
        ref = brentq(ergun, 1e-6, 10.0, xtol=1e-16, rtol=1e-15)
        U_mf = bed_expansion.minimum_fluidization_velocity(th, ph)
        assert U_mf == pytest.approx(ref, rel=1e-12)
        blended = bed_expansion.fluidization_velocity(th, ph)
        assert 1e-6 < abs(blended / U_mf - 1.0) < 2e-4
    assert bed_expansion.minimum_fluidization_velocity(0.6, ph) == pytest.approx(0.067924, rel=1e-4)


@pytest.mark.parametrize("form", limits.FORMS)
def test_compression_length_stokes(form):
    """l = p_s'(theta*) / f'(theta*) against the Stokes closed form f'(theta*) = 4.65 theta* (rho_s - rho_g)|g|
    / eps* (f = theta (rho_s - rho_g)|g| (U / (u_t eps^4.65) - 1)): to 1e-8 (a central difference; 8e-10
    reached), l from 0.06 to 85 mm."""
    for U in (0.005, 0.02, 0.05):
        th = bed_expansion.richardson_zaki_fraction(U, WATER)
        ref = limits.dpressure(th, G_A, G_B, form) * (1.0 - th) / (4.65 * th * WATER.buoyant)
        assert bed_expansion.compression_length(U, WATER, form=form) == pytest.approx(ref, rel=1e-8)


CASES = [(WATER, 0.02, "consistent"), (WATER, 0.02, "paper"), (AIR["wen_yu"], 0.6, "consistent"),
         (AIR["gidaspow"], 0.3, "paper")]
IDS = ["water-consistent", "water-paper", "air-wen_yu", "air-gidaspow"]


@pytest.mark.parametrize("ph, U, form", CASES, ids=IDS)
def test_tall_bed_holds_its_mass_and_its_interior_is_theta_star(ph, U, form):
    """A bed 60 compression lengths tall: the profile's int rho_s theta dx (Gauss-Legendre on the solution plus
    its tail) is the given mass to 1e-11 (2e-13 reached); the floor is theta* to 1e-10 (7e-12); theta* - theta
    grows upward as exp(x / l) between 1e-7 and 1e-4 theta* (the slope of its log to 5e-4: 9e-5 reached, the
    nonlinearity at 1e-4); theta falls monotonically upward
    (to 1e-11 at the floor, where it has reached theta*: the solver's jitter is 1e-12)."""
    th_s = bed_expansion.uniform_bed_fraction(U, ph)
    ell = bed_expansion.compression_length(U, ph, form=form)
    mass = ph.rho_s * th_s * 60.0 * ell
    col = bed_expansion.steady_column(mass, U, ph, form=form)
    assert ph.rho_s * profile_integral(col) == pytest.approx(mass, rel=1e-11)
    assert col.theta_floor == pytest.approx(th_s, abs=1e-10)
    assert np.all(np.diff(col.theta) < 1e-10 * th_s)
    x1, x2 = col.height_of(th_s * (1 - 1e-7)), col.height_of(th_s * (1 - 1e-4))
    assert math.log(1e3) / (x2 - x1) == pytest.approx(1.0 / ell, rel=5e-4)


@pytest.mark.parametrize("ph, U, form", CASES, ids=IDS)
def test_short_bed_against_the_quadrature_in_theta(ph, U, form):
    """A bed two compression lengths tall (floor well below theta*): with dx = p_s' dtheta / f, the heights
    x(theta) = int_theta^theta_floor p_s' / (-f) dtheta and the mass rho_s int_0^theta_floor theta p_s' / (-f)
    dtheta (quad) against the top-down integration: to 1e-10 (heights of levels 0.9 to 0.01 theta_floor; 9e-12
    reached) and 1e-10 (mass; 6e-12)."""
    th_s = bed_expansion.uniform_bed_fraction(U, ph)
    mass = ph.rho_s * th_s * 2.0 * bed_expansion.compression_length(U, ph, form=form)
    col = bed_expansion.steady_column(mass, U, ph, form=form)
    assert col.theta_floor < 0.99 * th_s

    def dx(t):
        return limits.dpressure(t, G_A, G_B, form) / -bed_expansion.column_rhs(t, U, ph)

    tb = col.theta_floor
    m = ph.rho_s * quad(lambda t: t * dx(t), 0.0, tb, epsabs=0.0, epsrel=1e-12, limit=200)[0]
    assert m == pytest.approx(mass, rel=1e-10)
    for f in (0.9, 0.5, 0.1, 0.01):
        x = quad(dx, f * tb, tb, epsabs=0.0, epsrel=1e-12, limit=200)[0]
        assert col.height_of(f * tb) == pytest.approx(x, rel=1e-10)


@pytest.mark.parametrize("ph, U, form", CASES, ids=IDS)
def test_column_mass_quantiles_against_the_integral(ph, U, form):
    """Column.quantiles (where the top-down integration leaves 1 - q of the mass above) against the profile's
    own integral from the floor up: int_0^x theta dx (Gauss-Legendre on theta_at) = q int_0^inf theta dx at
    the returned heights, to 1e-9 of the mass."""
    th_s = bed_expansion.uniform_bed_fraction(U, ph)
    col = bed_expansion.steady_column(ph.rho_s * th_s * 3.0 * bed_expansion.compression_length(U, ph, form=form), U, ph, form=form)
    fractions = (0.05, 0.25, 0.5, 0.75, 0.95)
    total = profile_integral(col)
    nodes, weights = np.polynomial.legendre.leggauss(40)
    for q, x in zip(fractions, col.quantiles(fractions)):
        edges = np.linspace(0.0, x, 41)
        a, b = edges[:-1, None], edges[1:, None]
        xs = 0.5 * (b - a) * nodes[None, :] + 0.5 * (a + b)
        below = float(np.sum(0.5 * (b - a) * weights[None, :] * col.theta_at(xs.ravel()).reshape(xs.shape)))
        assert below == pytest.approx(q * total, rel=1e-9)
    with pytest.raises(ValueError):
        col.quantiles([1.0])


@pytest.mark.parametrize("ph, U, form", CASES, ids=IDS)
def test_column_pressure_balance_by_finite_differences(ph, U, form):
    """(p_s(theta(x + h)) - p_s(theta(x - h))) / 2h = f(theta(x)) at five heights from 1e-3 of the bed to its
    theta_floor/10 level, h = 1e-4 of the local length (:func:`balance_error`): to 1e-7 of the buoyant weight
    theta (rho_s - rho_g)|g| (5e-9 reached; f itself is from 0 to 0.9 of it)."""
    th_s = bed_expansion.uniform_bed_fraction(U, ph)
    ell = bed_expansion.compression_length(U, ph, form=form)
    col = bed_expansion.steady_column(ph.rho_s * th_s * 5.0 * ell, U, ph, form=form)
    top = col.height_of(0.1 * col.theta_floor)
    for x in np.linspace(1e-3 * top, top, 5):
        err, th = balance_error(col, x, U, ph, form, ell)
        assert abs(err) < 1e-7 * th * ph.buoyant


# ---- reference 4: batch sedimentation ---------------------------------------------------------------------
@pytest.mark.parametrize("form", limits.FORMS)
def test_final_sediment(form):
    """Glass in water, theta0 = 0.1, H0 = 2 cm settled: the floor value from the hydrostatic identity
    p_s(theta_b) = p_s(0) + (rho_s - rho_g)|g| M / rho_s (solved here) to 1e-12 (8e-15 reached); the mass to
    1e-11 (5e-14); the balance dp_s/dx = -(rho_s - rho_g) theta |g| by finite differences to 1e-7 of it (5e-9;
    up to the theta_b/100 level);
    and below a lid at the level
    theta_b/2, analytic.settling_equilibrium (the walled column, shot from the floor by RK4 and bisection on its
    mass by the trapezoidal rule) with the mass below the lid (the hydrostatic identity): within 1e-4 with 400
    steps, the difference falling 4x from 200 (its trapezoidal mass is second order: it converges to this one)."""
    ph, mass = WATER, WATER.rho_s * 0.1 * 0.02
    col = kynch.final_sediment(mass, ph, form=form)
    target = limits.pressure(0.0, G_A, G_B, form) + ph.buoyant * mass / ph.rho_s
    tb = brentq(lambda t: limits.pressure(t, G_A, G_B, form) - target, 0.0, 1.0, xtol=1e-16, rtol=1e-15)
    if form == "consistent":
        assert tb == pytest.approx((math.log10(target * G_A * LN10) - G_B) / G_A, rel=1e-13)
    assert col.theta_floor == pytest.approx(tb, abs=1e-12)
    assert ph.rho_s * profile_integral(col) == pytest.approx(mass, rel=1e-11)
    top = col.height_of(0.01 * tb)
    for x in np.linspace(1e-3 * top, top, 6):
        err, th = balance_error(col, x, 0.0, ph, form, top)
        assert abs(err) < 1e-7 * th * ph.buoyant
    lid = col.height_of(tb / 2)
    below = mass / ph.rho_s - (limits.pressure(tb / 2, G_A, G_B, form)
                               - limits.pressure(0.0, G_A, G_B, form)) / ph.buoyant
    x = np.linspace(0.0, lid, 9)
    ours = col.theta_at(x)
    err = [np.max(np.abs(settling_equilibrium(x, below / lid, lid, ph.rho_s, ph.g * (1 - ph.rho_g / ph.rho_s),
                                              G_A, G_B, steps=n, form="paper" if form == "paper" else "closure")
                         / ours - 1.0)) for n in (200, 400)]
    assert err[1] < 1e-4
    assert err[0] / err[1] == pytest.approx(4.0, rel=0.1)


@pytest.mark.parametrize("theta0", [0.1, 0.15, 0.2])
def test_kynch_interface_speed_is_the_flux_chord(theta0):
    """MFiX PIC04's layers (H0 = 2 cm): the interface line's slope against the chord (F(theta0) - F(0)) /
    theta0 of the Stokes flux F = -u_t theta (1 - theta)^4.65 written out here, to 1e-12; with Wen & Yu in air
    the slope's drag carries the weight (drag.beta) to 1e-12."""
    s = kynch.batch_sedimentation(theta0, 0.02, WATER)
    t = 0.5 * s.meeting_time
    slope = (s.interface(t) - s.interface(0.0)) / t
    assert slope == pytest.approx((rz_flux(theta0, WATER) - 0.0) / theta0, rel=1e-12)
    a = AIR["wen_yu"]
    sa = kynch.batch_sedimentation(theta0, 0.02, a)
    speed = -(sa.interface(0.5 * sa.meeting_time) - sa.H0) / (0.5 * sa.meeting_time)
    eps = 1.0 - theta0
    assert beta(a, theta0, speed / eps) * speed == pytest.approx(theta0 * eps ** 2 * a.buoyant, rel=1e-12)


@pytest.mark.parametrize("form", limits.FORMS)
@pytest.mark.parametrize("theta0", [0.1, 0.2])
def test_kynch_sediment_front_and_meeting(form, theta0):
    """The sediment front's speed is the chord from (theta0, F(theta0)) to (theta_packed, 0) (F written out);
    the two lines meet at (t_m, h_m) with theta_packed h_m = theta0 H0 (to 1e-12); and the default theta_packed
    is the mean of the hydrostatic sediment whose top is at theta0 and which holds the layer, derived here in
    theta: its floor from p_s(theta_b) = p_s(theta0) + (rho_s - rho_g)|g| theta0 H0, its height int_theta0^theta_b
    p_s' / ((rho_s - rho_g)|g| theta) dtheta: to 1e-10 (2e-13 reached; theta_packed = 0.305 and 0.339 for the
    paper form, 0.394 and 0.431 for the consistent one, at theta0 = 0.1 and 0.2). Both lines are nan after t_m."""
    H0 = 0.02
    s = kynch.batch_sedimentation(theta0, H0, WATER, form=form)
    chord = (0.0 - rz_flux(theta0, WATER)) / (s.theta_packed - theta0)
    assert s.front_speed == pytest.approx(chord, rel=1e-12)
    tm = s.meeting_time
    assert s.interface(tm) == pytest.approx(s.meeting_height, rel=1e-12)
    assert s.sediment_front(tm) == pytest.approx(s.meeting_height, rel=1e-12)
    assert s.theta_packed * s.meeting_height == pytest.approx(theta0 * H0, rel=1e-12)
    assert np.isnan(s.interface(1.001 * tm)) and np.isnan(s.sediment_front(1.001 * tm))
    target = limits.pressure(theta0, G_A, G_B, form) + WATER.buoyant * theta0 * H0
    tb = brentq(lambda t: limits.pressure(t, G_A, G_B, form) - target, theta0, 1.0, xtol=1e-16, rtol=1e-15)
    h_m = quad(lambda t: limits.dpressure(t, G_A, G_B, form) / (WATER.buoyant * t), theta0, tb,
               epsabs=0.0, epsrel=1e-13)[0]
    assert s.meeting_height == pytest.approx(h_m, rel=1e-10)
    assert s.theta_packed == pytest.approx(theta0 * H0 / h_m, rel=1e-10)
    # a given packing: the kinematic answer, t_m = H0 (theta_p - theta0) / (theta_p |v0|)
    k = kynch.batch_sedimentation(theta0, H0, WATER, form=form, theta_packed=0.6)
    assert k.meeting_time == pytest.approx(H0 * (0.6 - theta0) / (0.6 * -rz_flux(theta0, WATER) / theta0), rel=1e-12)


def test_bad_input():
    with pytest.raises(ValueError):
        gr.hindered_settling_velocity(0.0, WATER)
    with pytest.raises(ValueError):
        gr.hindered_settling_velocity(1.0, WATER)
    with pytest.raises(ValueError):
        bed_expansion.steady_column(-1.0, 0.0, WATER)
    with pytest.raises(ValueError):
        bed_expansion.steady_column(1.0, 0.0, WATER, form="closure")
    with pytest.raises(ValueError):
        gr.relaxation_factor(0.1, "rk4")
    with pytest.raises(ValueError):
        gr.Phases(2500.0, 1000.0, 1e-3, 3e-4, 9.81, "ergun").beta(0.1, 0.1)
    with pytest.raises(ValueError):
        kynch.batch_sedimentation(0.1, 0.02, WATER, theta_packed=0.05)
