"""The solved gas at its extremes (docs/validation.md, "At the extremes"): a jet at 10 U_mf, a contrast of
10^6 between the permeability of clear gas and of the bed, bubbles that erupt at the bed's top. Each run is
in-process on one rank (``MPI.COMM_SELF``), stepped to its end and measured at its outputs: the state finite,
every grain between the plates, the largest theta, how often the walls' backstop put a grain back on a plate
(``walls.reflect``) and the smallest step.
"""
from dataclasses import dataclass
import math
import time

import numpy as np
from mpi4py import MPI

from parsph.setup.scenes import layer
from parsph.simulation.gas_stage import permeability_cap
from parsph.simulation.solver import Simulation
from parsph.sph.particles import GRAIN
from . import layers

BUBBLING = layers.RUN / "bubbling_bed.toml"
SINGLE_BUBBLE = layers.RUN / "single_bubble.toml"


@dataclass
class Extreme:
    name: str
    t_end: float
    steps: int
    finite: bool        # positions and velocities finite at every output
    x_min: float        # the lowest and highest grain over the outputs [m]; the plates are at 0 and L
    x_max: float
    L: float
    theta_max: float    # the largest theta of a grain over the outputs
    dt_min: float       # the smallest step taken [s]
    reflected: int      # grains walls.reflect put back on a plate
    seconds: float      # the run's wall time [s]

    @property
    def held(self):
        """Finite, and no grain outside the plates at any output."""
        return self.finite and self.x_min >= 0.0 and self.x_max <= self.L


def default_cap(path, sets=()):
    """The cap K_max the solved gas of ``path`` takes [m^2/(Pa s)] (by default 1000 K(theta0))."""
    return permeability_cap(layers.load(path, sets))


def minimum_fluidization(path, sets=()):
    """U_mf of the bed of ``path`` [m/s] (Ergun at theta0, as its banner prints it)."""
    return layer.numbers(layers.load(path, sets)).U_mf


def run(name, path, sets, t_end, n_times=10):
    """``path`` with ``sets`` to ``t_end`` on one rank, measured at ``n_times`` outputs: an :class:`Extreme`."""
    times = [float(t) for t in np.linspace(0.0, t_end, n_times + 1)[1:]]
    cfg = layers.load(path, [*sets, f"output.t_end={t_end!r}", f"output.times={times!r}",
                             "output.snapshots=false"])
    sim = Simulation(cfg, MPI.COMM_SELF)
    seen = {"finite": True, "lo": math.inf, "hi": -math.inf, "theta": 0.0, "dt": math.inf, "t": 0.0}

    def observe(s):  # every step: the step just taken
        if s.t > seen["t"]:
            seen["dt"] = min(seen["dt"], s.t - seen["t"])
        seen["t"] = s.t

    def output(frame, snapshot):
        ps = sim.ps
        n = ps.n_own
        f = ps.kind[:n] == GRAIN
        pos, vel = ps.pos[:n][f], ps.vel[:n][f]
        seen["finite"] &= bool(np.isfinite(pos).all() and np.isfinite(vel).all())
        seen["lo"] = min(seen["lo"], float(pos[:, 0].min()))
        seen["hi"] = max(seen["hi"], float(pos[:, 0].max()))
        seen["theta"] = max(seen["theta"], float(ps.theta[:n][f].max()))
    t0 = time.perf_counter()
    sim.run(output=output, observe=observe)
    return Extreme(name, t_end, sim.step, seen["finite"], seen["lo"], seen["hi"], cfg.L, seen["theta"],
                   seen["dt"], sim.reflections(), time.perf_counter() - t0)
