"""The slab decomposition as pure functions, and its refusal of slabs too thin for their ghost rows.

Serial: run with plain pytest. The one test that needs several ranks launches
``mpirun`` itself and is skipped inside an mpirun job (nested mpirun fails).
"""
import math
import types

import numpy as np
import pytest
from mpi4py import MPI

from parsph.errors import DecompositionError
from parsph.parallel.slab_ring import SlabRing
from parsph.parallel.slabs import fits, max_ranks, slab_bounds
from parsph.sph.cells import CELLS_PER_CUTOFF, Grid

from mpi_helpers import launch  # noqa: E402

H = 2.5e-4          # the paper's smoothing length [m]


def fake_comm(size, rank=0):
    """Enough of a communicator for SlabRing's constructor (it only reads rank and size)."""
    return types.SimpleNamespace(rank=rank, size=size)


# ---- slab_bounds -----------------------------------------------------------------
@pytest.mark.parametrize("Ly", [0.01, 0.0016, 1.0, 0.1, 3.0e-3, 7.3e-4, 1e-7])
@pytest.mark.parametrize("P", [1, 2, 3, 4, 5, 6, 7, 8, 13, 50])
def test_slab_bounds_edges(Ly, P):
    b = slab_bounds(Ly, P)
    assert b.shape == (P + 1,)
    assert b.dtype == np.float64
    assert b[0] == 0.0
    assert b[-1] == Ly                                  # exactly, not r*Ly/P rounded
    for r in range(P):                                  # every inner edge is r*Ly/P exactly
        assert b[r] == r * Ly / P
    w = np.diff(b)
    assert np.all(w > 0)                                # strictly increasing
    # equal up to the rounding of the edges themselves (a couple of ulp of Ly)
    np.testing.assert_allclose(w, Ly / P, rtol=0, atol=2 * np.spacing(Ly))


@pytest.mark.parametrize("P", [1, 2, 3, 7])
def test_slab_bounds_partition_every_y(P):
    """Every y in [0, Ly) has exactly one owner, including y next to each edge and next to Ly."""
    Ly = 0.0016
    b = slab_bounds(Ly, P)
    ys = np.concatenate([np.linspace(0, Ly, 1001, endpoint=False), b[:-1],
                         np.nextafter(b[1:], 0.0), [np.nextafter(Ly, 0.0), 0.0]])
    owner = np.searchsorted(b, ys, side="right") - 1
    assert owner.min() >= 0 and owner.max() <= P - 1
    for y, r in zip(ys, owner):
        assert b[r] <= y < b[r + 1]
    assert owner[-2] == P - 1                           # the largest y below Ly belongs to the last rank


# ---- slab widths -------------------------------------------------------------------
CUT = 2.4 * H       # neighbour-list cutoff 2h + skin (skin 0.4 h, the default)
M = CELLS_PER_CUTOFF


def grid(Ly, cutoff=CUT):
    """A Couette grid (walls in x) of the given Ly and cutoff."""
    return Grid(cutoff, 2, True, 0.01, Ly, 0.0, -2.5e-4, 0.01 + 2.5e-4)


@pytest.mark.parametrize("Ly", [0.0016, 0.0021, 0.005, 0.01, 0.0137, 1.0])
def test_slab_width_rule_between_its_bounds(Ly):
    """Slabs fit their ghost rows (M rows of side >= cutoff/M beyond their own) when at least (M + 2) rows
    wide, never when thinner than M rows: the rule lies between these two bounds for every P."""
    g = grid(Ly)
    side, ny = g.axes[1].side, g.axes[1].n
    assert side >= CUT / M * (1 - 1e-12) and abs(side * ny - Ly) < 1e-12 * Ly   # rows tile Ly, side >= cutoff/M
    for P in range(1, ny + 1):
        width = Ly / P
        if width >= (M + 2) * side * (1 + 1e-12):
            assert fits(Ly, P, side, ny, M), P
        if width < M * side * (1 - 1e-12):
            assert not fits(Ly, P, side, ny, M), P


