"""What ``parsph check``, ``parsph run`` and ``parsph plot`` make of a bubbling bed: a bed on a floor
(``fluidized_bed``) in the solved gas, past Wallis's bound, where no one-dimensional reference describes it
(docs/physics.md, reference 8). Serial: the output files alone (no MPI).

The verdict: the pressure drop across the bed (p' at the floor, extrapolated from the first two rows of cells
and averaged across; the open top holds p' = 0), averaged in time over the outputs from ``checks.settle`` on,
against the bed's buoyant weight per unit area, within :data:`TOL_DROP`, where that window spans at least
:data:`MIN_WINDOW` (a shorter one, a single bubble's, is reported, not judged: a bed at U_mf that sloshes
after an eruption, and whose free top rests on the grains below, is not a bubbling bed's average). Reported beside it, for information
(loose checks, :mod:`parsph.physics.bubbling`): the bubbles on each output's grid (:mod:`parsph.gas.bubbles`,
cells with theta below ``checks.bubble_theta``), their rise velocity between consecutive outputs against
0.5 sqrt(g D) (0.711 sqrt(g D) in 3-D), the gas through them in their frame against Davidson's 4 U_mf r_b
(3 pi U_mf r_b^2 in 3-D), their size against height and the bed's expansion. In 3-D the weight is per unit
floor area (L_y L_z).
"""
from dataclasses import dataclass, field
import math

import numpy as np

from parsph.gas.bubbles import MIN_CELLS

TOL_DROP = 0.01      # the time-averaged pressure drop against the buoyant weight, relative
MIN_WINDOW = 1.0     # reference 8's average: over at least 1 s of bubbling [s]; a shorter window is reported only
RISE_EXPECTED = 0.25  # reference 8: a bubble rises at c sqrt(g D) within about this (reported, not judged)


def bed_run(p):
    """The run's RunConfig where it is a bed in the solved gas past Wallis's bound, else None; p is
    read_profile's."""
    from .layer_report import layer_run
    cfg = layer_run(p)
    if cfg is None or cfg.gas is None or not cfg.gas.solved or not cfg.gas.U > 0:
        return None
    from parsph.setup.scenes import layer  # its references import scipy: not for every run's closing check
    return cfg if layer.numbers(cfg).past_wallis else None


@dataclass
class Frame:
    t: float
    drop: float            # [Pa]
    weight: float          # the solids' buoyant weight per unit area [Pa]
    heights: np.ndarray    # the heights below which 5, 25, 50, 75, 95% of the mass lies [m]
    bubbles: list


@dataclass
class Bed:
    """A bubbling bed's outputs, measured."""
    frames: list
    pairs: list = field(default_factory=list)        # (t, parsph.gas.bubbles.Pair, throughflow [m^2/s])
    settle: float = 0.0

    def window(self):
        return [f for f in self.frames if f.t >= self.settle]

    def drop_error(self):
        """(standard error, independent samples) of :meth:`mean_drop` from the drop's fluctuations in the
        window (:func:`mean_standard_error`; outputs at even times)."""
        return mean_standard_error([f.drop / f.weight for f in self.window()])

    def mean_drop(self):
        """The drop over the weight averaged in time over the window (trapezoids between outputs); NaN with
        fewer than two outputs in it."""
        w = self.window()
        if len(w) < 2:
            return math.nan
        t = np.array([f.t for f in w])
        r = np.array([f.drop / f.weight for f in w])
        return float(np.sum(0.5 * (r[1:] + r[:-1]) * np.diff(t)) / (t[-1] - t[0]))


def mean_standard_error(x):
    """(the standard error of the mean of the series x, its effective number of independent samples): for a
    stationary series, var(mean) = var(x) tau / n with tau = 1 + 2 sum_k rho_k, the integrated
    autocorrelation, summed here while rho_k stays positive (Geyer's initial positive sequence); NaN for
    fewer than 3 values."""
    x = np.asarray(x, float)
    n = len(x)
    if n < 3:
        return math.nan, math.nan
    d = x - x.mean()
    var = float(d @ d) / n
    if not var > 0:
        return 0.0, float(n)
    tau = 1.0
    for k in range(1, n - 1):
        rho = float(d[:-k] @ d[k:]) / (n * var)
        if rho <= 0:
            break
        tau += 2.0 * rho
    return math.sqrt(var * tau / n), n / tau


