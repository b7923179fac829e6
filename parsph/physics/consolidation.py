"""A layer's whole transient in the column closure, inertia dropped: the 1-D sedimentation-consolidation
equation (Buerger & Concha 1998; docs/physics.md, "The solid phase in a gas", references 3 and 4), solved to
convergence by the method of lines.

**The equation**, from the model of docs/physics.md (x up from the floor, g = |g|, Delta = rho_s - rho_g,
eps = 1 - theta). Dropping the solids' inertia, the solids' momentum balance per unit volume with the gas
pressure eliminated (docs/physics.md's per-particle force times rho_s theta) is

    0 = beta (u_g - v) / eps - dp_s/dx - theta Delta g,

and the column closure u_g = (U - theta v) / eps makes the slip u_g - v = (U - v) / eps. So the velocity
w = U - v of the gas through the solids (the superficial slip) solves

    beta(theta, |w| / eps) w = eps^2 (theta Delta g + dp_s/dx),      dp_s/dx = p_s'(theta) dtheta/dx,

with p_s of the pressure form in use (:func:`parsph.physics.limits.dpressure`: "consistent" p_s' = G(theta),
"paper" p_s' = G (1 + G_a ln10 theta)). beta w rises monotonically with w (no closure's beta falls with the
slip), so w is one root. The solids' flux is F = theta v = theta U - W with W = theta w, and mass balance is

    theta_t + F_x = 0,    F = theta U - W(theta, theta_x),    F = 0 at the floor and at the lid.

For the Stokes closure (beta = 18 mu_g theta eps^-2.65 / d^2) W is explicit:

    W = u_t eps^4.65 (theta + p_s'(theta) theta_x / (Delta g)),      u_t = Delta g d^2 / (18 mu_g),

i.e. F = f(theta) - D(theta) theta_x with Kynch's flux f = theta (U - u_t eps^4.65) and the diffusivity
D = u_t eps^4.65 p_s'(theta) / (Delta g): Buerger & Concha's equation with f_bk = -u_t theta eps^4.65 and
sigma_e' = p_s'. p_s' > 0 at every theta (G(0) = 10^G_b), so D > 0 everywhere: the equation is uniformly
parabolic (not degenerate, unlike an effective stress that vanishes below a critical concentration), its
solution smooth, and a finite-volume solution converges to it. Its limits: where D is small against f' H0,
Kynch's kinematic solution (the top falls at u_t (1 - theta0)^4.65, reference 4); at rest (F = 0), the steady
column of :func:`parsph.physics.bed_expansion.steady_column` (the final sediment for U = 0, the bed for U > 0),
which is what the transient tends to. What it leaves out: the solids' inertia (a lag of about v0 tau, tau the
drag's relaxation time: docs/validation.md, "The interface's offset") and the viscous stress (zero in a flow
that is uniform across the column).

**The discretisation**: N cells of width dx on [0, L] (floor to lid), theta the cells' averages; the flux at an
interior face between cells a (below) and b (above) is

    F = EO(a, b) - [W(theta_f, (b - a)/dx) - W(theta_f, 0)],      theta_f = (a + b) / 2,

with EO the Engquist-Osher flux of the kinematic part f(theta) = theta U - W(theta, 0) (upwind, monotone,
smooth; f has one minimum on (0, 1), at theta_m, found once) and the bracket the gradient's part, central
(for Stokes exactly -D(theta_f) (b - a)/dx). Zero flux on the two boundary faces: the mass sum(theta) dx is
conserved to the solver's tolerance. In time: scipy.integrate.solve_ivp, BDF (implicit: the diffusion is
stiff), with the tridiagonal Jacobian (each face's derivatives by differences of that face alone). Closures
other than Stokes solve W by Newton per face (numba), from the neighbouring cells' roots.

**Accuracy**: first order in dx (the upwind flux), tested on grids of 1x, 2x, 4x (tests/test_consolidation.py).
The default grid, cells of H0 / 400, puts the heights of the mass fractions within 0.03-0.06% of H0 of the
converged ones in the shipped layers (halving the cells moves them by that much), and the time integration
(rtol 1e-4) within 1e-5 H0: 1-3 s a layer.

The outputs are the profile at given times, and the heights below which given fractions of the layer's mass
lie (:meth:`Transient.quantiles`): what a layer's SPH run is checked against
(:mod:`parsph.cli.layer_report`).
"""
import math
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar
from scipy.sparse import diags

