"""The solved gas's runs against their references (docs/validation.md, "The solved gas"): reference 5, the
column reduction (run/sedimentation.toml and run/fluidized_bed.toml solved on the grid against their column
closure runs: the heights below which 5%..95% of the mass lies within 0.2% of H0 at every output; fine grains
at dt/tau >= 1e3); reference 7, voidage waves (run/voidage_waves.toml on both sides of Wallis's bound, column
and solved gas: growth rate and wave speed within 5%); a box periodic along gravity fed at U settling to
U - u_t eps0^4.65. A file of its own: its runs take a pytest worker for about two minutes."""
import numpy as np
import pytest
from mpi4py import MPI

from parsph.physics import drag
from parsph.setup.scenes import layer
from parsph.simulation.solver import Simulation
from parsph.sph.particles import GRAIN
from parsph.sph.profiles import mass_quantiles
from parsph.studies import layers


# ---- reference 5: the column reduction -------------------------------------------------------------------
def quantile_runs(path, times, extra=()):
    def measure(sim):
        ps = sim.ps
        f = ps.kind[:ps.n_own] == GRAIN
        return {"q": mass_quantiles(ps.pos[:ps.n_own, 0][f], ps.mass[:ps.n_own][f]),
                "finite": bool(np.isfinite(ps.vel[:ps.n_own]).all())}
    out = {}
    for flow in ("column", "solved"):
        out[flow] = layers.run(path, [f'gas.flow="{flow}"', *extra], times=times, measure=measure)
    return out


@pytest.mark.parametrize("path, times", [(layers.SEDIMENTATION, [0.1, 0.3, 0.6]),
                                         (layers.BED, [0.25, 0.5, 1.0])])
def test_column_reduction(path, times):
    runs = quantile_runs(path, times)
    H0 = layer.layer_height(runs["column"].cfg)
    assert len(runs["solved"].frames) == len(times)
    for a, b in zip(runs["column"].frames, runs["solved"].frames):
        assert a["t"] == b["t"]
        assert np.abs(a["q"] - b["q"]).max() < 2e-3 * H0, (a, b)
    moved = np.abs(runs["column"].frames[-1]["q"] - runs["column"].frames[0]["q"]).max()
    assert moved > 0.05 * H0  # the layer moved: the comparison is not of two resting states


def test_column_reduction_at_large_dt_over_tau():
    """Grains of 5 um in water (the drag's time tau = rho_s theta eps^2 / beta about 1e-6 s), the implicit drag
    at the step of the other limits: dt / tau >= 1e3, finite, and the quantiles of the column's run."""
    extra = ["material.d=5e-6", "output.snapshots=false"]
    cfg = layers.load(layers.SEDIMENTATION, [*extra, 'gas.flow="solved"'])
    eps = 1 - cfg.theta0
    tau = cfg.rho_s * cfg.gas.d ** 2 * eps ** 4.65 / (18 * cfg.gas.mu)  # Stokes, along the column
    assert cfg.dt / tau >= 1e3
    runs = quantile_runs(layers.SEDIMENTATION, [0.02, 0.05], extra)
    H0 = layer.layer_height(runs["column"].cfg)
    for a, b in zip(runs["column"].frames, runs["solved"].frames):
        assert b["finite"]
        assert np.abs(a["q"] - b["q"]).max() < 2e-3 * H0


@pytest.mark.parametrize("flow", ["column", "solved"])
@pytest.mark.parametrize("G_b", [-2.5, -1.0])  # past Wallis's bound (grows), inside it (decays)
def test_voidage_waves_grow_and_travel_as_reference_7(flow, G_b):
    """run/voidage_waves.toml: the 1 cm mode's growth rate and wave speed within 5% of the linear theory's."""
    from parsph.studies import voidage
    w = voidage.measure([f'gas.flow="{flow}"', f"material.G_b={G_b}"], n_times=11)
    growth, speed = w.theory
    assert (growth > 0) == (G_b == -2.5)
    assert w.growth == pytest.approx(growth, rel=0.05)
    assert w.speed == pytest.approx(speed, rel=0.05)


@pytest.mark.parametrize("flow", ["column", "solved"])
@pytest.mark.parametrize("U", [0.2, 0.02])
def test_fed_periodic_column_settles_to_U_less_hindered_settling(flow, U):
    """Unperturbed, a box periodic along gravity fed at U: the solids' mean velocity along e tends to
    U - u_t eps0^4.65 (Stokes; up where U exceeds the hindered settling speed, down below it). 0.5%: the
    lattice's theta is theta0 less 5.5e-4 of it, which moves eps0^4.65 by 0.2%."""
    rf = layers.load(layers.RUN / "voidage_waves.toml", [f'gas.flow="{flow}"', f"gas.U={U}", "output.t_end=0.06",
                                                         "output.times=[0.06]", "output.snapshots=false"],
                     drop=["perturbation.amplitude", "perturbation.wavelength"])
    sim = Simulation(rf, MPI.COMM_SELF)
    sim.run()
    ps = sim.ps
    f = ps.kind[:ps.n_own] == GRAIN
    v = ps.vel[:ps.n_own][f, 0].mean()
    u_t = drag.terminal_velocity(rf.rho_s, rf.gas.rho, 9.81, rf.gas.d, rf.gas.mu)
    want = U - u_t * (1 - rf.theta0) ** 4.65
    assert v == pytest.approx(want, rel=5e-3)
