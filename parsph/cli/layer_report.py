"""What ``parsph check``, ``parsph run`` and ``parsph plot`` make of the layer scenes (``sedimentation``,
``fluidized_bed``; docs/physics.md, "The solid phase in a gas", references 3 and 4). Serial: the output files alone
(no MPI).

The verdict judges what the references can judge:

- **heights**: at every output with particles, the heights below which 5, 25, 50, 75 and 95% of the layer's mass
  lies (:func:`parsph.sph.profiles.mass_quantiles` of the fluid particles), against the same heights of the
  layer's transient in the column closure with inertia dropped (the sedimentation-consolidation equation,
  :func:`parsph.setup.scenes.layer.transient`, which starts from the run's initial layer and ends as its
  steady state), in % of H0. Tolerance :data:`TOL_HEIGHTS`.
- **interior theta**: the profile's bins from 2h above the floor to 2h below where the end state (the steady
  column, :func:`parsph.setup.scenes.layer.end_state`: the hydrostatic sediment, or the bed's steady ODE,
  uniform at theta* only where the bed is much taller than its compression length) falls to half its interior
  value, against the end state's theta(x), as max |theta / theta_ref - 1|: at the outputs where the transient
  has reached its end state (its own interior within :data:`STEADY` of the tolerance of it); before, the
  layer is in transit and its heights carry the verdict. Tolerance :data:`TOL_THETA`.

Without a gas (the layer falls under gravity alone) the reference at every output is the end state. The
scene's pointwise table (theta(x) against a reference that steps where the layer is smooth: Kynch's fronts,
the end state while the bed still expands) is printed for information, not as the verdict.

The default tolerances are met with margin by the shipped run files and failed by a wrong run (runs with
another U or drag judged against the run file's reference; docs/validation.md, "Layers under clear gas"):
heights 3% of H0 (the shipped sedimentation, water bed and air bed: 0.51, 1.49 and 0.41% at most; wrong: the
water bed at U +-10% 10.2 / 6.6%, with Wen & Yu's drag 35%, the sedimentation with Wen & Yu's 14%), interior
theta 2% (shipped: 0.33, 0.41, 1.03%; wrong: the water bed at U +-10% 4.9 / 6.9%, the air bed at U +-10%
6.4 / 17%, whose heights move only 2.3 / 1.8% of H0).
"""
import math
import os
import re
from dataclasses import dataclass

import numpy as np

TOL_HEIGHTS = 0.03    # heights of the mass fractions, relative to H0
TOL_THETA = 0.02      # interior theta, relative
STEADY = 0.25         # interior judged where the transient is within STEADY * its tolerance of the end state


def layer_run(p):
    """The run's RunConfig where its scene is a layer scene (``free_surface``), else None; p is read_profile's."""
    from parsph.errors import ConfigError
    from parsph.setup.config import loads
    try:
        cfg = loads(p["attrs"]["run_file"])
    except (ConfigError, KeyError):
        return None
    return cfg if cfg.scene.free_surface else None


def _snapshots(path):
    """(time, fluid x, fluid mass) of every output with particles, by time."""
    import h5py
    from parsph.output import output_files
    from parsph.sph.particles import GRAIN
    out = []
    for fn in output_files(path):
        with h5py.File(fn, "r") as f:
            if "particles" not in f:
                continue
            g = f["particles"]
            kind = g["kind"][()]
            fluid = kind == GRAIN
            out.append((float(f.attrs["time"]), g["position"][()][fluid, 0], g["mass"][()][fluid]))
    out.sort(key=lambda r: r[0])
    return out


def interior_span(cfg):
    """[lo, hi] [m]: from 2h above the floor to 2h below where the end state falls to half its interior value."""
    from parsph.setup.scenes import layer
    end = layer.end_state(cfg)
    ref = end.theta_star if end.U > 0 else end.theta_floor
    return 2.0 * cfg.h, end.height_of(0.5 * ref) - 2.0 * cfg.h


