"""Newton's method on the contact normal: the end of a distance between two smooth, strictly convex bodies.

GJK converges only linearly between curved surfaces (about 15 iterations to 1e-10 between two
superellipsoids), because its simplex is a polytope approximating them. Near the answer the unit
normal n (from A to B, A's frame) instead solves P_n s_D(n) = 0, where s_D(n) = s_A(n) - s_B(-n) is
the support of A - B and P_n the projection on the plane orthogonal to n: the two support points
face each other along n. In a tangent basis E of n the derivative of that residual is
E^T (J_A + R J_B R^T) E + rho I, with J the support maps' derivatives (positive semi-definite) and
rho = -s_D(n).n > 0 the separating-plane bound, so Newton's steps are well defined while the
bodies are apart and converge quadratically from a rough normal: the caller's GJK between polytopes
inscribed in the two bodies (an overlap of those is the bodies' overlap) gives one cheaply.

Every step's support points give an upper bound (their distance) and its plane a lower bound, so
the result is certified exactly as GJK's is. A step that lowers the lower bound is halved (flat
sides, where a support map moves like a root of its direction, make full steps overshoot), and so is
one that raises it much less than its slope predicts (see SUFFICIENT); when that fails too, the
caller resumes GJK from the best normal found.
"""

from __future__ import annotations

import math

from spq.kernels.jit import kernel
from spq.kernels.kinds import STP, SUPERELLIPSOID
from spq.kernels.stp_support import stp_support_curvature
from spq.kernels.superellipsoid_support import F_E1, F_E2, superellipsoid_support_jacobian

NEWTON_EVALUATIONS = 12  # support pairs (with derivatives) before the caller's GJK takes over
NEWTON_HALVINGS = 4  # shortenings of a step in a row (see SUFFICIENT) before giving up
INNER_REL_TOL = 1e-2  # relative tolerance of the GJK between the inner polytopes that gives the start normal
SHORTEST = 0.1  # smallest factor a halving may shrink the step by (the parabola's maximum can sit near 0)
GROWTH = 1.5  # the step fraction regrows by this after an accepted step, up to a full Newton step
# A step is accepted only if it raises the lower bound by at least this fraction of the rise its
# slope predicts (a full Newton step on a quadratic model rises by half of it). Between flat sides,
# where a support map moves like a root of its direction, full steps can swap the normal between
# two sides of the answer with the bound barely rising: without this, about 4% of the separated
# boxy pairs of Table I (exponents 0.5, 0.6) ran out of evaluations that way and went to the
# plain GJK; with it, 0.3%. A quarter did as well there, but sent a few more pairs of the fitted
# cover (exponents 0.42, 1.02) to the plain GJK than no such test did; a tenth about as many.
SUFFICIENT = 0.1


@kernel(inline="always")
def _smooth_superellipsoid(k, f):
    return k == SUPERELLIPSOID and f[F_E1] < 2.0 and f[F_E2] < 2.0


@kernel(inline="always")
def smooth_pair(kA, fA, kB, fB):
    """Whether both bodies are superellipsoids with support maps with a bounded derivative almost
    everywhere."""
    return _smooth_superellipsoid(kA, fA) and _smooth_superellipsoid(kB, fB)


@kernel(inline="always")
def smooth_against_stp(kA, fA, kB, fB):
    """Whether one body is an STP-BV and the other such a superellipsoid: two curved sides, where
    GJK converges only linearly (Table I's CSE-STP)."""
    return ((kA == STP and _smooth_superellipsoid(kB, fB))
            or (kB == STP and _smooth_superellipsoid(kA, fA)))


@kernel(inline="always")
def _side(k, f, ix, d0, d1, d2, hints, slot, out, jac):
    """One body's support along the unit d and its derivative (see _evaluate); an STP-BV's search
    starts from hints[slot] and leaves its patch there. An STP-BV's derivative is stored compact
    (stp_support_curvature): jac[0, 0] = rad, jac[0, 1] = s, jac[1] = t; a superellipsoid's in full."""
    if k == STP:
        p, rad, s, t0, t1, t2 = stp_support_curvature(f, ix, d0, d1, d2, hints[slot], out)
        hints[slot] = p
        jac[0, 0], jac[0, 1] = rad, s
        jac[1, 0], jac[1, 1], jac[1, 2] = t0, t1, t2
        return True
    return superellipsoid_support_jacobian(f, d0, d1, d2, out, jac)


