"""Layers under clear gas (docs/physics.md, "The solid phase in a gas", references 3 and 4): runs of the
``sedimentation`` and ``fluidized_bed`` scenes measured against their references, for the tests
(tests/test_layers_scenes.py), the study (scripts/layers_study.py) and docs/validation.md.

Every run is in-process on one rank (``MPI.COMM_SELF``); a run file's values with overrides (``sets``,
"key=value" strings as ``parsph run --set`` takes them). The measures:

- the interface: :func:`parsph.sph.projected.interface_height` at theta0 / 2 (the top of Eq. (3)'s field
  averaged across the box), against Kynch's line H0 + v0 t (:func:`parsph.physics.kynch.batch_sedimentation`);
- the end state: the sediment's (or bed's) height at a level against the end state Column's
  (:func:`parsph.setup.scenes.layer.end_state`), and the particles' theta against the Column's theta(x) in
  the interior (from 2h above the floor to 2h below where the Column falls to half its interior value);
- a bed's interior: the same with the steady column at U (its interior is theta*).

Errors of heights are relative to H0; of theta, relative to the reference's theta at the particle.
"""
from dataclasses import dataclass, field
import math
from pathlib import Path

import numpy as np
from mpi4py import MPI

from parsph.physics import bed_expansion
from parsph.setup import config
from parsph.setup.runfile import RunFile
from parsph.setup.scenes import layer
from parsph.simulation.solver import Simulation
from parsph.sph import projected
from parsph.sph.particles import GRAIN

RUN = Path(__file__).resolve().parents[2] / "run"
SEDIMENTATION = RUN / "sedimentation.toml"
BED = RUN / "fluidized_bed.toml"
BED_AIR = RUN / "fluidized_bed_air.toml"


def fluid_state(sim):
    """The owned fluid particles' (x, mass, theta, |v|) as numpy copies."""
    ps = sim.ps
    f = ps.kind[:ps.n_own] == GRAIN
    v = ps.vel[:ps.n_own][f]
    return (ps.pos[:ps.n_own, 0][f].copy(), ps.mass[:ps.n_own][f].copy(), ps.theta[:ps.n_own][f].copy(),
            np.sqrt((v * v).sum(axis=1)))


@dataclass
class Run:
    """A run stepped to its output times, with what was read at each (``frames``: one dict per time)."""
    cfg: object
    frames: list = field(default_factory=list)
    steps: int = 0


NO_GAS = ("gas.rho", "gas.mu", "gas.flow", "gas.U")


def load(path, sets=(), drop=()):
    """``path`` without the keys ``drop`` ("section.key"), with the overrides ``sets``."""
    rf = RunFile.read(path)
    for name in drop:
        rf = rf.drop(*name.split("."))
    return config.build(rf.override(sets))


def run(path, sets=(), times=(), t_end=None, measure=None, drop=()):
    """Run ``path`` with ``sets`` to ``t_end`` (default max(times)), calling ``measure(sim)`` at each of ``times``
    (the auto step lands on them); returns a :class:`Run` with measure's dicts (plus ``t``)."""
    times = sorted(float(t) for t in times)
    t_end = float(t_end if t_end is not None else times[-1])
    cfg = load(path, [*sets, f"output.t_end={t_end!r}", f"output.times={times!r}", "output.snapshots=false"],
               drop)
    sim = Simulation(cfg, MPI.COMM_SELF)
    out = Run(cfg)

    def output(frame, snapshot):
        row = {"t": sim.t}
        if measure is not None:
            row.update(measure(sim))
        out.frames.append(row)
    sim.run(output=output)
    out.steps = sim.step
    return out


def interior(cfg, end, level_fraction=0.5):
    """The interior of a layer's end state Column ``end``: from 2h above the floor to 2h below where the
    Column falls to ``level_fraction`` of its interior value (theta* for a bed, the floor's for a sediment)."""
    ref = end.theta_star if end.U > 0 else end.theta_floor
    return 2.0 * cfg.h, end.height_of(level_fraction * ref) - 2.0 * cfg.h


def profile_error(cfg, end, x, theta, span=None):
    """max |theta_i / theta_ref(x_i) - 1| over the particles in ``span`` (default :func:`interior`)."""
    lo, hi = interior(cfg, end) if span is None else span
    sel = (x >= lo) & (x <= hi)
    if not sel.any():
        raise ValueError("no particle in the interior")
    return float(np.max(np.abs(theta[sel] / end.theta_at(x[sel]) - 1.0)))


# ---- batch sedimentation (reference 4) -------------------------------------------------------------------
def sedimentation_sets(theta0, H0=None, Ly=None, extra=()):
    sets = [f"material.theta0={theta0!r}"]
    if H0 is not None:
        sets.append(f"scene.height={H0!r}")
    if Ly is not None:
        sets.append(f"domain.Ly={Ly!r}")
    return [*sets, *extra]


