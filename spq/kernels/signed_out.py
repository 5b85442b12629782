"""How a signed result is written to a query's out vector (A's frame): when its bounds are closed (the
stopping rule), its status from the signed distance, its bounds, and witness points taken as the
bodies' supports along its normal. Shared by the EPA (spq.kernels.epa), the end of a signed query
(spq.kernels.signed) and the bounds from a ball hull's set of centres (spq.kernels.ball_hull_depth),
which the EPA also calls."""

from __future__ import annotations

import math

from spq.kernels.gjk import (
    OUT_DISTANCE,
    OUT_ITERATIONS,
    OUT_LOWER,
    OUT_NORMAL,
    OUT_POINT_A,
    OUT_POINT_B,
    OUT_STATUS,
    OUT_UPPER,
    OVERLAPPING,
    SEPARATED,
    TOUCHING,
    minkowski_support,
)
from spq.kernels.jit import kernel


@kernel(inline="always")
def bounds_closed(upper, lower, tol_abs, tol_rel):
    """The stopping rule: the bounds within tol_abs + tol_rel * |sd|, or |sd| <= tol_abs certified."""
    return (upper < math.inf and upper - lower <= tol_abs + tol_rel * abs(upper)) or (upper <= tol_abs
                                                                                       and lower >= -tol_abs)


@kernel(inline="always")
def status_of(sd, tol_abs):
    """'overlapping' below -tol_abs, 'touching' within it, 'separated' above."""
    if sd < -tol_abs:
        return OVERLAPPING
    if sd <= tol_abs:
        return TOUCHING
    return SEPARATED


@kernel
def set_result(upper, lower, iterations, tol_abs, out):
    out[OUT_DISTANCE] = upper
    out[OUT_UPPER] = upper
    out[OUT_LOWER] = min(lower, upper)  # rounding may cross them by an ulp
    out[OUT_ITERATIONS] = iterations
    out[OUT_STATUS] = status_of(upper, tol_abs)


@kernel
def supports_as_witnesses(pair, warm, work, out):
    """Witness points: the bodies' supports along out's normal n (A's) and -n (B's)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    n0, n1, n2 = out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2]
    if not (n0 == n0):
        n0, n1, n2 = 1.0, 0.0, 0.0
        out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2] = n0, n1, n2
    pa = work[16]
    pb = work[17]
    tmp = work[18]
    minkowski_support(pair, n0, n1, n2, warm, pa, pb, tmp)
    for c in range(3):
        out[OUT_POINT_A + c] = pa[c]
        out[OUT_POINT_B + c] = pb[c]
