"""Bubbles on a grid (parsph.gas.bubbles) against shapes whose measures are known, and reference 8's throughflow
against a grid solve past a void (reference 6 with kappa large)."""
import math
import re

import numpy as np
import pytest

from parsph.gas import bubbles, darcy
from parsph.physics import bubbling, inclusion


def disk(n, ci, cj, r, shape=None, inside=0.0, outside=0.6):
    """theta on an n x n grid (cell 1): ``inside`` where the cell centre lies within r of (ci, cj) (cell
    coordinates of the centre, periodic along both axes), else ``outside``."""
    i, j = np.meshgrid(np.arange(n) + 0.5, np.arange(n) + 0.5, indexing="ij")
    di = (i - ci + n / 2) % n - n / 2
    dj = (j - cj + n / 2) % n - n / 2
    return np.where(di * di + dj * dj < r * r, inside, outside)


def test_a_disk_is_one_bubble_of_its_area_and_centre():
    theta = disk(64, 30.0, 20.0, 10.0)
    found = bubbles.find(theta, 0.002, 0.002, 0.2)
    assert len(found) == 1
    b = found[0]
    assert b.area == pytest.approx(np.count_nonzero(theta < 0.2) * 0.002 ** 2, rel=1e-12)
    assert b.diameter == pytest.approx(2 * 10.0 * 0.002, rel=0.02)     # the pixelated circle
    assert (b.x, b.y) == pytest.approx((30.0 * 0.002, 20.0 * 0.002), rel=1e-12)  # symmetric about its centre


def test_a_bubble_across_the_periodic_edge_is_one_with_the_same_measures():
    here = bubbles.find(disk(64, 30.0, 32.0, 9.0), 1.0, 1.0, 0.2)[0]
    across = bubbles.find(disk(64, 30.0, 1.0, 9.0), 1.0, 1.0, 0.2)
    assert len(across) == 1
    b = across[0]
    assert b.area == here.area
    assert (b.x, b.y) == pytest.approx((30.0, 1.0), abs=1e-12)
    walled = bubbles.find(disk(64, 30.0, 1.0, 9.0), 1.0, 1.0, 0.2, periodic=(False, False))
    assert len(walled) == 2 and sum(w.area for w in walled) == here.area


def test_small_sets_and_dense_cells_are_not_bubbles():
    theta = np.full((20, 20), 0.6)
    theta[5, 5] = theta[5, 6] = theta[6, 5] = 0.0            # 3 cells: below MIN_CELLS
    theta[12:14, 12:14] = 0.19                              # 4 cells just under the threshold
    found = bubbles.find(theta, 1.0, 1.0, 0.2)
    assert [b.area for b in found] == [4.0]


def test_the_clear_gas_above_the_bed_is_not_a_bubble():
    theta = disk(64, 30.0, 20.0, 6.0)
    theta[50:] = 0.0                                        # the freeboard, open at the top
    theta[45:50, 40:44] = 0.0                               # a bubble erupting into it
    found = bubbles.find(theta, 1.0, 1.0, 0.2)
    assert [(b.x, b.y) for b in found] == [(30.0, 20.0)]
    assert len(bubbles.find(theta, 1.0, 1.0, 0.2, open_top=False)) == 2


def test_a_rising_bubble_is_matched_with_its_velocity():
    dt, h = 0.02, 0.002
    before = bubbles.find(disk(64, 20.0, 30.0, 8.0), h, h, 0.2)
    after = bubbles.find(disk(64, 23.0, 30.0, 8.0), h, h, 0.2)
    pairs = bubbles.match(before, after, dt, (64, 64))
    assert len(pairs) == 1
    assert pairs[0].velocity == pytest.approx(3 * h / dt, rel=1e-12)
    assert pairs[0].detached
    on_floor = bubbles.find(disk(64, 6.0, 30.0, 8.0), h, h, 0.2)     # its cells reach the first row
    assert not bubbles.match(on_floor, bubbles.find(disk(64, 9.0, 30.0, 8.0), h, h, 0.2), dt, (64, 64))[0].detached


def test_a_bubble_that_split_has_no_velocity():
    before = bubbles.find(disk(64, 20.0, 30.0, 8.0), 1.0, 1.0, 0.2)
    theta = np.minimum(disk(64, 22.0, 25.0, 4.0), disk(64, 22.0, 35.0, 4.0))
    after = bubbles.find(theta, 1.0, 1.0, 0.2)
    assert len(after) == 2
    assert bubbles.match(before, after, 0.02, (64, 64)) == []


