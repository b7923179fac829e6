"""Branch-free log, exp and atan for numba loops that LLVM vectorises (the drag's closures per particle).

numba calls glibc's scalar log/exp/atan (4-5 ns each, one particle at a time); without SVML (which would
change the bits of the existing vector loops) a loop calling them stays scalar. These are fdlibm's log,
exp with SLEEF's polynomial and Cephes's atan written without branches: range reduction through the
float's bits (:func:`bits`, :func:`from_bits`), a short polynomial or rational core, the edge cases as
selects. Inside a loop over contiguous arrays LLVM runs them on vector registers; as plain IEEE operations
without fast-math flags they give the same bits scalar or vectorised, on every thread and rank. The
polynomials use :func:`fma` explicitly (llvm.fma, one rounding, the same in every lane and in scalar code;
not the contraction fast-math would allow, which could differ between loops; a CPU without FMA would
call libm's fma, slower, same bits): a quarter less time. SWIFT's approx_math.h is the precedent.
Accuracy: within 1 ulp of glibc's math.log/exp/atan (tests/test_fastmath.py); exp(x) is 0 below
x = -708 and inf above 709 (no subnormal results, and exp(709 .. 709.78) reads as an overflow).
"""
import math

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic


@intrinsic
def bits(typingctx, x):
    """The float64 ``x``'s bits as an int64 (a bitcast)."""
    if not isinstance(x, types.Float):
        return None

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.IntType(64))
    return types.int64(types.float64), codegen