from . import drag, limits
from .closures import LN10

FRACTIONS = (0.05, 0.25, 0.5, 0.75, 0.95)   # the mass fractions a layer is measured by
TINY = 1e-250                                # below it theta counts as clear gas (no flux)
THETA_MAX = 0.99                             # theta is clipped to [0, THETA_MAX] inside the fluxes
CELLS_PER_H0 = 400                           # the default grid: cells of H0 / 400


@njit(cache=True, error_model="numpy")
def _dpressure(theta, G_a, G_b, paper):
    """p_s'(theta) [Pa] of the pressure form (paper: G (1 + G_a ln10 theta); consistent: G)."""
    G = math.exp((G_a * theta + G_b) * LN10)
    return G * (1.0 + G_a * LN10 * theta) if paper else G


@njit(cache=True, error_model="numpy")
def _drag_per_theta(model, theta, W, rho_g, mu_g, d):
    """beta / theta [kg/(m^3 s)] at the slip |u_g - v| = |W| / (theta eps) (W = theta w, w = U - v)."""
    eps = 1.0 - theta
    slip = abs(W) / (theta * eps)
    return eps * drag.rate(model, theta, slip * slip, 1.0, rho_g, mu_g, d)


@njit(cache=True, error_model="numpy")
def _superficial_flux(model, theta, R, rho_g, mu_g, d, guess):
    """W = theta w [m/s] with (beta(theta, |w|/eps) / theta) W = R (R = eps^2 (theta Delta g + dp_s/dx)):
    the solids' flux relative to the gas's superficial velocity U, down positive. Stokes: explicit;
    otherwise Newton on the monotone g(W) = (beta/theta)(W) W - R from ``guess`` (nan: the Stokes root),
    kept inside the bracket [0, the Stokes root] (bisection where a step leaves it), to 1e-14 relative."""
    if not theta > TINY or R == 0.0:
        return 0.0
    b0 = _drag_per_theta(drag.STOKES, theta, 0.0, rho_g, mu_g, d)
    W = R / b0
    if model == drag.STOKES:
        return W
    # beta grows with the slip: |W| <= |R| / b0, and the root has R's sign
    lo, hi = (0.0, W) if W > 0.0 else (W, 0.0)
    if lo < guess < hi:
        W = guess
    for _ in range(200):
        b = _drag_per_theta(model, theta, W, rho_g, mu_g, d)
        g = b * W - R
        if g == 0.0:
            return W
        if g > 0.0:
            hi = W
        else:
            lo = W
        h = 1e-7 * abs(W) + TINY
        dg = (_drag_per_theta(model, theta, W + h, rho_g, mu_g, d) * (W + h) - g - R) / h
        step = W - g / dg if dg > 0.0 else 0.5 * (lo + hi)
        if not lo < step < hi:
            step = 0.5 * (lo + hi)
        if abs(step - W) <= 1e-14 * abs(W) or hi - lo <= 1e-14 * abs(W):
            return step
        W = step
    return W


@njit(cache=True, error_model="numpy")
def _clip(theta):
    return min(max(theta, 0.0), THETA_MAX)


@njit(cache=True, error_model="numpy")
def _kinematic(model, theta, U, buoyant, rho_g, mu_g, d, guess):
    """(Kynch's flux f(theta) = theta U - W(theta, 0) [m/s], W(theta, 0)): no gradient, drag and weight
    balanced; theta clipped to [0, THETA_MAX]."""
    th = _clip(theta)
    eps = 1.0 - th
    W = _superficial_flux(model, th, eps * eps * th * buoyant, rho_g, mu_g, d, guess)
    return th * U - W, W