def test_throughflow_of_a_void_against_davidson():
    """A void of radius a (16 cells, its centre on a node) in a bed of permeability K passing U far away (the
    box's sides held at reference 6's exact p', so the box has no effect): the gas crossing its equator is
    2 kappa U / (1 + kappa) times 2 a, which reference 8 gives as 4 U a as kappa -> infinity; the grid's
    within 2% (its first-order error at 16 cells)."""
    a_cells, n, U, kappa = 16, 128, 0.2, 1e4
    h = 1e-3
    a, B = a_cells * h, n * h / 2
    theta = disk(n, n / 2, n / 2, a_cells)
    K = np.where(theta < 0.2, kappa, 1.0)
    xc = -B + (np.arange(n) + 0.5) * h
    exact = lambda x, y: inclusion.pressure(x, y, a, kappa, 1.0, U)
    sol = darcy.solve(K, np.zeros((n, n, 2)), h, h,
                      (darcy.Side("pressure", exact(-B, xc)), darcy.Side("pressure", exact(B, xc))),
                      (darcy.Side("pressure", exact(xc, -B)), darcy.Side("pressure", exact(xc, B))))
    found = bubbles.find(theta, h, h, 0.2, periodic=(False, False))
    assert len(found) == 1
    q = bubbles.throughflow(found[0], sol.centred()[..., 0], h, 0.0)
    assert bubbling.throughflow(U, a) == pytest.approx(2 * a * inclusion.inside_flux(1e12, U), rel=1e-9)
    assert q == pytest.approx(2 * a * inclusion.inside_flux(kappa, U), rel=0.02)
    assert q == pytest.approx(bubbling.throughflow(U, a), rel=0.02)
    # in the bubble's frame: a bubble rising at u_b carries u_b 2 a less through its equator
    assert bubbles.throughflow(found[0], sol.centred()[..., 0], h, 0.05) == pytest.approx(q - 0.05 * 2 * a,
                                                                                          rel=1e-12)


def test_rise_velocity():
    assert bubbling.rise_velocity(0.04, -9.81) == pytest.approx(0.5 * math.sqrt(9.81 * 0.04), rel=1e-15)


def test_time_average_of_the_drop_is_the_trapezoids():
    """Bed.mean_drop: drop/weight piecewise linear between outputs, averaged from checks.settle on: the exact
    integral over the window divided by its length."""
    from parsph.cli.bed_report import Bed, Frame
    t = [0.0, 0.1, 0.2, 0.4, 0.5]
    r = [3.0, 1.0, 2.0, 0.5, 1.5]
    bed = Bed([Frame(ti, ri * 7.0, 7.0, np.zeros(5), []) for ti, ri in zip(t, r)], settle=0.1)
    exact = (0.1 * (1.0 + 2.0) / 2 + 0.2 * (2.0 + 0.5) / 2 + 0.1 * (0.5 + 1.5) / 2) / 0.4
    assert bed.mean_drop() == pytest.approx(exact, rel=1e-14)
    assert math.isnan(Bed(bed.frames[:1], settle=0.0).mean_drop())


@pytest.mark.parametrize("phi", [0.0, 0.6, 0.9])
def test_standard_error_of_a_time_average_against_an_autoregressive_series(phi):
    """mean_standard_error over 300 series of 400 values of x_t = phi x_{t-1} + e_t (unit normal e): its
    squared error averaged over the series against the exact variance of the mean of such a series,
    var(x) / n^2 (n + 2 sum_k (n - k) phi^k) with var(x) = 1 / (1 - phi^2), within 15% (the estimator cuts
    the autocorrelation's sum where it first turns negative: a bias of a few %)."""
    from parsph.cli.bed_report import mean_standard_error
    n, m = 400, 300
    rng = np.random.default_rng(3)
    e = rng.normal(size=(m, n + 200))
    x = np.zeros_like(e)
    for t in range(1, n + 200):  # 200 values to forget the start
        x[:, t] = phi * x[:, t - 1] + e[:, t]
    x = x[:, 200:]
    k = np.arange(1, n)
    exact = 1.0 / (1.0 - phi ** 2) / n ** 2 * (n + 2.0 * np.sum((n - k) * phi ** k))
    estimated = np.mean([mean_standard_error(s)[0] ** 2 for s in x])
    assert estimated == pytest.approx(exact, rel=0.15)
    se, samples = mean_standard_error(x[0])
    assert samples == pytest.approx(n * np.var(x[0]) / n / se ** 2, rel=1e-12)
    assert math.isnan(mean_standard_error([1.0, 2.0])[0])