@kernel
def _evaluate(pair, n0, n1, n2, pa, pb, tmp, JA, JB, hints):
    """Support points pa = s_A(n), pb = s_B(-n) (A's frame) and their derivatives JA, JB (JB in
    B's frame, each as _side stores it); False where a derivative does not exist."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    ok_a = _side(kA, fA, iA, n0, n1, n2, hints, 0, pa, JA)
    b0 = -(R[0, 0] * n0 + R[1, 0] * n1 + R[2, 0] * n2)
    b1 = -(R[0, 1] * n0 + R[1, 1] * n1 + R[2, 1] * n2)
    b2 = -(R[0, 2] * n0 + R[1, 2] * n1 + R[2, 2] * n2)
    ok_b = _side(kB, fB, iB, b0, b1, b2, hints, 1, tmp, JB)
    for r in range(3):
        pb[r] = R[r, 0] * tmp[0] + R[r, 1] * tmp[1] + R[r, 2] * tmp[2] + t[r]
    return ok_a and ok_b


@kernel(inline="always")
def tangent_basis(n0, n1, n2):
    """Two unit vectors completing the unit n to an orthonormal basis."""
    if abs(n0) < 0.6:
        x0, x1, x2 = 0.0, n2, -n1  # n x (1, 0, 0)
    else:
        x0, x1, x2 = -n2, 0.0, n0  # n x (0, 1, 0)
    k = 1.0 / math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    x0, x1, x2 = x0 * k, x1 * k, x2 * k
    return x0, x1, x2, n1 * x2 - n2 * x1, n2 * x0 - n0 * x2, n0 * x1 - n1 * x0


@kernel(inline="always")
def _form(JA, JB, R, x0, x1, x2, y0, y1, y2):
    """x^T (JA + R JB R^T) y, both derivatives in full (two superellipsoids)."""
    s = 0.0
    bx0 = R[0, 0] * x0 + R[1, 0] * x1 + R[2, 0] * x2
    bx1 = R[0, 1] * x0 + R[1, 1] * x1 + R[2, 1] * x2
    bx2 = R[0, 2] * x0 + R[1, 2] * x1 + R[2, 2] * x2
    by0 = R[0, 0] * y0 + R[1, 0] * y1 + R[2, 0] * y2
    by1 = R[0, 1] * y0 + R[1, 1] * y1 + R[2, 1] * y2
    by2 = R[0, 2] * y0 + R[1, 2] * y1 + R[2, 2] * y2
    xs = (x0, x1, x2)
    ys = (y0, y1, y2)
    bxs = (bx0, bx1, bx2)
    bys = (by0, by1, by2)
    for i in range(3):
        for j in range(3):
            s += xs[i] * JA[i, j] * ys[j] + bxs[i] * JB[i, j] * bys[j]
    return s


@kernel(inline="always")
def _forms(k, J, x0, x1, x2, y0, y1, y2):
    """(x^T J x, x^T J y, y^T J y) of one side's derivative J (stored as _side stores it, in the side's
    frame) for orthonormal x, y orthogonal to the side's direction (its frame too): for an STP-BV,
    rad (x.y) - s (t.x)(t.y), the direction's own term u u^T vanishing across it."""
    if k == STP:
        tx = J[1, 0] * x0 + J[1, 1] * x1 + J[1, 2] * x2
        ty = J[1, 0] * y0 + J[1, 1] * y1 + J[1, 2] * y2
        rad, s = J[0, 0], J[0, 1]
        return rad - s * tx * tx, -s * tx * ty, rad - s * ty * ty
    xs = (x0, x1, x2)
    ys = (y0, y1, y2)
    xx = xy = yy = 0.0
    for i in range(3):
        for j in range(3):
            xx += xs[i] * J[i, j] * xs[j]
            xy += xs[i] * J[i, j] * ys[j]
            yy += ys[i] * J[i, j] * ys[j]
    return xx, xy, yy


@kernel(inline="always")
def _system(kA, JA, kB, JB, R, b0, b1, b2, e0, e1, e2):
    """(b^T M b, b^T M e, e^T M e) for M = JA + R JB R^T, the tangent basis (b, e) in A's frame."""
    if kA != STP and kB != STP:
        return (_form(JA, JB, R, b0, b1, b2, b0, b1, b2), _form(JA, JB, R, b0, b1, b2, e0, e1, e2),
                _form(JA, JB, R, e0, e1, e2, e0, e1, e2))
    xa, ya, za = _forms(kA, JA, b0, b1, b2, e0, e1, e2)
    xb, yb, zb = _forms(kB, JB, R[0, 0] * b0 + R[1, 0] * b1 + R[2, 0] * b2, R[0, 1] * b0 + R[1, 1] * b1 + R[2, 1] * b2,
                        R[0, 2] * b0 + R[1, 2] * b1 + R[2, 2] * b2, R[0, 0] * e0 + R[1, 0] * e1 + R[2, 0] * e2,
                        R[0, 1] * e0 + R[1, 1] * e1 + R[2, 1] * e2, R[0, 2] * e0 + R[1, 2] * e1 + R[2, 2] * e2)
    return xa + xb, ya + yb, za + zb


