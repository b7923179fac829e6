"""Error estimates from a sequence of resolutions (no MPI, no solver: arrays in, numbers out).

Levels l = 0 .. L-1 have spacings h_l = h_0 / R^l. If level l's profile obeys
f_l(x) = f(x) + C(x) h_l^p (the asymptotic range), the differences of
successive levels d_l = f_{l+1} - f_l = -C(x) h_l^p (1 - R^-p) keep their
shape and shrink by R^p per level:

    d_l(x) = R^p d_{l+1}(x)    for every x.

``estimate`` fits the ratio r = R^p by least squares over the bins
(r = <d_l, d_{l+1}> / <d_{l+1}, d_{l+1}>), so the observed order is
p = log r / log R, and the relative residual of that fit,
||d_l - r d_{l+1}|| / ||d_l||, measures how far the two difference profiles
are from one shape. Richardson extrapolation from the finest two levels gives

    f_inf = f_{L-1} + (f_{L-1} - f_{L-2}) / (R^p - 1),

and each level's estimated error is ||f_l - f_inf|| (max and RMS over bins),
for the finest |d_{L-2}| / (R^p - 1). An estimate is withheld (``err_max``
None) when the levels are not in the asymptotic range: differences that do
not shrink (a floor, or noise), difference profiles of different shapes, an
order above ``max_order`` (the coarsest level is pre-asymptotic), or, with
four or more levels, orders of successive triples that disagree.

Profiles are compared on the coarsest level's bin centres (``to_coarse``).

An error every level shares cannot show in their differences. The one SPH
has at fixed h/dx is the kernel's viscosity bias on the (sheared) particle
lattice, nu_eff = (1 + b) nu, a property of the kernel and h/dx alone
(:func:`kernel_bias`). ``estimate(..., bias=B)`` takes its effect on the
output, B(x) = f(k / (1 + b)) - f(k) at the coarsest level (one extra run,
made by ``parsph converge``), and moves the limit by it: the levels converge
to the flow of viscosity (1 + b) nu, the truth is that of nu, so
f_true = f_inf + B to first order in b.
"""
from dataclasses import dataclass, field
import math

import numpy as np

SHAPE_TOL = 0.35    # largest accepted ||d_l - r d_{l+1}|| / ||d_l||
ORDER_TOL = 0.5     # largest accepted spread of the orders of successive triples
MAX_ORDER = 3.0     # above any order the discretisations here have (1: wall cap, time; 2: kernel)
TIMES_TOL = 1.0     # orders of different output times further apart than this: a caution


def to_coarse(x_fine, f_fine, x_coarse, period=None):
    """A profile given at bin centres x_fine, at the points x_coarse (4-point Lagrange).

    Cubic interpolation is fourth order, so it adds nothing measurable to the
    errors being estimated; near walls the stencil is one-sided, with
    ``period`` (a periodic x of that length) it wraps. A NaN in the stencil
    (an empty bin) gives NaN. Bin averaging would instead converge to the
    cell average, which differs from the point values of the coarse level by
    h^2 f''/24, a difference that belongs to no run.
    """
    xf = np.asarray(x_fine, dtype=float)
    ff = np.asarray(f_fine, dtype=float)
    xc = np.asarray(x_coarse, dtype=float)
    n = xf.size
    if n < 4:
        raise ValueError("interpolation needs at least 4 bins")
    j = np.searchsorted(xf, xc)  # xf[j-1] < xc <= xf[j]
    if period is None:
        start = np.clip(j - 2, 0, n - 4)
        idx = start[:, None] + np.arange(4)
        xs = xf[idx]
    else:
        idx = (j - 2)[:, None] + np.arange(4)
        xs = xf[idx % n] + period * np.floor_divide(idx, n)
        idx = idx % n
    fs = ff[idx]
    out = np.zeros(xc.size)
    for a in range(4):
        w = np.ones(xc.size)
        for b in range(4):
            if b != a:
                w *= (xc - xs[:, b]) / (xs[:, a] - xs[:, b])
        out += w * fs[:, a]
    return out


