"""Newton's method on the closest points of two superellipsoids: the end of a distance between boxy ones.

Newton on the contact normal (newton_normal) stalls where a side is boxy (exponents below 1): near a
face's normal its support map moves like a small power of the direction (|n_t|^0.18 at exponent
0.3), so the support points jump across the face while the normal barely moves, and neither the
steps nor the upper bound settle (on Table I's link poses with exponents 0.3, 17% of the separated
pairs ran out of Newton steps and went to the plain GJK, taking 45% of the iterations). The same
surface is smooth in space: the implicit function
F(x) = (|x/a|^p2 + |y/b|^p2)^(e2/e1) + |z/c|^p1, p_i = 2/e_i, has a bounded Hessian wherever both
exponents are at most 1 (a face is nearly flat there, not nearly a root). So for such bodies the
unknowns are the closest points themselves: x on A, y on B and the multipliers of the Lagrangian
|x - y|^2 / 2 + lam (G_A(x) - 1) + mu (G_B(y) - 1), with G = F^(e1/2) the gauge (homogeneous of
degree 1, so the constraint is linear along rays where F, of degree 2/e1, is steep), whose
stationary point solves

    x - y + lam grad G_A(x) = 0,   y - x + mu grad G_B(y) = 0,   G_A(x) = 1,   G_B(y) = 1,

eight equations whose Jacobian is [[I + lam H_A, -I, g_A, 0], [-I, I + mu H_B, 0, g_B],
[g_A^T, 0, 0, 0], [0, g_B^T, 0, 0]]; its first block row gives dy, which leaves a 5 x 5 system.
From the closest points of the inscribed polytopes it converges in about three steps (on Table I's
poses with exponents 0.3, 4 in 5 pairs took 3 or 4 evaluations).

The result is certified as GJK's is: the upper bound is the distance between the two points
scaled onto the surfaces (x / G(x) lies on A's surface), the lower bound the width of the slab
between the support planes along A's normal there (support values are accurate even where the
support points are not; A's is 1 / |grad G|, see _certify). Exponents slightly above 1 (Table I's
fitted cover has 1.02) leave the Hessian unbounded only on the coordinate planes, which the
iterates do not hit; above PRIMAL_MAX_EXPONENT the caller keeps Newton on the normal, which suits
pointy bodies (in a prototype, from the polytopes' witnesses, the closest-point Newton converged on
79% of the separated pairs at exponents 1.5 and 1.4, against 100% at 1.0 and below).
"""

from __future__ import annotations

import math

from spq.kernels.indexing import at
from spq.kernels.jit import kernel
from spq.kernels.kinds import SUPERELLIPSOID
from spq.kernels.lane_powers import lanes_view, powers_in_place, rough_powers_in_place
from spq.kernels.superellipsoid_support import (F_A, F_B, F_C, F_E1, F_E2, F_GA, F_GB, F_GC, F_HA, F_HB, F_HC, F_IA,
                                                F_IB, F_IC, F_K, F_P1, F_P2, support_value)

PRIMAL_MAX_EXPONENT = 1.1  # both exponents of both bodies at most this: the primal Newton runs
PRIMAL_STEPS = 8  # Newton steps before the caller's Newton on the normal takes over
# The certificate (B's support value) is checked only once a step is this short relative to the
# bodies' size: before that the points are too far off for it to close.
CERTIFY_STEP = 1e-2
# Below this a reciprocal would overflow (or its products read 0 * inf): the quotients are taken as they
# are, so that a coordinate within rounding of a coordinate plane gives what the divisions give.
RECIPROCAL_MIN = 1e-300
PRIMAL_INNER_REL_TOL = 5e-2  # the inscribed polytopes' search that gives the start points
PRIMAL_RESTART_REL_TOL = 1e-4  # that search carried on this far when Newton failed from its first start


@kernel(inline="always")
def primal_pair(kA, fA, kB, fB):
    """Whether both bodies are superellipsoids with exponents at most PRIMAL_MAX_EXPONENT."""
    return (kA == SUPERELLIPSOID and kB == SUPERELLIPSOID and max(fA[F_E1], fA[F_E2]) <= PRIMAL_MAX_EXPONENT
            and max(fB[F_E1], fB[F_E2]) <= PRIMAL_MAX_EXPONENT)