def test_a_window_under_a_second_is_reported_not_judged():
    """Reference 8's average is over at least 1 s of bubbling: the Verdict of a shorter window judges nothing."""
    from parsph.cli import bed_report
    assert bed_report.MIN_WINDOW == 1.0
    verdict = bed_report.Verdict(math.nan, 0.01)
    assert not verdict.judged and verdict.ok and verdict.failures() == []
    assert bed_report.Verdict(-0.02, 0.01).failures() and bed_report.Verdict(-0.005, 0.01).ok


def test_check_of_a_bed_at_minimum_fluidisation(tmp_path):
    """`parsph check` of a bed in the solved gas past Wallis's bound judges its time-averaged pressure drop over
    at least 1 s. A small bed of run/single_bubble.toml without its jet, at U = U_mf (Ergun at theta0): at
    rest, inside, the gas carries the buoyant weight, so the grid's dp'/dx is -theta0 (rho_s - rho_g) |g|
    (within 0.5%), while the grains of the free top (theta below theta0) lean on those below and the drop
    across the whole bed is a few % under the weight (2.3% here, 1 cm tall); over 0.02 s check reports that
    and judges nothing. Over 1 s (the bed unstable, it stirs after 0.25 s) the average is judged: check exits
    0 within --tol, 1 beyond it with one line naming the drop. checks.settle at t_end is refused."""
    from conftest import ROOT, run_cli
    from parsph.output import output_files, read_grid
    from parsph.physics import bed_expansion
    from parsph.setup import config
    from parsph.setup.scenes import layer
    runfile = tmp_path / "bed.toml"
    runfile.write_text((ROOT / "run" / "single_bubble.toml").read_text().replace(
        "jet = [0.035, 0.045, 1.0, 0.05] # y0, y1 [m], U_jet [m/s], t_off [s]", ""))
    box = ["scene.height=0.01", "domain.L=0.04", "domain.Ly=0.016", "numerics.Nx=80", "checks.settle=0.0"]
    cfg = config.load(runfile, box)
    ph = layer.phases(cfg)
    box += [f"gas.U={bed_expansion.minimum_fluidization_velocity(cfg.theta0, ph)!r}"]
    sets = lambda extra: sum((["--set", s] for s in box + extra), [])

    code, out, err = run_cli("run", runfile, "--out", tmp_path / "rest", "--quiet",
                             *sets(["output.t_end=0.02", "output.times=[0.005, 0.01, 0.015, 0.02]"]), timeout=300)
    assert code == 0, err
    share = re.search(r"the gas solve [\d.]+ s \((\d+)% of the loop\)", out)
    assert share and 0 < int(share.group(1)) <= 100, out   # the loop's steps only: no compiling in it
    grid = read_grid(output_files(tmp_path / "rest")[-1])
    inside = grid["p"][1:4].mean(axis=1)                    # cells 2-8 mm above the floor, the top at 10 mm
    assert np.diff(inside).mean() / grid["attrs"]["cell"][0] == pytest.approx(-cfg.theta0 * ph.buoyant, rel=5e-3)
    code, out, err = run_cli("check", tmp_path / "rest", "--tol", "0.01")
    assert code == 0 and "bed check:" in out and "errors of theta" not in out, out + err
    assert "nothing to judge" in out and "under 1 s" in out
    rows = [line.split() for line in out.splitlines() if line[:10].strip() in ("0.005", "0.01", "0.015", "0.02")]
    assert len(rows) == 4 and all(0.95 < float(r[1]) < 1.0 for r in rows), rows

    code, out, err = run_cli("run", runfile, "--out", tmp_path / "second", "--quiet",
                             *sets(["output.t_end=1.0", "output.times=[0.0, 0.25, 0.5, 0.75, 1.0]"]), timeout=300)
    assert code == 0, err
    code, out, err = run_cli("check", tmp_path / "second", "--tol", "0.2")
    assert code == 0 and "within its tolerance" in out, out + err
    code, out, err = run_cli("check", tmp_path / "second", "--tol", "0.001")
    assert code == 1 and err.count("\n") == 1 and "pressure drop" in err, err
    code, out, err = run_cli("run", runfile, "--out", tmp_path / "late", *sets(["checks.settle=1.0",
                                                                                "output.t_end=1.0"]))
    assert code == 2 and err.count("\n") == 1 and "checks.settle" in err, err


