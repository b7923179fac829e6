"""The resident memory a run needs per particle: the bound that refuses runs too large for the nodes
(:func:`parsph.simulation.case.fits_in_memory`), apart from the run file's validation."""
import math


def bytes_per_particle(cfg, threads=1):
    """An upper bound of the resident memory per particle [bytes], to refuse runs that cannot fit.

    Fields (about 300 + 100 dim bytes) plus the neighbour list, 12 bytes per
    entry for the neighbours within 2h (the disc or ball's lattice points,
    +25% for a compressed lattice) and a margin of 4, with 30% spare capacity;
    the compact list of the pairs within 2h (``pass_data.PairList.cj``, ``cf``:
    12 bytes per listed pair, the list holding the pairs within 2h + skin, half
    an entry a pair). With threads the passes also keep 40 bytes per listed pair
    (the gather's entries and the pair values, ``pass_data.Gather``).
    Measured (tests/test_memory_estimate.py): 2-D 0.7 KB, 3-D 2.1 KB at h = 1.25 dx
    on one thread, 1.0 and 3.6 KB on two; this gives 1.3 and 3.1 KB, 2.0 and 5.3 KB.
    """
    reach = 2.0 * cfg.h
    cells = [reach / s for s in cfg.spacing]
    ball = math.pi * cells[0] * cells[1] if cfg.dim == 2 else 4.0 / 3.0 * math.pi * math.prod(cells)
    entries = 1.25 * ball + 4
    listed = entries / 2 * ((reach + cfg.get("numerics.skin") * cfg.h) / reach) ** cfg.dim  # pairs within 2h + skin
    threaded = 1.3 * (8 + 40 * entries / 2) if threads > 1 else 0.0
    return 300 + 100 * cfg.dim + 1.3 * 12 * entries + 1.3 * 12 * listed + threaded
