"""The reused neighbour list never misses a pair within 2h, and its grid stays bounded.

At every step of a few hundred, the pairs of the list whose members are now
within 2h are compared with a fresh brute-force search over all particles
(minimum image across the periodic directions, written here in numpy): not
one pair of an owned fluid particle may be missing. Scenes: the paper's
Couette flow from its impulsive start (the sheared layer at the moving
plate, which carries its neighbours along at V_w), the settling column (a
dense state that becomes disordered), and a periodic box of fast random
velocities with a small skin (rebuilds every few steps, x periodic too).
A particle in a dense cluster with ~100 neighbours gets them all (the list
has no fixed width per particle), and a runaway particle does not make the
cell grid grow.
"""
import tomllib

import numpy as np
import pytest
from mpi4py import MPI

from parsph.setup import config
from parsph.setup.runfile import RunFile
from parsph.sph.particles import FLUID
from parsph.simulation.solver import Simulation

from conftest import ROOT


def brute_pairs(sim):
    """{(gid_i, gid_j)}: owned fluid i, any j != i within 2h of it (minimum image), by brute force."""
    ps, cfg = sim.ps, sim.cfg
    n = ps.n_own
    pos = ps.pos[:n]
    gid = ps.gid[:n]
    fluid = ps.kind[:n] == FLUID
    d = pos[:, None, :] - pos[None, :, :]
    periods = [0.0 if cfg.scene.walls else cfg.L, cfg.Ly, cfg.Lz if cfg.dim == 3 else 0.0]
    for axis in range(cfg.dim):
        if periods[axis] > 0:
            d[..., axis] -= periods[axis] * np.rint(d[..., axis] / periods[axis])
    r2 = (d * d).sum(axis=-1)
    close = (r2 < (2 * cfg.h) ** 2) & fluid[:, None]
    np.fill_diagonal(close, False)
    i, j = np.nonzero(close)
    return set(zip(gid[i].tolist(), gid[j].tolist()))


def listed_pairs(sim):
    """{(gid_i, gid_j)}: the list's pairs now within 2h, from the side of each owned fluid member."""
    ps, R = sim.ps, sim.rates
    pi, pj = R.pi[:R.npairs], R.pj[:R.npairs]
    d = ps.pos[pi] - ps.pos[pj]
    near = (d * d).sum(axis=1) < (2 * sim.cfg.h) ** 2
    pi, pj = pi[near], pj[near]
    out = set()
    for a, b in ((pi, pj), (pj, pi)):
        mine = (a < ps.n_own) & (ps.kind[a] == FLUID)
        out |= set(zip(ps.gid[a[mine]].tolist(), ps.gid[b[mine]].tolist()))
    return out


def run_and_compare(cfg, steps):
    sim = Simulation(cfg, MPI.COMM_SELF)
    checked = 0
    for _ in range(steps):
        sim.compute_rates()
        want, have = brute_pairs(sim), listed_pairs(sim)
        missing = want - have
        assert not missing, f"step {sim.step}: {len(missing)} pairs within 2h missing, e.g. {sorted(missing)[:3]}"
        assert have <= want  # the list's pairs within 2h are real pairs (no duplicates of an image)
        checked += len(want)
        sim.advance(sim.dt)
    return sim, checked


def test_sheared_couette_from_the_impulsive_start():
    """The paper case (short box, N_x = 20) for 300 steps of 1e-5 s: the plate moves 3 mm, 4.8 cells."""
    raw = tomllib.loads((ROOT / "run" / "couette_paper.toml").read_text())
    del raw["numerics"]["h"]
    cfg = config.build(RunFile(raw).override(["numerics.Nx=20", "numerics.h_over_dx=1.25", "domain.Ly=0.004",
                                              "output.times=[]"]))
    sim, checked = run_and_compare(cfg, 300)
    assert checked > 100_000
    assert 2 <= sim.rebuilds < 300  # the list was reused, and rebuilt
    moved = np.abs(sim.ps.pos[:sim.ps.n_own, 1] - sim.ps.ref[:sim.ps.n_own, 1]).max()
    assert sim.t * cfg.V_w > 10 * sim.skin and moved > 0


def test_settling_column_disordered_dense_state():
    """The settling column (theta_0 = 0.55, gravity, consistent pressure) for 300 steps of dt auto."""
    cfg = config.load(ROOT / "run" / "settling.toml", ["output.times=[]", "numerics.Nx=30"])
    sim, checked = run_and_compare(cfg, 300)
    assert checked > 10_000 and sim.rebuilds >= 1


def test_fast_random_motion_small_skin():
    """A periodic box (x periodic: images), random velocities of 0.3 m/s, skin 0.1 h: many rebuilds."""
    cfg = config.load(ROOT / "run" / "periodic_box.toml",
                      ["output.times=[]", "numerics.Nx=16", "domain.L=0.0032", "domain.Ly=0.0032",
                       "numerics.skin=0.1", "numerics.dt=2e-6", "checks.energy=false"])
    sim = Simulation(cfg, MPI.COMM_SELF)
    rng = np.random.default_rng(1)
    n = sim.ps.n_own
    sim.ps.vel[:n] = rng.normal(0.0, 0.3, (n, 2))
    checked = 0
    for _ in range(200):
        sim.compute_rates()
        missing = brute_pairs(sim) - listed_pairs(sim)
        assert not missing, f"step {sim.step}: {len(missing)} pairs missing"
        checked += 1
        sim.advance(sim.dt)
    assert sim.rebuilds >= 5


def test_dense_cluster_gets_every_neighbour():
    """Particles squeezed to 0.25 dx around one point: ~100 neighbours within 2h, all of them listed."""
    cfg = config.load(ROOT / "run" / "periodic_box.toml",
                      ["output.times=[]", "numerics.Nx=16", "domain.L=0.0032", "domain.Ly=0.0032",
                       "checks.energy=false"])
    sim = Simulation(cfg, MPI.COMM_SELF)
    ps, n = sim.ps, sim.ps.n_own
    centre = np.array([0.0016, 0.0016])
    near = np.linalg.norm(ps.pos[:n] - centre, axis=1) < 0.0012
    ps.pos[:n][near] = centre + 0.25 * (ps.pos[:n][near] - centre)
    sim.compute_rates()
    want, have = brute_pairs(sim), listed_pairs(sim)
    counts = np.bincount([a for a, _ in want])
    assert counts.max() >= 100
    assert want == have


def test_runaway_particle_does_not_grow_the_grid():
    """A fluid particle 100 m beyond the plate is clamped into the edge cells: the grid keeps its size."""
    cfg = config.load(ROOT / "run" / "couette_paper.toml", ["domain.Ly=0.004", "output.times=[]"])
    sim = Simulation(cfg, MPI.COMM_SELF)
    sim.compute_rates()
    cells = int(np.prod(sim.rates.size))
    ps = sim.ps
    k = int(np.flatnonzero(ps.kind[:ps.n_own] == FLUID)[0])
    ps.pos[k, 0] = 100.0
    sim.force_rebuild = True
    sim.compute_rates()
    assert int(np.prod(sim.rates.size)) == cells
    assert len(sim.rates.box) <= cells
