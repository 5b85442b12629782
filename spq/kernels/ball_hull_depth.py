"""The depth between two ball hulls (STP-BVs, spheres) from their sets of admissible centres.

An STP-BV's support is s(v) = c*(v) + R v for unit v, c* minimising v.c over Q, its admissible
big-sphere centres (NOTES section 1): h(v) = R - h_Q(-v). A point core (a sphere's) is the case
Q = {0}, R = 0. So for two such cores, with B at (R, t) in A's frame, D = A - B has

    h_D(u) = S - h_E(u),  S = R_A + R_B,  E = Q_B - Q_A (both in A's frame),

and the depth min over unit u of h_D(u) is S - max over e in E of |e|. Near their least R the sets of
centres are small (millimetres for a body of a metre) while D is nearly a ball of radius S: there
the EPA's polytope, inscribed in a round D, closes only as its faces shrink everywhere, and where the
deepest normal lies on a torus band no sphere cap certifies it (spq.kernels.epa_caps): two STP-BVs
near their least R, one inside the other, left a gap of 1e-4 m after the EPA's 4072 expansions
(tests/fixtures/fuzz/stp-min-R-signed-failed-5.json).

E is small and nearly polyhedral (its faces are pieces of spheres of radius R - r), so the bound
is taken there instead: an outer polytope P of E, cut by the planes u.x <= h_E(u) (each holds E),
bounds max |e| from above by its farthest vertex, and each cut is made along that vertex's
direction (Kelley's cutting planes), which also bounds max |e| from below by h_E there. Where the
farthest point of E is a vertex of E the cuts meet it exactly; on an edge or a face of E they close
at a rate set by E's curvature, a few hundred cuts at most for 1e-10.

P is kept as its vertices, each the meeting point of three planes (a simple polytope: the cut
planes come from directions in floating point, so four planes through one point do not happen
except where a cut passes through vertices already there, which are then kept by loosening the cut).
Two vertices are joined by an edge when they share two planes. Each plane's offset is loosened by
the rounding of S - h_D, and each computed vertex x carries a bound E on its distance to the exact
meeting point x* of its stored planes (Cramer's rule: about eps |h| / det, large where the planes are
nearly parallel, as they are near the answer). Along a unit d with d = U^T mu (U the planes' normals)
the error is smaller: d.(x* - x) = -mu.r with r = U x - h the residuals, which is the bound used
(_error_along) for the farthest vertex's norm, |x*| <= |x| + |mu.r| + E^2 / (2 |x|), and for which
side of a cut a vertex lies on.

One ball hull against any other convex body Y (a polytope, a superellipsoid) is the same bound with
another objective: with A the ball hull, h_A(n) = R - h_Q(-n), so

    sd = max over c in Q of sd_Y(c) - R,

sd_Y the signed distance of a point to Y, convex and 1-Lipschitz (with B the ball hull, Q is B's set of
centres in A's frame and Y is A). An STP-BV near its least R holding a small body deep inside (the fuzz
reproducer stp-min-R-signed-failed-7) makes D nearly a sphere piece about a point a few millimetres from
the origin, where the EPA runs out of vertices; over Q, millimetres wide and nearly polyhedral, sd_Y is
nearly linear and the cuts close in a few steps. Each vertex x of P is bounded by a point query (a plain
descent between x and Y): for the point y of Y it ends on, g = (x - y) / |x - y| and the vertex's error
bound E, sd_Y(x*) <= |x* - y| <= |x - y| + |g.(x* - x)| + E^2 / (2 |x - y|), the norm's bound again (a
descent stopped short still gives a valid bound: y is a point of Y). The cut is made along g, where the
support of Q bounds max sd_Y from below by h_Q(g) - h_Y(g) = R - h_D(+-g). A farthest vertex inside Y
ends it: how far inside is not known there.

The EPA tries these bounds once midway through a run with a ball hull on a side (spq.kernels.epa.CENTRES_AFTER,
with fewer cuts), not only after a run that failed: P lives in the upper halves of the EPA's blocks, so the run
goes on from its own polytope where they do not close.
"""

