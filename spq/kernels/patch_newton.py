"""Newton's method on a boxy superellipsoid's point nearest an STP-BV: the end of a CSE-STP distance
where Newton on the normal stalls.

Newton on the contact normal (newton_normal) models the lower bound through both support maps'
derivatives. A boxy superellipsoid's (exponents below 1) jumps by orders of magnitude near a face's
normal, so on such pairs the bound creeps and the run falls back to the plain descent (panda_link_2's
covering fit, exponents 0.17 and 0.27, against its STP-BV: a sixth of the runs). Its implicit
function is smooth in space instead (closest_points_newton), and near the answer the STP-BV is one
patch's ball: a small sphere B(p, r), a big sphere B(c, R), or, on a torus patch, the spindle swept
by the balls B(m - a w, R) about the torus axis e (centre m, circle radius a), of which a point x
outside meets the one in its own meridian, w = P (x - m) / s, P = I - e e^T, s = |P (x - m)|. So
the superellipsoid's point x nearest to the STP-BV solves, with c(x) that ball's centre,

    x - c(x) + lam grad G(x) = 0,   G(x) = 1

(G the gauge, G = 1 on the surface, homogeneous of degree 1, as in closest_points_newton): four
equations whose Jacobian is [[M, g], [g^T, 0]], M = I + (a / s) t t^T + lam H (t = e x w; the term
in a is the spindle's centre turning with x, zero on a sphere). M is positive definite (H of a convex
gauge is positive semi-definite, lam > 0), so dx = M^-1 (-r1) - M^-1 g dlam, with dlam from g.dx = -r2.

Every evaluation takes the patch that owns the direction opposite the superellipsoid's normal g at x
(the STP-BV's support there), so the ball follows the point across patch boundaries, and certifies
as closest_points_newton does: the upper bound is the distance from x / G(x) (on the surface) to the
STP-BV's support point s along -g, the lower bound the slab along g between the superellipsoid's
support value 1 / |g| (Euler) and g.s / |g|. Both come with the patch search the step needs anyway.
"""

from __future__ import annotations

import math

from spq.kernels.closest_points_newton import PRIMAL_MAX_EXPONENT, _to_gauge, implicit
from spq.kernels.frames import rot_to_a, rot_to_b, to_a, to_b
from spq.kernels.indexing import at
from spq.kernels.jit import kernel
from spq.kernels.kinds import STP, SUPERELLIPSOID
from spq.kernels.stp_support import IDX_F, IDX_V, _offsets, ball_of_patch, find_patch_near
from spq.kernels.superellipsoid_support import F_E1, F_E2, support_point

# Newton on the superellipsoid's nearest point runs first, before Newton on the normal, where an
# exponent is at most this; elsewhere only after Newton on the normal failed. Evaluations per
# query against kuka_link_4's STP-BV (its box's semi-axes, 600 poses): first at exponents (0.2, 0.2)
# 6.30 against 7.86, (0.3, 0.3) 5.87 against 6.77, (1.0, 0.2) 5.39 against 6.02, but (0.5, 0.5)
# 5.60 against 5.41, (1.0, 0.4) 5.89 against 5.27 and (1.0, 1.0) 5.41 against 4.95.
PATCH_FIRST_EXPONENT = 0.3
PATCH_STEPS = 10  # evaluations before the caller's plain descent takes over
PATCH_HALVINGS = 4  # halvings of a step in a row that raised the upper bound


@kernel(inline="always")
def patch_newton_pair(kA, fA, kB, fB):
    """Whether one body is an STP-BV and the other a superellipsoid with both exponents at most
    PRIMAL_MAX_EXPONENT (its implicit function's Hessian bounded)."""
    if kA == STP and kB == SUPERELLIPSOID:
        return max(fB[F_E1], fB[F_E2]) <= PRIMAL_MAX_EXPONENT
    if kB == STP and kA == SUPERELLIPSOID:
        return max(fA[F_E1], fA[F_E2]) <= PRIMAL_MAX_EXPONENT
    return False


@kernel(inline="always")
def patch_newton_first(kA, fA, kB, fB):
    """Whether the pair is a patch_newton_pair whose superellipsoid has an exponent at most
    PATCH_FIRST_EXPONENT."""
    if not patch_newton_pair(kA, fA, kB, fB):
        return False
    f = fB if kA == STP else fA
    return min(f[F_E1], f[F_E2]) <= PATCH_FIRST_EXPONENT