@kernel(inline="always")
def _powers(r, p):
    """(r^p, r^(p-1), r^(p-2)) for r >= 0, p > 1; 0^(p-2) is inf for p < 2."""
    if r <= 0.0:
        return 0.0, 0.0, (1.0 if p == 2.0 else 0.0 if p > 2.0 else math.inf)
    return _lower_powers(r, r * r if p == 2.0 else math.pow(r, p), p)


@kernel(inline="always")
def _given_powers(r, rp, p):
    """_powers with r^p given (rp, as lane_powers gives it)."""
    if r <= 0.0:
        return 0.0, 0.0, (1.0 if p == 2.0 else 0.0 if p > 2.0 else math.inf)
    return _lower_powers(r, rp, p)


@kernel(inline="always")
def _lower_powers(r, rp, p):
    """(r^p, r^(p-1), r^(p-2)) from r > 0 and r^p."""
    if r < RECIPROCAL_MIN:
        return rp, rp / r, rp / (r * r)
    inv = 1.0 / r
    rp1 = rp * inv
    return rp, rp1, rp1 * inv


@kernel(inline="always")
def implicit(f, x0, x1, x2, g, H):
    """F(x) of the superellipsoid f at the local point x, its gradient into g (3,) and its Hessian
    into H (3, 3); inf or NaN where they do not exist (a coordinate plane of an exponent above 1, the
    z axis). The shape's constants (superellipsoid_support.pack) leave one division a coordinate."""
    p1, p2 = f[F_P1], f[F_P2]
    return _implicit_from(f, x0, x1, x2, _powers(abs(x0) * f[F_IA], p2), _powers(abs(x1) * f[F_IB], p2),
                          _powers(abs(x2) * f[F_IC], p1), g, H)


@kernel(inline="always")
def _lanes_in(f, x0, x1, x2, lanes, at0):
    """The bases of f's three coordinate powers at x into lanes[at0:at0 + 3] (see _implicit_lanes)."""
    lanes[at0] = abs(x0) * f[F_IA]
    lanes[at0 + 1] = abs(x1) * f[F_IB]
    lanes[at0 + 2] = abs(x2) * f[F_IC]


@kernel(inline="always")
def _implicit_lanes(f, x0, x1, x2, lanes, at0, g, H):
    """implicit at x from its coordinates' powers, which _lanes_in's bases became in lanes[at0:at0 + 3]."""
    p1, p2 = f[F_P1], f[F_P2]
    return _implicit_from(f, x0, x1, x2, _given_powers(abs(x0) * f[F_IA], lanes[at0], p2),
                          _given_powers(abs(x1) * f[F_IB], lanes[at0 + 1], p2),
                          _given_powers(abs(x2) * f[F_IC], lanes[at0 + 2], p1), g, H)


@kernel(inline="always")
def _implicit_from(f, x0, x1, x2, c0, c1, c2, g, H):
    """implicit from the powers (r^p, r^(p-1), r^(p-2)) of the three scaled coordinates."""
    k = f[F_K]
    P0, P0m1, P0m2 = c0
    P1, P1m1, P1m2 = c1
    P2, P2m1, P2m2 = c2
    u = P0 + P1
    du0 = math.copysign(f[F_GA] * P0m1, x0)
    du1 = math.copysign(f[F_GB] * P1m1, x1)
    d2u0 = f[F_HA] * P0m2
    d2u1 = f[F_HB] * P1m2
    if u > 0.0:
        uk = u if k == 1.0 else math.pow(u, k)  # equal exponents (boxes, ellipsoids) need no power
        if u >= RECIPROCAL_MIN:
            iu = 1.0 / u
            uk1 = uk * iu
            uk2 = uk1 * iu
        else:
            uk1 = uk / u
            uk2 = uk1 / u
    else:
        uk = uk1 = uk2 = math.nan
    g[0] = k * uk1 * du0
    g[1] = k * uk1 * du1
    g[2] = math.copysign(f[F_GC] * P2m1, x2)
    kk = k * (k - 1.0) * uk2
    H[0, 0] = kk * du0 * du0 + k * uk1 * d2u0
    H[0, 1] = H[1, 0] = kk * du0 * du1
    H[1, 1] = kk * du1 * du1 + k * uk1 * d2u1
    H[2, 2] = f[F_HC] * P2m2
    H[0, 2] = H[2, 0] = H[1, 2] = H[2, 1] = 0.0
    return uk + P2