@pytest.mark.parametrize("Ly", [0.0006, 0.0012, 0.0015, 0.0016, 0.0024, 0.01, 0.3])
def test_max_ranks_agrees_with_slabring(Ly):
    """max_ranks is accepted by SlabRing and one more rank is refused, with a message naming what works."""
    P = max_ranks(Ly, CUT, M)
    SlabRing(fake_comm(P), Ly, grid(Ly))
    with pytest.raises(DecompositionError) as e:
        SlabRing(fake_comm(P + 1), Ly, grid(Ly))
    msg = str(e.value)
    assert f"at most {P} ranks" in msg
    least = float(msg.split("Ly >= ")[1].split(" m")[0])
    SlabRing(fake_comm(P + 1), least, grid(least))      # the suggested length works


def test_paper_case_rank_limit():
    """The paper's box (Ly = 0.01 m, h = 2.5e-4 m, skin 0.4 h): slabs of at least 1.5 cutoffs, so at most
    0.01 / (1.5 * 6e-4) = 11 ranks (the ghost rows are M = 2 rows of 6e-4 m / 2 beyond a slab's own).
    The same count for a run (case.max_ranks, what validate_scenes prints) at the paper's L_y and shorter."""
    from parsph.setup import config
    from parsph.simulation.case import max_ranks as run_max_ranks
    from conftest import PAPER_TOML
    assert max_ranks(0.01, CUT, M) == 11
    for ly, most in ((0.01, 11), (0.005, 5), (0.002, 2), (0.001, 1)):
        assert run_max_ranks(config.load(str(PAPER_TOML), [f"domain.Ly={ly}"])) == most == math.floor(ly / 9e-4)


# ---- SlabRing ----------------------------------------------------------------------
def test_slabring_one_rank_comm_self():
    ring = SlabRing(MPI.COMM_SELF, 0.01, grid(0.01))
    assert ring.size == 1 and ring.rank == 0
    assert ring.left == 0 and ring.right == 0            # its own neighbour across y = Ly
    assert ring.lo == 0.0 and ring.hi == 0.01


@pytest.mark.parametrize("P", [2, 3, 5])
def test_slabring_ring_neighbours(P):
    Ly = P * 0.002
    b = slab_bounds(Ly, P)
    for r in range(P):
        ring = SlabRing(fake_comm(P, r), Ly, grid(Ly))
        assert ring.left == (r - 1) % P and ring.right == (r + 1) % P
        assert ring.lo == b[r] and ring.hi == b[r + 1]


def test_slabring_refuses_one_thin_slab_comm_self():
    with pytest.raises(DecompositionError) as e:
        SlabRing(MPI.COMM_SELF, 0.0004, grid(0.0004))
    assert "0.0004" in str(e.value) and "Ly >= " in str(e.value)


# ---- refusal through the command line, under mpirun ---------------------------------
@pytest.mark.skipif(launch.under_mpirun(), reason="launches mpirun itself (nested mpirun fails)")
def test_cli_refuses_thin_slabs_under_mpirun(tmp_path):
    """3 ranks on Ly = 0.0006 m (slabs of 2e-4 m, thinner than their ghost rows): exit 2, one message naming a fix."""
    r = launch.run(launch.mpirun_cmd(3, *launch.parsph_cmd(
        "run", launch.PAPER, "--set", "domain.Ly=0.0006", "--out", tmp_path / "out", "--force")), timeout=90)
    assert r.returncode == 2, r
    assert launch.count_lines(r.stderr, "parsph: error") == 1, r
    line = next(ln for ln in r.stderr.splitlines() if "parsph: error" in ln)
    assert "at most 1 ranks" in line and "Ly >= 0.0024 m" in line, r
    assert "Traceback" not in r.output, r
    # nothing written: no output file, complete or partial
    out = tmp_path / "out"
    assert not out.exists() or not list(out.glob("couette_paper*")), list(out.iterdir())
