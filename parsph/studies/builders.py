"""The cases the studies, benchmarks and tests run, built from Table 1 (:mod:`parsph.physics.table1`).

:func:`paper_run_file` is the paper's case as a run file (``run/couette_paper.toml``
is the same case, with comments); :func:`couette` is the one builder of the
Couette case at any N_x that the stability map, the sweep, the benchmarks and
the tests start from (a short periodic box ``L_y = ly_in_h h`` carries the
flow, which is 1-D in x); :func:`bench` is the benchmarks' Couette case.
:func:`settling` builds the granular column of ``run/settling.toml`` the same
way, and :func:`settling_limits` gives its predicted time-step limits. The
Reynolds number of a Couette column gives its k here and nowhere else
(:func:`couette_k`).
"""
import math

from parsph.physics import limits, table1
from parsph.setup import config
from parsph.setup.runfile import RunFile
from .machine import REPO

SETTLING_RUN = REPO / "run" / "settling.toml"


def paper_run_file():
    """Table 1 as a run file: the paper's transient Couette flow, square box, dt = 1e-5 s."""
    return RunFile({
        "scene": {"name": "couette", "dim": 2},
        "domain": {"L": table1.L, "Ly": table1.L},
        "material": {"rho_s": table1.RHO_S, "theta0": table1.THETA0, "k": table1.K},
        "walls": {"V_w": table1.V_W},
        "numerics": {"Nx": table1.NX, "h_over_dx": table1.H_OVER_DX, "dt": table1.DT,
                     "kernel": "cubic_spline", "integrator": "paper"},
        "output": {"t_end": table1.T_END, "times": list(table1.TIMES)},
    })


def couette_k(re, theta0=table1.THETA0):
    """k [Pa s] of the Couette case with Reynolds number Re = V_w L rho_s / (k theta_0) (Table 1's V_w,
    L and rho_s): how the stability map's columns, given by (theta_0, Re), set their viscosity."""
    return abs(table1.V_W) * table1.L * table1.RHO_S / (re * theta0)


def couette(nx=table1.NX, *, h_over_dx=table1.H_OVER_DX, ly_in_h=None, dt="auto", steps=None, overrides=(),
            theta0=None, re=None):
    """The paper's Couette case at N_x = ``nx`` with h = ``h_over_dx`` dx, as a RunConfig.

    ``ly_in_h``: L_y = ly_in_h h (h = h_over_dx L / N_x), else L; ``dt``: "auto" or seconds; no output
    times and no progress lines; ``theta0``: the initial volume fraction (else Table 1's), ``re``: the
    Reynolds number, which sets k (:func:`couette_k`; else Table 1's k); ``overrides``:
    ``section.key=value`` strings, applied after those; ``steps``: then t_end = steps dt (for "auto":
    the run's first dt, at theta_0).
    """
    rf = paper_run_file().set("numerics", Nx=int(nx), h_over_dx=h_over_dx, dt=dt)
    if ly_in_h is not None:
        rf = rf.set("domain", Ly=ly_in_h * (h_over_dx * (table1.L / nx)))
    if theta0 is not None:
        rf = rf.set("material", theta0=theta0)
    if re is not None:
        rf = rf.set("material", k=couette_k(re, rf.get("material", "theta0")))
    rf = rf.set("output", times=[], progress_interval=0.0).override(overrides)
    if steps is None:
        return config.build(rf)
    dt0 = config.build(rf.set("output", t_end=1.0)).dt if dt == "auto" else dt
    return config.build(rf.set("output", t_end=steps * dt0))


def bench(nx, overrides=()):
    """The benchmarks' case (scripts/bench.py, bench_pairs.py, scaling.py, dispatch_bench.py): the Couette
    case at N_x = ``nx``, L_y = L, h = 1.25 dx, dt = "auto", t_end = 1 s (longer than any benchmark)."""
    return couette(nx, overrides=["output.t_end=1.0", *overrides])


def settling_run_file(nx, theta0, *, ly_in_h):
    """``run/settling.toml`` at N_x = ``nx`` and theta_0 with L_y = ly_in_h h (h = h_over_dx L / N_x)."""
    rf = RunFile.read(SETTLING_RUN)
    h = rf.get("numerics", "h_over_dx") * (rf.get("domain", "L") / nx)
    return rf.set("numerics", Nx=int(nx)).set("material", theta0=theta0).set("domain", Ly=ly_in_h * h)


def settling_limits(nx, theta0, *, ly_in_h, theta=None):
    """The predicted limits [s] of the settling column at theta (default theta_0): those config.build
    takes (:func:`parsph.physics.limits.run_limits`: velocity scale sqrt(g h), |g|, the run file's
    integrator and pressure form)."""
    cfg = config.build(settling_run_file(nx, theta0, ly_in_h=ly_in_h).set("numerics", dt="auto"))
    g = math.sqrt(sum(x * x for x in cfg.g))
    return limits.run_limits(cfg, theta0 if theta is None else theta, cfg.velocity_scale, g)


def settling(nx, theta0, *, ly_in_h, dt, t_end, overrides=()):
    """The settling column at N_x = ``nx``, theta_0 and a fixed ``dt`` (numerics.allow_unstable_dt: the
    studies run it above its limit) to ``t_end``, no output times and no progress lines, as a RunConfig;
    ``overrides``: ``section.key=value`` strings applied after those."""
    rf = (settling_run_file(nx, theta0, ly_in_h=ly_in_h).set("numerics", dt=dt, allow_unstable_dt=True)
          .set("output", t_end=t_end, times=[], progress_interval=0.0))
    return config.build(rf.override(overrides))