@kernel
def patch_newton(pair, n, tol_abs, tol_rel, best_a, best_b, work, hints):
    """Newton's method on the superellipsoid's point nearest the STP-BV (see :func:`patch_newton_pair`),
    from the unit normal n (A to B, A's frame) of a separated pair; B at (R, t) in A's frame.

    Returns (converged, evaluations, upper, lower, m0, m1, m2) as newton_normal does: on convergence
    (upper - lower <= tol_abs + tol_rel * upper, lower > 0) the witness points are in best_a and
    best_b (A's frame) and m is the normal (A to B) there. work: (8, 4) scratch. hints: int64 (2,),
    the patch the STP-BV's (A: 0, B: 1) search starts from, left on its last patch."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    g = work[0]
    H = work[1:4]
    Q = work[4:7]  # the STP-BV's frame into the superellipsoid's: Q y + q
    q = work[7]
    cse_a = kA == SUPERELLIPSOID
    if cse_a:
        fX, fS, iS, slot = fA, fB, iB, 1
        for r in range(3):
            for c in range(3):
                Q[r, c] = R[r, c]
            q[r] = t[r]
        v0, v1, v2 = n
    else:
        fX, fS, iS, slot = fB, fA, iA, 0
        for r in range(3):
            for c in range(3):
                Q[r, c] = R[c, r]
            q[r] = -(R[0, r] * t[0] + R[1, r] * t[1] + R[2, r] * t[2])
        v0, v1, v2 = rot_to_b(R, -n[0], -n[1], -n[2])  # from B towards A, B's frame
    x0, x1, x2 = support_point(fX, v0, v1, v2)
    V, F = iS[IDX_V], iS[IDX_F]
    o_tori = _offsets(iS)[1]
    upper, lower = math.inf, -math.inf
    accepted = math.inf  # the upper bound at the last accepted point a, from which the step f was taken
    a0, a1, a2 = x0, x1, x2
    f0 = f1 = f2 = 0.0
    halvings = 0
    m0, m1, m2 = n
    evaluations = 0
    while evaluations < PATCH_STEPS:
        evaluations += 1
        G = implicit(fX, x0, x1, x2, g, H)
        if not (G > 0.0 and G < math.inf):
            break
        G = _to_gauge(G, fX[F_E1], g, H)
        gn = math.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
        if not (G > 0.0 and G < math.inf and gn > 0.0 and gn < math.inf):
            break
        n0, n1, n2 = g[0] / gn, g[1] / gn, g[2] / gn  # the superellipsoid's normal, towards the STP-BV
        u0, u1, u2 = rot_to_b(Q, -n0, -n1, -n2)  # the STP-BV's support direction, its frame
        p = find_patch_near(fS, iS, hints[slot], u0, u1, u2)
        hints[slot] = p
        c0, c1, c2, rad = ball_of_patch(fS, iS, p, u0, u1, u2)
        s0, s1, s2 = to_a(Q, q, c0 + rad * u0, c1 + rad * u1, c2 + rad * u2)
        k = 1.0 / G
        z0, z1, z2 = x0 * k, x1 * k, x2 * k  # x on the surface
        up = math.sqrt((s0 - z0) ** 2 + (s1 - z1) ** 2 + (s2 - z2) ** 2)
        lo = n0 * s0 + n1 * s1 + n2 * s2 - 1.0 / gn
        if up < upper:
            upper = up
            lower = max(lower, lo)
            if cse_a:
                best_a[0], best_a[1], best_a[2] = z0, z1, z2
                best_b[0], best_b[1], best_b[2] = s0, s1, s2
                m0, m1, m2 = n0, n1, n2
            else:
                best_b[0], best_b[1], best_b[2] = to_a(R, t, z0, z1, z2)
                best_a[0], best_a[1], best_a[2] = to_a(R, t, s0, s1, s2)
                m0, m1, m2 = rot_to_a(R, -n0, -n1, -n2)
        else:
            lower = max(lower, lo)
        if lower > 0.0 and upper - lower <= tol_abs + tol_rel * upper:
            return True, evaluations, upper, lower, m0, m1, m2
        if up > accepted and halvings < PATCH_HALVINGS:
            # the step crossed into patches whose balls its model did not see and overshot: back
            # towards the last accepted point (two balls' steps can otherwise swap forever)
            halvings += 1
            f0, f1, f2 = 0.5 * f0, 0.5 * f1, 0.5 * f2
            x0, x1, x2 = a0 + f0, a1 + f1, a2 + f2
            continue
        halvings = 0
        accepted = up
        a0, a1, a2 = x0, x1, x2
        # the ball's centre c(x) and M's spindle term (a / s) t t^T, in the superellipsoid's frame
        spin = 0.0
        t0 = t1 = t2 = 0.0
        if p >= V + F:
            kt = o_tori + 7 * (p - V - F)
            y0, y1, y2 = to_b(Q, q, x0, x1, x2)
            y0, y1, y2 = y0 - fS[at(kt)], y1 - fS[at(kt + 1)], y2 - fS[at(kt + 2)]
            e0, e1, e2, a = fS[at(kt + 3)], fS[at(kt + 4)], fS[at(kt + 5)], fS[at(kt + 6)]
            de = y0 * e0 + y1 * e1 + y2 * e2
            w0, w1, w2 = y0 - de * e0, y1 - de * e1, y2 - de * e2
            sw = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
            if not (sw > 0.0):
                break
            w0, w1, w2 = w0 / sw, w1 / sw, w2 / sw
            c0, c1, c2 = fS[at(kt)] - a * w0, fS[at(kt + 1)] - a * w1, fS[at(kt + 2)] - a * w2
            spin = a / sw
            t0, t1, t2 = rot_to_a(Q, e1 * w2 - e2 * w1, e2 * w0 - e0 * w2, e0 * w1 - e1 * w0)
        c0, c1, c2 = to_a(Q, q, c0, c1, c2)
        d0, d1, d2 = x0 - c0, x1 - c1, x2 - c2
        # the multiplier that fits x - c best (least squares): the ball changes with the patch (from
        # r to R about its centre), and a multiplier kept from another patch's ball sends the step astray
        lam = -(d0 * g[0] + d1 * g[1] + d2 * g[2]) / (gn * gn)
        # minus the residuals: -(x - c + lam g), 1 - G
        r0, r1, r2, r3 = -(d0 + lam * g[0]), -(d1 + lam * g[1]), -(d2 + lam * g[2]), 1.0 - G
        a00 = 1.0 + spin * t0 * t0 + lam * H[0, 0]
        a01 = spin * t0 * t1 + lam * H[0, 1]
        a02 = spin * t0 * t2 + lam * H[0, 2]
        a11 = 1.0 + spin * t1 * t1 + lam * H[1, 1]
        a12 = spin * t1 * t2 + lam * H[1, 2]
        a22 = 1.0 + spin * t2 * t2 + lam * H[2, 2]
        k00, k01, k02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
        k11, k12, k22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
        det = a00 * k00 + a01 * k01 + a02 * k02
        if not (det > 0.0 and det < math.inf):
            break
        # M^-1 (-r1) and M^-1 g, each times det
        b0, b1, b2 = k00 * r0 + k01 * r1 + k02 * r2, k01 * r0 + k11 * r1 + k12 * r2, k02 * r0 + k12 * r1 + k22 * r2
        h0 = k00 * g[0] + k01 * g[1] + k02 * g[2]
        h1 = k01 * g[0] + k11 * g[1] + k12 * g[2]
        h2 = k02 * g[0] + k12 * g[1] + k22 * g[2]
        gh = g[0] * h0 + g[1] * h1 + g[2] * h2
        if not (gh > 0.0):
            break
        dlam = (g[0] * b0 + g[1] * b1 + g[2] * b2 - det * r3) / gh
        f0, f1, f2 = (b0 - h0 * dlam) / det, (b1 - h1 * dlam) / det, (b2 - h2 * dlam) / det
        x0, x1, x2 = a0 + f0, a1 + f1, a2 + f2
        if not (abs(x0) + abs(x1) + abs(x2) < math.inf):
            break
    return False, evaluations, upper, lower, m0, m1, m2