from __future__ import annotations

import math

from spq.kernels.epa_layout import (
    EPA_ALIVE,
    EPA_CORNERS,
    EPA_DEAD,
    EPA_MAX_FACES,
    EPA_MAX_VERTICES,
    EPA_PA,
    EPA_PB,
    EPA_TMP,
    EPA_W,
)
from spq.kernels.gjk import (
    DESCENT_ROWS,
    EPA_IOFF,
    EPA_ROW,
    OUT_NORMAL,
    OVERLAPPING,
    WARM_SIZE,
    clear_warm,
    descend,
    minkowski_support,
)
from spq.kernels.jit import kernel
from spq.kernels.kinds import POINT, STP, STP_CORE
from spq.kernels.signed_out import bounds_closed, set_result, supports_as_witnesses
from spq.kernels.stp_support import F_BIG_R, F_R

MAX_CUTS = 600  # planes of P beyond the first six; each adds at most a few vertices
# P lives in the upper half of the EPA's vertex blocks (its planes in the w rows, its vertices in the
# rows of the points of A and of B) and in the int entries of the upper half of its face slots, so
# that a run of the EPA whose polytope still fits the lower halves keeps it through an attempt here
# (spq.kernels.epa.epa_run tries the centres once, after CENTRES_AFTER expansions)
SLOT0 = EPA_MAX_VERTICES // 2  # P's first vertex and plane slot in the EPA's vertex blocks
FACE0 = EPA_MAX_FACES // 2  # P's first slot in the EPA's per-face int blocks
MAX_VERTICES = EPA_MAX_VERTICES - SLOT0  # P's vertices
MAX_PLANES = EPA_MAX_VERTICES - SLOT0  # P's planes
PLANE_ROW = EPA_ROW + EPA_W + SLOT0
PA_ROW = EPA_ROW + EPA_PA + SLOT0  # a vertex: its point and error bound
PB_ROW = EPA_ROW + EPA_PB + SLOT0  # a vertex: its point query's normal and bound
CORNERS = EPA_IOFF + EPA_CORNERS + 3 * FACE0  # a vertex: its three planes
ALIVE = EPA_IOFF + EPA_ALIVE + FACE0
DEAD = EPA_IOFF + EPA_DEAD  # scratch of a cut (an EPA step's scratch too)
ROUNDING = 1e-14  # relative: rounding of a support value (a few dozen ulps of the bodies' scale)
EPS = 2.0 ** -52
CRAMER_ERR = 64.0 * EPS  # relative error bound of a vertex from three planes (Cramer's rule)
BH_OK, BH_NOT_BALLS, BH_DEGENERATE, BH_BUDGET = 0, 1, 2, 3
# what is bounded: E = Q_B - Q_A (both sides ball hulls), or one side's Q against the other body
BOTH_BALLS, BALL_A, BALL_B, NO_BALLS = 0, 1, 2, 3
POINT_QUERY_ITERATIONS = 256  # a point's descent against a curved body closes in a few dozen


@kernel(inline="always")
def is_ball_hull(kind):
    """Whether a core's support is R v plus a support of a convex set of centres (an STP-BV, its core:
    the ball hull at R - r, a point)."""
    return kind == STP or kind == STP_CORE or kind == POINT


@kernel(inline="always")
def ball_radius(kind, f):
    if kind == STP:
        return f[F_BIG_R]
    return f[F_BIG_R] - f[F_R] if kind == STP_CORE else 0.0


@kernel(inline="always")
def ball_sides(kA, kB):
    """Which sides are ball hulls: BOTH_BALLS, BALL_A, BALL_B or NO_BALLS."""
    if is_ball_hull(kA):
        return BOTH_BALLS if is_ball_hull(kB) else BALL_A
    return BALL_B if is_ball_hull(kB) else NO_BALLS


