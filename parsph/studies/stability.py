"""The stability map's measurements (docs/stability.md): a run observed criterion by criterion, its outcome
classified, the runs kept in a resumable CSV, and each column's time-step limit bracketed from them.

A run is *stable* when none of the run-time checks' criteria (:func:`parsph.simulation.guards.read`:
non-finite, beyond a wall, theta, kinetic energy) fired and nothing else failed. Not every failure is
a time-step failure: two failing runs >= 8 % apart in dt that fail by the same criterion within 5 %
of the same physical time failed because of the flow itself (``physical``); bounds count time-step
failures only. The map's runs are :mod:`.stability_cases`', its modes :mod:`.stability_map`'s (which
``scripts/stability_map.py`` drives), its figures :mod:`.stability_report`'s.
"""
import math
import time

import numpy as np
from mpi4py import MPI

from parsph.errors import GuardError
from parsph.simulation.guards import CRITERIA, CRITERION_OF, read
from parsph.simulation.solver import Simulation
from .runs import CsvRows, Runs


class CriterionFailed(RuntimeError):
    """A recorder that stops at its first failure stopped the run (the guard does not check its criteria)."""


class Recorder:
    """Observer of a run (``Simulation.run(observe=...)``): the checks' criteria at every step, the step each
    first failed (-1: never), and the largest theta deviation, kinetic energy over the scene's bound and
    speed over the velocity scale seen. It changes nothing; the run's own guard stops it, or, with
    ``stop``, this recorder at the first failure (CriterionFailed).

    ``theta_ref(x)``: what theta is measured against (default theta_0); ``acc``: read the accelerations
    too (the non-finite criterion then covers them, as the guard's check 1 does).
    """

    def __init__(self, cfg, theta_frac, theta_ref=None, stop=False, acc=False):
        self.cfg, self.theta_frac, self.theta_ref, self.stop, self.acc = cfg, theta_frac, theta_ref, stop, acc
        self.first = {c: -1 for c in CRITERIA}
        self.max_theta_dev = self.max_ke_ratio = self.max_speed_ratio = 0.0
        self.vy_min, self.vy_max = math.inf, -math.inf

    def __call__(self, sim):
        r = read(sim.particles(), self.cfg, self.theta_ref, sim.ps.acc[:sim.ps.n_own] if self.acc else None)
        now = r.failed(self.cfg, sim.t, self.theta_frac)
        for c in CRITERIA:
            if now[c] and self.first[c] < 0:
                self.first[c] = sim.step
        bound = self.cfg.scene.max_kinetic_energy(self.cfg, r.mass)
        ke_ratio = r.kinetic_energy / bound if math.isfinite(r.kinetic_energy) else math.inf
        self.max_theta_dev = max(self.max_theta_dev, r.theta_dev)
        self.max_ke_ratio = max(self.max_ke_ratio, ke_ratio)
        self.max_speed_ratio = max(self.max_speed_ratio, r.speed / self.cfg.velocity_scale)
        self.vy_min, self.vy_max = min(self.vy_min, r.vy_min), max(self.vy_max, r.vy_max)
        fired = [c for c in CRITERIA if now[c]]
        if self.stop and fired:
            raise CriterionFailed(f"probe: {', '.join(fired)} at step {sim.step}, t = {sim.t:.6g} s "
                                  f"(theta dev {r.theta_dev:.3g}, KE/bound {ke_ratio:.3g})")

    @property
    def fired(self):
        """{criterion: the step it first failed} of those that did."""
        return {c: s for c, s in self.first.items() if s >= 0}


def run_and_classify(cfg, rec):
    """Run ``cfg`` (the solver on MPI.COMM_SELF) to its end, observed by the recorder ``rec``; the outcome as
    the stability CSVs' columns.

    A failure of the package's guard (GuardError) is named by its result's code and counts for that
    criterion at its step (the per-step non-finite flag fires before the observer sees the step)."""
    sim = Simulation(cfg, MPI.COMM_SELF)
    guard = crash = message = ""
    t0 = time.perf_counter()
    try:
        with np.errstate(all="ignore"):
            sim.run(observe=rec)
    except GuardError as e:
        message = str(e)
        guard = CRITERION_OF.get(e.result.code, "other")
        if guard in rec.first and rec.first[guard] < 0:
            rec.first[guard] = e.result.step
    except CriterionFailed as e:
        message, guard = str(e), "probe"
    except Exception as e:  # noqa: BLE001 - anything else is a finding (the guard missed it)
        crash = type(e).__name__
        message = f"{type(e).__name__}: {e}"
    wall_s = time.perf_counter() - t0
    fired = rec.fired
    stable = not fired and not crash and not guard
    err_max = err_rms = math.nan
    if stable:
        err_max, err_rms = sim.profile()["err"]
    first = min(fired, key=lambda c: (fired[c], CRITERIA.index(c))) if fired else (crash or guard)
    return {"steps_done": sim.step, "t_done": sim.t, "stable": int(stable), "first_failure": first,
            "fail_step": -1 if stable else sim.step,
            **{f"{c}_step": rec.first[c] for c in CRITERIA},
            "max_theta_dev": rec.max_theta_dev, "max_ke_ratio": rec.max_ke_ratio,
            "max_speed_ratio": rec.max_speed_ratio, "err_max": err_max, "err_rms": err_rms,
            "guard": guard, "crash": crash, "message": message, "wall_s": round(wall_s, 3)}


