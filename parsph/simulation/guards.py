"""Run-time checks: a blow-up stops every rank with one message naming the worst particle.

:func:`run_checks` is collective. It finds, over all ranks, the first check
(in ``CHECKS`` order) that fails anywhere and within it the particle that
fails it most (deepest through a wall, furthest from theta_0, largest
jump); for the energy bound, the fastest fluid particle. It raises
:class:`GuardError` on every rank alike, carrying a :class:`GuardResult`
(the check's code, the particle, its position and value), so that callers
(the stability map, say) classify failures without reading the message.

The criteria are defined once (:func:`_per_particle`): the checks apply them
collectively with their thresholds, :func:`read` measures them over one rank's
particles without stopping anything (for observers of a run: the stability
map, the stability tests).
"""
from dataclasses import dataclass
import math

import numpy as np

from parsph.errors import GuardError
from parsph.sph.particles import FLUID

CHECKS = {1: "non-finite position, velocity or acceleration", 2: "fluid particle crossed a wall plane",
          3: "volume fraction out of range", 4: "kinetic energy above what the walls can inject",
          5: "particle moved more than h in one step"}
CRITERIA = ("nonfinite", "wall", "theta", "energy")   # checks 1-4 by name, as Reading.failed names them
CRITERION_OF = {1: "nonfinite", 2: "wall", 3: "theta", 4: "energy", 5: "jump"}


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


def _per_particle(pos, vel, theta, kind, cfg, acc=None, theta_ref=None):
    """Per particle: fluid; finite (position, velocity and, where given, acceleration); the depth
    beyond a wall plane [m] (-inf inside, for the others and without walls); |theta - theta_ref|
    (theta_ref: theta_0, or one per particle; 0 for the others)."""
    fluid = kind == FLUID
    finite = np.isfinite(pos).all(axis=1) & np.isfinite(vel).all(axis=1)
    if acc is not None:
        finite &= np.isfinite(acc).all(axis=1)
    depth = np.where(fluid & finite, np.maximum(-pos[:, 0], pos[:, 0] - cfg.L), -np.inf) \
        if cfg.scene.walls else np.full(len(kind), -np.inf)
    ref = cfg.theta0 if theta_ref is None else theta_ref
    dev = np.where(fluid & finite, np.abs(theta - ref), 0.0)
    return fluid, finite, depth, dev


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
                "energy": not self.kinetic_energy <= cfg.scene.max_kinetic_energy(cfg, self.mass, t)}


def read(fields, cfg, theta_ref=None, acc=None):
    """The Reading of ``fields`` (:meth:`Simulation.particles`); ``theta_ref(x)``: the theta each fluid
    particle is measured against (default theta_0); ``acc``: the owned particles' accelerations."""
    kind, pos, vel, theta = fields["kind"], fields["position"], fields["velocity"], fields["theta"]
    fl = kind == FLUID
    ref = cfg.theta0 if theta_ref is None else theta_ref(np.nan_to_num(pos[:, 0]))
    with np.errstate(all="ignore"):
        _, finite, depth, _ = _per_particle(pos, vel, theta, kind, cfg, acc)
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


def run_checks(collect, ps, cfg, step, t):
    """Collective run-time checks of the owned particles; raises GuardError on every rank on failure.

    ``collect``: the solver's :class:`parsph.parallel.collectives.Collectives`."""
    n = ps.n_own
    pos, vel = ps.pos[:n], ps.vel[:n]
    scene = cfg.scene
    report = np.zeros(6)  # code, severity, gid, x, y, value
    fluid, finite, depth, dev = _per_particle(pos, vel, ps.theta[:n], ps.kind[:n], cfg, ps.acc[:n])
    jump = np.where(finite, ps.jump[:n], 0.0)
    for code, severity, value in ((1, np.where(finite, 0.0, 1.0), ps.theta[:n]), (2, np.where(depth > 0, depth, 0.0), depth),
                                  (3, np.where(dev > cfg.get("checks.theta_change") * cfg.theta0, dev, 0.0), ps.theta[:n]),
                                  (5, np.where(jump > cfg.h, jump, 0.0), jump)):
        if n and severity.max() > 0:
            k = int(np.argmax(severity))
            report[:] = code, severity[k], ps.gid[k], pos[k, 0], pos[k, 1], value[k]
            break
    speed2 = np.where(fluid & finite, (vel ** 2).sum(axis=1), -1.0)
    k = int(np.argmax(speed2)) if n else 0
    fastest = np.array([speed2[k] if n else -1.0, ps.gid[k] if n else -1, pos[k, 0] if n else 0.0,
                        pos[k, 1] if n else 0.0])
    energy = np.array([0.5 * (ps.mass[:n][fluid] * (vel[fluid] ** 2).sum(axis=1)).sum(), ps.mass[:n][fluid].sum()])
    reports = collect.gather(report)
    fast = collect.gather(fastest)
    totals = collect.sum(energy)
    failed = reports[reports[:, 0] > 0]
    where = f"at step {step}, t = {t:.6g} s"
    y_shown = lambda y: y % cfg.Ly if math.isfinite(y) else y  # noqa: E731  (positions wrap at rebuilds only)
    if len(failed):
        failed = failed[failed[:, 0] == failed[:, 0].min()]
        code, severity, gid, x, y, value = failed[np.argmax(failed[:, 1])]
        code = int(code)
        extra = {2: f" ({severity:.3g} m beyond the plate)", 3: f" (theta = {value:.4g}, theta0 = {cfg.theta0:g})",
                 5: f" ({value:.3g} m; dt too large or the run blew up)"}.get(code, "")
        msg = (f"check failed: {CHECKS[code]} {where}: particle {int(gid)} "
               f"at x = {x:.6g} m, y = {y_shown(y):.6g} m{extra}")
        raise GuardError(GuardResult(code, step, t, int(gid), x, y_shown(y), float(value), msg))
    bound = scene.max_kinetic_energy(cfg, totals[1], t)
    if cfg.get("checks.energy") and not totals[0] <= bound:
        s2, gid, x, y = fast[np.argmax(fast[:, 0])]
        msg = (f"check failed: {CHECKS[4]} {where}: {totals[0]:.4g} J/m > {bound:.4g} J/m; "
               f"fastest particle {int(gid)} at x = {x:.6g} m, y = {y_shown(y):.6g} m, "
               f"|v| = {math.sqrt(max(s2, 0.0)):.4g} m/s")
        raise GuardError(GuardResult(4, step, t, int(gid), x, y_shown(y), float(totals[0]), msg))