@dataclass
class Row:
    """One output of a layer run: its time, the heights of the mass fractions (SPH, reference; [m]; ``sph``
    None where the output holds no particles), the interior's max |theta / theta_ref - 1| (None where the
    transient has not reached its end state) and the reference's own departure from it there."""
    t: float
    sph: object
    ref: np.ndarray
    interior: object
    transit: float

    def height_error(self, H0):
        """max |SPH - reference| over the fractions / H0 (None without particles)."""
        return None if self.sph is None else float(np.max(np.abs(self.sph - self.ref))) / H0


def _particles_at(path, times):
    """Per time of ``times``: (fluid x, fluid mass) of the output with particles at that time, else None."""
    snaps = _snapshots(path)
    out = []
    for t in times:
        hit = [(x, m) for ts, x, m in snaps if abs(ts - t) <= 1e-12 * max(1.0, abs(t))]
        out.append(hit[0] if hit else None)
    return out


def interior_error(p, cfg, k, end):
    """max |theta / theta_end(x) - 1| over the interior's bins holding particles at output k (nan if none)."""
    lo, hi = interior_span(cfg)
    theta, count = np.asarray(p["theta"][k], float), np.asarray(p["count"][k], float)
    sel = (p["x"] >= lo) & (p["x"] <= hi) & (count > 0)
    if not sel.any():
        return math.nan
    return float(np.max(np.abs(theta[sel] / end.theta_at(p["x"][sel]) - 1.0)))


def measures(path, p, cfg, tol_theta=TOL_THETA):
    """The layer's :class:`Row` at every output (p: read_profile's dict of the run in ``path``)."""
    from parsph.physics.consolidation import FRACTIONS
    from parsph.setup.scenes import layer
    from parsph.sph.profiles import mass_quantiles
    end = layer.end_state(cfg)
    times = [float(t) for t in p["time"]]
    positive = [t for t in times if t > 0]
    tr = layer.transient(cfg, positive) if positive else None
    lo, hi = interior_span(cfg)
    end_q = end.quantiles(FRACTIONS)
    parts = _particles_at(path, times)
    rows = []
    for k, t in enumerate(times):
        if tr is not None and t > 0:
            ref = tr.quantiles(t)
            xs = tr.centres[(tr.centres >= lo) & (tr.centres <= hi)]
            transit = float(np.max(np.abs(tr.theta_at(t, xs) / end.theta_at(xs) - 1.0))) if xs.size else math.inf
        elif tr is not None:   # t = 0: the initial layer
            H0 = layer.layer_height(cfg)
            ref, transit = np.asarray(FRACTIONS) * H0, math.inf
        else:                  # no gas: the end state is the reference throughout
            ref, transit = end_q, 0.0
        sph = mass_quantiles(*parts[k], FRACTIONS) if parts[k] is not None else None
        interior = interior_error(p, cfg, k, end) if transit <= STEADY * tol_theta else None
        rows.append(Row(t, sph, np.asarray(ref, float), interior, transit))
    return rows


@dataclass
class Verdict:
    """The layer's worst height error (of H0) and interior error over the outputs (nan where none was judged),
    the tolerances, and whether both hold."""
    heights: float
    interior: float
    tol_heights: float
    tol_theta: float

    @property
    def judged(self):
        """Whether any output was judged by either measure."""
        return not (math.isnan(self.heights) and math.isnan(self.interior))

    @property
    def ok(self):
        return not (self.heights > self.tol_heights or self.interior > self.tol_theta)

    def failures(self):
        out = []
        if self.heights > self.tol_heights:
            out.append(f"a height of the layer's mass {self.heights * 100:.3g}% of H0 from the reference, above "
                       f"the tolerance {self.tol_heights * 100:g}%")
        if self.interior > self.tol_theta:
            out.append(f"the interior theta {self.interior * 100:.3g}% from the end state's, above the tolerance "
                       f"{self.tol_theta * 100:g}%")
        return out


def _worst(values):
    vals = [v for v in values if v is not None]
    return max(vals) if vals else math.nan


