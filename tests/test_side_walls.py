"""Side walls (``walls.sides``): walls at y = 0 and y = L_y instead of the periodic strip, their rows beyond
L_y standing for both across the period (docs/physics.md, "Walls under a free surface"). The gas's part
(the deposit folding at them, the closed faces) is in test_solved_gas.py and below; the same bits on 1, 2
and 3 ranks in test_mpi_scenes.py (``fluidized_bed_sides``)."""
import math

import numpy as np
import pytest
from mpi4py import MPI

from parsph.errors import ConfigError
from parsph.setup import config
from parsph.simulation.solver import Simulation
from parsph.sph import projected
from parsph.sph.particles import GRAIN
from parsph.studies import layers

RUN = layers.RUN
LY = 1.2e-3  # 6 rows of grains between the walls (dx = 0.2 mm)


@pytest.mark.parametrize("name", ["couette_paper.toml", "periodic_box.toml", "settling.toml"])
def test_side_walls_are_refused_where_the_scene_is_periodic_along_y(name):
    with pytest.raises(ConfigError) as e:
        config.load(RUN / name, ["walls.sides=true"])
    assert e.value.key == "walls.sides" and "periodic along y" in e.value.reason


def _state(sim):
    ps, n = sim.ps, sim.ps.n_own
    f = ps.kind[:n] == GRAIN
    v = ps.vel[:n][f]
    return {"x": ps.pos[:n, 0][f].copy(), "y": np.mod(ps.pos[:n, 1][f], sim.cfg.Ly_ring), "m": ps.mass[:n][f].copy(),
            "theta": ps.theta[:n][f].copy(), "speed": np.sqrt((v * v).sum(axis=1)), "reflected": sim.reflections()}


def test_a_loose_layer_dropped_between_side_walls_comes_to_rest_inside_them():
    """theta0 = 0.2 (a dust that falls freely) on the floor without gas, between side walls 6 grains apart:
    every grain stays between them and above the floor by the walls' pressure alone (walls.reflect, the
    backstop, never acts), and the layer comes to rest at the hydrostatic sediment, which side walls at rest
    do not change: its top (the theta0/2 level) within 2h of the end state's, the rms speed below 2% of the
    impact speed sqrt(2 g H0); the particles' theta in the interior within 2% of the end state's, those in
    the rows along the side walls (their kernels cut by the wall, renormalised) as well as the middle ones."""
    sets = [*layers.sedimentation_sets(0.2, 0.005, LY, ['numerics.integrator="midpoint"', "domain.L=0.008",
                                                         "numerics.Nx=40", "material.k=1.0"]),
            'gas.drag="none"', "walls.sides=true"]
    cfg0 = layers.load(layers.SEDIMENTATION, sets, layers.NO_GAS)
    assert cfg0.sides and cfg0.Ly_ring == pytest.approx(LY + cfg0.layers * cfg0.dy)
    from parsph.setup.scenes import layer
    end = layer.end_state(cfg0)
    r = layers.run(layers.SEDIMENTATION, sets, [0.2, 0.45, 0.6], measure=_state, drop=layers.NO_GAS)
    cfg, h = r.cfg, r.cfg.h
    for f in r.frames:
        assert f["y"].min() >= 0.0 and f["y"].max() <= LY, (f["t"], f["y"].min(), f["y"].max())
        assert f["x"].min() >= 0.0
    last = r.frames[-1]
    assert last["reflected"] == 0
    top = projected.interface_height(cfg, last["x"], last["m"])
    assert abs(top - end.height_of(0.5 * cfg.theta0)) < 2 * h, (top, end.height_of(0.5 * cfg.theta0))
    impact = math.sqrt(2 * 9.81 * layer.layer_height(cfg))
    rms = math.sqrt(np.sum(last["m"] * last["speed"] ** 2) / np.sum(last["m"]))
    assert rms < 0.02 * impact, (rms, impact)
    along = (last["y"] < cfg.dy) | (last["y"] > LY - cfg.dy)
    assert along.sum() > 0 and (~along).sum() > 0
    for sel in (along, ~along):
        err = layers.profile_error(cfg, end, last["x"][sel], last["theta"][sel], span=layers.interior(cfg, end))
        assert err < 0.02, (err, "along the side walls" if sel is along else "between them")


def test_the_closed_side_walls_are_the_mirror_image_of_a_periodic_box_twice_as_wide():
    """The solved gas between side walls, fed through the floor with a jet against the wall at y = 0: its
    pressure equals, to the solve's round-off, that of a periodic box twice as wide holding the bed and its
    mirror image across y = L_y (K, V and the floor's feed mirrored, V_y reversed): a wall that no gas
    crosses is a plane of symmetry (the method of images), solved here without any wall."""
    from parsph.gas import darcy
    cfg = config.load(RUN / "bubbling_bed.toml", ["walls.sides=true", "domain.Ly=0.006", "domain.L=0.03", "numerics.Nx=60",
                                                  "scene.height=0.01", "perturbation.wavelength_y=0.006",
                                                  "gas.jet=[0.0, 0.002, 1.0]", "checks.settle=0.0",
                                                  "output.t_end=0.002", "output.times=[]"])
    sim = Simulation(cfg, MPI.COMM_SELF)
    sim.run()
    g, sol = sim.gas.grid, sim.gas.solution
    assert g.sides and sim.step >= 2
    assert np.all(sol.jy[:, 0] == 0.0) and np.all(sol.jy[:, -1] == 0.0)
    K2 = np.concatenate([sol.K, sol.K[:, ::-1]], axis=1)
    V2 = np.concatenate([sol.V, sol.V[:, ::-1] * np.array([1.0, -1.0])], axis=1)
    y = (np.arange(g.ny) + 0.5) * g.hy
    feed = np.where(y < 0.002, 1.0, cfg.gas.U)
    U2 = np.concatenate([feed, feed[::-1]])
    wide = darcy.solve(K2, V2, g.hx, g.hy, (darcy.Side("flux", U2), darcy.Side("pressure", np.zeros(2 * g.ny))),
                       None)
    scale = np.abs(sol.p).max()
    np.testing.assert_allclose(wide.p[:, :g.ny], sol.p, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(wide.p[:, g.ny:], sol.p[:, ::-1], rtol=0, atol=1e-9 * scale)
