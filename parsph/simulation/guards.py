"""Run-time checks: a blow-up stops every rank with one message naming the worst particle.

:func:`check_report` (numba) applies the checks' criteria to one rank's
particles: the first check (in ``CHECKS`` order) that fails there and the
particle that fails it most (deepest through a wall, furthest from theta_0,
largest jump), the fastest fluid particle and the fluid's kinetic energy
and mass. The compiled blocks (:mod:`.block`) run it every ``checks.every``
steps and all-reduce whether any rank failed; :func:`run_checks` (collective,
Python) runs it, gathers the reports and raises :class:`GuardError` on every
rank alike, carrying a :class:`GuardResult` (the check's code, the particle,
its position and value), so that callers (the stability map, say) classify
failures without reading the message.

:func:`read` measures the criteria over one rank's particles without
stopping anything (for observers of a run: the stability map, the stability
tests), against a theta of the caller's choice.
"""
from dataclasses import dataclass
import math
from typing import NamedTuple

import numpy as np
from numba import njit

from parsph.errors import GuardError
from parsph.sph.particles import GRAIN
from parsph.sph.walls import side_place

CHECKS = {1: "non-finite position, velocity or acceleration", 2: "fluid particle crossed a wall plane",
          3: "volume fraction out of range", 4: "kinetic energy above what the walls can inject",
          5: "particle moved more than h in one step"}
CRITERIA = ("nonfinite", "wall", "theta", "energy")   # checks 1-4 by name, as Reading.failed names them
CRITERION_OF = {1: "nonfinite", 2: "wall", 3: "theta", 4: "energy", 5: "jump"}
N_REPORT, N_FASTEST = 6, 3  # check_report's rows: (code, severity, place, x, y, value), (|v|^2, place, fluid mass)


class Bounds(NamedTuple):
    """The checks' thresholds (not the time step's limits, :mod:`parsph.physics.limits`), as
    :func:`check_report` and the compiled blocks take them."""
    every: int          # checks.every: the steps between two checks
    walls: bool         # plates at x = 0 and x = L (check 2)
    L: float
    theta0: float
    theta_tol: float    # checks.theta_change x theta_0 (check 3)
    h: float            # the jump limit (check 5)
    ke_bound: float     # check 4: the scene's bound at the run's fluid mass (inf: checks.energy off)
    side: float         # side walls at y = 0 and y = side (check 2; 0: none), in the period ``ring`` along y
    ring: float


def energy_bound(cfg, fluid_mass):
    """Check 4's bound [J/m]: the scene's, where it holds. A scene's bound counts only the forces it
    declares: with a gas, or a body force the scene is not driven by (a periodic box that falls freely),
    there is none (inf), and checks 1, 3 and 5 catch a blow-up."""
    undeclared = any(cfg.g) and not cfg.scene.terms.body_force
    if cfg.gas is not None or undeclared:
        return math.inf
    return cfg.scene.max_kinetic_energy(cfg, fluid_mass)


def bounds_of(cfg, fluid_mass):
    """The Bounds of a run whose fluid (over all ranks) has mass ``fluid_mass``."""
    bound = energy_bound(cfg, fluid_mass) if cfg.get("checks.energy") else math.inf
    return Bounds(int(cfg.get("checks.every")), bool(cfg.scene.walls), float(cfg.L), float(cfg.theta0),
                  float(cfg.get("checks.theta_change") * cfg.theta0), float(cfg.h), float(bound),
                  float(cfg.Ly) if cfg.sides else 0.0, float(cfg.Ly_ring))


