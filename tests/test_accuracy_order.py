"""The Couette error falls with resolution at the order the sweep measured (docs/accuracy.md).

A coarse, quick check, not the sweep (scripts/sweep.py): N_x = 20 and 40 at fixed
h/dx, dt = "auto", Eqs. (6)-(7), to t = 0.05 s on one rank. The two-point order
log2(err(20) / err(40)) of the max error at t = 0.05 s must lie within MARGIN of
the order the sweep measured for the same choices (docs/accuracy.md, table
"Convergence orders"):

* the paper's numerics (cubic spline, h = 1.25 dx, Morris cap beta_max = 1.5):
  0.98 (least squares over N_x = 20 ... 100; local orders 0.92 ... 1.05);
* the accurate preset's numerics (Wendland C2, h = 2 dx, beta_max = 6, inactive on
  the lattice): 2.0 over N_x = 20 ... 50 (local 2.07, 1.94), before the error
  levels off at the kernel's viscosity bias (about 2e-4 from N_x = 70 on).

The margins cover the spread of the sweep's local orders and the difference
between N_x = 20/40 and the sweep's resolutions; the serial run of both takes
about 10 s of CPU.
"""
import math

import numpy as np
import pytest
from mpi4py import MPI

from parsph import config
from parsph.solver import Simulation

from conftest import paper_raw

T = 0.05
# name: (kernel, h/dx, beta_max, measured order at t = 0.05 s, margin)
CASES = {
    "paper numerics (cubic, h/dx 1.25, cap 1.5)": ("cubic_spline", 1.25, 1.5, 0.98, 0.25),
    "accurate preset (Wendland C2, h/dx 2, cap 6)": ("wendland_c2", 2.0, 6.0, 2.0, 0.35),
}


def max_error(Nx, kernel, h_over_dx, beta_max):
    """Max |v_y - Eq. (8)| / V_w at t = T of the paper case with the given numerics."""
    raw = paper_raw()
    del raw["numerics"]["h"]  # exactly one of h and h_over_dx
    raw["numerics"].update({"Nx": Nx, "h_over_dx": h_over_dx, "kernel": kernel, "dt": "auto"})
    raw["walls"]["beta_max"] = beta_max
    raw["output"].update({"t_end": T, "times": [T], "progress_interval": 0.0, "snapshots": False})
    cfg = config.build(raw, config.dumps(raw))
    errs = []
    sim = Simulation(cfg, MPI.COMM_SELF)
    sim.run(output=lambda s, snapshot=None: errs.append(s.profile()["err"][0]))
    assert len(errs) == 1 and sim.t == pytest.approx(T, rel=1e-12)
    return errs[0]


@pytest.mark.parametrize("name", list(CASES))
def test_error_falls_at_measured_order(name):
    kernel, h_over_dx, beta_max, order, margin = CASES[name]
    coarse = max_error(20, kernel, h_over_dx, beta_max)
    fine = max_error(40, kernel, h_over_dx, beta_max)
    assert np.isfinite(coarse) and np.isfinite(fine)
    assert fine < coarse, f"{name}: error did not fall: {coarse:.3e} at N_x = 20, {fine:.3e} at N_x = 40"
    p = math.log(coarse / fine) / math.log(2.0)
    assert abs(p - order) <= margin, (f"{name}: order {p:.2f} from N_x = 20 to 40 ({coarse:.3e} -> {fine:.3e}); "
                                      f"the sweep measured {order} (margin {margin})")