def report(path, p, cfg, tol_heights=TOL_HEIGHTS, tol_theta=TOL_THETA):
    """(lines, Verdict): the layer's table of :func:`measures` with its header and a closing line."""
    from parsph.physics.consolidation import FRACTIONS
    from parsph.setup.scenes import layer
    H0 = layer.layer_height(cfg)
    end = layer.end_state(cfg)
    lo, hi = interior_span(cfg)
    rows = measures(path, p, cfg, tol_theta)
    tr = layer.transient(cfg, [r.t for r in rows if r.t > 0] or [1.0])
    if cfg.gas is None:
        what = "the end state (no gas: the layer falls under gravity alone to the hydrostatic sediment)"
    elif tr is None:
        what = ("the end state (the steady column with the packing limit's frictional pressure; the transient's "
                "solver has G's pressure only)")
    else:
        what = (f"the layer's transient (the sedimentation-consolidation equation of the column closure, "
                f"{tr.cells} cells)")
    if end.U > 0:
        l = _compression_length(cfg)
        shape = (f"the bed's steady column, theta* = {end.theta_star:.4g}"
                 + (f", not uniform: compression length {l * 1e3:.3g} mm" if l > 0.05 * (hi - lo) else
                    f", uniform inside: compression length {l * 1e3:.3g} mm"))
    else:
        shape = f"the hydrostatic sediment, theta = {end.theta_floor:.4g} at the floor"
    pct = "  ".join(f"{int(round(f * 100)):>13d}%" for f in FRACTIONS)
    lines = [f"layer check: the heights below which 5, 25, 50, 75, 95% of the mass lies, SPH (SPH - reference), in %"
             f" of H0 = {H0 * 1e3:.4g} mm, against {what}; tolerance {tol_heights * 100:g}% of H0",
             f"the interior's theta ({lo * 1e3:.3g} to {hi * 1e3:.3g} mm), max |theta / theta_ref - 1| over its "
             f"bins, against the end state ({shape}) "
             f"{'at every output' if cfg.gas is None else 'where the transient has reached it'}; tolerance "
             f"{tol_theta * 100:g}%",
             f"{'t [s]':>10} {pct}  {'max |diff|':>10}  interior theta"]
    for r in rows:
        err = r.height_error(H0)
        if r.sph is None:
            heights = f"{'(no particles written: heights not measured)':<{15 * len(FRACTIONS)}}"
            worst = f"{'-':>10}"
        else:
            heights = "  ".join(f"{s / H0 * 100:6.2f} ({(s - f) / H0 * 100:+5.2f})" for s, f in zip(r.sph, r.ref))
            worst = f"{err * 100:9.2f}%" + ("" if err <= tol_heights else " > tol")
        if r.interior is None:
            inner = f"in transit (the reference {r.transit * 100:.3g}% from its end state)" \
                if math.isfinite(r.transit) else "in transit"
        elif math.isnan(r.interior):
            inner = "no particle in the interior"
        else:
            inner = f"{r.interior * 100:.3g}%" + ("" if r.interior <= tol_theta else " > tol")
        lines.append(f"{r.t:>10.4g}  {heights}  {worst}  {inner}")
    verdict = Verdict(_worst(r.height_error(H0) for r in rows), _worst(r.interior for r in rows), tol_heights,
                      tol_theta)
    measured = sum(r.sph is not None for r in rows)
    judged = sum(r.interior is not None and not math.isnan(r.interior) for r in rows)
    heights = (f"heights within {verdict.heights * 100:.3g}% of H0 at {measured} of {len(rows)} outputs" if measured
               else "no heights measured (no output with particles)")
    inner = (f"interior theta within {verdict.interior * 100:.3g}% at {judged} (at its end state)" if judged
             else "the interior not judged (the layer in transit at every output)")
    lines.append(f"layer: {heights}; {inner}")
    return lines, verdict


def _compression_length(cfg):
    from parsph.physics import bed_expansion
    from parsph.setup.scenes import layer
    return bed_expansion.compression_length(cfg.gas.U, layer.phases(cfg), cfg.G_a, cfg.G_b, layer.form(cfg),
                                           cfg.packing)