# ---- in 3-D ----------------------------------------------------------------------------------------------
def ball(shape, centre, r, inside=0.0, outside=0.6):
    """theta on a grid of cells 1 (periodic along y and z): ``inside`` within r of ``centre``."""
    axes = np.meshgrid(*[np.arange(n) + 0.5 for n in shape], indexing="ij")
    d2 = (axes[0] - centre[0]) ** 2
    for a, n, c in zip(axes[1:], shape[1:], centre[1:]):
        d2 = d2 + ((a - c + n / 2) % n - n / 2) ** 2
    return np.where(d2 < r * r, inside, outside)


def test_a_ball_is_one_bubble_of_its_volume_and_centre_across_the_periodic_z():
    shape, h = (30, 24, 20), 0.002
    here = bubbles.find(ball(shape, (12.0, 10.0, 10.0), 6.0), h, h, 0.2, hz=h)
    assert len(here) == 1
    b = here[0]
    assert b.dim == 3 and b.area == pytest.approx(np.count_nonzero(ball(shape, (12.0, 10.0, 10.0), 6.0) < 0.2) * h ** 3,
                                                  rel=1e-12)
    assert b.diameter == pytest.approx(2 * 6.0 * h, rel=0.03)        # the voxelated sphere
    assert (b.x, b.y, b.z) == pytest.approx((12.0 * h, 10.0 * h, 10.0 * h), rel=1e-12)
    across = bubbles.find(ball(shape, (12.0, 10.0, 1.0), 6.0), h, h, 0.2, hz=h)
    assert len(across) == 1 and across[0].area == b.area
    assert (across[0].x, across[0].y, across[0].z) == pytest.approx((12.0 * h, 10.0 * h, 1.0 * h), abs=1e-12)
    walled_z = bubbles.find(ball(shape, (12.0, 10.0, 1.0), 6.0), h, h, 0.2, periodic=(False, True, False), hz=h)
    assert len(walled_z) == 2


def test_in_3d_a_bubble_needs_two_cells_along_every_axis():
    theta = np.full((12, 12, 12), 0.6)
    theta[3:5, 3:5, 3] = 0.0        # 4 cells, one layer: below 2 x 2 x 2
    theta[7:9, 7:9, 7:9] = 0.0      # 8 cells
    assert [b.area for b in bubbles.find(theta, 1.0, 1.0, 0.2, hz=1.0)] == [8.0]


def test_a_rising_ball_is_matched_with_its_velocity():
    shape, h, dt = (40, 20, 20), 0.001, 0.01
    before = bubbles.find(ball(shape, (14.0, 10.0, 10.0), 5.0), h, h, 0.2, hz=h)
    after = bubbles.find(ball(shape, (17.0, 10.0, 10.0), 5.0), h, h, 0.2, hz=h)
    (pair,) = bubbles.match(before, after, dt, shape)
    assert pair.velocity == pytest.approx(3 * h / dt, rel=1e-12)


def test_gas_through_a_spherical_void_is_three_pi_U_r_squared():
    """Reference 8 in 3-D: the sphere's closed form (Maxwell's: the flux inside a sphere of permeability ratio
    kappa is 3 kappa / (kappa + 2) U) at kappa -> infinity through its cross-section pi r^2; then a 3-D grid
    solve past a void of radius 5 cells in a bed fed at U (periodic across y and z, 40 x 28 x 28 cells): the
    gas through the bubble's equator within 6% of it (the voxelated sphere at 5 cells)."""
    U, a, kappa = 0.2, 0.01, 1e12
    assert bubbling.throughflow(U, a, 3) == pytest.approx(math.pi * a * a * 3 * kappa / (kappa + 2) * U, rel=1e-9)
    shape, h, r = (40, 28, 28), 0.002, 5.0
    theta = ball(shape, (20.0, 14.0, 14.0), r)
    K = np.where(theta < 0.2, 1e3, 1.0)
    sol = darcy.solve(K, np.zeros(shape + (3,)), h, h,
                      (darcy.Side("flux", U), darcy.Side("pressure", 0.0)), None, hz=h)
    (b,) = bubbles.find(theta, h, h, 0.2, periodic=(False, True, True), hz=h)
    q = bubbles.throughflow(b, sol.centred()[..., 0], h, 0.0, h)
    assert q == pytest.approx(bubbling.throughflow(U, 0.5 * b.diameter, 3), rel=0.06)


def test_rise_velocity_in_3d():
    assert bubbling.rise_velocity(0.04, -9.81, 3) == pytest.approx(0.711 * math.sqrt(9.81 * 0.04), rel=1e-15)
