"""The solved gas's part of an evaluation (docs/physics.md, "The solved gas"), between Eq. (3) and Eq. (5)
(the particles' theta of the state known): the owned particles deposited on the grid (:mod:`parsph.gas.deposit`:
theta and their drag resistance m C, and that times v), the deposits summed over the ranks
(:class:`parsph.parallel.grid_sum.GridSum`), K = 1 / R on the cells (capped), the pressure solved
(:mod:`parsph.gas.darcy`) and the mixture's flux j interpolated back to the owned particles (``ps.flux``), where
the drag loops read it (:func:`parsph.sph.body_force.drag_plain`: C = K_i / eps_i toward w = j, implicit in v
with ``numerics.drag_update = "implicit"``).

K from the particles' own drag rates, and V their velocity weighted as their drag weights it (not the cell's
mean theta and volume-weighted velocity): the grid's -grad p' is then the sum of the drag its particles feel,
so the gas takes the reaction of the force on the solids. With K from the cells' theta a bubbling box's mean
gradient carried 75% of its weight (a cluster's drag is not the drag of its mean theta), with the volume-
weighted V 113% (a cluster's particles fall faster than its cell's mean). Two more things keep the sum exact
where the grains move through the gas (a bubbling bed): the particles' drag uses the rates the last pass
deposited (``ps.drag_rate``; recomputed at the slip toward the final j, a bubbling bed's pressure drop was 1.9%
above its weight), and the faces' V is the cells' weighted by 1/K (:func:`parsph.gas.finite_volumes._face_v`; with
their plain mean, 4.1%).

The coupling: j of the state the passes evaluate, the particles' drag implicit toward it. The gradient part of
the solids' velocity (what compresses the mixture) is what p' removes; with j fixed it relaxes at the drag's
rate in one implicit update, stable at any dt/tau, and in a column 1-D in the mean j = U exactly, so the step
is the column closure's (docs/physics.md, "How parsph solves it").

A slip-dependent closure (Wen & Yu, Gidaspow) takes C at the slip toward the last solve's j, interpolated to
the particles where they are now: one solve an evaluation instead of two (the first at no slip, the second at
the slip toward the first's j), which halved the gas stage of run/bubbling_bed.toml (17 to 9 ms a step on one
rank); the slip in C lags by one evaluation, the drag stays implicit toward this state's j. The very first
solve of a run, with no j yet, still takes the two.

Every rank solves the same grid (the sums are exact), so every rank count gives the same bits; a wide band's two
blocks (:mod:`parsph.gas.split_band`) are factorised side by side, one a rank.
"""
import numpy as np

from parsph.errors import SolveError
from parsph.gas import darcy, deposit, permeability
from parsph.gas.grid import grid_of
from parsph.parallel.block_share import BlockShare
from parsph.parallel.grid_sum import GridSum
from parsph.physics.drag import STOKES, rate
from parsph.setup.gas_config import K_MAX_FACTOR
from parsph.sph import body_force, pass_data


def floor_flux(grid, gas, t=0.0):
    """The gas fed through each floor face at time t [m/s], (j, k) flattened: U, and U_jet where the face's
    centre lies under gas.jet (a strip y0 <= y < y1, across z in 3-D) while the jet blows (to its t_off, where
    one is given)."""
    U = np.full(grid.ny, gas.U)
    if gas.jet and t < gas.jet_until:
        y0, y1, U_jet = gas.jet
        y = (np.arange(grid.ny) + 0.5) * grid.hy
        U[(y >= y0) & (y < y1)] = U_jet
    return np.repeat(U, grid.nz)


def reference_rate(cfg):
    """C(theta0, no slip) / eps0 [1/s]: the scale in which the deposit sums the grains' drag rates."""
    gas, theta0 = cfg.gas, cfg.theta0
    return rate(gas.model, theta0, 0.0, cfg.rho_s, gas.rho, gas.mu, gas.d) / (1.0 - theta0)


