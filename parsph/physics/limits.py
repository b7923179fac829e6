"""Time-step limits: the sound speed of each pressure form and a stability limit derived from Eqs. (3)-(7).

Sound speed. The discrete pressure term of Eq. (5) is, to first order about a
uniform state, the symmetric SPH gradient ``sum_j m_j (p_i/rho_i^2 + p_j/rho_j^2) grad W``
of an effective pressure p(theta):

- ``paper`` (Eq. (5) as printed): p = G(theta) theta, so
  c_eff^2 = dp/dtheta / rho_s = G (1 + G_a ln10 theta) / rho_s;
- ``consistent``: p = G / (G_a ln 10), so c^2 = G / rho_s (the closure's).

Stability limit (von Neumann analysis of the discrete operator). Linearise
Eqs. (3) and (5) about the uniform lattice at rest, for a displacement
xi_j = xi exp(i kappa . R_j) and a velocity u_j = u exp(i kappa . R_j). With
F = (dW/dr)/r, H = F I + (dF/dr / r) R R^T (the Hessian of W), and sums over
the lattice neighbours R of one particle,

    b(kappa) = sum F R sin(kappa.R),   D(kappa) = sum H (1 - cos kappa.R),
    V(kappa) = -sum F (1 - cos kappa.R),

the acceleration of the mode is ``-K xi - gamma u`` with

    K = (m^2 Q' / rho_s) b b^T + m Q_0 D,      gamma = 2 k m V / rho_s^2,

Q_0 = 2 p / rho^2 and Q' = d(p/rho^2)/dtheta at the lattice's theta
(m = rho_s theta / sum W: the summation density of the lattice is theta).
As kappa h -> 0 these tend to c^2 kappa kappa^T and nu kappa^2. Each
eigenvalue omega^2 of K with its gamma is one mode x'' = -omega^2 x - gamma x'.
One step of an integrator multiplies (x, x') by a 2x2 matrix:

- ``paper`` (Eqs. (6)-(7), v first order): det = 1 - gamma dt + omega^2 dt^2 / 2,
  trace = 2 - gamma dt - omega^2 dt^2 / 2; both eigenvalues lie in the unit
  disk iff dt < 2 gamma / omega^2 (the acoustic growth, damped only by
  viscosity: term "damping") and dt < 2 / gamma (explicit diffusion: "viscous");
- ``midpoint`` (explicit midpoint, RK2): R(z) = 1 + z + z^2/2 with z = dt s,
  s^2 + gamma s + omega^2 = 0; the largest dt with |R| <= 1 for both roots
  is found by bisection ("acoustic" for an underdamped mode, "viscous" for an
  overdamped one).

The limit is the smallest over the wave vectors of the lattice's Brillouin
zone (a grid of ``NKAPPA`` points per axis, symmetric quarter). Not in the
analysis: walls (the wall particles' beta), the base shear flow (the lattice
rows slide past each other) and the finite length of a run (growth below the
unit circle's edge that needs more steps than a run takes); docs/stability.md
compares the prediction with the measured map. Two classical limits are kept
beside it: advection, dt <= 0.5 h / |v|_max (a particle moves at most h/4 in
half a step: the midpoint skin of the solver's halo), and a body force,
dt <= 0.25 sqrt(h / |a|_max) (Monaghan 1992). With a gas and explicit drag, ``drag``: dt <= tau_min =
1 / C_max, C the drag coefficient of :func:`parsph.sph.body_force.drag_plain` (the explicit update is
stable for dt < 2 tau and free of overshoot for dt < tau; docs/physics.md). Implicit drag has no limit.
:func:`state_limit` is the one place of these three (numba; the compiled blocks call it).

The functions take their arguments in three groups, as the passes do:
:class:`Material` (rho_s, k, G_a, G_b, the packing limit), :class:`Lattice` (h, the lattice
steps, the kernel, the walls' beta_max) and :class:`Terms` (which terms of
Eq. (5) and the pressure form); :func:`groups` makes them from a run.
"""
from functools import lru_cache
import math
from typing import NamedTuple, Optional

import numpy as np
from numba import njit

from . import closures
from .kernels import get_kernel
from .lattice_sums import lattice_points

FORMS = ("paper", "consistent")
NKAPPA = 25        # wave vectors per axis of the quarter Brillouin zone
LN10 = math.log(10.0)