@kernel
def newton_normal(pair, n, lower, tol_abs, tol_rel, best_a, best_b, work, hints):
    """Newton's method from the unit normal n (A to B, A's frame) of a separated pair of smooth
    bodies (see :func:`smooth_pair` and :func:`smooth_against_stp`), B at (R, t) in A's frame.

    Returns (converged, evaluations, upper, lower, m0, m1, m2): the best upper bound, whose support
    points are left in best_a and best_b (A's frame), the best lower bound (at least ``lower``) and
    the normal to resume from. converged: upper - lower <= tol_abs + tol_rel * upper.
    work: (9, 3) scratch. hints: int64 (2,), the patches an STP-BV side (A: 0, B: 1) starts its
    searches from (-1: none), left on its last patches.
    """
    kA, kB, R = pair[0], pair[4], pair[8]
    n0, n1, n2 = n
    pa = work[0]
    pb = work[1]
    tmp = work[2]
    JA = work[3:6]
    JB = work[6:9]
    upper = math.inf
    accepted = -math.inf  # the lower bound at the last accepted normal m
    m0, m1, m2 = n0, n1, n2
    evaluations = 0
    step0 = step1 = 0.0
    b0 = b1 = b2 = e0 = e1 = e2 = 0.0
    halvings = 0
    scale = 1.0  # the fraction of Newton's step taken: shrinks where steps overshot
    slope = 0.0  # the lower bound's derivative along the current step, at m
    while evaluations < NEWTON_EVALUATIONS:
        evaluations += 1
        ok = _evaluate(pair, n0, n1, n2, pa, pb, tmp, JA, JB, hints)
        s0, s1, s2 = pa[0] - pb[0], pa[1] - pb[1], pa[2] - pb[2]
        lo = -(s0 * n0 + s1 * n1 + s2 * n2)
        up = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        if up < upper:
            upper = up
            for c in range(3):
                best_a[c] = pa[c]
                best_b[c] = pb[c]
        if upper - max(lower, lo) <= tol_abs + tol_rel * upper:
            return True, evaluations, upper, max(lower, lo), n0, n1, n2
        if lo < accepted + SUFFICIENT * slope:  # the step overshot or stalled: shorten it (from m)
            lower = max(lower, lo)
            halvings += 1
            if halvings > NEWTON_HALVINGS:
                break
            # the maximum of the parabola through the bound and its slope at m and the bound here
            alpha = min(max(0.5 * slope / (accepted + slope - lo), SHORTEST), 0.5)
            scale *= alpha
            slope *= alpha
            step0 *= alpha
            step1 *= alpha
            n0, n1, n2 = step_on_sphere(m0, m1, m2, b0, b1, b2, e0, e1, e2, step0, step1)
            continue
        lower = max(lower, lo)
        if not ok or not (lo > 0.0):
            break
        halvings = 0
        accepted = lo
        m0, m1, m2 = n0, n1, n2
        b0, b1, b2, e0, e1, e2 = tangent_basis(n0, n1, n2)
        a00, a01, a11 = _system(kA, JA, kB, JB, R, b0, b1, b2, e0, e1, e2)
        a00 += lo
        a11 += lo
        r0 = -(b0 * s0 + b1 * s1 + b2 * s2)
        r1 = -(e0 * s0 + e1 * s1 + e2 * s2)
        det = a00 * a11 - a01 * a01
        if not (det > 0.0):
            break
        step0 = scale * (a11 * r0 - a01 * r1) / det
        step1 = scale * (a00 * r1 - a01 * r0) / det
        slope = r0 * step0 + r1 * step1
        scale = min(1.0, GROWTH * scale)
        n0, n1, n2 = step_on_sphere(m0, m1, m2, b0, b1, b2, e0, e1, e2, step0, step1)
    return False, evaluations, upper, lower, m0, m1, m2


@kernel(inline="always")
def step_on_sphere(m0, m1, m2, b0, b1, b2, e0, e1, e2, x, y):
    """The unit vector along m + x b + y e."""
    n0 = m0 + x * b0 + y * e0
    n1 = m1 + x * b1 + y * e1
    n2 = m2 + x * b2 + y * e2
    k = 1.0 / math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    return n0 * k, n1 * k, n2 * k
