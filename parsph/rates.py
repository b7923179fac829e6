"""The right-hand side on one rank: cell sort -> Eq. (3) -> halo rho -> Eq. (5).

Three numba calls per evaluation (sort, density, momentum), two of them
threaded; between the two passes the densities of halo copies must be
refreshed, which is the caller's business (a callback): this module knows
nothing of MPI.
"""
import time

import numpy as np

from . import equations, neighbours


class Rates:
    """Evaluates rho, theta and the accelerations of the owned particles of a ``Particles`` set.

    ``switches`` are :func:`equations.switch` values for (pressure,
    viscosity, symmetric viscosity, walls, consistent pressure); ``g`` the body
    force as a 3-vector; ``x0`` the lower x edge of the cell grid.
    """

    CELLS_PER_SUPPORT = 1  # cell side 2h (measured: finer cells, 2h/2 to 2h/4, were 3-10% slower)

    def __init__(self, kernel, h, dim, x0, rho_s, G_a, G_b, k, L, beta_max, g, switches):
        pressure, viscosity, symmetric_mu, walls, consistent = switches
        three_d = equations.switch(dim == 3)
        self.cell = kernel.support * h / self.CELLS_PER_SUPPORT
        self.x0 = x0
        # the constant trailing arguments of the two passes
        self.density_consts = (x0, self.cell, h, kernel.norm(h, dim), kernel.kid, rho_s, G_a, G_b,
                               pressure, consistent, three_d)
        self.momentum_consts = (rho_s, G_a, G_b, k, L, beta_max, np.asarray(g, float), pressure, viscosity,
                                symmetric_mu, walls, consistent, three_d)
        self.work = neighbours.Workspace()

    def __call__(self, ps, refresh_rho, timers=None):
        """Fill ps.rho, ps.theta and ps.acc of the owned particles; ``refresh_rho(ps)`` updates the halo's rho.

        Wall particles keep the rho they hold in ``ps.rho``.

        ``timers`` (a dict) gets the seconds of "neighbours", "density",
        "halo" (the callback) and "forces" added.
        """
        W, n = self.work, ps.n
        t0 = time.perf_counter()
        W.ensure(n)
        grid = neighbours.sort_into_cells(
            ps.pos, ps.vel, ps.mass, ps.kind, ps.gid, n, ps.n_own, self.x0, self.cell,
            W.order, W.cell_of, W.tmp, W.sx, W.sy, W.sz, W.svx, W.svy, W.svz, W.sm, W.skind, W.owned)
        t1 = time.perf_counter()
        while True:
            most = equations.density(n, W.sx, W.sy, W.sz, W.sm, W.skind, W.owned, W.order, W.cell_of,
                                     *grid, *self.density_consts, ps.rho, W.stheta, W.sinv, W.spress,
                                     W.nbr_n, W.nbr_j, W.nbr_f)
            if most <= W.width:
                break
            W.ensure_width(most)
        t2 = time.perf_counter()
        refresh_rho(ps)
        t3 = time.perf_counter()
        equations.momentum(n, W.sx, W.sy, W.sz, W.svx, W.svy, W.svz, W.sm, W.skind, W.owned, W.order, ps.rho,
                           W.stheta, W.sinv, W.spress, W.nbr_n, W.nbr_j, W.nbr_f, *self.momentum_consts,
                           ps.acc, ps.theta)
        t4 = time.perf_counter()
        if timers is not None:
            timers["neighbours"] += t1 - t0
            timers["density"] += t2 - t1
            timers["halo"] += t3 - t2
            timers["forces"] += t4 - t3