@dataclass
class Estimate:
    """What ``estimate`` finds at one output time (errors relative to ``scale``)."""
    diff_max: list                 # max |f_{l+1} - f_l| / scale, l = 0 .. L-2
    diff_rms: list
    orders: list = field(default_factory=list)   # observed order of each triple (l, l+1, l+2)
    shapes: list = field(default_factory=list)   # shape residual of each triple
    order: float = None            # the finest triple's order
    err_max: list = None           # estimated error of each level (None: not asymptotic)
    err_rms: list = None
    asymptotic: bool = False
    reasons: list = field(default_factory=list)  # why not, in words
    bins: int = 0                  # bins compared (finite in every level)
    bias_max: float = None         # max |B| / scale: the kernel's viscosity bias's effect (None: not given)
    richardson_max: list = None    # max |f_l - f_inf| / scale: the estimate without the bias
    _ok: object = None             # the bins used (mask over the given ones)
    _rich: object = None           # (f_finest - f_inf) / scale on those bins
    _bias: object = None           # B / scale on those bins

    @property
    def used(self):
        """The bins the estimate used (a mask over the bins given)."""
        return self._ok

    def as_dict(self):
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _ratio(d0, d1):
    """Least-squares r in d0 = r d1, and the relative residual ||d0 - r d1|| / ||d0||."""
    den = float(np.dot(d1, d1))
    n0 = float(np.sqrt(np.dot(d0, d0)))
    if den == 0.0 or n0 == 0.0:
        return math.nan, math.nan
    r = float(np.dot(d0, d1)) / den
    return r, float(np.sqrt(np.sum((d0 - r * d1) ** 2))) / n0


def estimate(profiles, ratio, scale=1.0, max_order=MAX_ORDER, shape_tol=SHAPE_TOL, order_tol=ORDER_TOL,
             bias=None):
    """Observed order and per-level errors from profiles (L, nbins) on common points, coarse first.

    ``bias``: the profile B(x) that an error common to all levels adds (the kernel's
    viscosity bias, see the module's docstring), on the same points; the limit the
    errors are measured from is then f_inf + B. Bins that are not finite in every level
    (or in B) are left out.
    """
    F = np.asarray(profiles, dtype=float)
    if F.ndim != 2 or F.shape[0] < 2:
        raise ValueError("need profiles of at least two levels, shape (levels, bins)")
    if not ratio > 1:
        raise ValueError("the refinement ratio must exceed 1")
    ok = np.all(np.isfinite(F), axis=0)
    if bias is not None:
        B = np.asarray(bias, dtype=float)
        ok &= np.isfinite(B)
    F = F[:, ok] / abs(scale)
    B = B[ok] / abs(scale) if bias is not None else np.zeros(F.shape[1])
    L = F.shape[0]
    D = np.diff(F, axis=0)
    est = Estimate(diff_max=[float(np.max(np.abs(d), initial=0.0)) for d in D],
                   diff_rms=[float(np.sqrt(np.mean(d * d))) if d.size else 0.0 for d in D], bins=int(ok.sum()),
                   _ok=ok, _bias=B)
    if bias is not None:
        est.bias_max = float(np.max(np.abs(B), initial=0.0))
    if F.shape[1] == 0:
        est.reasons.append("no bin has data in every level")
        return est
    if L < 3:
        est.reasons.append("two levels give a difference but no order; run three or more (--levels 3)")
        return est
    for l in range(L - 2):
        r, res = _ratio(D[l], D[l + 1])
        est.orders.append(math.log(r) / math.log(ratio) if r > 0 else math.nan)
        est.shapes.append(res)
    if est.diff_max[-1] == 0.0:
        # converged to round-off (e.g. a state the discretisation holds exactly): the finest is the limit
        est.order, est.asymptotic = math.inf, True
        _errors(est, F, F[-1], B)
        return est
    p, res = est.orders[-1], est.shapes[-1]
    est.order = p
    if not p > 0:  # NaN (r <= 0: the differences change sign) or r <= 1
        est.reasons.append("the differences between levels do not shrink with refinement "
                           "(a floor or noise: the error no longer falls as h^p)")
    elif p > max_order:
        est.reasons.append(f"observed order {p:.2f} is above {max_order:g}, more than the discretisation has: "
                           f"the coarse levels are not yet in the asymptotic range (refine further)")
    if not res <= shape_tol:
        est.reasons.append(f"the difference profiles of successive levels differ in shape "
                           f"(residual {res:.2f} > {shape_tol:g}): the error is not C(x) h^p bin by bin")
    if L > 3:
        spread = max(est.orders[-2:]) - min(est.orders[-2:])
        if not spread <= order_tol:
            est.reasons.append(f"the orders of the two finest triples differ by {spread:.2f} (> {order_tol:g})")
    if est.reasons:
        return est
    est.asymptotic = True
    _errors(est, F, F[-1] + (F[-1] - F[-2]) / (ratio ** p - 1.0), B)
    return est


