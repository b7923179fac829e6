"""The runs of the stability map (docs/stability.md): its columns, each run at a multiple of the predicted
time-step limit, and the row each run leaves in the map's CSVs.

Every run is the real solver (``Simulation.run``, the loop ``parsph run`` drives)
on ``MPI.COMM_SELF`` in one process: the flow is 1-D in x, so a short periodic
box ``L_y = 8 h`` (10 rows) carries it and the slab decomposition plays no
part. A Couette column is (theta_0, Re) at one N_x, Re = V_w L rho_s /
(k theta_0) (:func:`parsph.studies.builders.couette_k`); a run takes ``STEPS`` =
2,000 steps of a fixed

    dt = multiple * predicted limit,  predicted limit = the smallest of config.build's limits at theta_0

(``parsph.physics.limits``: the von Neumann limit of the integrator, advection
0.5 h / V_w; ``numerics.allow_unstable_dt`` lets the multiples above 1 run).
The package's guard runs every step (``checks.every = 1``) with the threshold
THETA_FRAC and stops the run; the observer (:class:`parsph.studies.stability.
Recorder`) records the four criteria separately at every step, and a guard
failure counts for its criterion by its ``GuardResult.code``:

    nonfinite  a fluid particle with a non-finite position or velocity (the guard: acceleration too)
    wall       a fluid particle beyond a wall plane (x < 0 or x > L)
    theta      max |theta - theta_0| / theta_0 over fluid particles > THETA_FRAC
    energy     fluid kinetic energy > 1/2 M V_w^2 (the maximum principle |v| <= V_w)

A row (FIELDS) holds the step each criterion first fired (-1: never), the
largest theta deviation, kinetic-energy ratio and speed ratio seen, the
guard's message, the profile error against Eq. (8) at the end of stable runs,
and the short commit the run was made at (empty in rows from before the
column; a CSV whose header lacks it is appended to without it).

The settling column (run/settling.toml: gravity -30 m/s^2 along x, floor and
lid, k = 1, the consistent pressure form, the paper integrator) at theta_0 in
SETTLING["theta0"], N_x = SETTLING["nx"], L_y = 8 h: its predicted limit is
config.build's (min(CFL with sqrt(g h), viscous, force with |g|, damping) at
theta_0); each run lasts SETTLING["steps"] steps of that limit in time (the
column's first transient, not its settling: that takes 0.4 s), and at least
SETTLING["min_steps"] steps (a time-step instability grows per step).
Criteria: non-finite; wall = a fluid particle below the floor or above the
lid; theta = max |theta - theta_eq(x)| / theta_eq(x) > THETA_FRAC against the
equilibrium the run's pressure form converges to (scenes/settling.wall_theta);
energy above the scene's own bound (M g L). The recorder stops a run at its
first failure (these are not the guard's criteria).
"""
from functools import lru_cache
import math
import os
from typing import NamedTuple

import numpy as np

from parsph.physics import limits
from parsph.physics.closures import modulus
from . import builders
from .machine import commit
from .runs import append_row, load_rows
from .stability import Recorder, Results, run_and_classify

THETAS = (0.05, 0.1, 0.2, 0.35, 0.5, 0.6, 0.64, 0.7)
RES = (1.0, 10.0, 57.0, 400.0, 2000.0)
MULTS = (0.25, 0.5, 1.0, 1.5, 2.0, 4.0)
NXS = (10, 50, 200)
STEPS = 2000
THETA_FRAC = 0.2       # criterion "theta": largest accepted |theta - theta0| / theta0
LY_IN_H = 8            # L_y = 8 h = 10 dx: 10 lattice rows
MIDPOINT = {"theta0": (0.5, 0.6, 0.64, 0.7), "Re": (10.0, 57.0, 400.0, 2000.0), "multiple": (0.5, 1.0, 2.0)}
SETTLING = {"theta0": (0.55, 0.6, 0.64, 0.7), "nx": 20, "steps": 2000, "min_steps": 1000}