@intrinsic
def from_bits(typingctx, i):
    """The float64 whose bits are the int64 ``i`` (a bitcast)."""
    if not isinstance(i, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return types.float64(types.int64), codegen


@intrinsic
def fma(typingctx, a, b, c):
    """a b + c rounded once (llvm.fma: one instruction on x86-64 with FMA, vectorised like the others)."""
    if not all(isinstance(t, types.Float) for t in (a, b, c)):
        return None

    def codegen(context, builder, sig, args):
        return builder.fma(*[context.cast(builder, v, t, types.float64) for v, t in zip(args, sig.args)])
    return types.float64(a, b, c), codegen


_LN2_HI, _LN2_LO = 6.93147180369123816490e-01, 1.90821492927058770002e-10  # ln 2 = hi + lo, k hi exact
_LG1, _LG2, _LG3, _LG4 = 6.666666666666735130e-01, 3.999999999940941908e-01, 2.857142874366239149e-01, \
    2.222219843214978396e-01
_LG5, _LG6, _LG7 = 1.818357216161805012e-01, 1.531383769920937332e-01, 1.479819860511658591e-01
_SQRT2_OFF = 0x3FF0000000000000 - 0x3FE6A09E00000000  # moves the mantissa's cut to sqrt(2)/2
_MANT = 0x000FFFFFFFFFFFFF
_TINY = 2.2250738585072014e-308  # the smallest normal float
_TWO52 = 4503599627370496.0


@njit(cache=True, inline="always", error_model="numpy")
def log(x):
    """ln x (fdlibm's e_log.c): x = 2^k z, z in [sqrt(2)/2, sqrt(2)), f = z - 1, s = f / (2 + f),
    ln z = f - f^2/2 + s (f^2/2 + R(s^2)); ln 0 = -inf, ln inf = inf, nan for x < 0 or nan;
    subnormal x scaled by 2^52 first."""
    sub = x < _TINY
    xs = x * _TWO52 if sub else x
    ix = bits(xs) + _SQRT2_OFF
    k = (ix >> 52) - 0x3FF
    z = from_bits((ix & _MANT) + 0x3FE6A09E00000000)
    dk = float(k) - (52.0 if sub else 0.0)
    f = z - 1.0
    hfsq = 0.5 * f * f
    s = f / (2.0 + f)
    s2 = s * s
    w = s2 * s2
    t1 = w * fma(w, fma(w, _LG6, _LG4), _LG2)
    t2 = s2 * fma(w, fma(w, fma(w, _LG7, _LG5), _LG3), _LG1)
    r = fma(s, hfsq + (t2 + t1), dk * _LN2_LO) - hfsq + f + dk * _LN2_HI
    r = -math.inf if x == 0.0 else r
    r = x if x == math.inf else r
    return math.nan if not x >= 0.0 else r


_INV_LN2 = 1.44269504088896338700e+00
_SHIFT = 6755399441055744.0  # 1.5 * 2^52: t + _SHIFT rounds t to an integer, held in the low bits
# e^r - 1 - r = r^2 (1/2 + r/6 + ...): a minimax fit on |r| <= ln 2 / 2 (SLEEF's xexp, 1 ulp)
_E12, _E11, _E10, _E9 = 2.08860621107283687536341e-09, 2.51112930892876518610661e-08, \
    2.75573911234900471893338e-07, 2.75572362911928827629423e-06
_E8, _E7, _E6, _E5 = 2.4801587159235472998791e-05, 0.000198412698960509205564975, \
    0.00138888888889774492207962, 0.00833333333331652721664984
_E4, _E3 = 0.0416666666666665047591422, 0.166666666666666851703837
_EXP_LO, _EXP_HI = -708.0, 709.0


@njit(cache=True, inline="always", error_model="numpy")
def exp(x):
    """e^x: x = k ln 2 + r, |r| <= ln 2 / 2 (Cody & Waite, ln 2 in two parts), e^r = 1 + r + r^2 P(r) with
    SLEEF's degree-12 fit (no division), times 2^k through the exponent's bits; 0 below -708, inf above 709,
    nan for nan."""
    xc = x if x > _EXP_LO else _EXP_LO
    xc = xc if xc < _EXP_HI else _EXP_HI
    t = fma(xc, _INV_LN2, _SHIFT)
    kf = t - _SHIFT
    k = bits(t) - bits(_SHIFT)
    r = fma(-kf, _LN2_LO, fma(-kf, _LN2_HI, xc))
    p = fma(fma(fma(fma(fma(fma(fma(fma(fma(fma(_E12, r, _E11), r, _E10), r, _E9), r, _E8), r, _E7), r, _E6), r,
                                _E5), r, _E4), r, _E3), r, 0.5)
    y = fma(r * r, p, r) + 1.0
    e = y * from_bits((k + 0x3FF) << 52)
    e = 0.0 if x < _EXP_LO else e
    e = math.inf if x > _EXP_HI else e
    return x if x != x else e


_AT_P0, _AT_P1, _AT_P2, _AT_P3, _AT_P4 = (-8.750608600031904122785e-01, -1.615753718733365076637e+01,
                                          -7.500855792314704667340e+01, -1.228866684490136173410e+02,
                                          -6.485021904942025371773e+01)
_AT_Q0, _AT_Q1, _AT_Q2, _AT_Q3, _AT_Q4 = (2.485846490142306297962e+01, 1.650270098316988542046e+02,
                                          4.328810604912902668951e+02, 4.853903996359136964868e+02,
                                          1.945506571482613964425e+02)
_T3P8 = 2.41421356237309504880  # tan(3 pi / 8)
_MOREBITS = 6.123233995736765886130e-17  # pi/2 - float(pi/2)


@njit(cache=True, inline="always", error_model="numpy")
def atan(x):
    """arctan x (Cephes's atan.c): |x| reduced to [0, 0.66] by atan x = pi/2 + atan(-1/x) above
    tan(3 pi/8), pi/4 + atan((x - 1)/(x + 1)) above 0.66, then u + u z P(z) / Q(z), z = u^2."""
    a = abs(x)
    big = a > _T3P8
    mid = a > 0.66
    num = -1.0 if big else (a - 1.0 if mid else a)
    den = a if big else (a + 1.0 if mid else 1.0)
    y0 = math.pi / 2 if big else (math.pi / 4 if mid else 0.0)
    more = _MOREBITS if big else (0.5 * _MOREBITS if mid else 0.0)
    u = num / den
    z = u * u
    p = fma(fma(fma(fma(_AT_P0, z, _AT_P1), z, _AT_P2), z, _AT_P3), z, _AT_P4)
    q = fma(fma(fma(fma(z + _AT_Q0, z, _AT_Q1), z, _AT_Q2), z, _AT_Q3), z, _AT_Q4)
    y = y0 + (fma(u, z * p / q, u) + more)
    return -y if x < 0.0 else y
