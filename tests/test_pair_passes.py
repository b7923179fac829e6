"""The density and momentum passes against the scalar loops they replaced, on real pair lists, bit for bit.

:mod:`parsph.sph.reference_passes` keeps the loops as they were before the density pass was split into
blocks (distances, a vector loop for the kernel, sums in pair order) and the loops were given unsigned
indices: the same floating-point operations in the same order, so every sum must come out the same to the
last bit. Checked on the solver's own neighbour list after some steps (particles off the lattice) for the
scenes' combinations of terms: 2-D and 3-D, walls on and off, body force, the paper's and the consistent
pressure, both viscosity forms, both kernels, equal masses (the serial passes load none) and unequal ones;
the serial and the threaded passes. One case is also checked against a brute-force sum of Eq. (3) over every
pair of local particles (an independent reference).
"""
import numba
import numpy as np
import pytest
from mpi4py import MPI
from numba import njit

from parsph.physics.kernels import get_kernel
from parsph.setup import config
from parsph.simulation.solver import Simulation
from parsph.sph import density, momentum, pass_data, reference_passes

from conftest import ROOT

CASES = {
    "couette_paper": ("couette_paper", ["domain.Ly=0.001"]),
    "consistent_symmetric_wendland": ("couette_paper", ["domain.Ly=0.001", 'numerics.pressure_form="consistent"',
                                                        'numerics.viscosity_form="symmetric"',
                                                        'numerics.kernel="wendland_c2"']),
    "couette_3d": ("couette_3d", []),
    "periodic_box": ("periodic_box", ["domain.Ly=0.001"]),
    "settling": ("settling", []),
    "unequal_masses": ("couette_paper", ["domain.Ly=0.001"], 0.1),
}


def stepped(name, over, mass_spread=0.0, steps=20):
    """The scene after ``steps`` steps; with ``mass_spread``, its particles' masses scattered by up to that
    fraction (so the passes load each particle's mass)."""
    cfg = config.load(ROOT / "run" / f"{name}.toml", [*over, "output.times=[]"])
    state = None
    if mass_spread:
        gid, kind, mass, pos, vel = cfg.scene.particles(cfg, 0.0, cfg.Ly)
        mass = mass * (1.0 + mass_spread * np.random.default_rng(5).uniform(-1.0, 1.0, mass.size))
        state = {"id": gid, "kind": kind, "mass": mass, "position": pos, "velocity": vel,
                 "attrs": {"step": 0, "time": 0.0, "dt": cfg.dt}}
    sim = Simulation(cfg, MPI.COMM_SELF, state=state)
    assert sim.rates.switches.uniform_mass == pass_data.switch(not mass_spread)
    for _ in range(steps):
        sim.compute_rates()
        sim.integrate(sim.dt)
    sim.compute_rates()
    R = sim.rates
    return sim, (R.list, pass_data.particle_arrays(sim.ps), R.consts, R.switches)


def results(args, need_only=False):
    """rho_sum (all local particles, or those that need sums), fp as bits, acc of the owned particles."""
    lst, parts = args[0], args[1]
    rho = lst.rho_sum[:lst.n]
    return {"rho_sum": rho[lst.need[:lst.n]].copy() if need_only else rho.copy(),
            "fp": lst.fp[:lst.npairs].view(np.int64).copy(), "acc": parts.acc[:parts.n_own].copy()}


def pairs_of_full_list(lst, fp):
    """The pairs of nonzero (dW/dr)/r in a full list's (dW/dr)/r: per place their count, j and the bits of f."""
    n, npairs = lst.n, lst.npairs
    keep = fp[:npairs] != 0
    kept_before = np.concatenate([[0], np.cumsum(keep)])
    counts = kept_before[lst.pstart[1:n + 1]] - kept_before[lst.pstart[:n]]
    return {"counts": counts, "j": lst.pj[:npairs][keep].astype(np.int64), "f": fp[:npairs][keep].view(np.int64)}


def pairs_of_compact_list(lst):
    """The same of the compact list the serial density pass writes (pairs of f = 0 left out)."""
    n, cstart = lst.n, lst.cstart
    keep = lst.cf[:cstart[n]] != 0
    place = np.repeat(np.arange(n), np.diff(cstart[:n + 1]))
    return {"counts": np.bincount(place[keep], minlength=n), "j": lst.cj[:cstart[n]][keep].astype(np.int64),
            "f": lst.cf[:cstart[n]][keep].view(np.int64)}


def serial_results(args):
    """rho_sum, the compact list's pairs and acc after the serial passes (which leave the full fp unwritten)."""
    lst, parts = args[0], args[1]
    return {"rho_sum": lst.rho_sum[:lst.n].copy(), "pairs": pairs_of_compact_list(lst),
            "acc": parts.acc[:parts.n_own].copy()}


def assert_same(ref, new, what):
    for key in ref:
        if isinstance(ref[key], dict):
            assert_same(ref[key], new[key], f"{what}: {key}")
        else:
            assert np.array_equal(ref[key], new[key]), f"{what}: {key} differs from the reference loops"


