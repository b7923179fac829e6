"""The cases the studies, benchmarks and tests run, built from Table 1 (:mod:`parsph.physics.table1`).

:func:`paper_run_file` is the paper's case as a run file (``run/couette_paper.toml``
is the same case, with comments); :func:`couette` is the one builder of the
Couette case at any N_x that the stability map, the sweep, the benchmarks and
the tests start from (a short periodic box ``L_y = ly_in_h h`` carries the
flow, which is 1-D in x).
"""
from parsph.physics import table1
from parsph.setup import config
from parsph.setup.runfile import RunFile


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


def couette(nx=table1.NX, *, h_over_dx=table1.H_OVER_DX, ly_in_h=None, dt="auto", steps=None, overrides=()):
    """The paper's Couette case at N_x = ``nx`` with h = ``h_over_dx`` dx, as a RunConfig.

    ``ly_in_h``: L_y = ly_in_h h (h = h_over_dx L / N_x), else L; ``dt``: "auto" or seconds; no output
    times and no progress lines; ``overrides``: ``section.key=value`` strings, applied after those;
    ``steps``: then t_end = steps dt (for "auto": the run's first dt, at theta_0).
    """
    rf = paper_run_file().set("numerics", Nx=int(nx), h_over_dx=h_over_dx, dt=dt)
    if ly_in_h is not None:
        rf = rf.set("domain", Ly=ly_in_h * (h_over_dx * (table1.L / nx)))
    rf = rf.set("output", times=[], progress_interval=0.0).override(overrides)
    if steps is None:
        return config.build(rf)
    dt0 = config.build(rf.set("output", t_end=1.0)).dt if dt == "auto" else dt
    return config.build(rf.set("output", t_end=steps * dt0))