def sedimentation(theta0, H0=None, Ly=None, n_times=6, settle=2.0, extra=(), path=SEDIMENTATION):
    """Batch sedimentation at theta0: the interface at ``n_times`` times in (0, t_m) against Kynch's line, then
    the end state at t_m * ``settle`` and t_m * (``settle`` + 1) (the sediment's height at theta0 / 2 and the
    interior profile). Returns a dict of the numbers."""
    cfg0 = load(path, sedimentation_sets(theta0, H0, Ly, extra))
    k = layer.sedimentation(cfg0)
    t_m = k.meeting_time
    kynch_times = list(np.linspace(0.0, t_m, n_times + 2)[1:-1])
    end_times = [settle * t_m, (settle + 1.0) * t_m]

    def measure(sim):
        x, m, th, speed = fluid_state(sim)
        return {"interface": projected.interface_height(sim.cfg, x, m), "x": x, "theta": th,
                "speed": float(speed.max())}
    r = run(path, sedimentation_sets(theta0, H0, Ly, extra), [*kynch_times, *end_times], measure=measure)
    cfg = r.cfg
    H0 = k.H0
    line = [f for f in r.frames if f["t"] < t_m * (1 - 1e-9)]
    errs = [(f["interface"] - float(k.interface(f["t"]))) / H0 for f in line]
    end = k.final
    level = 0.5 * cfg.theta0
    final = r.frames[-1]
    return {
        "theta0": theta0, "H0": H0, "Ly": cfg.Ly, "Nx": cfg.Nx, "steps": r.steps,
        "v0": k.settling_velocity, "front_speed": k.front_speed, "theta_packed": k.theta_packed,
        "meeting_time": t_m, "meeting_height": k.meeting_height,
        "times": [f["t"] for f in line], "interface": [f["interface"] for f in line],
        "kynch": [float(k.interface(f["t"])) for f in line], "interface_errors": errs,
        "end_times": [f["t"] for f in r.frames[len(line):]],
        "end_height": [f["interface"] for f in r.frames[len(line):]],
        "end_height_ref": end.height_of(level),
        "end_height_errors": [(f["interface"] - end.height_of(level)) / H0 for f in r.frames[len(line):]],
        "end_profile_error": profile_error(cfg, end, final["x"], final["theta"]),
        "end_floor_theta": float(np.mean(final["theta"][final["x"] < cfg.dx])), "floor_theta_ref": end.theta_floor,
        "end_speed": final["speed"],
    }


# ---- a layer without gas: the free surface -----------------------------------------------------------------
def free_surface(theta0=0.2, H0=0.005, Ly=8e-4, t_end=0.3, n_times=6, extra=(), path=SEDIMENTATION):
    """A layer at rest under gravity with no gas (``gas.drag = "none"``): the highest particle, and the top
    (interface_height at theta0 / 2 and at theta0 / 20) against the hydrostatic end state's, at
    ``n_times`` times to ``t_end``."""
    sets = [*sedimentation_sets(theta0, H0, Ly, extra), 'gas.drag="none"']
    times = list(np.linspace(0.0, t_end, n_times + 1)[1:])
    cfg0 = load(path, sets, NO_GAS)
    end = layer.end_state(cfg0)

    def measure(sim):
        x, m, th, speed = fluid_state(sim)
        return {"top": projected.interface_height(sim.cfg, x, m),
                "low": projected.interface_height(sim.cfg, x, m, level=0.05 * sim.cfg.theta0),
                "highest": float(x.max()), "speed": float(speed.max()),
                "rms_speed": float(np.sqrt(np.sum(m * speed ** 2) / np.sum(m))), "x": x, "theta": th,
                "reflected": sim.reflections()}
    r = run(path, sets, times, measure=measure, drop=NO_GAS)
    cfg = r.cfg
    ref_top, ref_low = end.height_of(0.5 * theta0), end.height_of(0.05 * theta0)
    return {
        "theta0": theta0, "H0": layer.layer_height(cfg), "h": cfg.h, "steps": r.steps,
        "times": [f["t"] for f in r.frames], "top": [f["top"] for f in r.frames], "top_ref": ref_top,
        "low": [f["low"] for f in r.frames], "low_ref": ref_low,
        "highest": [f["highest"] for f in r.frames], "speed": [f["speed"] for f in r.frames],
        "rms_speed": [f["rms_speed"] for f in r.frames], "floor_theta_ref": end.theta_floor,
        "reflected": r.frames[-1]["reflected"],
        "profile_error": profile_error(cfg, end, r.frames[-1]["x"], r.frames[-1]["theta"]),
    }