@pytest.fixture(scope="module", params=sorted(CASES))
def case(request):
    sim, args = stepped(*CASES[request.param])
    reference_passes.density_serial(*args)
    reference_passes.momentum_serial(*args)
    ref = results(args)
    serial = {"rho_sum": ref["rho_sum"], "pairs": pairs_of_full_list(args[0], args[0].fp), "acc": ref["acc"]}
    return request.param, sim, args, serial, results(args, need_only=True)


def test_serial_passes_equal_the_scalar_loops(case):
    name, sim, args, ref, _ = case
    lst = args[0]
    assert lst.npairs > 2 * density.CHUNK or name == "couette_3d", "the list should span several chunks"
    assert np.abs(ref["acc"]).max() > 0 and len(ref["pairs"]["j"]) < lst.npairs  # pairs in the skin too
    density.density_serial(*args)
    momentum.momentum_serial(*args)
    assert_same(ref, serial_results(args), name)


@pytest.mark.parametrize("chunk", [1, 5, 64])
def test_any_chunk_gives_the_same_sums(case, chunk):
    """Chunks shorter than a particle's pairs: each takes one place's row whole, and a place's sum, its
    part of the compact list and the momentum pass on it come out the same."""
    name, sim, args, ref, _ = case
    density.density_chunks(*args, chunk)
    momentum.momentum_serial(*args)
    assert_same(ref, serial_results(args), f"{name}, chunk {chunk}")


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba allows one thread here")
def test_threaded_passes_equal_the_scalar_loops(case):
    name, sim, args, _, ref = case
    gather = sim.rates.gather_arrays()
    for threads in (1, 2):
        numba.set_num_threads(threads)
        try:
            density.density_threaded(*args, gather)
            momentum.momentum_threaded(*args, gather)
        finally:
            numba.set_num_threads(1)
        assert_same(ref, results(args, need_only=True), f"{name}, {threads} threads")


def test_density_against_brute_force():
    """Eq. (3) by numpy over every pair of local particles (no list, no cells), to round-off."""
    sim, args = stepped("couette_paper", ["domain.Ly=0.001"])
    lst, parts, c = args[0], args[1], args[2]
    density.density_serial(*args)
    n = lst.n
    pos, mass = parts.pos[:n], parts.mass[:n]
    kernel = get_kernel(sim.cfg.kernel, sim.cfg.dim)
    r = np.sqrt(((pos[:, None, :] - pos[None, :, :]) ** 2).sum(axis=2))
    w = np.vectorize(lambda x: kernel.w(x, c.inv_h, c.norm))(r)
    need = lst.need[:n]
    brute = (w * mass[None, :]).sum(axis=1)[need]
    assert need.sum() > 100
    np.testing.assert_allclose(lst.rho_sum[:n][need], brute, rtol=1e-12)


def test_compact_list_holds_the_pairs_within_2h(case):
    """The compact list the density pass writes for the momentum pass: each place's listed pairs closer than
    2h (distances by numpy from the positions), in pair order, with the kernel's (dW/dr)/r of their distance;
    none is missing and none beyond 2h is kept (pairs within 1e-9 h of 2h may go either way)."""
    _, sim, args, _, _ = case
    lst, parts, c = args[0], args[1], args[2]
    density.density_serial(*args)
    kernel = get_kernel(sim.cfg.kernel, sim.cfg.dim)
    support = kernel.support / c.inv_h
    n, npairs = lst.n, lst.npairs
    pi, pj = lst.pi[:npairs].astype(np.int64), lst.pj[:npairs].astype(np.int64)
    pos = parts.pos
    r = np.sqrt(((pos[pi] - pos[pj]) ** 2).sum(axis=1))
    cstart = lst.cstart[:n + 1]
    assert cstart[0] == 0 and np.all(np.diff(cstart) >= 0)
    for a in [*range(min(n, 64)), *range(64, n, 97)]:  # the first places and a sample of the rest
        rows = np.arange(lst.pstart[a], lst.pstart[a + 1])
        lo, hi = cstart[a], cstart[a + 1]
        within, edge = r[rows] < support, np.abs(r[rows] - support) < 1e-9 * support
        kept = set(lst.cj[lo:hi].tolist())
        assert set(pj[rows][within & ~edge].tolist()) <= kept
        assert kept <= set(pj[rows][within | edge].tolist())
        order = [int(np.flatnonzero(pj[rows] == j)[0]) for j in lst.cj[lo:hi]]
        assert order == sorted(order), f"place {a}: the compact pairs are not in pair order"
        want = np.array([kernel.dwdr(x, c.inv_h, c.norm) / x for x in r[rows][order]])
        np.testing.assert_allclose(lst.cf[lo:hi], want, rtol=1e-10)
    total = cstart[n]
    # every pair within 2h, once (those within 1e-9 h of 2h either way)
    assert np.count_nonzero(r < (1 - 1e-9) * support) <= total <= np.count_nonzero(r < (1 + 1e-9) * support)
    assert 0.5 * npairs < total < npairs  # the skin holds some of the listed pairs


@njit(cache=True)
def _both_passes(lst, parts, c, sw):
    density.density_serial(lst, parts, c, sw)
    momentum.momentum_serial(lst, parts, c, sw)


def test_passes_run_inside_another_compiled_function(case):
    """The integrator's compiled step loop calls the passes from numba: the same numbers."""
    name, sim, args, ref, _ = case
    _both_passes(*args)
    assert_same(ref, serial_results(args), name)