@kernel
def _centre_support(pair, S, u0, u1, u2, warm, work):
    """(h_E(u) loosened by its rounding, h_E(u)) for u of any length: S |u| - u.(s_A(u) - s_B(-u))."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    pa = work[EPA_ROW + EPA_TMP]
    pb = work[EPA_ROW + EPA_TMP + 1]
    tmp = work[EPA_ROW + EPA_TMP + 2]
    minkowski_support(pair, u0, u1, u2, warm, pa, pb, tmp)
    nu = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    hd = u0 * (pa[0] - pb[0]) + u1 * (pa[1] - pb[1]) + u2 * (pa[2] - pb[2])
    scale = abs(pa[0]) + abs(pa[1]) + abs(pa[2]) + abs(pb[0]) + abs(pb[1]) + abs(pb[2])
    h = S * nu - hd
    return h + ROUNDING * (S + scale) * nu, h


@kernel
def _cut_support(pair, sides, S, u0, u1, u2, warm, work):
    """Along unit u: (the cut's offset, the support of the set cut, loosened by its rounding; a lower
    bound on the objective's max; the unit normal d along which sd >= that bound - S, as -h_D(d)).
    BOTH_BALLS: the set is E, the objective |e|, both h_E(u). BALL_A: the set is Q_A, the objective
    sd_B, whose max is at least h_Q(u) - h_B(u) = S - h_D(-u); BALL_B: Q_B and sd_A, S - h_D(u)."""
    if sides == BOTH_BALLS:
        hl, h = _centre_support(pair, S, u0, u1, u2, warm, work)
        return hl, h, u0, u1, u2
    pa = work[EPA_ROW + EPA_TMP]
    pb = work[EPA_ROW + EPA_TMP + 1]
    tmp = work[EPA_ROW + EPA_TMP + 2]
    s = -1.0 if sides == BALL_A else 1.0
    minkowski_support(pair, s * u0, s * u1, s * u2, warm, pa, pb, tmp)
    ua = u0 * pa[0] + u1 * pa[1] + u2 * pa[2]
    ub = u0 * pb[0] + u1 * pb[1] + u2 * pb[2]
    hq, hy = (S + ua, ub) if sides == BALL_A else (S + ub, ua)
    scale = abs(pa[0]) + abs(pa[1]) + abs(pa[2]) + abs(pb[0]) + abs(pb[1]) + abs(pb[2])
    return hq + ROUNDING * (S + scale), hq - hy, s * u0, s * u1, s * u2


@kernel
def _point_query(pair, sides, v, tol_abs, tol_rel, work, iw):
    """For vertex v of P (BALL_A or BALL_B): an upper bound on the objective sd_Y at the exact vertex, and
    the unit normal g of Y's boundary towards it (its gradient), from a plain descent between the point
    and Y; kept in the vertex's EPA_PB row, computed once. A point inside Y is bounded by its error
    alone (sd_Y <= 0), its normal set to zero: centre_set_bounds then gives up."""
    prow = PB_ROW + v
    if work[prow, 3] == work[prow, 3]:
        return work[prow, 3]
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    row = PA_ROW + v
    x0, x1, x2, err = work[row, 0], work[row, 1], work[row, 2], work[row, 3]
    g0, g1, g2 = work[prow, 0], work[prow, 1], work[prow, 2]  # the cut's normal that made v: a start
    shift = work[DESCENT_ROWS, 0:3]
    start = work[DESCENT_ROWS + 1, 0:3]
    warm = iw[WARM_SIZE:EPA_IOFF]
    clear_warm(warm)
    s = 1.0 if sides == BALL_A else -1.0  # the descent's closest point is s |x - y| g
    start[0], start[1], start[2] = -s * g0, -s * g1, -s * g2
    if sides == BALL_A:  # the point at A's origin shifted by x: B moves by -x
        shift[0], shift[1], shift[2] = t[0] - x0, t[1] - x1, t[2] - x2
        sub = (POINT, 0.0, fA, iA, kB, 0.0, fB, iB, R, shift)
    else:
        shift[0], shift[1], shift[2] = x0, x1, x2
        sub = (kA, 0.0, fA, iA, POINT, 0.0, fB, iB, R, shift)
    status, k, v0, v1, v2, vv, lower, it = descend(sub, (tol_abs, tol_rel, POINT_QUERY_ITERATIONS), start, warm, work)
    # (any point of Y bounds sd_Y from above, so a descent stopped short still gives a valid bound)
    scale = abs(x0) + abs(x1) + abs(x2) + abs(t[0]) + abs(t[1]) + abs(t[2])
    if status == OVERLAPPING or not vv > 0.0:
        # inside Y: sd_Y <= 0 there, but how far below is not known; a zero normal says so
        g0 = g1 = g2 = 0.0
        bound = err + ROUNDING * scale
    else:
        upper = math.sqrt(vv)
        g0, g1, g2 = s * v0 / upper, s * v1 / upper, s * v2 / upper
        if upper > err:
            # y, the descent's point of Y, has x - y = upper g: sd_Y(x*) <= |x* - y| <= upper + |g.(x* - x)|
            # + |x* - x|^2 / (2 upper)
            bound = upper + _error_along(work, iw, v, g0, g1, g2) + err * err / (2.0 * upper)
        else:
            bound = upper + err
        bound = bound * (1.0 + 4.0 * EPS) + ROUNDING * (upper + scale)
    work[prow, 0], work[prow, 1], work[prow, 2], work[prow, 3] = g0, g1, g2, bound
    return bound


@kernel(inline="always")
def _plane(work, p):
    row = PLANE_ROW + p
    return work[row, 0], work[row, 1], work[row, 2], work[row, 3]


@kernel(inline="always")
def _residual(a0, a1, a2, h, y0, y1, y2):
    """(u.y - h, a bound on the rounding of its evaluation)."""
    ya = abs(y0) + abs(y1) + abs(y2)
    return a0 * y0 + a1 * y1 + a2 * y2 - h, 4.0 * EPS * (ya * (abs(a0) + abs(a1) + abs(a2)) + abs(h))


@kernel(inline="always")
def _corner_system(work, p, q, r):
    """The planes p, q, r (normals a, b, c and offsets h), then the columns of det U^-1 (b x c, c x a,
    a x b) and det U, U the matrix of rows a, b, c."""
    a0, a1, a2, ha = _plane(work, p)
    b0, b1, b2, hb = _plane(work, q)
    c0, c1, c2, hc = _plane(work, r)
    x00, x01, x02 = b1 * c2 - b2 * c1, b2 * c0 - b0 * c2, b0 * c1 - b1 * c0
    x10, x11, x12 = c1 * a2 - c2 * a1, c2 * a0 - c0 * a2, c0 * a1 - c1 * a0
    x20, x21, x22 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
    det = a0 * x00 + a1 * x01 + a2 * x02
    return a0, a1, a2, ha, b0, b1, b2, hb, c0, c1, c2, hc, x00, x01, x02, x10, x11, x12, x20, x21, x22, det


@kernel
def _set_vertex(work, iw, v, p, q, r):
    """Vertex slot v := the meeting point of planes p, q, r, with a bound on its error; False if they do
    not meet in one point. Cramer's rule, then two steps of refinement on the residuals: near the
    answer the planes are nearly parallel (det about 1e-9), where Cramer's point alone misses its own
    planes by about eps / det."""
    (a0, a1, a2, ha, b0, b1, b2, hb, c0, c1, c2, hc,
     x00, x01, x02, x10, x11, x12, x20, x21, x22, det) = _corner_system(work, p, q, r)
    if not abs(det) > 16.0 * EPS:
        return False
    y0 = (ha * x00 + hb * x10 + hc * x20) / det
    y1 = (ha * x01 + hb * x11 + hc * x21) / det
    y2 = (ha * x02 + hb * x12 + hc * x22) / det
    for _ in range(2):
        ra, _e = _residual(a0, a1, a2, ha, y0, y1, y2)
        rb, _e = _residual(b0, b1, b2, hb, y0, y1, y2)
        rc, _e = _residual(c0, c1, c2, hc, y0, y1, y2)
        y0 -= (ra * x00 + rb * x10 + rc * x20) / det
        y1 -= (ra * x01 + rb * x11 + rc * x21) / det
        y2 -= (ra * x02 + rb * x12 + rc * x22) / det
    ra, ea = _residual(a0, a1, a2, ha, y0, y1, y2)
    rb, eb = _residual(b0, b1, b2, hb, y0, y1, y2)
    rc, ec = _residual(c0, c1, c2, hc, y0, y1, y2)
    n0 = math.sqrt(x00 * x00 + x01 * x01 + x02 * x02) + 4.0 * EPS
    n1 = math.sqrt(x10 * x10 + x11 * x11 + x12 * x12) + 4.0 * EPS
    n2 = math.sqrt(x20 * x20 + x21 * x21 + x22 * x22) + 4.0 * EPS
    # x* - x = -U^-1 r, |U^-1 r| <= sum |r_i| |column i| / |det| (det and the columns to a few eps)
    err = ((abs(ra) + ea) * n0 + (abs(rb) + eb) * n1 + (abs(rc) + ec) * n2) / (abs(det) - 8.0 * EPS)
    err *= 1.0 + 16.0 * EPS
    if not err < math.inf:
        return False
    row = PA_ROW + v
    work[row, 0], work[row, 1], work[row, 2], work[row, 3] = y0, y1, y2, err
    # its point query's row (one ball hull): not run yet; the normal of its last plane, a start for it
    row = PB_ROW + v
    work[row, 0], work[row, 1], work[row, 2], work[row, 3] = c0, c1, c2, math.nan
    k = CORNERS + 3 * v
    iw[k], iw[k + 1], iw[k + 2] = p, q, r
    iw[ALIVE + v] = 1
    return True


@kernel
def _error_along(work, iw, v, d0, d1, d2):
    """A bound on |d.(x* - x)| for vertex v (x computed, x* exact) and unit d: from the residuals of
    its planes where d is well inside their span, else its error bound E."""
    k = CORNERS + 3 * v
    (a0, a1, a2, ha, b0, b1, b2, hb, c0, c1, c2, hc,
     x00, x01, x02, x10, x11, x12, x20, x21, x22, det) = _corner_system(work, iw[k], iw[k + 1], iw[k + 2])
    row = PA_ROW + v
    y0, y1, y2, err = work[row, 0], work[row, 1], work[row, 2], work[row, 3]
    if not abs(det) > 16.0 * EPS:
        return err
    m0 = (x00 * d0 + x01 * d1 + x02 * d2) / det  # mu = U^-T d, refined once on U^T mu - d
    m1 = (x10 * d0 + x11 * d1 + x12 * d2) / det
    m2 = (x20 * d0 + x21 * d1 + x22 * d2) / det
    z0 = m0 * a0 + m1 * b0 + m2 * c0 - d0
    z1 = m0 * a1 + m1 * b1 + m2 * c1 - d1
    z2 = m0 * a2 + m1 * b2 + m2 * c2 - d2
    m0 -= (x00 * z0 + x01 * z1 + x02 * z2) / det
    m1 -= (x10 * z0 + x11 * z1 + x12 * z2) / det
    m2 -= (x20 * z0 + x21 * z1 + x22 * z2) / det
    ra, ea = _residual(a0, a1, a2, ha, y0, y1, y2)
    rb, eb = _residual(b0, b1, b2, hb, y0, y1, y2)
    rc, ec = _residual(c0, c1, c2, hc, y0, y1, y2)
    ms = abs(m0) + abs(m1) + abs(m2)
    # d.(x* - x) = -mu.r - (U^T mu - d).(x* - x): the second term through the whole error bound
    z0 = m0 * a0 + m1 * b0 + m2 * c0 - d0
    z1 = m0 * a1 + m1 * b1 + m2 * c1 - d1
    z2 = m0 * a2 + m1 * b2 + m2 * c2 - d2
    miss = math.sqrt(z0 * z0 + z1 * z1 + z2 * z2) + 8.0 * EPS * (ms + 1.0)
    bound = abs(m0 * ra + m1 * rb + m2 * rc) + abs(m0) * ea + abs(m1) * eb + abs(m2) * ec + 4.0 * EPS * (
        abs(m0 * ra) + abs(m1 * rb) + abs(m2 * rc)) + miss * err
    return min(err, bound * (1.0 + 16.0 * EPS))


@kernel
def _norm_bound(work, iw, v):
    """An upper bound on |x*| for vertex v."""
    row = PA_ROW + v
    y0, y1, y2, err = work[row, 0], work[row, 1], work[row, 2], work[row, 3]
    yn = math.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
    if not yn > err:
        return yn + err
    along = _error_along(work, iw, v, y0 / yn, y1 / yn, y2 / yn)
    return (yn + along + err * err / (2.0 * yn)) * (1.0 + 4.0 * EPS)


@kernel(inline="always")
def _has_plane(iw, v, p):
    k = CORNERS + 3 * v
    return iw[k] == p or iw[k + 1] == p or iw[k + 2] == p


@kernel
def _vertex_bound(pair, sides, work, iw, v, tol_abs, tol_rel):
    """An upper bound on the objective at vertex v of P (exact, not as computed)."""
    if sides == BOTH_BALLS:
        return _norm_bound(work, iw, v)
    return _point_query(pair, sides, v, tol_abs, tol_rel, work, iw)


@kernel
def centre_set_bounds(pair, tol_abs, tol_rel, max_cuts, max_width, warm, work, iw):
    """Bounds on the signed distance of two cores (A's frame, margins not included), one of them at least
    a ball hull, from its set of centres (module docstring), after at most max_cuts cuts, and none where the
    set's box is wider than max_width times S (the balls' radii) along an axis (inf: any width).

    Returns (code, lower, upper, u0, u1, u2, cuts): code BH_OK when lower <= sd <= upper hold and met
    the tolerance (the stopping rule of spq.kernels.epa.bounds_closed), u the unit normal along which
    sd >= lower is reached as -h_D(u) (its supports are the witness points); otherwise why not. Uses the
    upper halves of the EPA's vertex and face blocks (SLOT0, FACE0), its support rows and the descent's
    rows: an EPA whose polytope fits the lower halves can go on after it.
    """
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    sides = ball_sides(kA, kB)
    if sides == NO_BALLS:
        return BH_NOT_BALLS, -math.inf, math.inf, 1.0, 0.0, 0.0, 0
    S = (ball_radius(kA, fA) if sides != BALL_B else 0.0) + (ball_radius(kB, fB) if sides != BALL_A else 0.0)
    tol_point = (0.25 * tol_abs, 0.25 * tol_rel)  # a point query's share of the tolerance
    lower_m = -math.inf  # the objective's max >= lower_m
    b0, b1, b2 = 1.0, 0.0, 0.0
    # the box of the set: planes +-x, +-y, +-z as planes 0..5
    for axis in range(3):
        for side in range(2):
            p = 2 * axis + side
            s = 1.0 if side == 0 else -1.0
            u0, u1, u2 = (s if axis == 0 else 0.0), (s if axis == 1 else 0.0), (s if axis == 2 else 0.0)
            hl, h, d0, d1, d2 = _cut_support(pair, sides, S, u0, u1, u2, warm, work)
            if h > lower_m:
                lower_m, b0, b1, b2 = h, d0, d1, d2
            row = PLANE_ROW + p
            work[row, 0], work[row, 1], work[row, 2], work[row, 3] = u0, u1, u2, hl
    for axis in range(3):
        # (a wide set closes slowly, its farthest point on a curved face: a hopeful attempt ends at its box)
        if work[PLANE_ROW + 2 * axis, 3] + work[PLANE_ROW + 2 * axis + 1, 3] > max_width * S:
            return BH_BUDGET, -math.inf, math.inf, b0, b1, b2, 0
    nv = 0
    for sx in range(2):
        for sy in range(2):
            for sz in range(2):
                if not _set_vertex(work, iw, nv, sx, 2 + sy, 4 + sz):
                    return BH_DEGENERATE, -math.inf, math.inf, b0, b1, b2, 0
                nv += 1
    n_planes = 6
    cuts = 0
    while True:
        # the farthest vertex of P, its objective with its error bound: max <= upper_m
        far = -1
        upper_m = -math.inf
        for v in range(nv):
            if iw[ALIVE + v] == 0:
                continue
            row = PA_ROW + v
            y0, y1, y2 = work[row, 0], work[row, 1], work[row, 2]
            if sides == BOTH_BALLS and math.sqrt(y0 * y0 + y1 * y1 + y2 * y2) * (1.0 + 4.0 * EPS) + work[
                    row, 3] <= upper_m:
                continue  # cannot beat the farthest so far even with its whole error
            r = _vertex_bound(pair, sides, work, iw, v, tol_point[0], tol_point[1])
            if r > upper_m:
                upper_m, far = r, v
        if far < 0:
            return BH_DEGENERATE, -math.inf, math.inf, b0, b1, b2, cuts
        if _closed(upper_m - S, lower_m - S, tol_abs, tol_rel):
            return BH_OK, lower_m - S, upper_m - S, b0, b1, b2, cuts
        if cuts >= max_cuts or n_planes >= MAX_PLANES:
            return BH_BUDGET, lower_m - S, upper_m - S, b0, b1, b2, cuts
        row = PA_ROW + far
        y0, y1, y2 = work[row, 0], work[row, 1], work[row, 2]
        if sides == BOTH_BALLS:  # along the farthest vertex: the norm's gradient
            yn = math.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
            if not yn > 0.0:
                return BH_DEGENERATE, lower_m - S, upper_m - S, b0, b1, b2, cuts
            u0, u1, u2 = y0 / yn, y1 / yn, y2 / yn
        else:  # along Y's normal at the farthest vertex: sd_Y's gradient
            grow = PB_ROW + far
            u0, u1, u2 = work[grow, 0], work[grow, 1], work[grow, 2]
            if u0 == 0.0 and u1 == 0.0 and u2 == 0.0:
                # the farthest vertex lies inside Y, so all of Q may: depths inside Y are not bounded here
                return BH_DEGENERATE, lower_m - S, upper_m - S, b0, b1, b2, cuts
            yn = u0 * y0 + u1 * y1 + u2 * y2
        hl, h, d0, d1, d2 = _cut_support(pair, sides, S, u0, u1, u2, warm, work)
        if h > lower_m:
            lower_m, b0, b1, b2 = h, d0, d1, d2
            if _closed(upper_m - S, lower_m - S, tol_abs, tol_rel):
                return BH_OK, lower_m - S, upper_m - S, b0, b1, b2, cuts
        # loosen the cut past every vertex it would pass within that vertex's error of (it stays a
        # plane holding the set), so each vertex is clearly kept or clearly cut off
        loosened = True
        while loosened:
            loosened = False
            for v in range(nv):
                if iw[ALIVE + v] == 0:
                    continue
                row = PA_ROW + v
                g = u0 * work[row, 0] + u1 * work[row, 1] + u2 * work[row, 2]
                slack = ROUNDING * (abs(g) + abs(hl))
                if abs(g - hl) > 2.0 * work[row, 3] + slack:
                    continue
                band = 2.0 * _error_along(work, iw, v, u0, u1, u2) + slack
                if abs(g - hl) <= band:
                    hl = g + 2.0 * band
                    loosened = True
        if not yn - _error_along(work, iw, far, u0, u1, u2) > hl:
            # the cut no longer reaches the farthest vertex: P is as tight as this precision allows
            return BH_BUDGET, lower_m - S, upper_m - S, b0, b1, b2, cuts
        code, nv = _cut(work, iw, nv, n_planes, u0, u1, u2, hl)
        if code != BH_OK:
            return code, lower_m - S, upper_m - S, b0, b1, b2, cuts
        n_planes += 1
        cuts += 1


@kernel(inline="always")
def _closed(upper, lower, tol_abs, tol_rel):
    return upper - lower <= tol_abs + tol_rel * abs(upper)


@kernel
def _cut(work, iw, nv, p, u0, u1, u2, h):
    """Cut P by plane p := (u, h): drop the vertices beyond it and add one on each edge from a dropped
    vertex to a kept one. Returns (code, new vertex count bound)."""
    row = PLANE_ROW + p
    work[row, 0], work[row, 1], work[row, 2], work[row, 3] = u0, u1, u2, h
    n_dead = 0
    for v in range(nv):
        if iw[ALIVE + v] == 0:
            continue
        row = PA_ROW + v
        if u0 * work[row, 0] + u1 * work[row, 1] + u2 * work[row, 2] > h:
            iw[DEAD + n_dead] = v
            n_dead += 1
            iw[ALIVE + v] = 2  # to be dropped
    if n_dead == 0:
        return BH_DEGENERATE, nv
    made = 0
    free = 0  # the next slot to try for a new vertex: first the dropped ones' (after this pass), then nv
    top = nv
    for i in range(n_dead):
        v = iw[DEAD + i]
        k = CORNERS + 3 * v
        for e in range(3):
            pq0, pq1 = iw[k + e], iw[k + (e + 1) % 3]
            found = -1
            for w in range(nv):
                if w == v or iw[ALIVE + w] == 0:
                    continue
                if _has_plane(iw, w, pq0) and _has_plane(iw, w, pq1):
                    if found >= 0:
                        return BH_DEGENERATE, nv  # an edge with three ends: not a simple polytope
                    found = w
            if found < 0:
                return BH_DEGENERATE, nv
            if iw[ALIVE + found] == 2:
                continue  # both ends dropped: the edge goes
            if top >= MAX_VERTICES:
                return BH_BUDGET, nv
            if not _set_vertex(work, iw, top, pq0, pq1, p):
                return BH_DEGENERATE, nv
            iw[ALIVE + top] = 3  # new: not an end of the edges of this pass
            top += 1
            made += 1
    if made < 3:
        return BH_DEGENERATE, nv
    for v in range(top):
        a = iw[ALIVE + v]
        if a == 2:
            iw[ALIVE + v] = 0
        elif a == 3:
            iw[ALIVE + v] = 1
    # compact: move the last live vertices into dropped slots so the scan stays short
    while top > 0 and iw[ALIVE + top - 1] == 0:
        top -= 1
    while free < top:
        if iw[ALIVE + free] == 0:
            last = top - 1
            for c in range(4):
                work[PA_ROW + free, c] = work[PA_ROW + last, c]
                work[PB_ROW + free, c] = work[PB_ROW + last, c]
            for c in range(3):
                iw[CORNERS + 3 * free + c] = iw[CORNERS + 3 * last + c]
            iw[ALIVE + free] = 1
            iw[ALIVE + last] = 0
            top -= 1
            while top > 0 and iw[ALIVE + top - 1] == 0:
                top -= 1
        free += 1
    return BH_OK, top


@kernel
def settle_from_centres(pair, tol, upper, iterations, warm, work, iw, out):
    """Whether the bounds from the set of centres (centre_set_bounds, tol = (tol_abs, tol_rel, max_cuts, max_width))
    with a known upper bound ``upper`` on sd meet the tolerance; the result (cores, A's frame, margins
    not included: normal, supports as witness points, bounds, status, iterations + cuts) is then in
    out. The lower bound is -h_D(u), reached along the normal u by its supports, the witness points
    (an EPA's lower bound, its best support over the run, need not be reached along its normal, its
    least face's)."""
    tol_abs, tol_rel, max_cuts, max_width = tol
    code, low, up, u0, u1, u2, cuts = centre_set_bounds(pair, tol_abs, tol_rel, max_cuts, max_width, warm, work, iw)
    if code != BH_OK:
        return False
    up = min(up, upper)
    if not bounds_closed(up, low, tol_abs, tol_rel):
        return False
    out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2] = u0, u1, u2
    supports_as_witnesses(pair, warm, work, out)
    set_result(up, low, iterations + cuts, tol_abs, out)
    return True