def measure(path, cfg):
    """The :class:`Bed` of a run's outputs (those with particles and a grid)."""
    import h5py
    from parsph.gas import bubbles
    from parsph.gas.grid import floor_drop
    from parsph.output import output_files
    from parsph.sph.particles import GRAIN
    from parsph.sph.profiles import mass_quantiles
    g = abs(cfg.g[0])
    threshold = cfg.get("checks.bubble_theta")
    settle = cfg.get("checks.settle")
    bed = Bed([], settle=cfg.get("output.t_end") / 3.0 if settle is None else settle)
    before = None
    for fn in output_files(path):
        with h5py.File(fn, "r") as f:
            if "particles" not in f or "grid" not in f or "theta" not in f["grid"]:
                continue
            t = float(f.attrs["time"])
            gr = f["grid"]
            theta, p, u_gx = gr["theta"][()], gr["p"][()], gr["u_g"][()][..., 0]
            cell = [float(c) for c in gr.attrs["cell"]]
            kind = f["particles/kind"][()]
            fluid = kind == GRAIN
            x = f["particles/position"][()][fluid, 0]
            m = f["particles/mass"][()][fluid]
        hx, hy, hz = cell[0], cell[1], (cell[2] if theta.ndim == 3 else 1.0)
        floor = cfg.Ly * (cfg.Lz if theta.ndim == 3 else 1.0)  # per unit floor area (2-D: per unit depth)
        weight = float(m.sum()) * g * (1.0 - cfg.gas.rho / cfg.rho_s) / floor
        found = bubbles.find(theta, hx, hy, threshold, periodic=(False, not cfg.sides), hz=hz)
        frame = Frame(t, floor_drop(p), weight, mass_quantiles(x, m), found)
        if before is not None and frame.t > before.t:
            for pair in bubbles.match(before.bubbles, found, frame.t - before.t, theta.shape):
                bed.pairs.append((frame.t, pair, bubbles.throughflow(pair.after, u_gx, hy, pair.velocity, hz)))
        bed.frames.append(frame)
        before = frame
    bed.frames.sort(key=lambda f: f.t)
    return bed


@dataclass
class Verdict:
    """The time-averaged drop's deviation from the weight (NaN where not judged) and its tolerance."""
    drop: float
    tol: float

    @property
    def judged(self):
        return not math.isnan(self.drop)

    @property
    def ok(self):
        return not abs(self.drop) > self.tol

    def failures(self):
        if self.ok:
            return []
        return [f"the bed's time-averaged pressure drop {self.drop * 100:+.3g}% from its buoyant weight, beyond the "
                f"tolerance {self.tol * 100:g}%"]


def _quartiles(values):
    q = np.percentile(values, [25, 50, 75])
    return f"median {q[1]:.3g} (quartiles {q[0]:.3g}-{q[2]:.3g})"