@njit(cache=True, error_model="numpy")
def _gradient_part(a, b, dx, model, buoyant, rho_g, mu_g, d, G_a, G_b, paper, guess):
    """A face's flux less its Engquist-Osher part: -[W(theta_f, dtheta/dx) - W(theta_f, 0)], theta_f the
    mean of the cells a (below) and b (above); ``guess`` W(theta_f, 0)'s estimate (nan: none)."""
    a, b = _clip(a), _clip(b)
    tf = 0.5 * (a + b)
    if not tf > TINY or b == a:
        return 0.0
    ef = 1.0 - tf
    R0 = ef * ef * tf * buoyant
    R = R0 + ef * ef * _dpressure(tf, G_a, G_b, paper) * (b - a) / dx
    W0 = _superficial_flux(model, tf, R0, rho_g, mu_g, d, guess)
    return -(_superficial_flux(model, tf, R, rho_g, mu_g, d, W0 * (R / R0)) - W0)


@njit(cache=True, error_model="numpy")
def _cell_fluxes(theta, U, model, buoyant, rho_g, mu_g, d, theta_m, f_m):
    """Per cell: the Engquist-Osher parts f(max(theta, theta_m)) (a face's lower cell) and
    f(min(theta, theta_m)) (its upper cell), and W(theta, 0) (the faces' guesses). Each root starts from
    the cell below's slip w = W / theta."""
    n = theta.size
    up, down, Wk = np.empty(n), np.empty(n), np.empty(n)
    w = np.nan
    for i in range(n):
        th = _clip(theta[i])
        f, W = _kinematic(model, th, U, buoyant, rho_g, mu_g, d, w * th)
        if th > 0.0:
            w = W / th
        Wk[i] = W
        up[i] = f if th > theta_m else f_m
        down[i] = f if th < theta_m else f_m
    return up, down, Wk


@njit(cache=True, error_model="numpy")
def _rhs(theta, dx, U, model, buoyant, rho_g, mu_g, d, G_a, G_b, paper, theta_m, f_m):
    """dtheta/dt = -(F_{i+1/2} - F_{i-1/2}) / dx over the cells, F = 0 on the floor's and the lid's faces,
    F = EO + the gradient's part (the module's docstring)."""
    n = theta.size
    up, down, Wk = _cell_fluxes(theta, U, model, buoyant, rho_g, mu_g, d, theta_m, f_m)
    out = np.empty(n)
    prev = 0.0
    for i in range(n - 1):
        F = up[i] + down[i + 1] - f_m + _gradient_part(theta[i], theta[i + 1], dx, model, buoyant, rho_g, mu_g, d,
                                                        G_a, G_b, paper, 0.5 * (Wk[i] + Wk[i + 1]))
        out[i] = (prev - F) / dx
        prev = F
    out[n - 1] = prev / dx
    return out


@njit(cache=True, error_model="numpy")
def _jacobian(theta, dx, U, model, buoyant, rho_g, mu_g, d, G_a, G_b, paper, theta_m, f_m):
    """The rhs's tridiagonal Jacobian as (below, diagonal, above): each face's dF/da and dF/db by one-sided
    differences (step 1e-7 (theta + 1e-3)) of its own parts."""
    n = theta.size
    up, down, Wk = _cell_fluxes(theta, U, model, buoyant, rho_g, mu_g, d, theta_m, f_m)
    hs = 1e-7 * (np.abs(theta) + 1e-3)
    up2, down2, _ = _cell_fluxes(theta + hs, U, model, buoyant, rho_g, mu_g, d, theta_m, f_m)
    lower, diag, upper = np.zeros(n - 1), np.zeros(n), np.zeros(n - 1)
    for i in range(n - 1):
        a, b = theta[i], theta[i + 1]
        ha, hb = hs[i], hs[i + 1]
        guess = 0.5 * (Wk[i] + Wk[i + 1])
        G = _gradient_part(a, b, dx, model, buoyant, rho_g, mu_g, d, G_a, G_b, paper, guess)
        dFa = (up2[i] - up[i]) / ha \
            + (_gradient_part(a + ha, b, dx, model, buoyant, rho_g, mu_g, d, G_a, G_b, paper, guess) - G) / ha
        dFb = (down2[i + 1] - down[i + 1]) / hb \
            + (_gradient_part(a, b + hb, dx, model, buoyant, rho_g, mu_g, d, G_a, G_b, paper, guess) - G) / hb
        # dtheta_i/dt = -F/dx + ...;  dtheta_{i+1}/dt = +F/dx + ...
        diag[i] -= dFa / dx
        upper[i] = -dFb / dx
        lower[i] = dFa / dx
        diag[i + 1] += dFb / dx
    return lower, diag, upper


