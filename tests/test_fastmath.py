"""parsph.physics.fastmath: the branch-free log, exp and atan the drag's vector loops use.

- within 1 ulp of math.log / math.exp / math.atan (glibc, itself within about half an ulp) over the ranges
  the closures use: eps in [1e-3, 1], slip^2 from 1e-30 to 1e8, exp's argument in [-50, 50], atan's the
  blend's 262.5 (eps - 0.8), and wider;
- the edge cases the closures rely on (ln 0 = -inf, exp(-inf) = 0, nan and inf through);
- a vector loop gives the bits of the scalar calls (no fast-math: the same IEEE operations in each lane).
"""
import math

import numpy as np
import pytest
from numba import njit

from parsph.physics import fastmath as fm


@njit(error_model="numpy")
def _loop_log(x, out):
    for i in range(len(x)):
        out[i] = fm.log(x[i])


@njit(error_model="numpy")
def _loop_exp(x, out):
    for i in range(len(x)):
        out[i] = fm.exp(x[i])


@njit(error_model="numpy")
def _loop_atan(x, out):
    for i in range(len(x)):
        out[i] = fm.atan(x[i])


LOOPS = {"log": (_loop_log, fm.log, math.log), "exp": (_loop_exp, fm.exp, math.exp),
         "atan": (_loop_atan, fm.atan, math.atan)}


def _args(name):
    rng = np.random.default_rng(3)
    if name == "log":
        return np.concatenate([1.0 - rng.uniform(0.0, 0.999, 20000), np.exp(rng.uniform(-69.1, 18.5, 20000)),
                               np.exp(rng.uniform(-700.0, 700.0, 2000)), [1.0, 0.5, 2.0, 1e-3, 1e-30, 1e8,
                                                                          5e-324, 1e-310, 1.7e308]])
    if name == "exp":
        return np.concatenate([rng.uniform(-50.0, 50.0, 20000), rng.uniform(-1.0, 1.0, 5000),
                               rng.uniform(-700.0, 700.0, 2000), [0.0, -0.0, 1e-300, 0.5 * math.log(2.0)]])
    return np.concatenate([262.5 * (rng.uniform(0.0, 1.0, 20000) - 0.8), rng.uniform(-3.0, 3.0, 5000),
                           np.exp(rng.uniform(-40.0, 40.0, 2000)), [0.0, 0.66, 2.414213562373095, 1e300]])


@pytest.mark.parametrize("name", ["log", "exp", "atan"])
def test_within_one_ulp_of_libm(name):
    loop, _, ref = LOOPS[name]
    x = _args(name)
    got = np.empty_like(x)
    loop(x, got)
    want = np.array([ref(v) for v in x])
    ulps = np.abs(got - want) / np.spacing(np.abs(want))
    assert ulps.max() <= 1.0, x[ulps.argmax()]


@pytest.mark.parametrize("name", ["log", "exp", "atan"])
def test_vector_loop_gives_the_scalar_bits(name):
    loop, scalar, _ = LOOPS[name]
    x = _args(name)[:4099]  # a vector body and a scalar remainder
    got = np.empty_like(x)
    loop(x, got)
    assert np.array_equal(got.view(np.int64), np.array([scalar(float(v)) for v in x]).view(np.int64))


def test_edge_cases():
    inf, nan = math.inf, math.nan
    assert fm.log(0.0) == -inf and fm.log(-0.0) == -inf and fm.log(inf) == inf
    assert math.isnan(fm.log(-1.0)) and math.isnan(fm.log(-inf)) and math.isnan(fm.log(nan))
    assert fm.exp(-inf) == 0.0 and fm.exp(-800.0) == 0.0 and fm.exp(inf) == inf and fm.exp(800.0) == inf
    assert math.isnan(fm.exp(nan)) and fm.exp(0.0) == 1.0
    assert fm.exp(0.687 * (0.5 * fm.log(0.0))) == 0.0  # slip 0: Re^0.687 = 0
    assert fm.atan(inf) == math.pi / 2 and fm.atan(-inf) == -math.pi / 2 and math.isnan(fm.atan(nan))