@njit(cache=True)
def check_report(pos, vel, acc, theta, jump, kind, mass, n, lim, report, fastest):
    """Checks 1, 2, 3 and 5 of particles 0..n-1; returns the fluid's kinetic energy 0.5 sum m |v|^2.

    ``report`` gets (code, severity, place, x, y, value) of the first check
    in CHECKS order that fails (code 0: none) at the particle that fails it
    most (the first such place); severity 1 (check 1: a non-finite position,
    velocity or acceleration, any particle), the depth beyond a wall plane
    (2), |theta - theta_0| above lim.theta_tol (3) or the jump above h (5),
    of finite fluid particles (any finite particle for 5). ``fastest``: the
    largest |v|^2 of a finite fluid particle (-1: none), its place and the
    fluid's mass.
    """
    dim = pos.shape[1]
    worst = np.zeros(6)  # by code: the largest severity so far
    place = np.full(6, -1)
    fast, fast_at, ke, fluid_mass = -1.0, -1, 0.0, 0.0
    for i in range(n):
        v2 = 0.0
        finite = True
        for d in range(dim):
            v2 += vel[i, d] * vel[i, d]
            finite = finite and math.isfinite(pos[i, d]) and math.isfinite(vel[i, d]) and math.isfinite(acc[i, d])
        fluid = kind[i] == GRAIN
        if fluid:
            ke += mass[i] * v2
            fluid_mass += mass[i]
        if not finite:
            if worst[1] < 1.0:
                worst[1], place[1] = 1.0, i
            continue
        if fluid:
            if v2 > fast:
                fast, fast_at = v2, i
            depth = max(-pos[i, 0], pos[i, 0] - lim.L)
            if lim.side > 0.0:
                depth = max(depth, side_place(pos[i, 1], lim.side, lim.ring)[1])
            if lim.walls and depth > 0 and depth > worst[2]:
                worst[2], place[2] = depth, i
            dev = abs(theta[i] - lim.theta0)
            if dev > lim.theta_tol and dev > worst[3]:
                worst[3], place[3] = dev, i
        if jump[i] > lim.h and jump[i] > worst[5]:
            worst[5], place[5] = jump[i], i
    report[:] = 0.0
    for code in (1, 2, 3, 5):
        k = place[code]
        if k >= 0:
            value = theta[k] if code in (1, 3) else (worst[2] if code == 2 else jump[k])
            report[0], report[1], report[2], report[3], report[4], report[5] = (code, worst[code], k, pos[k, 0],
                                                                                pos[k, 1], value)
            break
    fastest[0], fastest[1], fastest[2] = fast, fast_at, fluid_mass
    return 0.5 * ke


@dataclass(frozen=True)
class GuardResult:
    """A failed check: its code (CHECKS), where and when, the particle, and the offending value."""
    code: int
    step: int
    t: float
    gid: int
    x: float
    y: float
    value: float  # 2: depth beyond the plate [m]; 3: theta; 4: kinetic energy [J/m]; 5: the jump [m]
    message: str


@dataclass(frozen=True)
class Reading:
    """The checks' criteria over one rank's fluid particles now (no communication)."""
    nonfinite: bool         # a non-finite position or velocity (acceleration too, where read)
    depth: float            # the largest depth beyond a wall plane [m] (-inf: none, or no walls)
    theta_dev: float        # max |theta - theta_ref| / theta_ref (inf: a theta is not finite)
    kinetic_energy: float   # of the fluid [J/m in 2-D]
    mass: float             # of the fluid
    speed: float            # the largest |v| [m/s]
    vy_min: float
    vy_max: float

    def failed(self, cfg, t, theta_frac):
        """{criterion: whether it fails}: beyond a wall, theta_dev above theta_frac, the kinetic energy
        above the scene's bound (the checks' own thresholds, but theta's, which is the caller's)."""
        return {"nonfinite": self.nonfinite, "wall": self.depth > 0, "theta": not self.theta_dev <= theta_frac,
                "energy": not self.kinetic_energy <= energy_bound(cfg, self.mass)}


