"""Closed forms for the pairs whose cores are points and segments (spheres and capsules against each
other) or a box and a point (a box against a sphere): the cores' closest points, certified by the
cores' own supports along the normal, without a descent.

The general query takes about 250 to 300 ns on these pairs (a descent's fixed cost and at least one
iteration, as between polytopes); the closed form, a few dozen. Spheres and boxes are most of the
collision bodies of some robots (the Allegro hands, panda_collision's 26 spheres, the legged robots'
feet), so the pairs are common in scenes.

The bodies are the cores grown by their margins, so while the cores stay apart (their distance c > 0)
the signed distance is c - mA - mB exactly, along the cores' normal. Where the cores meet, or nearly
(the normal would come from rounding), or where the certificate does not close (nearly parallel
segments), the query goes on to the general path.
"""

from __future__ import annotations

import math

from spq.kernels.epa import bounds_closed
from spq.kernels.frames import rot_to_a, to_a, to_b
from spq.kernels.gjk import OUT_DISTANCE, OUT_ITERATIONS, OUT_LOWER, OUT_NORMAL, OUT_POINT_A, OUT_POINT_B, \
    OUT_STATUS, OUT_UPPER, OVERLAPPING
from spq.kernels.jit import kernel
from spq.kernels.kinds import BOX, POINT, SEGMENT
from spq.kernels.signed_out import status_of

PARALLEL = 1e-12  # 1 - cos^2 of the segments' angle below which they are treated as parallel
MEET = 1e-9  # the cores' distance over their scale at or below which the general path takes the pair


@kernel(inline="always")
def closed_form_kinds(kA, kB):
    """Whether :func:`primitive_query` knows the pair: points and segments, or a box and a point."""
    a_ball = kA == POINT or kA == SEGMENT
    b_ball = kB == POINT or kB == SEGMENT
    return (a_ball and b_ball) or (kA == BOX and kB == POINT) or (kA == POINT and kB == BOX)


@kernel(inline="always")
def _clamp(x, h):
    return max(-h, min(x, h))  # minsd/maxsd: the data decides, not a branch


@kernel(inline="always")
def _segments(hA, hB, w0, w1, w2, t0, t1, t2):
    """Closest points of A's segment s * e_z (|s| <= hA) and B's t + u * w (|u| <= hB, w unit): (s, u).

    The unconstrained minimum clamped to A's range, B's parameter for it clamped, then A's again for
    that one (exact for two segments; parallel ones start from s = 0)."""
    b = w2
    d1 = t2
    d2 = w0 * t0 + w1 * t1 + w2 * t2
    den = 1.0 - b * b
    s = _clamp((d1 - b * d2) / den, hA) if den > PARALLEL else 0.0
    u = s * b - d2
    if u < -hB or u > hB:
        u = _clamp(u, hB)
        s = _clamp(u * b + d1, hA)
    return s, u


@kernel(inline="always")
def primitive_query(pair, tol, signed, dir_io, out):
    """The query of a pair (see spq.kernels) whose kinds :func:`closed_form_kinds` accepts, into out as
    gjk_query writes it (A's frame, margins included; signed as there). Returns the status code, or
    -1 when the general path must take it (out then untouched): the cores within MEET of their scale
    of each other, or bounds that do not close (about parallel segments)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    if kA == BOX or kB == BOX:
        h = fA if kA == BOX else fB
        if kA == BOX:  # B's point is t
            p0, p1, p2 = t[0], t[1], t[2]
        else:  # A's point (the origin) in B's frame
            p0, p1, p2 = to_b(R, t, 0.0, 0.0, 0.0)
        q0, q1, q2 = _clamp(p0, h[0]), _clamp(p1, h[1]), _clamp(p2, h[2])
        # in the box's frame: from the box's point to the point
        g0, g1, g2 = p0 - q0, p1 - q1, p2 - q2
        c = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        scale = abs(p0) + abs(p1) + abs(p2) + h[0] + h[1] + h[2]
        if not c > MEET * scale:
            return -1
        n0, n1, n2 = g0 / c, g1 / c, g2 / c
        # the slab between the point and the box's support along n
        lower = n0 * p0 + n1 * p1 + n2 * p2 - (h[0] * abs(n0) + h[1] * abs(n1) + h[2] * abs(n2))
        if kA == BOX:
            a0, a1, a2, b0, b1, b2 = q0, q1, q2, p0, p1, p2
        else:  # back to A's frame, where the box's point is on B and the normal points at it
            a0 = a1 = a2 = 0.0
            b0, b1, b2 = to_a(R, t, q0, q1, q2)
            m0, m1, m2 = rot_to_a(R, n0, n1, n2)
            n0, n1, n2 = -m0, -m1, -m2
    else:
        hA = fA[0] if kA == SEGMENT else 0.0
        hB = fB[0] if kB == SEGMENT else 0.0
        w0, w1, w2 = R[0, 2], R[1, 2], R[2, 2]
        s = u = 0.0
        if kA == SEGMENT or kB == SEGMENT:  # two spheres: the centres
            s, u = _segments(hA, hB, w0, w1, w2, t[0], t[1], t[2])
        a0, a1, a2 = 0.0, 0.0, s
        b0, b1, b2 = t[0] + u * w0, t[1] + u * w1, t[2] + u * w2
        g0, g1, g2 = b0 - a0, b1 - a1, b2 - a2
        c = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        if not c > MEET * (abs(t[0]) + abs(t[1]) + abs(t[2]) + hA + hB):
            return -1
        n0, n1, n2 = g0 / c, g1 / c, g2 / c
        # the slab between the segments' supports along n: min over B of n.b less max over A of n.a
        lower = n0 * t[0] + n1 * t[1] + n2 * t[2] - hB * abs(n0 * w0 + n1 * w1 + n2 * w2) - hA * abs(n2)
    if not bounds_closed(c, lower, tol_abs, tol_rel):
        return -1
    # the bodies' result, as add_margins and unsigned_of_signed would make it from the cores' (written
    # out here: their calls take a third of the time of this pair)
    sd = c - (mA + mB)
    status = status_of(sd, tol_abs)
    dir_io[0], dir_io[1], dir_io[2] = n0, n1, n2
    out[OUT_ITERATIONS] = 1
    out[OUT_STATUS] = status
    if not signed and status == OVERLAPPING:
        for i in range(OUT_POINT_A, OUT_NORMAL + 3):
            out[i] = math.nan
        out[OUT_DISTANCE] = out[OUT_LOWER] = out[OUT_UPPER] = 0.0
        return status
    out[OUT_POINT_A], out[OUT_POINT_A + 1], out[OUT_POINT_A + 2] = a0 + mA * n0, a1 + mA * n1, a2 + mA * n2
    out[OUT_POINT_B], out[OUT_POINT_B + 1], out[OUT_POINT_B + 2] = b0 - mB * n0, b1 - mB * n1, b2 - mB * n2
    out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2] = n0, n1, n2
    low = min(lower, c) - (mA + mB)
    if signed:
        out[OUT_DISTANCE] = out[OUT_UPPER] = sd
        out[OUT_LOWER] = low
    else:
        out[OUT_DISTANCE] = out[OUT_UPPER] = max(sd, 0.0)
        out[OUT_LOWER] = max(low, 0.0)
    return status