FIELDS = ["nx", "theta0", "Re", "k", "multiple", "dt", "dt_limit", "limit_term", "dt_cfl", "dt_viscous",
          "dt_acoustic_damping", "steps_planned", "steps_done", "t_done", "stable", "first_failure",
          "fail_step", "nonfinite_step", "wall_step", "theta_step", "energy_step", "max_theta_dev",
          "max_ke_ratio", "max_speed_ratio", "err_max", "err_rms", "guard", "crash", "message", "wall_s",
          "source", "commit"]
SETTLING_FIELDS = FIELDS + ["integrator", "dt_force", "dt_damping", "theta_eq_max", "dt_limit_eq",
                            "limit_term_eq", "ke_bound"]
AUTO_FIELDS = ["nx", "theta0", "Re", "integrator", "k", "dt_first", "term", "steps_done", "t_done", "stable",
               "fired", "message", "wall_s", "commit"]


@lru_cache(maxsize=1)
def run_commit():
    """The short commit the rows are run at (a row without one predates the column: see docs/stability.md)."""
    return commit()


# ---- the Couette columns -------------------------------------------------------------------------------
class Prediction(NamedTuple):
    """A Couette column's k [Pa s], h [m], the predicted limits [s] (config.build's), the binding term,
    and 2 nu / c_eff^2 [s] (the acoustic damping limit's asymptote, the paper form's sound speed)."""
    k: float
    h: float
    limits: dict
    term: str
    acoustic_damping: float

    @property
    def dt(self):
        """The predicted limit [s]."""
        return self.limits[self.term]


def prediction(theta0, Re, nx, integrator="paper"):
    """The prediction now for the Couette column (theta_0, Re) at N_x (a Prediction; memoised)."""
    return _prediction(float(theta0), float(Re), int(nx), integrator)


@lru_cache(maxsize=4096)
def _prediction(theta0, Re, nx, integrator):
    cfg = builders.couette(nx, ly_in_h=LY_IN_H, theta0=theta0, re=Re, overrides=[f'numerics.integrator="{integrator}"'])
    lim = dict(cfg.limits)
    c2 = limits.sound_speed(theta0, cfg.rho_s, cfg.G_a, cfg.G_b, "paper") ** 2
    return Prediction(cfg.k, cfg.h, lim, min(lim, key=lim.get), 2.0 * cfg.k * theta0 / cfg.rho_s / c2)


def case_config(theta0, Re, nx, multiple, steps=STEPS, theta_frac=THETA_FRAC, extra=(), integrator="paper"):
    """The column's Couette case (builders.couette: L_y = 8 h) at dt = multiple x the predicted limit for
    ``steps`` steps, the guard at every step with the map's theta threshold."""
    return builders.couette(nx, ly_in_h=LY_IN_H, dt=multiple * prediction(theta0, Re, nx, integrator).dt, steps=steps,
                         theta0=theta0, re=Re, overrides=[
                             "numerics.allow_unstable_dt=true", "checks.every=1", f"checks.theta_change={theta_frac!r}",
                             "checks.energy=true", f'numerics.integrator="{integrator}"', *extra])


def run_case(theta0, Re, nx, multiple, steps=STEPS, theta_frac=THETA_FRAC, source="grid", integrator="paper"):
    """Run one case; return its CSV row (dict)."""
    cfg = case_config(theta0, Re, nx, multiple, steps, theta_frac, integrator=integrator)
    p = prediction(theta0, Re, nx, integrator)
    outcome = run_and_classify(cfg, Recorder(cfg, theta_frac))
    return {
        "nx": nx, "theta0": theta0, "Re": Re, "k": p.k, "multiple": multiple, "dt": cfg.dt,
        "dt_limit": p.dt, "limit_term": p.term, "dt_cfl": p.limits["advection"],
        "dt_viscous": p.limits.get("viscous", math.inf), "dt_acoustic_damping": p.acoustic_damping,
        "steps_planned": cfg.nsteps, **outcome, "source": source, "commit": run_commit(), "integrator": integrator,
    }