class Material(NamedTuple):
    """The solid: rho_s [kg/m^3], mu_s = k theta [Pa s], G = 10^(G_a theta + G_b) [Pa] and the packing
    limit (theta_min, theta_max) of the frictional pressure, () for none (:func:`.closures.packing_pressure`)."""
    rho_s: float
    k: float
    G_a: float
    G_b: float
    packing: tuple = ()


class Lattice(NamedTuple):
    """The particles: h [m], the lattice step per dimension [m] (a tuple), the kernel's name, and
    ``beta_max``, the Morris cap of a channel with walls (None: no walls)."""
    h: float
    spacing: tuple
    kernel: str = "cubic_spline"
    beta_max: Optional[float] = None


class Terms(NamedTuple):
    """The terms of Eq. (5) that the run computes, and its pressure form (:data:`FORMS`)."""
    pressure: bool = True
    viscosity: bool = True
    form: str = "paper"


def groups(cfg):
    """(Material, Lattice, Terms) of the run ``cfg``."""
    return (Material(cfg.rho_s, cfg.k, cfg.G_a, cfg.G_b, cfg.packing),
            Lattice(cfg.h, tuple(cfg.spacing), cfg.kernel, cfg.beta_max if cfg.scene.walls else None),
            Terms(bool(cfg.pressure), bool(cfg.viscosity), cfg.get("numerics.pressure_form")))


# ---- the sound speed of each pressure form -----------------------------------------------------------
def pressure(theta, G_a, G_b, form, packing=()):
    """The effective pressure p(theta) [Pa] whose SPH gradient the discrete Eq. (5) is (with a packing limit
    (theta_min, theta_max), the consistent form's p plus the frictional p_f)."""
    G = closures.modulus(theta, G_a, G_b)
    if form == "paper":
        return G * theta
    return G / (G_a * LN10) + (closures.packing_pressure(theta, *packing)[0] if packing else 0.0)


def dpressure(theta, G_a, G_b, form, packing=()):
    """dp/dtheta [Pa]: G (1 + G_a ln10 theta) for the paper form, G (+ dp_f/dtheta) for the consistent one."""
    G = closures.modulus(theta, G_a, G_b)
    if form == "paper":
        return G * (1.0 + G_a * LN10 * theta)
    return G + (closures.packing_pressure(theta, *packing)[1] if packing else 0.0)


def sound_speed(theta, rho_s, G_a, G_b, form, packing=()):
    """c = sqrt(dp/dtheta / rho_s) [m/s] of the pressure form."""
    return math.sqrt(dpressure(theta, G_a, G_b, form, packing) / rho_s)


# ---- classical limits ----------------------------------------------------------------------------------
def classical_limits(theta, vmax, material, lattice, terms=Terms(), amax=0.0):
    """Monaghan's limits [s] with the form's sound speed: CFL 0.25 h / (c + |v|), viscous 0.125 h^2 / nu,
    force 0.25 sqrt(h / |a|) (inf where absent). For comparison; the run uses :func:`limits`."""
    rho_s, k, G_a, G_b, packing = material
    h = lattice.h
    c = sound_speed(theta, rho_s, G_a, G_b, terms.form, packing)
    nu = k * theta / rho_s
    return {"cfl": 0.25 * h / (c + vmax) if c + vmax > 0 else math.inf,
            "viscous": 0.125 * h * h / nu if nu > 0 else math.inf,
            "force": 0.25 * math.sqrt(h / amax) if amax > 0 else math.inf}