@kernel(inline="always")
def _to_gauge(F, e1, g, H):
    """The gauge G = F^(e1/2) (homogeneous of degree 1, G = 1 on the surface) from F, with its
    gradient and Hessian written over F's in g and H. The constraint G = 1 is linear along rays,
    where F's (degree 2/e1, up to 20) is steep: Newton's radial steps land on the surface."""
    beta = 0.5 * e1
    G = math.pow(F, beta)
    if F >= RECIPROCAL_MIN:
        inv = 1.0 / F
        c = beta * G * inv
        d = (beta - 1.0) * inv
    else:
        c = beta * G / F
        d = (beta - 1.0) / F
    for i in range(3):
        for j in range(3):
            H[i, j] = c * (H[i, j] + d * g[i] * g[j])
    for i in range(3):
        g[i] *= c
    return G


@kernel(inline="always")
def _m(mat, i, j):
    """Entry (i, j) of the 5 x 6 augmented system, stored two rows of mat (10, 4) per row (unsigned
    indices: the pivot's row is data, which numba would otherwise wrap as if it could be negative)."""
    return mat[at(2 * i + (j >> 2)), at(j & 3)]


@kernel(inline="always")
def _set(mat, i, j, value):
    mat[at(2 * i + (j >> 2)), at(j & 3)] = value


@kernel(inline="always")
def _rotate(k, v0, v1, v2):
    """(v0, v1, v2) rotated so that entry k comes first, the others in cyclic order."""
    if k == 1:
        return v1, v2, v0
    if k == 2:
        return v2, v0, v1
    return v0, v1, v2