def _errors(est, F, f_inf, B):
    """Each level's error against the limit f_inf + B, and against f_inf alone (Richardson)."""
    L = F.shape[0]
    est._rich = F[-1] - f_inf
    est.richardson_max = [float(np.max(np.abs(F[l] - f_inf))) for l in range(L)]
    est.err_max = [float(np.max(np.abs(F[l] - f_inf - B))) for l in range(L)]
    est.err_rms = [float(np.sqrt(np.mean((F[l] - f_inf - B) ** 2))) for l in range(L)]


def kernel_bias(kernel, h_over_dx, dim=2, offsets=40, dy=1.0, dz=1.0):
    """b in nu_eff = (1 + b) nu: the Morris viscous operator's lattice sum for the kernel at h/dx,
    averaged over the sheared lattices (shift s = 0, 1/offsets, ...) that a shear flow passes
    through as its columns slide (:mod:`parsph.physics.lattice_sums`), in 2-D or 3-D (None otherwise);
    ``dy``, ``dz``: the lattice's other spacings in units of dx."""
    if dim not in (2, 3):
        return None
    from parsph.physics.lattice_sums import sheared_lattice_sums
    return float(np.mean([sheared_lattice_sums(kernel, h_over_dx, s, dim, dy, dz)[0]
                          for s in np.arange(offsets) / offsets])) - 1.0


def times_caution(orders, tol=TIMES_TOL):
    """A sentence when the orders found at different output times (asymptotic ones) disagree, else None."""
    ps = [p for p in orders if p is not None and math.isfinite(p)]
    if len(ps) >= 2 and max(ps) - min(ps) > tol:
        return (f"the observed orders differ across output times ({min(ps):.2f} to {max(ps):.2f}): "
                f"different error sources lead at different times; trust each time's estimate only "
                f"as far as its own checks go")
    return None


def cost_at(nx, levels_nx, levels_cost):
    """Cost of a run at N_x from measured (N_x, cost) pairs: log-log interpolation between
    levels, extrapolation with the exponent of the nearest pair (the finest pair above)."""
    n = np.log(np.asarray(levels_nx, dtype=float))
    c = np.log(np.maximum(np.asarray(levels_cost, dtype=float), 1e-300))
    x = math.log(nx)
    if x >= n[-1]:
        k = len(n) - 2
    elif x <= n[0]:
        k = 0
    else:
        k = int(np.searchsorted(n, x)) - 1
    a = (c[k + 1] - c[k]) / (n[k + 1] - n[k])
    return float(math.exp(c[k] + a * (x - n[k]))), float(a)


def predict_nx(levels_nx, estimates, target):
    """The smallest N_x predicted to meet ``target`` at every output time, or (None, why).

    Each time's error model is its finest level's estimate scaled as h^p,
    err(N) = err_fine (N_fine / N)^p, used only where that time's estimate
    is asymptotic; N is not taken below the coarsest level measured. With a
    bias effect B (``est.bias_max``), which no N removes, the model is
    err(N) = rich_fine (N_fine / N)^p + max |B| (an upper bound of the max of
    their sum), and a target at or below max |B| cannot be met at this h/dx.
    """
    need = levels_nx[0]
    for t, est in estimates:
        if not est.asymptotic or est.err_max is None:
            return None, f"t = {t:g} s: no trustworthy estimate ({'; '.join(est.reasons) or 'not asymptotic'})"
        e = est.err_max[-1]
        floor = est.bias_max or 0.0
        if floor > 0.0:
            if floor >= target:
                return None, (f"t = {t:g} s: the kernel's viscosity bias alone gives {floor:.2e} "
                              f"at this h/dx, whatever N_x (another kernel or h/dx)")
            e, target_t = est.richardson_max[-1], target - floor
        else:
            target_t = target
        if est.order == math.inf:
            n_t = levels_nx[-1] if e > target_t else levels_nx[0]
        else:
            n_t = math.ceil(levels_nx[-1] * (e / target_t) ** (1.0 / est.order) - 1e-9)
        need = max(need, n_t)
    return need, None