# ---- the runs so far: a CSV a stopped map resumes from --------------------------------------------
def key_of(row):
    return (int(row["nx"]), round(float(row["theta0"]), 6), round(float(row["Re"]), 6),
            round(float(row["multiple"]), 9))


class Results:
    """The CSV of one integrator's (or scene's) runs, keyed by (N_x, theta_0, Re, multiple): the studies'
    resumable runner (:class:`parsph.studies.runs.Runs`) on a CSV, so that a run already in it is not
    repeated. ``runner(theta0, Re, nx, multiple, source)`` makes one run's row."""

    def __init__(self, path, runner, fields):
        self.runner = runner
        self.runs = Runs(CsvRows(path, fields, key_of))

    @property
    def rows(self):
        """Every run so far (as strings)."""
        return self.runs.store.rows

    def get(self, theta0, Re, nx, multiple, source="grid"):
        key = (nx, round(theta0, 6), round(Re, 6), round(multiple, 9))
        return self.runs.get(key, lambda: self.runner(theta0, Re, nx, multiple, source), then=_say)


def _say(row):
    verdict = "stable  " if row["stable"] == "1" else f"UNSTABLE ({row['first_failure']} at step {row['fail_step']})"
    print(f"Nx={int(row['nx']):3d} theta0={float(row['theta0']):<5g} Re={float(row['Re']):<6g} "
          f"dt/limit={float(row['multiple']):<8.4g} {verdict}  [{float(row['wall_s']):.1f} s]", flush=True)


# ---- verdicts: a time-step instability, or a failure at a fixed physical time ----------------------
def column(rows, nx, theta0, Re):
    """The runs of one (N_x, theta_0, Re) column, sorted by multiple."""
    sel = [r for r in rows if int(r["nx"]) == nx and abs(float(r["theta0"]) - theta0) < 1e-9
           and abs(float(r["Re"]) - Re) < 1e-9]
    return sorted(sel, key=lambda r: float(r["multiple"]))


def physical_time(col, m_ratio=1.08, t_tol=0.05):
    """(t, criterion) when two failing runs of the column, >= m_ratio apart in dt, failed by the same
    criterion within t_tol of the same physical time; else None.

    A time-step instability fails later at a smaller dt (its growth per unit time falls with dt);
    a failure that comes at the same time whatever dt is set by the flow itself (the physics or
    the spatial resolution). Crashes count as time-step failures.
    """
    bad = [r for r in col if r["stable"] == "0" and not r["crash"]]
    for i, a in enumerate(bad):
        for b in bad[i + 1:]:
            ma, mb, ta, tb = float(a["multiple"]), float(b["multiple"]), float(a["t_done"]), float(b["t_done"])
            if (mb / ma >= m_ratio and a["first_failure"] == b["first_failure"]
                    and abs(tb / ta - 1.0) <= t_tol):
                return 0.5 * (ta + tb), a["first_failure"]
    return None


def verdict(row, phys, t_tol=0.1):
    """'stable', 'physical' (failed at the column's physical failure time) or 'dt'."""
    if row["stable"] == "1":
        return "stable"
    if phys and not row["crash"] and row["first_failure"] == phys[1] \
            and abs(float(row["t_done"]) / phys[0] - 1.0) <= t_tol:
        return "physical"
    return "dt"


def dt_bounds(col):
    """(largest multiple with no time-step failure at or below it, smallest with one)."""
    phys = physical_time(col)
    lo = hi = None
    for r in col:
        v, m = verdict(r, phys), float(r["multiple"])
        if v == "dt":
            hi = m
            break
        lo = m
    return lo, hi


def measured_bounds(rows):
    """(largest dt [s] with no time-step failure at or below it, smallest dt with one) of one column."""
    rows = sorted(rows, key=lambda r: float(r["dt"]))
    phys = physical_time(sorted(rows, key=lambda r: float(r["multiple"])))
    lo = hi = None
    for r in rows:
        v = r.get("verdict") or verdict(r, phys)
        if v == "dt":
            hi = float(r["dt"])
            break
        lo = float(r["dt"])
    return lo, hi


def search(res, theta0, Re, nx, down, up, tol, span, max_runs, source):
    """Run the column at new multiples until its time-step limit lies within a ratio ``tol``:
    ``down(hi)`` below a failure at the smallest multiple, ``up(lo)`` above the largest stable one,
    bisection (geometric mean) between; stop beyond 1/span or span. ``res.get(theta0, Re, nx, m,
    source)`` runs one (a resumable store's: ``res.rows`` are the runs so far). Returns (stable, failing)."""
    for _ in range(max_runs):
        lo, hi = dt_bounds(column(res.rows, nx, theta0, Re))
        if lo is None:
            m = down(hi)
            if m < 1 / span:
                break
        elif hi is None:
            m = up(lo)
            if m > span:
                break
        elif hi / lo > tol:
            m = math.sqrt(lo * hi)
        else:
            break
        res.get(theta0, Re, nx, m, source=source)
    return dt_bounds(column(res.rows, nx, theta0, Re))
