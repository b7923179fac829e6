"""The solved gas's part of a step (docs/physics.md, "The solved gas"), before the passes of an evaluation:
the owned particles deposited on the grid (:mod:`parsph.gas.deposit`), the deposits summed over the ranks
(:class:`parsph.parallel.grid_sum.GridSum`), K on the cells, the pressure solved (:mod:`parsph.gas.darcy`) and
the mixture's flux j interpolated back to the owned particles (``ps.flux``), where the drag loops read it
(:func:`parsph.sph.equations.drag_plain`: C = K / eps toward w = j, implicit in v with
``numerics.drag_update = "implicit"``).

The coupling: j of the state the passes evaluate, the particles' drag implicit toward it. The gradient
part of the solids' velocity (what compresses the mixture) is what p' removes; with j fixed it relaxes at the
drag's rate in one implicit update, stable at any dt/tau, and in a column 1-D in the mean j = U exactly, so the
step is the column closure's (docs/physics.md, "Stiffness").

Every rank solves the same grid (the sums are exact), so every rank count gives the same bits.
"""
import numpy as np

from parsph.errors import SolveError
from parsph.gas import darcy, deposit
from parsph.gas.grid import grid_of
from parsph.gas.permeability import permeability
from parsph.parallel.grid_sum import GridSum
from parsph.setup.config import K_MAX_FACTOR
from parsph.physics.drag import STOKES


class GasStage:
    def __init__(self, cfg, comm, ps):
        gas = cfg.gas
        self.gas = gas
        self.rho_s = cfg.rho_s
        self.grid = grid_of(cfg.L, cfg.Ly, gas.cell, walls=cfg.scene.walls)
        g = self.grid
        self.sums = np.zeros((3, g.nx, g.ny), np.int64)
        self.exchange = GridSum(comm)
        self.K_max = gas.K_max or K_MAX_FACTOR * float(
            permeability(np.array([cfg.theta0]), 0.0, gas.model, gas.rho, gas.mu, gas.d, np.inf)[0])
        if g.walls:  # the floor fed at U, the lid open (p' = 0); y periodic
            self.darcy = darcy.Darcy(g.nx, g.ny, g.hx, g.hy, (darcy.Side("flux", np.full(g.ny, gas.U)),
                                                              darcy.Side("pressure", np.zeros(g.ny))), None)
        else:  # periodic along gravity: the mean flux U through every cross-section
            self.darcy = darcy.Darcy(g.nx, g.ny, g.hx, g.hy, None, None, mean_flux=gas.U)
        self.every = gas.solve_every
        self.solved_at = None
        self.solves = 0
        self.j = None          # the mixture's flux at the cell centres (nx, ny, 2)
        self.solution = None   # the last darcy.Solution, with theta and V of its deposit
        ps.add_field("flux")

    def __call__(self, ps, step, t):
        """ps.flux of the owned particles for the state at ``step``, ``t`` (a solve where one is due)."""
        if self.j is None or self.every == 1 or (step % self.every == 0 and step != self.solved_at):
            self.solve(ps, step, t)
        g = self.grid
        deposit.interpolate(ps.pos, ps.kind, ps.n_own, self.j, g.nx, g.ny, g.hx, g.hy, g.nx * g.hx, g.ny * g.hy,
                            g.walls, ps.flux)

    def solve(self, ps, step, t):
        g, gas = self.grid, self.gas
        self.sums[:] = 0
        deposit.deposit(ps.pos, ps.vel, ps.mass, ps.kind, ps.n_own, self.rho_s, g.nx, g.ny, g.hx, g.hy,
                        g.nx * g.hx, g.ny * g.hy, g.walls, self.sums)
        self.exchange(self.sums)
        theta, V = deposit.fields_of(self.sums, g)
        failed = None
        try:
            slip = 0.0
            for _ in range(1 if gas.model == STOKES else 2):  # the slip-dependent closures: K at the slip of a first solve
                K = permeability(theta, slip, gas.model, gas.rho, gas.mu, gas.d, self.K_max)
                sol = self.darcy.solve(K, V)
                j = sol.centred()
                slip = np.sqrt(((j - V) ** 2).sum(axis=-1)) / (1.0 - np.minimum(theta, 0.95))
        except darcy.SolveFailed as e:
            failed = str(e)
        if self.exchange.agree_failed(failed is not None):
            raise SolveError(f"the gas pressure solve failed at step {step}, t = {t:.6g} s "
                             f"({failed or 'on another rank'})")
        sol.theta, sol.V, sol.K = theta, V, K
        self.solution = sol
        self.j = np.ascontiguousarray(j)
        self.solved_at = step
        self.solves += 1
