"""The slab decomposition as pure functions, and its refusal of slabs thinner than 2h.

Serial: run with plain pytest. The one test that needs several ranks launches
``mpirun`` itself and is skipped inside an mpirun job (nested mpirun fails).
"""
import math
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from parsph.decomposition import DecompositionError, SlabRing, max_ranks, slab_bounds

sys.path.insert(0, str(Path(__file__).resolve().parent / "mpi_helpers"))
import launch  # noqa: E402

H = 2.5e-4          # the paper's smoothing length [m]
SUPPORT = 2 * H     # cubic spline support = halo width = smallest slab [m]


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


# ---- max_ranks ---------------------------------------------------------------------
@pytest.mark.parametrize("Ly, w, expect", [
    (1.0, 0.25, 4), (1.0, 0.3, 3), (0.01, SUPPORT, 20), (0.0016, SUPPORT, 3), (0.0015, SUPPORT, 3),
    (0.0012, SUPPORT, 2), (0.3, 0.1, 3),   # 0.3/0.1 = 2.9999999999999996 in floats: still 3
    (0.0006, SUPPORT, 1), (1e-9, 1.0, 1),   # never below 1
])
def test_max_ranks(Ly, w, expect):
    assert max_ranks(Ly, w) == expect


@pytest.mark.parametrize("Ly, w", [(Ly, w) for w in (SUPPORT, 0.1, 0.07)
                                   for Ly in (0.0005, 0.0006, 0.0012, 0.0015, 0.0016, 0.01, 0.3, 0.7, 1.0)
                                   if Ly >= w])
def test_max_ranks_agrees_with_slabring(Ly, w):
    """max_ranks(Ly, w) is accepted by SlabRing and one more rank is refused."""
    P = max_ranks(Ly, w)
    SlabRing(fake_comm(P), Ly, w)
    with pytest.raises(DecompositionError):
        SlabRing(fake_comm(P + 1), Ly, w)


# ---- SlabRing ----------------------------------------------------------------------
def test_slabring_one_rank_comm_self():
    ring = SlabRing(MPI.COMM_SELF, 0.01, SUPPORT)
    assert ring.size == 1 and ring.rank == 0
    assert ring.left == 0 and ring.right == 0            # its own neighbour across y = Ly
    assert ring.lo == 0.0 and ring.hi == 0.01


@pytest.mark.parametrize("P", [2, 3, 5])
def test_slabring_ring_neighbours(P):
    Ly = P * 0.001
    b = slab_bounds(Ly, P)
    for r in range(P):
        ring = SlabRing(fake_comm(P, r), Ly, SUPPORT)
        assert ring.left == (r - 1) % P and ring.right == (r + 1) % P
        assert ring.lo == b[r] and ring.hi == b[r + 1]


def test_slabring_accepts_exactly_2h():
    SlabRing(MPI.COMM_SELF, SUPPORT, SUPPORT)
    SlabRing(fake_comm(3), 3 * SUPPORT, SUPPORT)        # 0.0015 / 3 may round below 5e-4
    SlabRing(fake_comm(20), 0.01, SUPPORT)


def test_slabring_refuses_one_thin_slab_comm_self():
    with pytest.raises(DecompositionError) as e:
        SlabRing(MPI.COMM_SELF, 0.0004, SUPPORT)
    msg = str(e.value)
    assert "Ly >= 0.0005 m" in msg                       # the smallest Ly that works
    assert "0.0005" in msg and "0.0004" in msg


@pytest.mark.parametrize("P, Ly, most, least_Ly", [
    (3, 0.0012, 2, "0.0015"), (3, 0.0006, 1, "0.0015"), (21, 0.01, 20, "0.0105"), (4, 0.0016, 3, "0.002"),
])
def test_slabring_refusal_message_names_what_works(P, Ly, most, least_Ly):
    with pytest.raises(DecompositionError) as e:
        SlabRing(fake_comm(P), Ly, SUPPORT)
    msg = str(e.value)
    assert f"at most {most} ranks" in msg                # the largest P that works
    assert f"Ly >= {least_Ly} m" in msg                  # the smallest Ly that works
    # and both suggestions really work
    SlabRing(fake_comm(most), Ly, SUPPORT)
    SlabRing(fake_comm(P), float(least_Ly), SUPPORT)


# ---- refusal through the command line, under mpirun ---------------------------------
@pytest.mark.skipif(launch.under_mpirun(), reason="launches mpirun itself (nested mpirun fails)")
def test_cli_refuses_thin_slabs_under_mpirun(tmp_path):
    """3 ranks on Ly = 0.0006 m (slabs 2e-4 m < 2h = 5e-4 m): exit 2, one message naming a fix."""
    r = launch.run(launch.mpirun_cmd(3, *launch.parsph_cmd(
        "run", launch.PAPER, "--set", "domain.Ly=0.0006", "--out", tmp_path / "out", "--force")), timeout=90)
    assert r.returncode == 2, r
    assert launch.count_lines(r.stderr, "parsph: error") == 1, r
    line = next(ln for ln in r.stderr.splitlines() if "parsph: error" in ln)
    assert "at most 1 ranks" in line and "Ly >= 0.0015 m" in line, r
    assert "Traceback" not in r.output, r
    # nothing written: no output file, complete or partial
    out = tmp_path / "out"
    assert not out.exists() or not list(out.glob("couette_paper*")), list(out.iterdir())
