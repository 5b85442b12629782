"""Powers x^p over a short array at once: the loop LLVM's vectorizer turns into SIMD code.

``math.pow`` is a call into the C library that no vectorizer can split into lanes, and the
closest-point Newton between two superellipsoids (closest_points_newton) spends about 60% of an
evaluation on its powers: six independent ones per step (three coordinates a side). Written here as
arithmetic only (the logarithm by the atanh series on the mantissa, the exponential by its Taylor
series after a reduction by ln 2, and the exponent fields moved by integer operations), with no
branch in the loop body, eight of them cost about 28 ns against about 81 ns for eight ``math.pow``
(AMD EPYC znver4; fused multiply-adds on, zmm lanes).

Accuracy: a relative error of about |p log x| times 2.2e-16 (the rounding of y = p log x, which the
exponential magnifies), against math.pow's half an ulp: 7.5e-15 at most on x in [1e-3, 1.5] and
p up to 10 (tests/test_lane_powers.py, against math.pow). The closest-point Newton takes its gauges
from these powers, and its certificate places its points on the surfaces with them: a relative error
near 1e-14 moves them about 1e-14 of the bodies' size, four orders below the default tolerance.

``rough_powers_in_place`` cuts both series short (the logarithm's at z^4 / 9, the exponential's at r^7):
a relative error of about 2e-8 (3.4e-8 at p = 40), eight powers about 12 ns sooner. The closest-point
Newton takes it at the steps it does not certify, whose points the next, exact evaluation corrects
(CSE-CSE unsigned 1.02x to 1.06x, same process; the certified rows within each other's bounds).

Special values (either version): x = 0 gives 0, x = inf gives inf, NaN gives NaN (p > 0); a result below about
3e-308 (y = p log x < -708) gives 0 and one above e^709 gives inf. Subnormal x is scaled first.
"""

from __future__ import annotations

import math

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.imputils import impl_ret_borrowed
from numba.extending import intrinsic
from numba.np.arrayobj import populate_array

from spq.kernels.jit import kernel

LN2_HI = 6.93147180369123816490e-01  # ln 2 split so that n * LN2_HI is exact for |n| < 2^20
LN2_LO = 1.90821492927058770002e-10
INV_LN2 = 1.4426950408889634
ROUND_SHIFT = 6755399441055744.0  # 1.5 * 2^52: adding it rounds a double below 2^51 to an integer
SQRT_HALF_BITS = 0x3FE6A09E667F3BCD  # bits of sqrt(1/2): mantissas are taken in [sqrt(1/2), sqrt(2))
EXPONENT_ONE = 1023 << 52  # bits of 1.0
MIN_NORMAL = 2.2250738585072014e-308
SUBNORMAL_SCALE = 18014398509481984.0  # 2^54
UNDERFLOW_Y = -708.0  # below, 2^n has no normal double: the result is taken as 0
OVERFLOW_Y = 709.0  # above, the result is taken as inf


LANES = 8  # powers per call in the kernels' use: two rows of a (n, 4) scratch


@intrinsic
def lanes_view(typingctx, arr, row):
    """LANES consecutive slots from arr[row, 0] of a C-contiguous 2-d float64 array as a 1-d view (rows
    row and row + 1 of an (n, 4) scratch; no bounds check: the caller keeps row + 1 < n). Built in place:
    numba's reshape is a call into its helper library (about 10 ns), and its carray a function that
    returns a new array, which a kernel without NRT may not call."""
    if not (isinstance(arr, types.Array) and arr.ndim == 2 and arr.dtype == types.float64 and arr.layout == "C"):
        return None  # typing fails: a C-contiguous 2-d float64 scratch only
    view = types.Array(types.float64, 1, "C")

    def codegen(context, builder, signature, args):
        src = context.make_array(signature.args[0])(context, builder, args[0])
        data = cgutils.get_item_pointer(context, builder, signature.args[0], src,
                                        [args[1], context.get_constant(types.intp, 0)], wraparound=False)
        out = context.make_array(view)(context, builder)
        itemsize = context.get_constant(types.intp, 8)
        populate_array(out, data=data, shape=[context.get_constant(types.intp, LANES)], strides=[itemsize],
                       itemsize=itemsize, meminfo=src.meminfo, parent=src.parent)
        return impl_ret_borrowed(context, builder, view, out._getvalue())
    return view(arr, row), codegen


@intrinsic
def _bits(typingctx, x):
    """A double's bits as an int64 (no conversion)."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))
    return types.int64(types.float64), codegen


@intrinsic
def _double(typingctx, i):
    """An int64's bits as a double (no conversion)."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return types.float64(types.int64), codegen


@kernel(inline="always")
def _mantissa(x):
    """(k, s) for x >= 0: x = 2^k m with m in [sqrt(1/2), sqrt(2)) (a subnormal x scaled first), and
    s = (m - 1) / (m + 1), whence log m = 2 atanh(s), |s| <= 0.172."""
    sub = x < MIN_NORMAL
    xs = x * SUBNORMAL_SCALE if sub else x
    i = _bits(xs)
    k = (i - SQRT_HALF_BITS) >> 52
    m = _double(i - (k << 52))
    f = m - 1.0
    return float(k) - (54.0 if sub else 0.0), f / (2.0 + f)