@kernel
def _solve(mat, step):
    """Newton's 5 x 6 augmented system in mat, solved into step (2, 4), row-major: (dx, dlam, dmu).
    False where a pivot vanishes or the system is singular.

    Its shape is fixed: rows 0-2 [C | g_A + .. | g_B | r], row 3 [g_A | 0 | 0 | r3], row 4
    [q | g_A.g_B | 0 | r4]. dmu appears only in rows 0-2, so the row of g_B's largest entry gives it;
    row 3 gives the dx entry where g_A is largest; a 3 x 3 system (Cramer's rule) leaves the other
    two and dlam. The pivots are gradient entries, chosen from the gradients alone, so no step waits
    on a comparison of eliminated values: 26 ns against 103 for partial pivoting over the whole
    system (Newton's own matrices on Table I's poses; the steps agree with LAPACK's to a median of
    3.5e-16 relative). C is nearly singular where both bodies are nearly flat, which these pivots
    keep out of the first two eliminations."""
    c00, c01, c02, a0, b0, r0 = _m(mat, 0, 0), _m(mat, 0, 1), _m(mat, 0, 2), _m(mat, 0, 3), _m(mat, 0, 4), _m(mat, 0, 5)
    c10, c11, c12, a1, b1, r1 = _m(mat, 1, 0), _m(mat, 1, 1), _m(mat, 1, 2), _m(mat, 1, 3), _m(mat, 1, 4), _m(mat, 1, 5)
    c20, c21, c22, a2, b2, r2 = _m(mat, 2, 0), _m(mat, 2, 1), _m(mat, 2, 2), _m(mat, 2, 3), _m(mat, 2, 4), _m(mat, 2, 5)
    g0, g1, g2, r3 = _m(mat, 3, 0), _m(mat, 3, 1), _m(mat, 3, 2), _m(mat, 3, 5)
    q0, q1, q2, s, r4 = _m(mat, 4, 0), _m(mat, 4, 1), _m(mat, 4, 2), _m(mat, 4, 3), _m(mat, 4, 5)
    # dmu: the row of g_B's largest entry first, eliminated from the other two
    if abs(b1) > abs(b0) and abs(b1) >= abs(b2):
        c00, c01, c02, a0, b0, r0, c10, c11, c12, a1, b1, r1 = c10, c11, c12, a1, b1, r1, c00, c01, c02, a0, b0, r0
    elif abs(b2) > abs(b0) and abs(b2) > abs(b1):
        c00, c01, c02, a0, b0, r0, c20, c21, c22, a2, b2, r2 = c20, c21, c22, a2, b2, r2, c00, c01, c02, a0, b0, r0
    if not (b0 != 0.0):
        return False
    f1, f2 = b1 / b0, b2 / b0
    u0, u1, u2, ua, ur = c10 - f1 * c00, c11 - f1 * c01, c12 - f1 * c02, a1 - f1 * a0, r1 - f1 * r0
    v0, v1, v2, va, vr = c20 - f2 * c00, c21 - f2 * c01, c22 - f2 * c02, a2 - f2 * a0, r2 - f2 * r0
    # dx_k, k where g_A is largest (the columns rotated to put it first), eliminated with row 3
    k = 0
    if abs(g1) > abs(g0) and abs(g1) >= abs(g2):
        k = 1
    elif abs(g2) > abs(g0) and abs(g2) > abs(g1):
        k = 2
    g0, g1, g2 = _rotate(k, g0, g1, g2)
    u0, u1, u2 = _rotate(k, u0, u1, u2)
    v0, v1, v2 = _rotate(k, v0, v1, v2)
    q0, q1, q2 = _rotate(k, q0, q1, q2)
    if not (g0 != 0.0):
        return False
    fu, fv, fq = u0 / g0, v0 / g0, q0 / g0
    # the 3 x 3 system in (the other two dx entries, dlam), by Cramer's rule
    m00, m01, m02, y0 = u1 - fu * g1, u2 - fu * g2, ua, ur - fu * r3
    m10, m11, m12, y1 = v1 - fv * g1, v2 - fv * g2, va, vr - fv * r3
    m20, m21, m22, y2 = q1 - fq * g1, q2 - fq * g2, s, r4 - fq * r3
    k00, k01, k02 = m11 * m22 - m12 * m21, m02 * m21 - m01 * m22, m01 * m12 - m02 * m11
    det = m00 * k00 + m10 * k01 + m20 * k02
    if not (det != 0.0 and abs(det) < math.inf):
        return False
    k10, k11, k12 = m12 * m20 - m10 * m22, m00 * m22 - m02 * m20, m02 * m10 - m00 * m12
    k20, k21, k22 = m10 * m21 - m11 * m20, m01 * m20 - m00 * m21, m00 * m11 - m01 * m10
    x1 = (k00 * y0 + k01 * y1 + k02 * y2) / det
    x2 = (k10 * y0 + k11 * y1 + k12 * y2) / det
    dlam = (k20 * y0 + k21 * y1 + k22 * y2) / det
    x0 = (r3 - g1 * x1 - g2 * x2) / g0
    d0, d1, d2 = _rotate((3 - k) % 3, x0, x1, x2)  # back to dx's own order
    step[0, 0], step[0, 1], step[0, 2], step[0, 3] = d0, d1, d2, dlam
    step[1, 0] = (r0 - c00 * d0 - c01 * d1 - c02 * d2 - a0 * dlam) / b0
    return True


@kernel
def _certify(fB, R, t, x, y, FA, FB, gA, best_a, best_b):
    """(upper, lower) of the points x (A's frame) and y (B's frame) scaled onto the surfaces by their
    gauges FA, FB, and of the slab along A's normal at x (gA: the gauge's gradient there); the scaled
    points (A's frame) into best_a, best_b.

    A's side of the slab costs no support call: the gauge G is homogeneous of degree 1, so its
    gradient g is constant along rays and g.x = G(x) (Euler), and the tangent plane at x / G(x)
    supports A: max over A of (g / |g|).z = (g / |g|).(x / G(x)) = 1 / |g|. Its width is second
    order in the points' error, as along the points' own difference (which needs both support
    values): on Table I's poses at exponents 0.3, 27% of the pairs needed a second certificate
    against 23%, and the query ran 1.07x faster."""
    sa = 1.0 / FA  # the gauges: x / G(x) lies on the surface
    sb = 1.0 / FB
    for r in range(3):
        best_a[r] = x[r] * sa
    for r in range(3):
        best_b[r] = (R[r, 0] * y[0] + R[r, 1] * y[1] + R[r, 2] * y[2]) * sb + t[r]
    n0, n1, n2 = best_b[0] - best_a[0], best_b[1] - best_a[1], best_b[2] - best_a[2]
    upper = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if not (upper > 0.0):
        return upper, -math.inf
    norm = math.sqrt(gA[0] * gA[0] + gA[1] * gA[1] + gA[2] * gA[2])
    if not (norm > 0.0 and norm < math.inf):
        return upper, -math.inf
    top_a = 1.0 / norm
    n0, n1, n2 = gA[0] * top_a, gA[1] * top_a, gA[2] * top_a
    b0 = -(R[0, 0] * n0 + R[1, 0] * n1 + R[2, 0] * n2)
    b1 = -(R[0, 1] * n0 + R[1, 1] * n1 + R[2, 1] * n2)
    b2 = -(R[0, 2] * n0 + R[1, 2] * n1 + R[2, 2] * n2)
    # min over B of n.(R s + t) = -(max over B's s of b.s) + n.t
    bottom_b = -support_value(fB, b0, b1, b2) + n0 * t[0] + n1 * t[1] + n2 * t[2]
    return upper, bottom_b - top_a


