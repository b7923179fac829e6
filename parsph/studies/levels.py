"""The run files of a ``parsph converge`` study: a family's numerics, its levels, the bias run's viscosity.

Pure functions of :class:`parsph.setup.runfile.RunFile` values (no runs, no MPI); the study
(:mod:`.converge`) runs them and the analysis (:mod:`.converge_report`) reads them back.
"""
from typing import NamedTuple

from parsph.setup import config
from . import estimates

# Numerics of the presets (docs/accuracy.md, "The frontier"), for --family; "given" is the run file's own.
FAMILIES = {
    "fast": {"kernel": "cubic_spline", "h_over_dx": 1.25, "beta_max": 6.0},       # run/couette_fast.toml
    "accurate": {"kernel": "wendland_c2", "h_over_dx": 2.5, "beta_max": 8.0},     # run/couette_accurate.toml
    "paper": {"kernel": "cubic_spline", "h_over_dx": 1.25, "beta_max": 1.5},      # run/couette_paper.toml
}
DT_SCALINGS = ("limit", "dx2")
BIAS_MIN = 1e-6  # |b| below this: no bias run (its effect is below any error measured here)


class Level(NamedTuple):
    """One level of a family: N_x and its run file."""
    nx: int
    run_file: object


class FamilyPlan(NamedTuple):
    """A family's levels, coarsest first."""
    family: str
    levels: tuple


def family_run_file(run_file, family):
    """The run file with a family's numerics (dt "auto" for a preset family)."""
    if family == "given":
        return run_file
    f = FAMILIES[family]
    return (run_file.drop("numerics", "h").set("numerics", kernel=f["kernel"], h_over_dx=f["h_over_dx"], dt="auto")
            .set("walls", beta_max=f["beta_max"]))


def level_run_file(run_file, nx, dt_scaling="limit"):
    """Level N_x of a run file: h / dx kept, dt by ``dt_scaling``, no particle snapshots.

    ``"limit"``: ``dt = "auto"`` kept (each level at its own stability limit, times the
    run file's dt_safety), a fixed dt scaled with the limit (its margin kept). Cheapest,
    but the binding limit can change between levels (advection ~ dx, damping ~ 1,
    viscous ~ dx^2), so the first-order time error of Eqs. (6)-(7) is then not one
    power of dx across them. ``"dx2"``: dt_l = dt_0 (N_x0 / N_x)^2 from the base level's
    (its automatic dt at theta_0 for "auto", kept automatic with the dt_safety that gives
    dt_l at theta_0, so it still follows the state), so the time error falls as dx^2 at
    every level; every limit shrinks at most as dx^2, so dt_l stays within them.
    """
    if dt_scaling not in DT_SCALINGS:
        raise ValueError(f"dt_scaling {dt_scaling!r}: one of {DT_SCALINGS}")
    base = config.build(run_file)
    out = run_file.set("numerics", Nx=int(nx))
    if out.get("numerics", "h") is not None:
        out = out.set("numerics", h=base.h * base.Nx / nx)
    lim = min(config.build(out.set("numerics", dt="auto")).limits.values())
    if dt_scaling == "dx2":
        dt = float(base.dt) * (base.Nx / nx) ** 2
        if out.get("numerics", "dt") == "auto":
            out = out.set("numerics", dt_safety=min(1.0, dt / lim))
        else:
            out = out.set("numerics", dt=dt)
    elif out.get("numerics", "dt") != "auto":
        out = out.set("numerics", dt=float(base.dt) * lim / min(base.limits.values()))
    return out.set("output", snapshots=False)


def plan_family(run_file, family, levels, ratio, dt_scaling):
    """A family's levels N_x0 R^l, l < levels (N_x0: the run file's), each validated: ConfigError names
    the run file's key (the base level is validated first)."""
    base = family_run_file(run_file, family)
    nx0 = config.build(base).Nx
    plan = FamilyPlan(family, tuple(Level(nx0 * ratio ** l, level_run_file(base, nx0 * ratio ** l, dt_scaling))
                                    for l in range(levels)))
    for level in plan.levels:
        config.build(level.run_file)
    return plan


def bias_of(run_file):
    """b in nu_eff = (1 + b) nu for a run file's kernel, h/dx and lattice spacings (None for a scene
    without viscosity)."""
    cfg = config.build(run_file)
    if cfg.k == 0 or not cfg.viscosity:
        return None
    return estimates.kernel_bias(cfg.kernel, cfg.h / cfg.dx, cfg.dim, dy=cfg.dy / cfg.dx, dz=cfg.dz / cfg.dx)


def bias_run_file(run_file, b):
    """The run file with the viscosity k / (1 + b): on a lattice whose operator gives (1 + b) k, the
    flow of viscosity k."""
    return run_file.set("material", k=float(run_file.get("material", "k")) / (1.0 + b))