# ---- lattice sums ------------------------------------------------------------------------------------------
@lru_cache(maxsize=16)  # a run asks with the same lattice at every step; callers do not modify the arrays
def lattice_sums(kernel, dim, spacing, nkappa=NKAPPA):
    """Sums of the lattice with h = 1 and steps ``spacing`` (in units of h) over the quarter zone.

    Returns (kappa [nk, dim], S = sum W, b [nk, dim], D [nk, dim, dim], V [nk]) as in the module doc,
    the self term in S only. For h != 1 scale S by h^-dim, b by h^-(dim+1), D and V by h^-(dim+2).
    """
    kern = get_kernel(kernel, dim)
    norm = kern.norm(1.0, dim)
    reach = kern.support
    R = lattice_points(spacing, reach) * np.asarray(spacing, dtype=float)
    r = np.sqrt((R * R).sum(axis=1))
    S = sum(kern.w(float(x), 1.0, norm) for x in r)
    R, r = R[(r > 0) & (r < reach)], r[(r > 0) & (r < reach)]
    dw = np.array([kern.dwdr(float(x), 1.0, norm) for x in r])
    eps = 1e-5
    d2w = np.array([(kern.dwdr(float(x) + eps, 1.0, norm) - kern.dwdr(float(x) - eps, 1.0, norm)) / (2 * eps)
                    for x in r])
    F = dw / r
    Fp_over_r = (d2w - F) / (r * r)          # (dF/dr) / r
    H = F[:, None, None] * np.eye(dim) + Fp_over_r[:, None, None] * R[:, :, None] * R[:, None, :]
    grids = np.meshgrid(*[np.linspace(0.0, math.pi / s, nkappa) for s in spacing], indexing="ij")
    kappa = np.stack([g.ravel() for g in grids], axis=1)
    nk = len(kappa)
    b, D, V = np.zeros((nk, dim)), np.zeros((nk, dim, dim)), np.zeros(nk)
    chunk = max(1, (1 << 21) // max(len(r), 1))  # wave vectors per pass: [chunk, nbr] arrays stay below 16 MB
    for lo in range(0, nk, chunk):
        phase = kappa[lo:lo + chunk] @ R.T                       # [chunk, nbr]
        b[lo:lo + chunk] = (np.sin(phase) * F) @ R
        one_minus_cos = 1.0 - np.cos(phase)
        D[lo:lo + chunk] = np.einsum("kn,nij->kij", one_minus_cos, H)
        V[lo:lo + chunk] = -(one_minus_cos * F).sum(axis=1)
    for a in (kappa, b, D, V):  # cached and shared: read-only
        a.setflags(write=False)
    return kappa, S, b, D, V


def modes(theta, material, lattice, terms=Terms(), nkappa=NKAPPA):
    """omega^2 [nk, dim] (eigenvalues of K) and gamma [nk] of the lattice's modes, and their kappa [nk, dim]."""
    rho_s, k, G_a, G_b, packing = material
    h, spacing, kernel = lattice.h, lattice.spacing, lattice.kernel
    form, pressure_on, viscosity_on = terms.form, terms.pressure, terms.viscosity
    dim = len(spacing)
    kappa, S, b, D, V = lattice_sums(kernel, dim, tuple(round(s / h, 12) for s in spacing), nkappa)
    S, b, D, V = S / h ** dim, b / h ** (dim + 1), D / h ** (dim + 2), V / h ** (dim + 2)
    m = rho_s * theta / S
    if pressure_on:
        rho = rho_s * theta
        p, dp = pressure(theta, G_a, G_b, form, packing), dpressure(theta, G_a, G_b, form, packing)
        Q0 = 2.0 * p / (rho * rho)
        Qp = (dp - 2.0 * p / theta) / (rho * rho)
        K = (m * m * Qp / rho_s) * b[:, :, None] * b[:, None, :] + m * Q0 * D
        omega2 = np.linalg.eigvalsh(K)
    else:
        omega2 = np.zeros((len(kappa), dim))
    gamma = 2.0 * k * m * V / rho_s ** 2 if viscosity_on else np.zeros(len(kappa))
    return omega2, gamma, kappa / h


@lru_cache(maxsize=16)
def wall_gamma_max(kernel, dim, spacing, beta_max, nrows=12, nkappa=NKAPPA):
    """The largest damping rate of the viscous operator in a channel with walls (h = 1, dimensionless).

    ``nrows`` fluid rows x = (i + 1/2) s_x between wall layers covering 2h,
    Fourier modes along the periodic directions; a wall neighbour j of fluid
    particle i enters Eq. (5) as beta (v_i - v_j) with v_j fixed,
    beta = min(beta_max, 1 + d_j / d_i). The operator is symmetric: its largest
    eigenvalue over the wave vectors. Scale by 2 k m / rho_s^2 h^-(dim+2).
    """
    kern = get_kernel(kernel, dim)
    norm = kern.norm(1.0, dim)
    sx, rest = spacing[0], spacing[1:]
    nw = math.ceil(kern.support / sx - 1e-9)
    cols = np.arange(-nw, nrows + nw)
    xs = (cols + 0.5) * sx
    Lx = nrows * sx
    off = lattice_points(rest, kern.support) * np.asarray(rest, dtype=float)            # [noff, dim-1]
    grids = np.meshgrid(*[np.linspace(0.0, math.pi / s, nkappa) for s in rest], indexing="ij")
    kappa = np.stack([g.ravel() for g in grids], axis=1)
    cosk = np.cos(kappa @ off.T)                                                       # [nk, noff]
    A = np.zeros((len(kappa), nrows, nrows))
    for i in range(nrows):
        for c, xj in zip(cols, xs):
            dxij = xs[nw + i] - xj
            r = np.sqrt(dxij * dxij + (off * off).sum(axis=1))
            F = np.array([kern.dwdr(float(x), 1.0, norm) / x if 0 < x < kern.support else 0.0 for x in r])
            if 0 <= c < nrows:
                A[:, i, i] -= F.sum()
                A[:, i, c] += cosk @ F
            else:
                d_i, d_j = (xs[nw + i], -xj) if xj < 0 else (Lx - xs[nw + i], xj - Lx)
                A[:, i, i] -= F.sum() * min(beta_max, 1.0 + d_j / d_i)
    return float(np.linalg.eigvalsh(A).max())


def _rk2_growth(z):
    return np.abs(1.0 + z + 0.5 * z * z)


def mode_limits(omega2, gamma, integrator):
    """Largest stable dt [s] of each mode x'' = -omega2 x - gamma x' (arrays of one shape), and whether
    the viscous condition is the one that binds (else the acoustic one).

    omega2 <= 0 is clipped to 0: such a mode (the lattice's own instability,
    see :func:`lattice_growth`) grows at a rate that no dt changes.
    """
    omega2, gamma = np.broadcast_arrays(np.maximum(np.asarray(omega2, float), 0.0), np.asarray(gamma, float))
    with np.errstate(divide="ignore", invalid="ignore"):
        viscous = np.where(gamma > 0, 2.0 / gamma, np.inf)
        if integrator == "paper":
            damping = np.where(omega2 > 0, 2.0 * gamma / omega2, np.inf)
            return np.minimum(damping, viscous), viscous <= damping
        # midpoint: the roots s of s^2 + gamma s + omega2 = 0, |R(dt s)| <= 1 for both, bisected in dt |s|
        disc = np.sqrt((gamma * gamma - 4.0 * omega2).astype(complex))
        s1, s2 = 0.5 * (-gamma + disc), 0.5 * (-gamma - disc)
        scale = np.maximum(np.abs(s1), np.abs(s2))
        scale = np.where(scale > 0, scale, 1.0)

        def ok(u):
            return (_rk2_growth(u / scale * s1) <= 1.0 + 1e-14) & (_rk2_growth(u / scale * s2) <= 1.0 + 1e-14)
        lo = np.zeros(omega2.shape)
        hi = np.full(omega2.shape, np.inf)
        for u in np.geomspace(1e-9, 2.0 + 1e-9, 80):   # the first u at which the mode leaves the region
            bad = ~ok(u) & np.isinf(hi)
            hi = np.where(bad, u, hi)
            lo = np.where(np.isinf(hi), u, lo)
        for _ in range(45):
            mid = np.where(np.isinf(hi), lo, 0.5 * (lo + hi))
            good = ok(mid)
            lo = np.where(good & np.isfinite(hi), mid, lo)
            hi = np.where(~good & np.isfinite(hi), mid, hi)
        dt = np.where(np.isfinite(hi), lo / scale, np.inf)
        dt = np.where((omega2 > 0) | (gamma > 0), dt, np.inf)
        return dt, (gamma * gamma >= 4.0 * omega2)


def lattice_growth(omega2, gamma):
    """Growth rate [1/s] of the modes with omega2 < 0 (s = (-gamma + sqrt(gamma^2 - 4 omega2)) / 2), else 0."""
    omega2, gamma = np.broadcast_arrays(np.asarray(omega2, float), np.asarray(gamma, float))
    s = 0.5 * (-gamma + np.sqrt(np.maximum(gamma * gamma - 4.0 * omega2, 0.0)))
    return float(np.where(omega2 < 0, s, 0.0).max(initial=0.0))


def linear_limit(theta, material, lattice, terms=Terms(), integrator="paper", nkappa=NKAPPA):
    """The von Neumann limit [s] of the module doc and its term ("damping", "acoustic" or "viscous").

    ``lattice.beta_max``: the scene has walls (the viscous condition is also
    taken in the channel, :func:`wall_gamma_max`). Undamped modes (k = 0 with
    pressure) are unstable at every dt in both integrators (slowly); the limit
    is then the CFL one, term "cfl".
    """
    rho_s, k, G_a, G_b, packing = material
    h, spacing, kernel, beta_max = lattice
    if terms.pressure and not (terms.viscosity and k > 0):
        return 0.25 * h / sound_speed(theta, rho_s, G_a, G_b, terms.form, packing), "cfl"
    omega2, gamma, _ = modes(theta, material, lattice, terms, nkappa)
    omega2, gamma = omega2.ravel(), np.repeat(gamma, omega2.shape[1])
    if beta_max is not None and terms.viscosity:
        dim = len(spacing)
        S = lattice_sums(kernel, dim, tuple(round(s / h, 12) for s in spacing), nkappa)[1] / h ** dim
        g_wall = wall_gamma_max(kernel, dim, tuple(round(s / h, 12) for s in spacing), beta_max) \
            * 2.0 * k * (rho_s * theta / S) / rho_s ** 2 / h ** (dim + 2)
        omega2, gamma = np.append(omega2, 0.0), np.append(gamma, g_wall)
    dt, viscous = mode_limits(omega2, gamma, integrator)
    i = int(np.argmin(dt))
    if not np.isfinite(dt[i]):
        return math.inf, "none"
    if viscous[i]:
        return float(dt[i]), "viscous"
    return float(dt[i]), "damping" if integrator == "paper" else "acoustic"


# ---- the limits of a run --------------------------------------------------------------------------------
THETA_STEP = 2.5e-4   # theta is rounded up to a multiple of this for the cached linear limit (G: +0.5 %)


@lru_cache(maxsize=256)
def _linear_cached(*args):
    return linear_limit(*args)


@njit(cache=True)
def advection_limit(h, vmax):
    """0.5 h / |v|_max [s] (inf at rest)."""
    return 0.5 * h / vmax if vmax > 0 else math.inf


@njit(cache=True)
def force_limit(h, amax):
    """0.25 sqrt(h / |a|_max) [s] (Monaghan 1992; inf without acceleration)."""
    return 0.25 * math.sqrt(h / amax) if amax > 0 else math.inf


@njit(cache=True)
def drag_limit(drag_max):
    """1 / C_max = tau_min [s], explicit drag's limit (inf without drag)."""
    return 1.0 / drag_max if drag_max > 0 else math.inf


@njit(cache=True)
def state_limit(h, vmax, amax, drag_max):
    """The smallest of the advection, force and drag limits [s] of a state."""
    return min(advection_limit(h, vmax), force_limit(h, amax), drag_limit(drag_max))


@njit(cache=True)
def landing(dt, remaining):
    """(dt, lands) of the auto rule's next step with ``remaining`` seconds to the next output or the end:
    the whole rest where it fits in one step (lands), half of it where it fits in two (two equal steps,
    not a sliver), else dt. Both paths of the step take it from here."""
    if remaining <= dt:
        return remaining, True
    if remaining < 2 * dt:
        return 0.5 * remaining, False
    return dt, False


def limits(theta, vmax, amax, material, lattice, terms=Terms(), integrator="paper", drag_max=0.0):
    """The limits [s] at (theta, |v|_max, |a|_max) (inf where absent): the linear one under its term's
    name, ``advection`` 0.5 h / |v|_max, ``force`` 0.25 sqrt(h / |a|_max) and, where ``drag_max`` (the
    largest explicit drag coefficient C [1/s]) is positive, ``drag`` 1 / C. The smallest is the stable step.

    The linear limit falls as theta rises; it is evaluated at theta rounded up
    to a multiple of THETA_STEP (a cache: a run's theta_max takes few values).
    """
    h = lattice.h
    th = min(math.ceil(theta / THETA_STEP - 1e-9) * THETA_STEP, 0.999)
    dt, term = _linear_cached(th, Material(*material), lattice._replace(spacing=tuple(lattice.spacing)),
                              Terms(bool(terms.pressure), bool(terms.viscosity), terms.form), integrator)
    out = {term: dt} if term != "none" else {}
    out["advection"] = advection_limit(h, vmax)
    out["force"] = force_limit(h, amax)
    if drag_max > 0:
        out["drag"] = drag_limit(drag_max)
    return out


def run_limits(cfg, theta, vmax, amax, drag_max=0.0):
    """:func:`limits` for the run ``cfg`` at (theta, |v|_max, |a|_max, C_max of explicit drag)."""
    return limits(theta, vmax, amax, *groups(cfg), cfg.integrator, drag_max)


def stable_dt(cfg, theta_max, v_max, a_max, drag_max=0.0):
    """(largest stable dt [s], the term that sets it) of run ``cfg`` at the current state.

    theta_max: the largest fluid theta (the stiffest, least damped modes); drag_max: the largest
    explicit drag coefficient C [1/s] (0 for none, or implicit drag).
    ``numerics.dt_safety`` is the caller's to apply.
    """
    lim = run_limits(cfg, min(theta_max, 0.999), v_max, a_max, drag_max)
    term = min(lim, key=lim.get)
    return lim[term], term