def run_auto(theta0, Re, nx, steps=STEPS, integrator="paper"):
    """dt = "auto" (the run's limits) for about ``steps`` steps of its first dt (config.build's):
    (the outcome's CSV columns, the first dt)."""
    cfg = case_config(theta0, Re, nx, 1.0, steps, extra=['numerics.dt="auto"'], integrator=integrator)
    return run_and_classify(cfg, Recorder(cfg, THETA_FRAC)), cfg.dt


def couette_results(path, integrator="paper", steps=STEPS):
    """The resumable CSV of the Couette runs of one integrator (runs of ``steps`` steps)."""
    return Results(path, lambda t, r, nx, m, source: run_case(t, r, nx, m, steps=steps, source=source,
                                                              integrator=integrator), FIELDS)


def grid(nxs, quick=False):
    """The map's (theta_0, Re, N_x, multiple) runs: the whole grid at each N_x (quick: 12 runs)."""
    if quick:
        return [(t, r, 50, m) for t in (0.05, 0.7) for r in (57.0, 2000.0) for m in (0.5, 1.0, 4.0)]
    return [(t, r, nx, m) for nx in nxs for t in THETAS for r in RES for m in MULTS]


# ---- the settling column -------------------------------------------------------------------------------
def settling_limits(theta0, nx, theta=None):
    """The predicted limits [s] of the column at theta (default theta_0)."""
    return builders.settling_limits(nx, theta0, ly_in_h=LY_IN_H, theta=theta)


def settling_config(theta0, nx, multiple, steps=None, extra=()):
    """The column at dt = multiple x the predicted limit, for steps x that limit in time, and for
    at least SETTLING["min_steps"] steps (a time-step instability grows per step)."""
    lim = min(settling_limits(theta0, nx).values())
    steps = max(steps or SETTLING["steps"], SETTLING["min_steps"] * multiple)
    return builders.settling(nx, theta0, ly_in_h=LY_IN_H, dt=multiple * lim, t_end=steps * lim, overrides=[
        "checks.every=1", "checks.theta_change=1.0", "checks.energy=true", *extra])


def settling_recorder(cfg):
    """The column's criteria, the run stopped at the first that fails: theta against the balance the
    run's pressure form converges to (what the scene's walls hold), the scene's energy bound; and
    that balance on 2,001 points of [0, L]."""
    xs = np.linspace(0.0, cfg.L, 2001)
    theta_eq = cfg.scene.wall_theta(cfg, xs)
    return Recorder(cfg, THETA_FRAC, theta_ref=lambda x: np.interp(x, xs, theta_eq), stop=True), theta_eq


def run_settling_case(theta0, Re, nx, multiple, source="grid", steps=None):
    """One column run; its CSV row (Re is the column's, sqrt(g h) L / nu: one k)."""
    cfg = settling_config(theta0, nx, multiple, steps)
    lim = settling_limits(theta0, nx)
    term = min(lim, key=lim.get)
    rec, theta_eq = settling_recorder(cfg)
    th_eq = float(theta_eq.max())
    lim_eq = settling_limits(theta0, nx, th_eq)
    outcome = run_and_classify(cfg, rec)
    c2 = modulus(theta0, cfg.G_a, cfg.G_b) / cfg.rho_s
    return {
        "nx": nx, "theta0": theta0, "Re": Re, "k": cfg.k, "multiple": multiple, "dt": cfg.dt,
        "dt_limit": lim[term], "limit_term": term, "dt_cfl": lim["advection"],
        "dt_viscous": lim.get("viscous", math.inf),
        "dt_acoustic_damping": 2.0 * cfg.nu / c2, "steps_planned": cfg.nsteps,
        **outcome, "source": source, "commit": run_commit(),
        "integrator": cfg.integrator, "dt_force": lim["force"], "dt_damping": lim.get("damping", math.inf),
        "theta_eq_max": th_eq, "dt_limit_eq": min(lim_eq.values()), "limit_term_eq": min(lim_eq, key=lim_eq.get),
        "ke_bound": cfg.scene.max_kinetic_energy(cfg, 1.0),
    }