class Transient:
    """A layer's transient (:func:`solve`): cell averages ``theta[k]`` (shape (times, cells)) at ``times``,
    on ``cells`` cells of width ``dx`` over [0, ``top``]; ``mass`` = int theta dx [m] (per unit rho_s)."""

    def __init__(self, times, theta, dx, theta0, H0, U, rhs_calls):
        self.times = np.asarray(times, dtype=float)
        self.theta = np.asarray(theta, dtype=float)
        self.dx, self.theta0, self.H0, self.U, self.rhs_calls = dx, theta0, H0, U, rhs_calls
        self.cells = self.theta.shape[1]
        self.top = self.cells * dx
        self.centres = (np.arange(self.cells) + 0.5) * dx
        self.mass = theta0 * H0

    def _index(self, t):
        k = int(np.argmin(np.abs(self.times - t)))
        if not abs(self.times[k] - t) <= 1e-9 * max(1.0, abs(t)):
            raise ValueError(f"t = {t!r} is not one of the solved times")
        return k

    def profile(self, t):
        """The cells' theta at the solved time ``t``."""
        return self.theta[self._index(t)]

    def theta_at(self, t, x):
        """theta at heights ``x`` [m] at the solved time ``t``: linear between the cells' centres (the floor's
        and the lid's cells flat to the wall)."""
        return np.interp(np.asarray(x, dtype=float), self.centres, self.profile(t))

    def quantiles(self, t, fractions=FRACTIONS):
        """The heights [m] below which each of ``fractions`` of the layer's mass lies at the solved time ``t``:
        the inverse of the cumulative int_0^x theta dx, exact for theta constant over each cell."""
        th = np.maximum(self.profile(t), 0.0)
        cum = np.concatenate([[0.0], np.cumsum(th) * self.dx])
        edges = np.arange(self.cells + 1) * self.dx
        return np.interp(np.asarray(fractions, dtype=float) * cum[-1], cum, edges)

    def level_height(self, t, level):
        """The highest height [m] where the profile at the solved time ``t`` (linear between the cells'
        centres) falls through ``level`` going up; nan where it never reaches it."""
        th = self.profile(t)
        above = np.flatnonzero(th >= level)
        if above.size == 0:
            return math.nan
        i = above[-1]
        if i == self.cells - 1:
            return self.centres[i]
        a, b = th[i], th[i + 1]
        return self.centres[i] + self.dx * (a - level) / (a - b)


class _Closure(NamedTuple):
    model: int
    buoyant: float
    rho_g: float
    mu_g: float
    d: float

    def kinematic(self, theta, U):
        return _kinematic(self.model, float(theta), float(U), self.buoyant, self.rho_g, self.mu_g, self.d,
                          np.nan)[0]


