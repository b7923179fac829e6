"""What an output writes of a run's state: the profile v_y(x), theta(x), v_x(x) summed over ranks with the
scene's reference and error, and the owned particles."""
import math

import numpy as np

from parsph.output import Frame
from parsph.sph.profiles import bin_centres, bin_sums, errors


class Frames:
    """The profile's bins (``cfg.Nx`` across the channel) and their buffers; reductions through ``collect``."""

    def __init__(self, cfg, grid, collect):
        self.cfg, self.grid, self.collect = cfg, grid, collect
        self.nbins = cfg.Nx
        self.period_x = 0.0 if cfg.scene.walls else cfg.L
        self._sums = np.zeros((4, self.nbins))

    def frame(self, ps, timeline, snapshot=True):
        """What an output writes: time, step, dt, the profile and (``snapshot``) the owned particles."""
        t = timeline.t
        return Frame(t, timeline.step, timeline.dt, self.profile(ps, t), self.particles(ps) if snapshot else None)

    def profile(self, ps, t):
        """Global v_y(x), theta(x) and v_x(x): per-bin sums and counts all-reduced over ranks.

        Returns a dict: x, vy, theta, count, vx, the scene's reference profiles
        (vy_exact, theta_exact, vx_exact; NaN where it has none) and (err_max, err_rms)
        of its error field, relative to ``cfg.error_scale(t)``.
        """
        cfg, scene = self.cfg, self.cfg.scene
        bin_sums(ps.pos, ps.vel, ps.theta, ps.kind, ps.n_own, cfg.L / self.nbins, self.nbins, self.period_x,
                 self._sums)
        # v_x's row reduced on its own: the other rows' all-reduce (its size, hence MPI's choice of algorithm
        # and order of additions) is what it was before v_x was profiled
        sums, vx = self.collect.sum(self._sums[:3]), self.collect.sum(self._sums[3])
        count = sums[2]
        with np.errstate(invalid="ignore", divide="ignore"):
            out = {"x": bin_centres(cfg.L, self.nbins), "vy": sums[0] / count, "theta": sums[1] / count,
                   "count": count, "vx": vx / count}
        ref = scene.reference(cfg, out["x"], t) if scene.reference else {}
        for key in ("vy", "theta", "vx"):
            out[key + "_exact"] = ref.get(key, np.full(self.nbins, np.nan))
        field = scene.error_field
        out["err"] = errors(out[field], out[field + "_exact"], cfg.error_scale(t)) if field in ref \
            else (math.nan, math.nan)
        return out

    def particles(self, ps):
        """The owned particles as an output writes them (read-only views; ``position`` wrapped into the
        box, a copy; ``position_raw`` and ``ref`` as the solver holds them, for a restart)."""
        n = ps.n_own
        pos = ps.pos[:n].copy()
        for axis in range(ps.dim):
            a = self.grid.axes[axis]
            if a.periodic:
                pos[:, axis] %= a.period
        fields = {"id": ps.gid[:n], "kind": ps.kind[:n], "mass": ps.mass[:n], "position": pos,
                  "velocity": ps.vel[:n], "theta": ps.theta[:n], "position_raw": ps.pos[:n], "ref": ps.ref[:n]}
        for v in fields.values():
            if v is not pos:
                v.flags.writeable = False  # views of the solver's arrays
        return fields