@kernel
def closest_points_newton(pair, start, tol_abs, tol_rel, best_a, best_b, work, mat, step):
    """Newton's method on the closest points of two superellipsoids (see :func:`primal_pair`) from
    start = (x0, x1, x2, y0, y1, y2), points near A and B (A's frame); B at (R, t) in A's frame.

    Returns (converged, steps, upper, lower): on convergence (upper - lower <= tol_abs + tol_rel *
    upper, lower > 0) the witness points on the surfaces are in best_a and best_b (A's frame).
    work: (9, 4) scratch; mat: (17, 4) scratch for the linear system and the powers; step: (2, 4) scratch.
    """
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    x0, x1, x2, y0, y1, y2 = start
    gA = work[0]
    gB = work[1]
    sup = work[2]
    HA = work[3:6]
    HB = work[6:9]
    size = (fA[F_A] + fA[F_B] + fA[F_C] + fB[F_A] + fB[F_B] + fB[F_C]) / 6.0
    lanes = lanes_view(mat, 13)  # rows 13 to 16 of mat
    exponents = lanes_view(mat, 15)
    exponents[0] = exponents[1] = fA[F_P2]
    exponents[2] = fA[F_P1]
    exponents[3] = exponents[4] = fB[F_P2]
    exponents[5] = fB[F_P1]
    exponents[6] = exponents[7] = 1.0
    lam = mu = 0.0
    last = math.inf  # the last step's length
    steps = 0
    upper, lower = math.inf, -math.inf
    while steps < PRIMAL_STEPS:
        steps += 1
        d0, d1, d2 = y0 - t[0], y1 - t[1], y2 - t[2]  # y in B's frame: R^T (y - t)
        yb0 = R[0, 0] * d0 + R[1, 0] * d1 + R[2, 0] * d2
        yb1 = R[0, 1] * d0 + R[1, 1] * d1 + R[2, 1] * d2
        yb2 = R[0, 2] * d0 + R[1, 2] * d1 + R[2, 2] * d2
        # the six coordinate powers in one vectorized call (lanes 6 and 7 idle at 1^1)
        _lanes_in(fA, x0, x1, x2, lanes, 0)
        _lanes_in(fB, yb0, yb1, yb2, lanes, 3)
        lanes[6] = lanes[7] = 1.0
        if last > CERTIFY_STEP * size:
            # no certificate at this step: its points are only the next step's start, whose exact
            # evaluation corrects them (the slab's width is second order in their error)
            rough_powers_in_place(lanes, exponents)
        else:
            powers_in_place(lanes, exponents)
        FA = _implicit_lanes(fA, x0, x1, x2, lanes, 0, gA, HA)
        FB = _implicit_lanes(fB, yb0, yb1, yb2, lanes, 3, sup, HB)
        if not (FA > 0.0 and FB > 0.0 and FA < math.inf and FB < math.inf):
            return False, steps, upper, lower
        FA = _to_gauge(FA, fA[F_E1], gA, HA)
        FB = _to_gauge(FB, fB[F_E1], sup, HB)
        # B's gradient into A's frame
        for r in range(3):
            gB[r] = R[r, 0] * sup[0] + R[r, 1] * sup[1] + R[r, 2] * sup[2]
        if not (FA > 0.0 and FB > 0.0 and FA < math.inf and FB < math.inf):
            return False, steps, upper, lower
        w0, w1, w2 = y0 - x0, y1 - x1, y2 - x2
        gap = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        if steps == 1:
            lam = gap / math.sqrt(gA[0] ** 2 + gA[1] ** 2 + gA[2] ** 2)
            mu = gap / math.sqrt(gB[0] ** 2 + gB[1] ** 2 + gB[2] ** 2)
        if last <= CERTIFY_STEP * size:
            upper, lower = _certify(fB, R, t, (x0, x1, x2), (yb0, yb1, yb2), FA, FB, gA, best_a, best_b)
            if lower > 0.0 and upper - lower <= tol_abs + tol_rel * upper:
                return True, steps, upper, lower
        # Newton's system, with dy = A1 dx + g_A dlam - r1 (its first block row) put into the others:
        # (B1 A1 - I) dx + B1 g_A dlam + g_B dmu = r2 + B1 r1, g_A.dx = r3, A1 g_B.dx + g_A.g_B dlam
        # = r4 + g_B.r1, with A1 = I + lam H_A, B1 = I + mu H_B (A's frame), r = minus the residuals
        HBa = mat[10:13]
        for i in range(3):
            for j in range(3):
                h = 0.0
                for k in range(3):
                    h += R[i, k] * (HB[k, 0] * R[j, 0] + HB[k, 1] * R[j, 1] + HB[k, 2] * R[j, 2])
                HBa[i, j] = h
        r10, r11, r12 = w0 - lam * gA[0], w1 - lam * gA[1], w2 - lam * gA[2]
        for i in range(3):
            for j in range(3):
                c = lam * HA[i, j] + mu * HBa[i, j]
                c += lam * mu * (HBa[i, 0] * HA[0, j] + HBa[i, 1] * HA[1, j] + HBa[i, 2] * HA[2, j])
                _set(mat, i, j, c)
            hg = HBa[i, 0] * gA[0] + HBa[i, 1] * gA[1] + HBa[i, 2] * gA[2]
            hr = HBa[i, 0] * r10 + HBa[i, 1] * r11 + HBa[i, 2] * r12
            _set(mat, i, 3, gA[i] + mu * hg)
            _set(mat, i, 4, gB[i])
            _set(mat, i, 5, -(w0, w1, w2)[i] - mu * gB[i] + (r10, r11, r12)[i] + mu * hr)
            _set(mat, 3, i, gA[i])
            _set(mat, 4, i, gB[i] + lam * (HA[i, 0] * gB[0] + HA[i, 1] * gB[1] + HA[i, 2] * gB[2]))
        _set(mat, 3, 3, 0.0)
        _set(mat, 3, 4, 0.0)
        _set(mat, 3, 5, 1.0 - FA)
        _set(mat, 4, 3, gA[0] * gB[0] + gA[1] * gB[1] + gA[2] * gB[2])
        _set(mat, 4, 4, 0.0)
        _set(mat, 4, 5, 1.0 - FB + gB[0] * r10 + gB[1] * r11 + gB[2] * r12)
        if not _solve(mat, step):
            return False, steps, upper, lower
        dx0, dx1, dx2, dlam, dmu = step[0, 0], step[0, 1], step[0, 2], step[0, 3], step[1, 0]
        dy0 = dx0 + lam * (HA[0, 0] * dx0 + HA[0, 1] * dx1 + HA[0, 2] * dx2) + gA[0] * dlam - r10
        dy1 = dx1 + lam * (HA[1, 0] * dx0 + HA[1, 1] * dx1 + HA[1, 2] * dx2) + gA[1] * dlam - r11
        dy2 = dx2 + lam * (HA[2, 0] * dx0 + HA[2, 1] * dx1 + HA[2, 2] * dx2) + gA[2] * dlam - r12
        x0 += dx0
        x1 += dx1
        x2 += dx2
        y0 += dy0
        y1 += dy1
        y2 += dy2
        lam += dlam
        mu += dmu
        last = math.sqrt(dx0 * dx0 + dx1 * dx1 + dx2 * dx2 + dy0 * dy0 + dy1 * dy1 + dy2 * dy2)
        if not (lam > 0.0 and mu > 0.0 and last < math.inf):
            return False, steps, upper, lower
    return False, steps, upper, lower