def kinematic_minimum(ph, U=0.0):
    """(theta_m, f(theta_m)): where Kynch's flux f(theta) = theta (U - U_f(theta)) [m/s] has its minimum on
    (0, THETA_MAX) (Stokes, U = 0: theta_m = 1/5.65). ValueError where f has more than one local minimum
    there (the Engquist-Osher flux above assumes one)."""
    cl = _closure(ph)
    grid = np.linspace(0.0, THETA_MAX, 2001)
    f = np.array([cl.kinematic(t, U) for t in grid])
    k = int(np.argmin(f))
    falls = np.diff(f) < 0.0
    if np.any(falls[k:]) or not np.all(falls[:k]):
        raise ValueError("Kynch's flux has more than one minimum on (0, 0.99): not a single-hump flux")
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    if k == 0:
        return 0.0, 0.0
    r = minimize_scalar(lambda t: cl.kinematic(t, U), bounds=(lo, hi), method="bounded",
                        options={"xatol": 1e-12})
    return float(r.x), cl.kinematic(r.x, U)


def _closure(ph):
    return _Closure(ph.model_id, ph.buoyant, float(ph.rho_g), float(ph.mu_g), float(ph.d))


def default_cells(H0, L):
    """The default grid: cells of H0 / 400 over [0, L]. Its heights of the mass fractions are within
    0.03-0.06% of H0 of the converged ones in the shipped layers (first order: halving the cells halves the
    difference; tests/test_consolidation.py, docs/validation.md)."""
    return int(math.ceil(CELLS_PER_H0 * L / H0 - 1e-9))


def solve(theta0, H0, ph, times, L, U=0.0, G_a=8.76, G_b=-1.183, form="paper", cells=None, rtol=1e-4):
    """The transient of a layer theta0 of height H0 [m] on the floor, clear gas above up to a lid at L [m],
    gas fed through the floor at U [m/s] (0: a closed column), at ``times`` [s] (> 0); ``ph`` the phases
    (:class:`parsph.physics.gas_references.Phases`, its drag closure), p_s of ``form`` with
    G = 10^(G_a theta + G_b).

    ``cells`` finite volumes on [0, L] (default :func:`default_cells`; the initial step's cell averaged
    exactly), BDF to relative tolerance ``rtol`` and absolute rtol theta0 (the time error of the mass
    fractions' heights is then below 1e-5 H0, against 1e-3 H0 for the default grid). Returns a
    :class:`Transient`; RuntimeError where the integration fails."""
    if not 0.0 < theta0 < 1.0:
        raise ValueError(f"theta0 = {theta0!r} must lie in (0, 1)")
    if not 0.0 < H0 < L:
        raise ValueError("the layer must fit under the lid: 0 < H0 < L")
    if U < 0:
        raise ValueError("U must be >= 0")
    if form not in limits.FORMS:
        raise ValueError(f"pressure form {form!r}: one of {limits.FORMS}")
    times = np.asarray(sorted(set(float(t) for t in times)))
    if not times.size or times[0] <= 0.0:
        raise ValueError("times must be > 0")
    n = default_cells(H0, L) if cells is None else int(cells)
    if n < 3:
        raise ValueError("at least 3 cells")
    dx = L / n
    edges = np.arange(n + 1) * dx
    theta_init = theta0 * np.clip((H0 - edges[:-1]) / dx, 0.0, 1.0)
    cl = _closure(ph)
    theta_m, f_m = kinematic_minimum(ph, U)
    args = (dx, float(U), cl.model, cl.buoyant, cl.rho_g, cl.mu_g, cl.d, float(G_a), float(G_b), form == "paper",
            theta_m, f_m)

    def rhs(_, y):
        return _rhs(y, *args)

    def jac(_, y):
        lower, diag, upper = _jacobian(y, *args)
        return diags([lower, diag, upper], [-1, 0, 1], format="csc")

    # BDF's update of its difference table can subtract inf from inf after a rejected step (scipy's own
    # arithmetic, not the equation's; numpy warns): the accepted states are checked finite below instead
    with np.errstate(invalid="ignore", over="ignore"):
        sol = solve_ivp(rhs, (0.0, times[-1]), theta_init, method="BDF", t_eval=times, rtol=rtol,
                        atol=rtol * theta0, jac=jac)
    if not sol.success or not np.all(np.isfinite(sol.y)):
        raise RuntimeError(f"consolidation: {sol.message}")
    return Transient(sol.t, sol.y.T, dx, theta0, H0, U, sol.nfev)