def read(fields, cfg, theta_ref=None, acc=None):
    """The Reading of ``fields`` (:meth:`Simulation.particles`); ``theta_ref(x)``: the theta each fluid
    particle is measured against (default theta_0); ``acc``: the owned particles' accelerations."""
    kind, pos, vel, theta = fields["kind"], fields["position"], fields["velocity"], fields["theta"]
    fl = kind == GRAIN
    ref = cfg.theta0 if theta_ref is None else theta_ref(np.nan_to_num(pos[:, 0]))
    with np.errstate(all="ignore"):
        finite = np.isfinite(pos).all(axis=1) & np.isfinite(vel).all(axis=1)
        if acc is not None:
            finite &= np.isfinite(acc).all(axis=1)
        depth = np.where(fl & finite, np.maximum(-pos[:, 0], pos[:, 0] - cfg.L), -np.inf) \
            if cfg.scene.walls else np.full(len(kind), -np.inf)   # beyond a wall plane [m]
        if cfg.sides:
            yy = np.mod(pos[:, 1], cfg.Ly_ring)
            depth = np.maximum(depth, np.where(fl & finite, np.minimum(yy - cfg.Ly, cfg.Ly_ring - yy), -np.inf))
        th = theta[fl]
        rel = np.abs(th - (ref if np.ndim(ref) == 0 else ref[fl])) / (ref if np.ndim(ref) == 0 else ref[fl])
        dev = math.inf if not np.isfinite(th).all() else float(rel.max(initial=0.0))
        m, v = fields["mass"][fl], vel[fl]
        v2 = (v ** 2).sum(axis=1)
        ke = 0.5 * float((m * v2).sum())
        speed = float(np.sqrt(v2).max(initial=0.0))
    return Reading(not finite[fl].all(), float(depth.max(initial=-math.inf)), dev, ke if math.isfinite(ke) else math.inf,
                   float(m.sum()), speed if math.isfinite(speed) else math.inf,
                   float(v[:, 1].min(initial=math.inf)), float(v[:, 1].max(initial=-math.inf)))


def run_checks(collect, ps, cfg, step, t, lim):
    """Collective run-time checks of the owned particles; raises GuardError on every rank on failure.

    ``collect``: the solver's :class:`parsph.parallel.collectives.Collectives`; ``lim``: the run's Bounds."""
    n = ps.n_own
    report, fastest = np.zeros(N_REPORT), np.zeros(N_FASTEST)
    ke = check_report(ps.pos, ps.vel, ps.acc, ps.theta, ps.jump, ps.kind, ps.mass, n, lim, report, fastest)
    if report[0] > 0:
        report[2] = ps.gid[int(report[2])]
    k = int(fastest[1])
    fast = collect.gather(np.array([fastest[0], ps.gid[k], ps.pos[k, 0], ps.pos[k, 1]]) if k >= 0
                          else np.array([-1.0, -1.0, 0.0, 0.0]))
    reports = collect.gather(report)
    totals = collect.sum(np.array([ke, fastest[2]]))
    failed = reports[reports[:, 0] > 0]
    where = f"at step {step}, t = {t:.6g} s"
    y_shown = lambda y: y % cfg.Ly_ring if math.isfinite(y) else y  # noqa: E731  (positions wrap at rebuilds only)
    if len(failed):
        failed = failed[failed[:, 0] == failed[:, 0].min()]
        code, severity, gid, x, y, value = failed[np.argmax(failed[:, 1])]
        code = int(code)
        extra = {2: f" ({severity:.3g} m beyond the plate)", 3: f" (theta = {value:.4g}, theta0 = {cfg.theta0:g})",
                 5: f" ({value:.3g} m; dt too large or the run blew up)"}.get(code, "")
        msg = (f"check failed: {CHECKS[code]} {where}: particle {int(gid)} "
               f"at x = {x:.6g} m, y = {y_shown(y):.6g} m{extra}")
        raise GuardError(GuardResult(code, step, t, int(gid), x, y_shown(y), float(value), msg))
    if not totals[0] <= lim.ke_bound:
        s2, gid, x, y = fast[np.argmax(fast[:, 0])]
        msg = (f"check failed: {CHECKS[4]} {where}: {totals[0]:.4g} J/m > {lim.ke_bound:.4g} J/m; "
               f"fastest particle {int(gid)} at x = {x:.6g} m, y = {y_shown(y):.6g} m, "
               f"|v| = {math.sqrt(max(s2, 0.0)):.4g} m/s")
        raise GuardError(GuardResult(4, step, t, int(gid), x, y_shown(y), float(totals[0]), msg))