# how each stability limit scales with dx at fixed h/dx (parsph.physics.limits): advection 0.5 h / v, the
# von Neumann limits 2 gamma / omega^2 (damping, independent of dx), 2 / gamma (viscous) and the
# RK2 acoustic one (~ h / c), the body-force limit 0.25 sqrt(h / a)
LIMIT_POWERS = {"advection": 1.0, "damping": 0.0, "viscous": 2.0, "acoustic": 1.0, "force": 0.5}


def limit_at(nx, measured):
    """The stability limit at N_x, scaled from the limits of the levels run, [(N_x, limits)], each term
    with its power of dx (the smallest over levels and terms; None if a term's scaling is unknown).
    A level names only the smaller of its two von Neumann terms, so coarse and fine levels together
    give both."""
    out = math.inf
    for n0, limits in measured:
        for k, v in limits.items():
            if not math.isfinite(v):
                continue
            if k not in LIMIT_POWERS:
                return None
            out = min(out, v * (n0 / nx) ** LIMIT_POWERS[k])
    return out


def predict_setting(levels_nx, estimates, target, time_model, cost_of, max_factor=4, fractions=(0, 0.25, 0.5, 0.75, 1)):
    """The cheapest (N_x, dt) predicted to meet ``target`` at every output time, from levels run with
    dt ~ dx^2 and one run of the finest level at its stability limit. Returns (N_x, dt, dt_limit,
    predicted error, cost) or (None, why).

    ``estimates``: [(t, Estimate, T)], T(x) = (f(finest, dt_lim) - f(finest, dt_fine)) / scale / (dt_lim -
    dt_fine) on the estimate's bins: the first-order time error per second of dt, measured.
    ``time_model``: (dt_fine, dt_limit(N)): the finest level's dt and the limit at N.
    ``cost_of(N)``: the cost at N with dt ~ dx^2 (the levels' scaling); a step costs the same at any dt,
    so the cost at dt is cost_of(N) dt_dx2(N) / dt.

    The error of level N at dt is modelled bin by bin as
    R(x) (N_fine / N)^p - B(x) + T(x) (dt - dt_dx2(N)), R the finest level's Richardson error,
    B the bias effect, dt_dx2(N) = dt_fine (N_fine / N)^2, dt between dt_dx2(N) and the limit.
    """
    dt_fine, dt_limit = time_model
    nf = levels_nx[-1]
    for t, est, _ in estimates:
        if not est.asymptotic or est._rich is None or est.order == math.inf:
            return None, f"t = {t:g} s: no trustworthy estimate ({'; '.join(est.reasons) or 'not asymptotic'})"
    best = None
    for n in range(levels_nx[0], max_factor * nf + 1):
        lim = dt_limit(n)
        d2 = dt_fine * (nf / n) ** 2
        if lim is None or not d2 <= lim * (1 + 1e-9):
            continue
        for u in fractions:
            dt = d2 + u * (lim - d2)
            err = 0.0
            for t, est, T in estimates:
                b = est._bias if est._bias is not None else 0.0
                e = est._rich * (nf / n) ** est.order - b + T * (dt - d2)
                err = max(err, float(np.max(np.abs(e))))
            if err <= target:
                cost = cost_of(n) * d2 / dt
                if best is None or cost < best[4]:
                    best = (n, dt, lim, err, cost)
    if best is None:
        return None, f"no N_x up to {max_factor * nf} is predicted to meet {target:g}"
    return best