def profile_figure(p, cfg):
    """theta(x) and v_x(x) over their references, one panel each (a Figure): theta over the layer's transient
    (:func:`parsph.setup.scenes.layer.transient`; without a gas the scene's end state), v_x over the scene's."""
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.4))
    colors = plt.cm.viridis(np.linspace(0, 0.9, max(1, len(p["time"]))))
    L = cfg.L
    x_fine = np.linspace(0.0, L, 401)
    from parsph.setup.scenes import layer
    positive = [float(t) for t in p["time"] if t > 0]
    tr = layer.transient(cfg, positive) if positive else None
    for c, t, k in zip(colors, p["time"], range(len(p["time"]))):
        ref = cfg.scene.reference(cfg, x_fine, float(t))
        if tr is not None and t > 0:   # theta: the transient the check judges by (the scene's steps in time)
            ref = {**ref, "theta": tr.theta_at(float(t), x_fine)}
        for ax, key in zip(axes, ("theta", "vx")):
            ax.plot(x_fine / L, ref[key], "-", color=c, lw=1.2)
            ax.plot(p["x"] / L, p[key][k], "o", color=c, ms=3, label=f"t = {t:g} s")
    axes[0].set_ylabel("theta")
    axes[1].set_ylabel("v_x [m/s]")
    for ax in axes:
        ax.set_xlabel("x / L (floor 0, lid 1)")
        ax.set_xlim(0.0, 1.0)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{cfg.scene.name}: SPH (points) against the reference (lines; theta: the layer's transient)")
    fig.tight_layout()
    return fig


def top_png(profile_png):
    """DIR/<stem>_interface.png beside DIR/<stem>_profile.png."""
    return re.sub(r"_profile\.png$", "_interface.png", profile_png)


def top_figure(path, p, cfg):
    """The heights below which 5, 25, 50, 75, 95% of the layer's mass lies against time: the SPH's (points, from
    the outputs with particles) over the transient's (lines; without a gas, the end state's), what the check
    judges; for a sedimentation also Kynch's interface line and sediment front (dashed). A Figure."""
    import matplotlib.pyplot as plt
    from parsph.physics.consolidation import FRACTIONS
    from parsph.setup.scenes import layer
    from parsph.sph.profiles import mass_quantiles
    end = layer.end_state(cfg)
    snaps = _snapshots(path)
    t_end = max([cfg.t_end] + [t for t, _, _ in snaps])
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    colors = plt.cm.viridis(np.linspace(0, 0.9, len(FRACTIONS)))
    tt = np.linspace(0.0, t_end, 121)[1:]
    tr = layer.transient(cfg, tt)
    ref = np.array([tr.quantiles(t) for t in tt]) if tr is not None else \
        np.tile(end.quantiles(FRACTIONS), (tt.size, 1))
    for j, (f, c) in enumerate(zip(FRACTIONS, colors)):
        ax.plot(tt, ref[:, j] * 1e3, "-", color=c, lw=1.2, label=f"{f * 100:g}% of the mass below")
        if snaps:
            ax.plot([t for t, _, _ in snaps], [mass_quantiles(x, m, [f])[0] * 1e3 for _, x, m in snaps], "o",
                    color=c, ms=4)
    if cfg.scene.name == "sedimentation" and cfg.gas is not None:
        k = layer.sedimentation(cfg)
        tk = np.linspace(0.0, k.meeting_time, 101)
        ax.plot(tk, k.interface(tk) * 1e3, "--", color="0.5", lw=1, label="Kynch: interface, sediment front")
        ax.plot(tk, k.sediment_front(tk) * 1e3, "--", color="0.5", lw=1)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("height [mm]")
    what = "the layer's transient" if tr is not None else "the end state"
    ax.set_title(f"{cfg.scene.name}: heights of the mass fractions, SPH (points) over {what} (lines)", fontsize=9)
    ax.legend(fontsize=7)
    ax.set_ylim(bottom=0)
    fig.tight_layout()
    return fig


def save(fig, png):
    import matplotlib.pyplot as plt
    os.makedirs(os.path.dirname(os.path.abspath(png)), exist_ok=True)
    fig.savefig(png, dpi=120)
    plt.close(fig)
    return png