# ---- bed expansion (reference 3) --------------------------------------------------------------------------
def bed_velocity(theta_star, cfg):
    """U [m/s] that holds a uniform bed at theta_star for ``cfg``'s grains and gas (the balance's inverse)."""
    return bed_expansion.fluidization_velocity(theta_star, layer.phases(cfg))


def bed(theta_star=None, U=None, H0=None, Ly=None, t_end=2.0, n_times=4, extra=(), path=BED):
    """A fluidised bed at U (or the U of ``theta_star``): the particles' theta in the interior against the
    steady column's theta(x) at the last ``n_times`` // 2 of ``n_times`` times to ``t_end``; the top
    (interface_height at theta* / 2) against the column's."""
    base = [*([f"scene.height={H0!r}"] if H0 is not None else []), *([f"domain.Ly={Ly!r}"] if Ly is not None else []),
            *extra]
    if U is None and theta_star is not None:
        U = bed_velocity(theta_star, load(path, base))
    sets = [*base, *([f"gas.U={U!r}"] if U is not None else [])]
    cfg0 = load(path, sets)
    end = layer.end_state(cfg0)
    times = list(np.linspace(0.0, t_end, n_times + 1)[1:])

    def measure(sim):
        x, m, th, speed = fluid_state(sim)
        return {"top": projected.interface_height(sim.cfg, x, m, level=0.5 * end.theta_star),
                "error": profile_error(sim.cfg, end, x, th), "speed": float(speed.max()),
                "mean": float(np.mean(th[(x >= interior(sim.cfg, end)[0]) & (x <= interior(sim.cfg, end)[1])]))}
    r = run(path, sets, times, measure=measure)
    ph = layer.phases(r.cfg)
    U = r.cfg.gas.U
    return {
        "U": U, "theta_star": end.theta_star, "eps_star": 1.0 - end.theta_star, "steps": r.steps,
        "u_t": ph.u_t, "H0": layer.layer_height(r.cfg), "Ly": r.cfg.Ly,
        "rz_theta": bed_expansion.richardson_zaki_fraction(U, ph) if U < ph.u_t else math.nan,
        "compression_length": bed_expansion.compression_length(U, ph, r.cfg.G_a, r.cfg.G_b, layer.form(r.cfg),
                                                                    r.cfg.packing),
        "U_mf": bed_expansion.minimum_fluidization_velocity(r.cfg.theta0, ph),
        "top_ref": end.height_of(0.5 * end.theta_star),
        "times": [f["t"] for f in r.frames], "errors": [f["error"] for f in r.frames],
        "means": [f["mean"] for f in r.frames], "tops": [f["top"] for f in r.frames],
        "speed": [f["speed"] for f in r.frames],
    }


# ---- plots -------------------------------------------------------------------------------------------------
def plot_bed_expansion(beds, path, ph):
    """eps against U: Richardson & Zaki's line (Stokes) and the beds' interior eps (1 - their mean theta)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5.2, 3.8))
    U = np.linspace(0.002, 0.9 * ph.u_t, 200)
    ax.plot(U * 1e3, [1.0 - bed_expansion.richardson_zaki_fraction(u, ph) for u in U], "k-",
            label=r"Richardson & Zaki: $U = u_t\,\varepsilon^{4.65}$")
    ax.plot([b["U"] * 1e3 for b in beds], [1.0 - b["means"][-1] for b in beds], "o", color="C3",
            label="parsph: interior of the bed")
    ax.set_xlabel("U [mm/s]")
    ax.set_ylabel(r"$\varepsilon = 1 - \theta$ in the bed")
    ax.set_title("Bed expansion: glass 0.3 mm in water, Stokes drag", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_sedimentation(cases, path):
    """Interface height against time over Kynch's lines (and the sediment fronts), one colour per theta0."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5.6, 4.0))
    for i, c in enumerate(cases):
        col = f"C{i}"
        tm = c["meeting_time"]
        t = np.array([0.0, tm])
        ax.plot(t, (c["H0"] + c["v0"] * t) * 1e3, "-", color=col, lw=1)
        ax.plot(t, c["front_speed"] * t * 1e3, "--", color=col, lw=1)
        ax.plot(c["times"], np.array(c["interface"]) * 1e3, "o", color=col, ms=4,
                label=fr"$\theta_0$ = {c['theta0']:g}")
        ax.plot(c["end_times"], np.array(c["end_height"]) * 1e3, "s", color=col, ms=4, mfc="none")
        ax.axhline(c["end_height_ref"] * 1e3, color=col, lw=0.6, ls=":")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("height [mm]")
    ax.set_title("Batch sedimentation: interface (o) on Kynch's line, sediment front (--),\n"
                 "after the meeting (s) on the hydrostatic sediment (:)", fontsize=9)
    ax.legend(fontsize=8)
    ax.set_ylim(bottom=0)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
