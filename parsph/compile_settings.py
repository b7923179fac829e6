"""How numba compiles parsph's loops: with LLVM's SLP vectoriser, which numba leaves off by default.

The SLP vectoriser packs the same operation on neighbouring scalars (a pair's
x and y, its pressure and viscous factors) into one vector instruction; each
lane does the scalar's IEEE operation, so the results are the same bit for
bit (no reassociation, no fused multiply-add: those need fastmath, which
parsph never asks for). It shortens the scalar force pass by about a seventh
(docs/performance.md, "The SLP vectoriser and the all-reduce behind Eq. (3)"). Set ``NUMBA_SLP_VECTORIZE=0`` to
compile without it; numba reads the setting at each compilation, so this
must run before the first loop compiles (parsph's ``__init__`` runs it).
"""
import os

ENV = "NUMBA_SLP_VECTORIZE"


def apply():
    """SLP vectorisation on for what compiles from here on, unless the environment says otherwise."""
    if ENV in os.environ:
        return
    from numba.core import config
    config.SLP_VECTORIZE = 1