@kernel(inline="always")
def _exponent_split(fk, s, z, series, p):
    """(y, t, r): y = p log x (x = 2^fk m, log m = 2s (1 + z series), z = s^2), and e^y = 2^n e^r with
    n the integer nearest y / ln 2 (held in t's low bits) and |r| <= ln 2 / 2."""
    hs = 2.0 * s
    log_m = hs + hs * z * series
    y = p * (fk * LN2_HI + (log_m + fk * LN2_LO))
    t = y * INV_LN2 + ROUND_SHIFT
    n = t - ROUND_SHIFT
    return y, t, (y - n * LN2_HI) - n * LN2_LO


@kernel(inline="always")
def _scaled(x, y, t, e):
    """x^p from e = e^r and (y, t) of _exponent_split, with the special values of the module docstring."""
    scale = _double(((_bits(t) - _bits(ROUND_SHIFT)) << 52) + EXPONENT_ONE)  # 2^n
    res = e * scale if y > UNDERFLOW_Y else 0.0
    res = res if y < OVERFLOW_Y else math.inf
    res = res if x > 0.0 else (0.0 if x == 0.0 else x)  # NaN stays NaN
    return math.inf if x == math.inf else res


@kernel(inline="always", fastmath={"contract"})
def lane_power(x, p):
    """x^p for x >= 0 (or inf, NaN) and p > 0, branch-free (see the module docstring)."""
    fk, s = _mantissa(x)
    # log m = 2s (1 + z/3 + z^2/5 + ... + z^11/23), z = s^2 (the next term is below 1e-17 of the sum),
    # in Estrin's order for a short chain
    z = s * s
    z2 = z * z
    z4 = z2 * z2
    z8 = z4 * z4
    q01 = 0.3333333333333333 + 0.2 * z
    q23 = 0.14285714285714285 + 0.1111111111111111 * z
    q45 = 0.09090909090909091 + 0.07692307692307693 * z
    q67 = 0.06666666666666667 + 0.058823529411764705 * z
    q89 = 0.05263157894736842 + 0.047619047619047616 * z
    series = (q01 + q23 * z2) + (q45 + q67 * z2) * z4 + (q89 + 0.043478260869565216 * z2) * z8
    y, t, r = _exponent_split(fk, s, z, series, p)
    # e^r by its Taylor series to r^13 (r^14 / 14! < 4e-18)
    r2 = r * r
    r4 = r2 * r2
    r8 = r4 * r4
    a01 = 1.0 + r
    a23 = 0.5 + 0.16666666666666666 * r
    a45 = 0.041666666666666664 + 0.008333333333333333 * r
    a67 = 0.001388888888888889 + 0.0001984126984126984 * r
    a89 = 2.48015873015873e-05 + 2.7557319223985893e-06 * r
    a1011 = 2.755731922398589e-07 + 2.505210838544172e-08 * r
    a1213 = 2.08767569878681e-09 + 1.6059043836821613e-10 * r
    e = (a01 + a23 * r2) + (a45 + a67 * r2) * r4 + ((a89 + a1011 * r2) + a1213 * r4) * r8
    return _scaled(x, y, t, e)


@kernel(inline="always", fastmath={"contract"})
def rough_lane_power(x, p):
    """lane_power to a relative error of about 2e-8 (p up to 20), with shorter series: for Newton steps
    that are not certified, whose points the next, exact evaluation corrects (closest_points_newton)."""
    fk, s = _mantissa(x)
    z = s * s  # log m's series to z^4 / 9 (the next term is below 2.2e-9 of the sum)
    series = (0.3333333333333333 + 0.2 * z) + (0.14285714285714285 + 0.1111111111111111 * z) * (z * z)
    y, t, r = _exponent_split(fk, s, z, series, p)
    r2 = r * r  # e^r to r^7 (r^8 / 8! < 5.2e-9)
    e = ((1.0 + r) + (0.5 + 0.16666666666666666 * r) * r2) + ((0.041666666666666664 + 0.008333333333333333 * r)
                                                             + (0.001388888888888889 + 0.0001984126984126984 * r)
                                                             * r2) * (r2 * r2)
    return _scaled(x, y, t, e)


@kernel(fastmath={"contract"})
def powers_in_place(x, p):
    """x[i] = x[i]^p[i] for every i (1-d arrays of equal length, x >= 0; see lane_power). Not inlined
    by numba: a loop whose trip count LLVM's loop vectorizer sees as a constant eight was unrolled
    into scalar code instead (numba leaves the SLP vectorizer off); this one became eight-lane code."""
    for i in range(x.shape[0]):
        x[i] = lane_power(x[i], p[i])


@kernel(fastmath={"contract"})
def rough_powers_in_place(x, p):
    """powers_in_place with rough_lane_power (a relative error of about 2e-8)."""
    for i in range(x.shape[0]):
        x[i] = rough_lane_power(x[i], p[i])
