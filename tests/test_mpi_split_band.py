"""The split band's blocks over the ranks (parsph.gas.split_band, parsph.parallel.block_share): the same bits
as one process doing both blocks, factorised afresh and reused as the conjugate gradients' preconditioner; a
block that is not positive definite on one rank raises on every rank (no rank left waiting)."""
import numpy as np
import pytest

from parsph.gas import darcy


def _case(seed=4):
    rng = np.random.default_rng(seed)
    nx, ny = 14, 10
    K = rng.uniform(0.05, 5.0, (nx, ny))
    V = rng.normal(size=(nx, ny, 2)) * 0.01
    sides = (darcy.Side("flux", rng.uniform(0.0, 0.1, ny)), darcy.Side("pressure", 0.0))
    return nx, ny, K, V, sides


@pytest.mark.mpi(min_size=2)
def test_split_band_over_the_ranks_is_bit_for_bit():
    from mpi4py import MPI
    from parsph.parallel.block_share import BlockShare
    nx, ny, K, V, sides = _case()
    here = darcy.Darcy(nx, ny, 1e-3, 1e-3, sides, None, method="split")
    spread = darcy.Darcy(nx, ny, 1e-3, 1e-3, sides, None, method="split", share=BlockShare(MPI.COMM_WORLD))
    for scale in (1.0, 1.001, 1.002):  # a factorisation, then solves preconditioned by it
        a, b = here.solve(K * scale, V), spread.solve(K * scale, V)
        assert np.array_equal(a.p, b.p) and np.array_equal(a.jx, b.jx) and np.array_equal(a.jy, b.jy)
    assert spread.factorisations == here.factorisations == 1 and spread.iterations == here.iterations > 0


@pytest.mark.mpi(min_size=2)
def test_a_failed_block_raises_on_every_rank():
    from mpi4py import MPI
    from parsph.parallel.block_share import BlockShare
    nx, ny, K, V, sides = _case()
    K[-3:] = -1.0  # block 1 (the rows above the separator) not positive definite: rank 1's
    d = darcy.Darcy(nx, ny, 1e-3, 1e-3, sides, None, method="split", share=BlockShare(MPI.COMM_WORLD))
    with pytest.raises(darcy.SolveFailed):
        d.solve(K, V)
    MPI.COMM_WORLD.Barrier()