def settling_re(theta0, nx):
    """The column's Reynolds number sqrt(g h) L / nu (its key in the CSV)."""
    return round(settling_config(theta0, nx, 1.0).reynolds, 6)


def settling_results(path):
    """The resumable CSV of the settling column's runs."""
    return Results(path, lambda t, r, nx, m, source: run_settling_case(t, r, nx, m, source), SETTLING_FIELDS)


# ---- dt = "auto" runs (stability_auto.csv) -----------------------------------------------------------
def auto_row(nx, theta0, Re, integrator, outcome, first, term, k):
    return {"nx": nx, "theta0": repr(theta0), "Re": repr(Re), "integrator": integrator, "k": k,
            "dt_first": first, "term": term, "steps_done": outcome["steps_done"], "t_done": outcome["t_done"],
            "stable": outcome["stable"], "fired": outcome["first_failure"], "message": outcome["message"],
            "wall_s": outcome["wall_s"], "commit": run_commit()}


def record_auto(path, row):
    append_row(path, AUTO_FIELDS, row)
    print(f"auto Nx={row['nx']} theta0={row['theta0']} Re={row['Re']} {row['integrator']}: first dt "
          f"{row['dt_first']:.3g} s ({row['term']}), {row['steps_done']} steps, "
          f"{'stable' if row['stable'] else 'UNSTABLE ' + row['fired'] + ' ' + row['message']}", flush=True)


# ---- rows against the prediction now -------------------------------------------------------------------
def columns_of(path, cols=None):
    """{(integrator, N_x, theta_0, Re): rows} of a CSV of Couette runs (added to ``cols``); the settling
    column's runs (a file named *settling*) as integrator 'settling'."""
    cols = {} if cols is None else cols
    settling = "settling" in os.path.basename(path)
    for r in load_rows(path):
        if settling:
            integ = "settling"
        else:
            r.setdefault("integrator", "paper")
            if "midpoint" in os.path.basename(path):
                r["integrator"] = "midpoint"
            integ = r["integrator"] or "paper"
        cols.setdefault((integ, int(r["nx"]), round(float(r["theta0"]), 6), round(float(r["Re"]), 6)), []).append(r)
    return cols


def renormalised(rows, integrator="paper"):
    """The rows with ``multiple`` = dt / the prediction now (runs made against any earlier prediction
    are at an absolute dt), so that bounds, verdicts and figures are in multiples of the new limit."""
    out = []
    for r in rows:
        integ = r.get("integrator") or integrator
        p = prediction(float(r["theta0"]), float(r["Re"]), int(r["nx"]), integ).dt
        out.append({**r, "integrator": integ, "multiple": repr(float(r["dt"]) / p), "dt_limit": repr(p)})
    return out


def renormalised_settling(rows):
    """Settling rows against the prediction now: multiple, dt_limit, the limit at the floor's theta and the
    classical terms (what the settling figure draws)."""
    out, cache = [], {}
    for r in rows:
        t = float(r["theta0"])
        if t not in cache:
            lim = settling_limits(t, SETTLING["nx"])
            eq = settling_limits(t, SETTLING["nx"], float(r["theta_eq_max"]))
            cache[t] = {"dt_limit": min(lim.values()), "limit_term": min(lim, key=lim.get),
                        "dt_limit_eq": min(eq.values()), "dt_cfl": lim["advection"],
                        "dt_viscous": lim.get("viscous", math.inf), "dt_force": lim["force"]}
        c = cache[t]
        out.append({**r, **{k: repr(v) if isinstance(v, float) else v for k, v in c.items()},
                    "multiple": repr(float(r["dt"]) / c["dt_limit"])})
    return out