def report(path, cfg, tol=TOL_DROP, rows=20):
    """(lines, Verdict) of a bubbling bed's outputs; the per-output table thinned to about ``rows`` rows."""
    from parsph.physics import bubbling
    from parsph.setup.scenes import layer
    n = layer.numbers(cfg)
    bed = measure(path, cfg)
    g = abs(cfg.g[0])
    threshold = cfg.get("checks.bubble_theta")
    lines = [f"bed check: a bed in the solved gas past Wallis's bound (c_d/c_k = {n.c_d / n.c_k:.3g}); U = "
             f"{n.U:.4g} m/s = {n.U / n.U_mf:.3g} U_mf (Ergun at theta0: {n.U_mf:.4g} m/s), H0 = {n.H0 * 1e3:.4g} mm",
             f"the pressure drop across the bed (p' at the floor) over its buoyant weight per unit area W, averaged in "
             f"time over the outputs from t = {bed.settle:g} s; tolerance {tol * 100:g}%",
             f"bubbles: connected cells with theta < {threshold:g}, at least {MIN_CELLS[cfg.dim]}, not open to the gas "
             "above the bed",
             f"{'t [s]':>10} {'drop/W':>8} {'h50 [mm]':>9} {'h95 [mm]':>9} {'bubbles':>8} {'D mean [mm]':>12} "
             f"{'D max [mm]':>11}"]
    step = max(1, len(bed.frames) // rows)
    for k, f in enumerate(bed.frames):
        if k % step and k != len(bed.frames) - 1:
            continue
        D = [b.diameter * 1e3 for b in f.bubbles]
        sizes = f"{np.mean(D):12.3g} {max(D):11.3g}" if D else f"{'-':>12} {'-':>11}"
        lines.append(f"{f.t:>10.4g} {f.drop / f.weight:8.4f} {f.heights[2] * 1e3:9.2f} {f.heights[4] * 1e3:9.2f} "
                     f"{len(f.bubbles):8d} {sizes}")
    w = bed.window()
    mean = bed.mean_drop()
    span = w[-1].t - w[0].t if len(w) > 1 else 0.0
    verdict = Verdict(mean - 1.0 if span >= MIN_WINDOW * (1 - 1e-9) else math.nan, tol)
    if math.isnan(mean):
        lines.append(f"bed: the drop not judged (fewer than two outputs from t = {bed.settle:g} s)")
        return lines, verdict
    h = np.mean([f.heights for f in w], axis=0)
    se, samples = bed.drop_error()
    spread = (f"; its standard error {se * 100:.2g}%, from {samples:.3g} independent samples of the drop's "
              "fluctuations") if math.isfinite(se) else ""
    lines.append(f"averaged over {w[0].t:g}-{w[-1].t:g} s ({span:.3g} s, {len(w)} outputs): drop/W = {mean:.5f} "
                 f"({(mean - 1) * 100:+.2f}%{spread}); h50 = {h[2] * 1e3:.4g} mm, h95 = {h[4] * 1e3:.4g} mm (h95 / H0 = "
                 f"{h[4] / n.H0:.3g}); {np.mean([len(f.bubbles) for f in w]):.3g} bubbles an output"
                 + ("" if verdict.judged else f"; under the {MIN_WINDOW:g} s of bubbling reference 8's average asks "
                                              "for: reported, not judged"))
    pairs = [(t, pr, q) for t, pr, q in bed.pairs if t >= bed.settle and pr.detached]
    if pairs:
        rise = np.array([pr.velocity / bubbling.rise_velocity(pr.diameter, g, cfg.dim) for _, pr, _ in pairs])
        flow = np.array([q / bubbling.throughflow(n.U_mf, 0.5 * pr.diameter, cfg.dim) for _, pr, q in pairs])
        D = np.array([pr.diameter for _, pr, _ in pairs]) * 1e3
        med = float(np.median(rise))
        lines.append(f"rise velocity: {len(pairs)} bubbles matched between consecutive outputs (D {D.min():.3g} to "
                     f"{D.max():.3g} mm, clear of the floor's row of cells); u_b / ({bubbling.RISE_CONSTANT[cfg.dim]:g} sqrt(g D)): "
                     f"{_quartiles(rise)}" + ("" if abs(med - 1) <= RISE_EXPECTED else
                                              f" (outside the expected {RISE_EXPECTED * 100:g}%)"))
        lines.append(f"gas through a bubble in its frame / Davidson's "
                     f"{'4 U_mf r_b' if cfg.dim == 2 else '3 pi U_mf r_b^2'}: {_quartiles(flow)}")
        top = max(f.heights[4] for f in w)
        edges = np.linspace(0.0, top, 5)
        x = np.array([pr.after.x for _, pr, _ in pairs])
        cells = []
        for lo, hi in zip(edges[:-1], edges[1:]):
            sel = (x >= lo) & (x < hi)
            cells.append(f"{lo * 1e3:.0f}-{hi * 1e3:.0f} mm: {D[sel].mean():.3g} mm ({sel.sum()})" if sel.any()
                         else f"{lo * 1e3:.0f}-{hi * 1e3:.0f} mm: -")
        lines.append("bubble size against height (mean D of the matched bubbles, their number): " + "; ".join(cells))
    else:
        lines.append("rise velocity: no bubble matched between consecutive outputs from t = "
                     f"{bed.settle:g} s (outputs closer in time than a bubble's size over its rise velocity)")
    if verdict.judged:
        unresolved = (not verdict.ok and math.isfinite(se) and abs(mean - 1.0) < 2.0 * se)
        lines.append(f"bed: the time-averaged drop {'within' if verdict.ok else 'beyond'} {tol * 100:g}% of the "
                     f"weight ({(mean - 1) * 100:+.2f}%)"
                     + (f"; within two standard errors ({se * 100:.2g}%) of it: the window is too short to resolve "
                        f"{tol * 100:g}%" if unresolved else ""))
    else:
        lines.append(f"bed: the drop not judged (its window {span:.3g} s, under {MIN_WINDOW:g} s)")
    return lines, verdict


def figure(path, cfg):
    """The bed against time: its pressure drop over its buoyant weight (the averaging window shaded), the
    heights below which 50 and 95% of its mass lies [mm] and its bubbles' count and mean diameter. A Figure."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    bed = measure(path, cfg)
    t = np.array([f.t for f in bed.frames])
    fig, ax = plt.subplots(3, 1, figsize=(6.4, 7.2), sharex=True)
    ax[0].plot(t, [f.drop / f.weight for f in bed.frames], "-", lw=1)
    ax[0].axhline(1.0, color="k", lw=0.8)
    if t.size:
        ax[0].axvspan(bed.settle, t[-1], color="0.9", zorder=0, label="averaged")
    mean = bed.mean_drop()
    ax[0].set_ylabel("drop / buoyant weight")
    ax[0].set_title("a bubbling bed" + ("" if math.isnan(mean) else f": mean drop / weight {mean:.4f}"))
    ax[1].plot(t, [f.heights[4] * 1e3 for f in bed.frames], "-", label="95% of the mass below")
    ax[1].plot(t, [f.heights[2] * 1e3 for f in bed.frames], "-", label="50%")
    ax[1].set_ylabel("height [mm]")
    ax[1].legend(fontsize=8)
    ax[2].plot(t, [len(f.bubbles) for f in bed.frames], "-", label="bubbles")
    ax[2].plot(t, [np.mean([b.diameter for b in f.bubbles]) * 1e3 if f.bubbles else np.nan for f in bed.frames],
               "-", label="their mean D [mm]")
    ax[2].set_xlabel("t [s]")
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    return fig