def permeability_cap(cfg):
    """K_max of the run's solve [m^2/(Pa s)]: ``gas.K_max``, else K_MAX_FACTOR K(theta0)."""
    return cfg.gas.K_max or K_MAX_FACTOR * permeability.of_uniform(cfg.theta0, reference_rate(cfg), cfg.rho_s)


class GasStage:
    def __init__(self, cfg, comm, ps):
        gas = cfg.gas
        self.gas = gas
        self.rho_s = cfg.rho_s
        self.grid = grid_of(cfg.L, cfg.Ly, gas.cell, walls=cfg.scene.walls, sides=cfg.sides,
                            Lz=cfg.Lz if cfg.dim == 3 else 0.0)
        self.ring = cfg.Ly_ring  # the particles' period along y
        g = self.grid
        self.sums = np.zeros(g.shape + (2 + g.dim,), np.int64)  # theta, R, R v per cell (deposit.deposit)
        self.exchange = GridSum(comm)
        self.rate_ref = reference_rate(cfg)
        self.K_max = permeability_cap(cfg)
        if g.walls:  # the floor fed at U (U_jet under a jet), the lid open (p' = 0); y periodic or closed
            closed = (darcy.Side("flux", np.zeros(g.nx * g.nz)),) * 2 if g.sides else None
            self.darcy = darcy.Darcy(g.nx, g.ny, g.hx, g.hy, (darcy.Side("flux", floor_flux(g, gas)),
                                                              darcy.Side("pressure", np.zeros(g.ny * g.nz))), closed,
                                     nz=g.nz, hz=g.hz, share=BlockShare(comm))
        else:  # periodic along gravity: the mean flux U through every cross-section
            self.darcy = darcy.Darcy(g.nx, g.ny, g.hx, g.hy, None, None, mean_flux=gas.U, nz=g.nz, hz=g.hz)
        self.every = gas.solve_every
        self.solved_at = None
        self.solves = 0
        self.j = None          # the mixture's flux at the cell centres (cells..., dim)
        self.solution = None   # the last darcy.Solution, with theta, V and K of its deposit
        self.no_stream = np.zeros(3)
        self.cells = np.zeros((0, 2 * g.dim), np.int32)  # the owned particles' cells and weights (_place)
        self.weights = np.zeros((0, 2 * g.dim))
        self.three_d = pass_data.switch(g.dim == 3)  # the velocities' stride (drag_rates)
        self.before = (None, None, (None, None))  # what the last call started from (j, solved_at, darcy's start)
        self.earlier = self.before                # and the call before it
        ps.add_field("flux")

    def __call__(self, ps, step, t):
        """ps.flux of the owned particles for the state at ``step``, ``t`` (a solve where one is due)."""
        self.earlier = self.before
        self.before = (self.j, self.solved_at, self.darcy.start())
        self._place(ps)
        due = self.j is None or self.every == 1 or (step % self.every == 0 and step != self.solved_at)
        if due:
            self.solve(ps, step, t)
        self._interpolate(ps)
        if not due:  # between solves: the rates at the slip toward the last solve's flux
            self._rates(ps, ps.flux, ps.drag_rate)

    def fields(self):
        """What an output keeps of the grid (:class:`parsph.output.Frame`'s ``grid``): the last solve's theta,
        p' [Pa], the mixture's flux j and the gas's velocity u_g = (j - theta V) / eps [m/s] at the cells
        (nx, ny[, nz][, dim]), and under start/ what the last call started from, so that a restart from this state
        makes the same solves: the flux it held, the warm start, the factor's K."""
        sol = self.solution
        out = {"attrs": {"cell": self.grid.cell, "solves": self.solves}}
        if sol is not None:
            eps = (1.0 - sol.theta)[..., None]
            out.update({"theta": sol.theta, "p": sol.p, "j": self.j,
                        "u_g": (self.j - sol.theta[..., None] * sol.V) / eps})
        j, solved_at, (factor_K, warm) = self.before
        out["attrs"]["start_solved_at"] = -1 if solved_at is None else solved_at
        if j is not None:
            out["start/j"] = j
        if warm is not None:
            out["start/warm"] = np.stack(warm)
        if factor_K is not None:
            out["start/factor_K"] = factor_K
        return out

    def step_back(self):
        """The call before the last becomes the last (:meth:`fields` keeps what it started from): a step whose
        midpoint evaluation failed is written as its start's state, whose evaluation a restart makes again."""
        self.before = self.earlier

    def restore(self, grid):
        """Start from an output's /grid (:meth:`fields`): the state before its last call, which the restart
        makes again."""
        solved_at = int(grid["attrs"]["start_solved_at"])
        self.solved_at = None if solved_at < 0 else solved_at
        self.j = grid.get("start/j")
        warm = grid.get("start/warm")
        self.darcy.restore(grid.get("start/factor_K"), None if warm is None else list(warm))

    def _place(self, ps):
        """The owned particles' cells and weights on the grid (deposit.weights), for this call's deposits and
        interpolations."""
        g = self.grid
        if len(self.cells) < ps.n_own:
            self.cells = np.zeros((ps.capacity, 2 * g.dim), np.int32)
            self.weights = np.zeros((ps.capacity, 2 * g.dim))
        deposit.weights(ps.pos, ps.kind, ps.n_own, g.nx, g.ny, g.nz, g.hx, g.hy, g.hz, g.nx * g.hx, g.ny * g.hy,
                        g.nz * g.hz, g.walls, g.sides, self.ring, self.cells, self.weights)

    def _interpolate(self, ps):
        g = self.grid
        deposit.interpolate(self.cells, self.weights, ps.n_own, self.j.reshape(g.shape3 + (g.dim,)), ps.flux)

    def _rates(self, ps, flux, out):
        """out[k] = K of the owned particles at the slip toward ``flux`` (body_force.drag_rates)."""
        gas = self.gas
        body_force.drag_rates(ps.n_own, ps.vel, ps.theta, self.rho_s, gas.model, gas.rho, gas.mu, gas.d,
                              pass_data.TOWARD_FLUX, 0, 0.0, 0.0, self.no_stream, flux, out, self.three_d)

    def solve(self, ps, step, t):
        g, gas = self.grid, self.gas
        failed = None
        # a slip-dependent closure's C at the slip toward the last solve's flux, interpolated to the particles'
        # places now (j is what a restart point keeps: the same bits after a restart); at the first solve, toward
        # a first solve's flux of C at no slip
        lagged = gas.model != STOKES and self.j is not None
        passes = 1 if gas.model == STOKES or lagged else 2
        if lagged:
            self._interpolate(ps)
        if gas.jet_until < np.inf:  # a jet that stops: the floor's feed at this state's time
            self.darcy.feed(floor_flux(g, gas, t))
        for p in range(passes):
            # C = K / eps along every axis, at the slip toward ps.flux (or none: toward the particles' own
            # velocity); the last pass's K are the particles' (ps.drag_rate: the passes read them, so that the
            # drag the grains feel sums to the grid's -grad p')
            self._rates(ps, ps.flux if p > 0 or lagged else ps.vel, ps.drag_rate)
            deposit.deposit(self.cells, self.weights, ps.vel, ps.mass, ps.n_own, self.rho_s, g.hx, g.hy, g.hz,
                            self.sums.reshape(g.shape3 + self.sums.shape[-1:]), ps.drag_rate, ps.theta, self.rate_ref)
            self.exchange(self.sums)
            theta, R, V = deposit.cells_of(self.sums, self.rho_s, self.rate_ref)
            K = permeability.from_resistance(R, self.K_max)
            try:
                sol = self.darcy.solve(K, V)
            except darcy.SolveFailed as e:
                failed = str(e)
            if self.exchange.agree_failed(failed is not None):
                raise SolveError(f"the gas pressure solve failed at step {step}, t = {t:.6g} s "
                                 f"({failed or 'on another rank'})")
            self.j = sol.centred()
            if p + 1 < passes:
                self._interpolate(ps)
        sol.theta, sol.V, sol.K = theta, V, K
        self.solution = sol
        self.solved_at = step
        self.solves += 1
