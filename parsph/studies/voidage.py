"""Voidage waves measured (docs/physics.md, reference 7; docs/validation.md, "The solved gas"): a perturbed
uniform bed (run/voidage_waves.toml) stepped on one rank, the particles' mass mode a(t) = sum_i m_i
exp(-i k x_i) read at each output time, and its growth rate d ln|a| / dt and wave speed -(d arg a / dt) / k
fitted by least squares once the fast root has decayed; against :class:`parsph.physics.voidage_waves.Bed`."""
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from parsph.gas.grid import floor_drop
from parsph.physics import limits
from parsph.physics.voidage_waves import Bed
from parsph.setup import config
from parsph.simulation.solver import Simulation
from parsph.sph.particles import GRAIN
from parsph.sph.profiles import mass_quantiles

WAVES = Path(__file__).resolve().parents[2] / "run" / "voidage_waves.toml"
BED_AIR = WAVES.parent / "fluidized_bed_air.toml"
QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)


def bed_of(cfg):
    """The linear theory's bed for a run (Stokes drag, the pressure form in use, mu_s = k theta0)."""
    gas = cfg.gas
    g = math.sqrt(sum(x * x for x in cfg.g))
    return Bed(cfg.theta0, cfg.rho_s, gas.rho, gas.mu, gas.d, g, cfg.k * cfg.theta0,
               limits.dpressure(cfg.theta0, cfg.G_a, cfg.G_b, cfg.get("numerics.pressure_form"), cfg.packing),
               gas.model)


def mass_mode(ps, k):
    """sum_i m_i exp(-i k x_i) over the owned fluid particles."""
    f = ps.kind[:ps.n_own] == GRAIN
    return complex(np.sum(ps.mass[:ps.n_own][f] * np.exp(-1j * k * ps.pos[:ps.n_own, 0][f])))


@dataclass
class Wave:
    growth: float       # [1/s]
    speed: float        # [m/s]
    theory: tuple       # (growth, speed) of reference 7
    times: np.ndarray
    modes: np.ndarray   # a(t)


def measure(sets=(), n_times=21, t_end=None, path=WAVES):
    """Run the case with ``sets``, reading a(t) at n_times times, and fit the second half of them."""
    cfg0 = config.load(path, sets)
    t_end = t_end or cfg0.t_end
    times = [round(t_end * i / (n_times - 1), 12) for i in range(n_times)]
    cfg = config.load(path, [*sets, f"output.t_end={t_end!r}", f"output.times={times!r}", "output.snapshots=false"])
    k = 2 * math.pi / cfg.get("perturbation.wavelength")
    sim = Simulation(cfg, MPI.COMM_SELF)
    modes = []
    sim.run(output=lambda frame, snapshot: modes.append(mass_mode(sim.ps, k)))
    modes = np.array(modes)
    t = np.array(times)
    late = t >= 0.5 * t_end
    growth = np.polyfit(t[late], np.log(np.abs(modes[late])), 1)[0]
    omega = np.polyfit(t[late], np.unwrap(np.angle(modes[late])), 1)[0]
    bed = bed_of(cfg)
    return Wave(float(growth), float(-omega / k), bed.growth_and_speed(2 * math.pi / k), t, modes)


@dataclass
class PeriodicBed:
    """A box periodic along gravity in the solved gas, read at every step: the mean gradient G of p' (its
    pressure drop per unit height), the smallest and largest theta of the grid's cells, the solids' mean
    velocity along x."""
    cfg: object
    t: np.ndarray
    gradient: np.ndarray   # [Pa/m]
    theta_min: np.ndarray
    theta_max: np.ndarray
    v_mean: np.ndarray     # [m/s]

    def weight(self):
        """The solids' buoyant weight per unit volume theta_mean (rho_s - rho_g) |g| [Pa/m]: what the mean
        gradient carries when the solids' mean momentum does not change."""
        cfg = self.cfg
        return cfg.theta0 * (cfg.rho_s - cfg.gas.rho) * math.sqrt(sum(x * x for x in cfg.g))


def periodic_bed(sets=(), t_end=1.0, path=WAVES):
    """Run a box periodic along gravity with the solved gas (run/voidage_waves.toml with ``sets``) to t_end."""
    cfg = config.load(path, ['gas.flow="solved"', *sets, f"output.t_end={t_end!r}", f"output.times=[{t_end!r}]",
                             "output.snapshots=false"])
    sim = Simulation(cfg, MPI.COMM_SELF)
    rows = []

    def observe(s):
        sol = s.gas.solution
        f = s.ps.kind[:s.ps.n_own] == GRAIN
        rows.append((s.t, s.gas.darcy.gradient, sol.theta.min(), sol.theta.max(), s.ps.vel[:s.ps.n_own][f, 0].mean()))
    sim.run(observe=observe)
    a = np.array(rows)
    return PeriodicBed(cfg, *a.T)


@dataclass
class FloorBed:
    """A bed on a floor fed at U in the solved gas, read at every step: the pressure drop across it (p' at the
    floor, extrapolated from the first two rows of cells and averaged across; the open top holds p' = 0), the
    smallest theta of the grid's cells below the bed's median height (a void reads near 0), and the
    layer's mass-fraction heights (5% .. 95%)."""
    cfg: object
    t: np.ndarray
    drop: np.ndarray        # [Pa]
    theta_min: np.ndarray
    heights: np.ndarray     # (steps, 5) [m]
    weight: float           # the solids' buoyant weight per unit area [Pa]
    reflected: int          # grains walls.reflect put back on a plate (0: the walls' pressure held them all)

    def mean_drop(self, t0):
        """The pressure drop averaged over time from t0 to the end (each step weighted by its dt)."""
        sel = self.t >= t0
        t, d = self.t[sel], self.drop[sel]
        return float(np.sum(0.5 * (d[1:] + d[:-1]) * np.diff(t)) / (t[-1] - t[0]))


def floor_bed(sets=(), t_end=2.0, path=BED_AIR):
    """Run a bed on a floor with the solved gas (run/fluidized_bed_air.toml with ``sets``) to t_end."""
    cfg = config.load(path, ['gas.flow="solved"', *sets, f"output.t_end={t_end!r}", f"output.times=[{t_end!r}]",
                             "output.snapshots=false"])
    sim = Simulation(cfg, MPI.COMM_SELF)
    ps = sim.ps
    f = ps.kind[:ps.n_own] == GRAIN
    g = math.sqrt(sum(x * x for x in cfg.g))
    weight = float(ps.mass[:ps.n_own][f].sum()) * g * (1.0 - cfg.gas.rho / cfg.rho_s) / cfg.Ly
    rows, heights = [], []

    def observe(s):
        sol = s.gas.solution
        p = sol.p
        fl = s.ps.kind[:s.ps.n_own] == GRAIN
        h = mass_quantiles(s.ps.pos[:s.ps.n_own][fl, 0], s.ps.mass[:s.ps.n_own][fl], QUANTILES)
        below = (np.arange(p.shape[0]) + 0.5) * s.gas.grid.hx < h[2]
        rows.append((s.t, floor_drop(p), float(sol.theta[below].min())))
        heights.append(h)
    sim.run(observe=observe)
    a = np.array(rows)
    return FloorBed(cfg, a[:, 0], a[:, 1], a[:, 2], np.array(heights), weight, sim.reflections())
