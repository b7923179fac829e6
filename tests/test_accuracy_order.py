"""The Couette error falls with resolution at the order the scheme's analysis predicts.

A coarse, quick check, not the sweep (scripts/sweep.py): N_x = 20 and 40 at fixed
h/dx, dt = "auto" at a quarter of the limit, Eqs. (6)-(7), to t = 0.05 s on one rank. The two-point order
log2(err(20) / err(40)) of the max error against Eq. (8) must lie within a margin of
the order the numerics should have:

* the paper's numerics (cubic spline, h = 1.25 dx, Morris cap beta_max = 1.5): order 1.
  On the lattice the first fluid column sits at d_i = dx/2 from the plate, and the two
  wall rows within its support (2h = 2.5 dx) at d_j = dx/2 and 3dx/2, so Morris's linear
  extrapolation beta = 1 + d_j/d_i would be 2 and 4: the cap sets both to 1.5. The ghost
  velocities then do not extrapolate the near-wall profile linearly, which acts as a slip
  over a length of order dx: an error proportional to dx;
* Wendland C2 at h = 2 dx with cap 6: order 2. The first column's beta = 1 + d_j/d_i
  exceeds 6 only for the fourth wall row (d_j = 7dx/2), which lies 4dx = 2h away, on the
  edge of the support; so the cap is inactive on the lattice, the ghosts extrapolate
  linearly, and what is left is the kernel's smoothing error, O(h^2) = O(dx^2) at fixed
  h/dx. The lattice's viscosity bias (nu_eff / nu at fixed h/dx, parsph.physics.lattice_sums)
  does not fall with dx: it is a floor, and the test checks that the error at N_x = 40 is
  still at least twice the floor's.

The margins are empirical, not derived: two resolutions this coarse are pre-asymptotic,
and the share of the next-order terms at N_x = 20 (the kernel's smoothing error for the
first-order case; the first-order time error of Eqs. (6)-(7), with dt proportional to dx,
and the bias floor for the second-order case) is not known a priori. They are wide
enough for that and narrow enough to tell the orders 1 and 2 apart. The sweep's fits over
N_x = 20 ... 100 and 20 ... 50 at the full stability limit (docs/accuracy.md) give 0.95 and
2.48, the latter raised by the first-order time error cancelling part of the spatial one,
which is why this test steps at a quarter of the limit. The serial run of both cases takes
a few s of CPU.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from parsph.setup import config
from parsph.setup.runfile import RunFile
from parsph.physics.analytic import couette_velocity
from parsph.physics.lattice_sums import viscosity_bias
from parsph.simulation.solver import Simulation

from conftest import paper_raw

T = 0.05
# name: (kernel, h/dx, beta_max, the scheme's order, margin)
CASES = {
    "paper numerics (cubic, h/dx 1.25, cap 1.5)": ("cubic_spline", 1.25, 1.5, 1.0, 0.25),
    "Wendland C2, h/dx 2, cap 6 (second order)": ("wendland_c2", 2.0, 6.0, 2.0, 0.35),
}


def max_error(Nx, kernel, h_over_dx, beta_max):
    """Max |v_y - Eq. (8)| / V_w at t = T of the paper case with the given numerics."""
    raw = paper_raw()
    del raw["numerics"]["h"]  # exactly one of h and h_over_dx
    # a quarter of the stability limit: the first-order time error of Eqs. (6)-(7) stays below the
    # spatial error being measured (at the full limit it raised the second-order case's apparent order to 3)
    raw["numerics"].update({"Nx": Nx, "h_over_dx": h_over_dx, "kernel": kernel, "dt": "auto", "dt_safety": 0.25})
    raw["walls"]["beta_max"] = beta_max
    raw["output"].update({"t_end": T, "times": [T], "progress_interval": 0.0, "snapshots": False})
    cfg = config.build(RunFile(raw))
    errs = []
    sim = Simulation(cfg, MPI.COMM_SELF)
    sim.run(output=lambda s, snapshot=None: errs.append(s.profile["err"][0]))
    assert len(errs) == 1 and sim.t == pytest.approx(T, rel=1e-12)
    return errs[0]


def bias_floor(kernel, h_over_dx, L=0.01, nu=1.75e-4, V_w=1.0):
    """Max |Eq. (8) with nu_eff - Eq. (8) with nu| / V_w at t = T: the error left when dx -> 0 at fixed h/dx."""
    x = np.linspace(0.0, L, 401)
    ratio = viscosity_bias(kernel, h_over_dx)
    return float(np.abs(couette_velocity(x, T, nu * ratio, L, V_w) - couette_velocity(x, T, nu, L, V_w)).max() / V_w)


@pytest.mark.parametrize("name", list(CASES))
def test_error_falls_at_the_schemes_order(name):
    kernel, h_over_dx, beta_max, order, margin = CASES[name]
    coarse = max_error(20, kernel, h_over_dx, beta_max)
    fine = max_error(40, kernel, h_over_dx, beta_max)
    assert np.isfinite(coarse) and np.isfinite(fine)
    assert fine < coarse, f"{name}: error did not fall: {coarse:.3e} at N_x = 20, {fine:.3e} at N_x = 40"
    p = math.log(coarse / fine) / math.log(2.0)
    assert abs(p - order) <= margin, (f"{name}: order {p:.2f} from N_x = 20 to 40 ({coarse:.3e} -> {fine:.3e}); "
                                      f"the scheme's order is {order:g} (margin {margin})")
    # at N_x = 40 the error is still the discretisation's, at least twice the fixed-h/dx floor
    assert bias_floor(kernel, h_over_dx) < 0.5 * fine
