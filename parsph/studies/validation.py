"""The checks of docs/validation.md's tables of validated cases (scripts/validate_scenes.py): what a run's
outputs say against its reference, read from its files.

A settled column is compared after it settles (theta(x) averaged over the
late outputs, against the balance the run's pressure form converges to and
against the paper form's); a decaying flow relative to the amplitude left
(its decay rate from the projection on the reference's shape), since an
error relative to the start would shrink with the flow; every other scene by
the error the run recorded against its reference.
"""
import math
import warnings

import numpy as np
from mpi4py import MPI

from parsph.output import output_files, read_profile, read_snapshot
from parsph.physics.analytic import settling_equilibrium
from parsph.setup import config
from parsph.simulation.solver import Simulation
from parsph.sph.particles import GRAIN


def settling_time(outdir, tol=1e-4):
    """The first output time from which the fluid's largest |v_x| stays below ``tol`` [m/s] (None: never)."""
    settled = None
    for f in output_files(outdir):
        snap = read_snapshot(f)
        vx = np.abs(snap["velocity"][snap["kind"] == GRAIN, 0]).max()
        if vx < tol:
            settled = settled if settled is not None else float(snap["attrs"]["time"])
        else:
            settled = None
    return settled


def in_process(text, over):
    """Run a run file (TOML text, overrides) on COMM_SELF in this process: (cfg, sim, its last profile)."""
    cfg = config.loads(text, over)
    sim = Simulation(cfg, MPI.COMM_SELF)
    last = {}
    sim.run(output=lambda s, snapshot=None: last.update(s.profile))
    return cfg, sim, last


def theta_spread(outdir):
    """Standard deviation of the fluid particles' theta over their mean, at the last output."""
    snap = read_snapshot(output_files(outdir)[-1])
    th = snap["theta"][snap["kind"] == GRAIN]
    return float(th.std() / th.mean())


def scene_error(outdir):
    """(particles, the error column of the validated-cases table) of the run whose outputs are in ``outdir``."""
    p = read_profile(outdir)
    at = p["attrs"]
    if at["error_field"] == "theta":
        late = p["time"] >= 0.4 * p["time"][-1]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a bin can be empty at every late output
            theta = np.nanmean(p["theta"][late], axis=0)
        ref = p["theta_exact"][-1]
        cfg = config.loads(at["run_file"])
        paper = settling_equilibrium(p["x"], cfg.theta0, cfg.L, cfg.rho_s, -cfg.g[0], cfg.G_a, cfg.G_b,
                                     form="paper")
        err = np.abs(theta - ref) / cfg.theta0
        errp = np.abs(theta - paper) / cfg.theta0
        settled = settling_time(outdir)
        when = f"settled (max \\|v_x\\| < 1e-4 m/s) from t = {settled:g} s" if settled is not None \
            else "not settled (max \\|v_x\\| >= 1e-4 m/s at the last output)"
        msg = (f"{when}; theta(x) averaged over t >= {p['time'][late][0]:g} s: max {np.nanmax(err):.2e}, "
               f"RMS {math.sqrt(np.nanmean(err ** 2)):.2e} of theta_0 over {np.isfinite(err).sum()} of "
               f"{err.size} bins (floor {theta[0]:.4f} vs {ref[0]:.4f}); against the paper form's balance: "
               f"max {np.nanmax(errp):.2e}")
    elif config.loads(at["run_file"]).scene.current_scale is not None:
        # a decaying flow: errors relative to the amplitude left, and the decay rate of the
        # simulated amplitude (its projection on the reference's shape) against the reference's
        cfg = config.loads(at["run_file"])
        rows = []
        for t, f, fe in zip(p["time"], p["vy"], p["vy_exact"]):
            a = cfg.error_scale(t)
            ratio = float(np.dot(f, fe) / np.dot(fe, fe))  # A_sim / A_ref
            rate = math.log(ratio * a / cfg.error_scale(0.0)) / math.log(a / cfg.error_scale(0.0)) - 1.0
            rows.append(f"t = {t:g} s: {np.nanmax(np.abs(f - fe)) / a:.2e} of the amplitude left "
                        f"({a / cfg.error_scale(0.0):.1e} U), decay rate {rate:+.2%}")
        msg = "; ".join(rows)
    else:
        k = int(np.nanargmax(p["err_max"]))
        msg = (f"t = {p['time'][-1]:g} s: max {p['err_max'][-1]:.2e}, RMS {p['err_rms'][-1]:.2e} "
               f"of {at['error_scale']:.3g} m/s; largest over the outputs {p['err_max'][k]:.2e} at "
               f"t = {p['time'][k]:g} s")
    return at["n_particles"], msg
