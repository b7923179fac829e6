"""Run-time checks: a blow-up stops every rank with one message naming the worst particle.

:func:`run_checks` is collective. It finds, over all ranks, the first check
(in ``CHECKS`` order) that fails anywhere and within it the particle that
fails it most (deepest through a wall, furthest from theta_0, largest
jump); for the energy bound, the fastest fluid particle. It raises
:class:`GuardError` on every rank alike, carrying a :class:`GuardResult`
(the check's code, the particle, its position and value), so that callers
(the stability map, say) classify failures without reading the message.
"""
from dataclasses import dataclass
import math

import numpy as np

from parsph.errors import GuardError
from parsph.sph.particles import FLUID

CHECKS = {1: "non-finite position, velocity or acceleration", 2: "fluid particle crossed a wall plane",
          3: "volume fraction out of range", 4: "kinetic energy above what the walls can inject",
          5: "particle moved more than h in one step"}


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


def run_checks(collect, ps, cfg, step, t):
    """Collective run-time checks of the owned particles; raises GuardError on every rank on failure.

    ``collect``: the solver's :class:`parsph.parallel.collectives.Collectives`."""
    n = ps.n_own
    pos, vel = ps.pos[:n], ps.vel[:n]
    fluid = ps.kind[:n] == FLUID
    scene = cfg.scene
    report = np.zeros(6)  # code, severity, gid, x, y, value
    finite = np.isfinite(pos).all(axis=1) & np.isfinite(vel).all(axis=1) & np.isfinite(ps.acc[:n]).all(axis=1)
    depth = np.where(fluid & finite, np.maximum(-pos[:, 0], pos[:, 0] - cfg.L), -np.inf) \
        if scene.walls else np.full(n, -np.inf)
    dev = np.where(fluid & finite, np.abs(ps.theta[:n] - cfg.theta0), 0.0)
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
