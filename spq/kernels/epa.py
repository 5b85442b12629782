"""Penetration depth: the expanding polytope algorithm (EPA) on the Minkowski difference D = A - B.

The signed distance of two convex bodies is sd = -min over unit n of h_D(n), h_D(n) = h_A(n) +
h_B(-n) the support function of D: the distance when the origin lies outside D, minus the depth
(the length of the shortest translation of B that separates them) when it lies inside.

The EPA keeps a convex polytope P of support points of D (so P lies inside D) and grows it towards
D's boundary where that boundary is nearest the origin. Two bounds hold at every step:

- upper: while the origin is inside P, depth >= the distance from the origin to P's boundary, the
  least offset of P's faces, so sd <= -(least offset); before that, the GJK's own upper bound;
- lower: every support point w along a unit n gives sd >= -n.w, since D lies below that plane.

It stops when upper - lower <= tol_abs + tol_rel * |upper| (the certificate of the separated case),
or when |sd| <= tol_abs is certified on both sides (touching). Each step expands the face of least
offset, negative ones first (the origin on their outer side), so the same loop starts from any
tetrahedron of support points, whether or not it holds the origin: from the GJK's simplex grown
into a tetrahedron when the GJK ended with the origin on a point, segment or triangle of it.

Faces are triangles in counter-clockwise order seen from outside, each knowing its three
neighbours; a new support point replaces the faces it sees by a fan over the horizon, which a
depth-first walk from the expanded face collects in order. A fan that would hold a sliver (a plane
ill-defined in floating point), face inwards or break the horizon's loop is not made: the polytope
stays as it was and the bounds reached stay valid. The run then sets that face aside (at most
MAX_BLOCKED of them) and goes on from the others, one of which may take in the same region of D from
a better-conditioned side. The face still counts in the upper bound, by its certified offset or by
its triangle's distance from the origin, whichever is larger: such a face is typically a sliver
along a ridge of D, whose plane may pass near the origin while the triangle itself lies far from it.
A run that would end short of the tolerance after such faces takes them back once and goes on
leniently: a fan that cannot be made is tried again with the faces whose planes the point lies just
below (LENIENT_REL) replaced too, on a nearly flat stretch of D where the point is within rounding
of them, and if a fan face would still face inwards, with the faces across its horizon edge too, as
deep as the point lies under them (_carve_inward, within CARVE_REL). P then drops those faces' other
corners from its boundary and is no longer exactly convex, but it still lies in D (its boundary is a
closed surface of D's points about the origin), so its faces still bound the depth. A run between a
polytope and a superellipsoid that still ends short where the polytope's support ties over an edge
takes that edge's other end for each of its vertices from one end (_tie_partners) and goes on once.
If the bounds do not meet the tolerance in the end, the caller reports them with status FAILED.

Witness points: on the face of least offset, the barycentric coordinates of the origin's projection
combine its corners' support points of A and of B, so that point_b - point_a = sd * normal and both
points lie within the gap of their bodies' supporting planes.

Everything runs in body A's frame, with B at (R, t) in it, like the GJK (spq.kernels.gjk). The
polytope lives in the query's scratch (layout in spq.kernels.epa_layout), so nothing is allocated.
"""

from __future__ import annotations

import math

from spq.kernels.ball_hull_depth import BOTH_BALLS, FACE0, NO_BALLS, SLOT0, ball_sides, settle_from_centres
from spq.kernels.epa_layout import (
    EPA_ADJ,
    EPA_ALIVE,
    EPA_BEST,
    EPA_CAPS,
    EPA_CERTIFIED,
    EPA_CLOCK,
    EPA_CORNERS,
    EPA_DEAD,
    EPA_FAN,
    EPA_FEATURES,
    EPA_FREE,
    EPA_HORIZON,
    EPA_MAX_FACES,
    EPA_MAX_VERTICES,
    EPA_NEAR,
    EPA_NFREE,
    EPA_PA,
    EPA_PB,
    EPA_PLANES,
    EPA_STACK,
    EPA_STAMP,
    EPA_TMP,
    EPA_W,
)
from spq.kernels.epa_caps import (
    can_cap,
    certified,
    certified_offset,
    clear_best,
    clear_sphere,
    deepest_normal,
    has_best,
    keep_best,
    set_certified,
    support_sphere,
)
from spq.kernels.epa_curved import certifying_sides, clear_set, face_certificate, may_certify, set_tried, tried
from spq.kernels.gjk import (
    EPA_IOFF,
    EPA_ROW,
    FAILED,
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
    closest_on_triangle,
    minkowski_support,
)
from spq.kernels.indexing import at
from spq.kernels.jit import kernel
from spq.kernels.kinds import POLYTOPE, SUPERELLIPSOID
from spq.kernels.signed_out import bounds_closed

SLIVER_SIN = 1e-7  # least sine of a face's largest angle: below, its plane is ill-defined in floating point
VISIBLE_REL = 1e-13  # a face sees a point above its plane by more than this times the polytope's size
NOISE_REL = 1e-14  # a difference of points below this times the polytope's size is rounding noise
FLAT_REL = 1e-13  # support points within this (relative) of a line or plane: D has no extent across it
STALL_SLACK = 1e-9  # relative: a stalled expansion still counts as converged within this gap
WALK_STEPS = 16  # steps across coplanar neighbours to the face holding the origin's projection
# Expansions an EPA run may take: EPA_STEPS_PER_ITERATION per GJK iteration of the caller's max_iter
# (128 by default), at most EPA_MAX_STEPS. A deep overlap of round bodies (STP-BVs with R near its
# minimum, superellipsoids, hulls of hundreds of points on a sphere) has a depth that varies little
# with the normal, so the polytope must be refined over a wide cap before its least offset comes
# within 1e-10 of the depth: fuzzed 'contained' poses took 200 to 2000 expansions, and two nearly
# concentric STP-BVs more than 16,000. The sphere caps (spq.kernels.epa_caps) certify most of such a
# polytope; what is left, along the regions' edges, took those about 3000.
EPA_MAX_STEPS = EPA_MAX_VERTICES - 24
EPA_STEPS_PER_ITERATION = 32
CERT_WINDOW = 2e-3  # relative: a face is certified from curved sets only within this of the depth's bound
# (further below, its cap is too wide for the sets; trying every least face cost more than it saved)
CAPS_AFTER = 128  # steps of a run before it takes the sphere caps (see epa_run)
# A run with a ball hull on a side (an STP-BV, its core, a sphere) still open after CENTRES_AFTER steps tries
# the bounds from its set of centres once (spq.kernels.ball_hull_depth), with at most CENTRES_CUTS cuts, and
# goes on where they do not close: a nearly round D (an STP-BV near its least R holding a body deep inside
# it) took the EPA 800 to 4,100 steps (1.8 to 15 ms) where the centres close in 2 to 50 cuts (10 to 120 us);
# kuka_link_4's STP-BV overlaps take at most 79 steps, so they never reach it. Between two ball hulls (two
# STP-BVs' cores) the cuts need no point queries, so a run whose set of centres is narrow (its box at most
# CENTRES_EARLY_WIDTH times the balls' radii along each axis: STP-BVs near their least R) tries them sooner,
# after CENTRES_AFTER_BALLS steps (and again after CENTRES_AFTER where that does not close); a wide set
# (kuka_link_4's at R = 2 m: about twice) closes slowly, so there the early attempt ends at its box (stop 131)
CENTRES_AFTER = 128
CENTRES_AFTER_BALLS = 32
CENTRES_EARLY_WIDTH = 0.25
CENTRES_CUTS = 64
# Faces a run may set aside when floating point cannot make their expansion (see _block): a fan
# along a ridge of D that its support points trace as a line (a boxy superellipsoid's straight edge
# swept by a polytope's edge) can face inwards at one face and not at the next
MAX_BLOCKED = 8
# A run that would end FAILED after such expansions goes on once more with the set-aside faces taken
# back, each failed expansion retried with the faces its point lies within this (relative to the
# polytope's size) below also replaced (see epa_run). A run that closes never takes it, so its
# result does not depend on it.
LENIENT_REL = 1e-9
# A lenient expansion whose fan would still face inwards replaces, besides, the faces across the horizon
# edges of the inward fan faces, as deep below as the point lies under them, within this (relative to
# the polytope's size): see _carve_inward.
CARVE_REL = 1e-7
CARVE_TRIES = 8
# A polytope's vertices whose support values along a direction lie within this (relative to its largest
# coordinate) of the best tie there: see _tie_partners.
TIE_REL = 1e-6

# why the last run stopped, kept in the scratch (work[EPA_ROW + EPA_TMP, 3]) for diagnostics
STOP_CLOSED, STOP_ITERATIONS, STOP_VERTICES, STOP_NO_PROGRESS = 1, 2, 3, 4
STOP_HORIZON, STOP_FACE_SLOTS, STOP_FAN_SLIVER, STOP_FAN_INWARD = 5, 6, 7, 8  # expansions not made
STOP_CENTRES = 9  # settled from a ball hull's set of centres (CENTRES_AFTER)
PLANE_OK, PLANE_SLIVER, PLANE_INWARD = 0, 1, 2

# EPA outcomes
EPA_RESULT = 0  # out holds the result (status FAILED if the bounds did not close): the origin in P, or
# outside it nearer P than the caller's upper bound (P lies in D, so its distance bounds sd from above)
EPA_OUTSIDE = 1  # the origin lies outside P, no nearer than the caller's bound: the GJK's points stand
EPA_FLAT = 2  # D has no interior (flat cores): sd >= 0; out's normal is one across the flat set (NaN: any)


# ------------------------------------------------------------------------------------------
# the polytope's storage
# ------------------------------------------------------------------------------------------
@kernel(inline="always")
def _row(i):
    return at(EPA_ROW + EPA_W + i)


@kernel(inline="always")
def _corner(iw, f, k):
    return iw[at(EPA_IOFF + EPA_CORNERS + 3 * f + k)]


@kernel(inline="always")
def _adj(iw, f, k):
    return iw[at(EPA_IOFF + EPA_ADJ + 3 * f + k)]


@kernel(inline="always")
def _set_adj(iw, f, k, g):
    iw[at(EPA_IOFF + EPA_ADJ + 3 * f + k)] = g


@kernel(inline="always")
def _alive(iw, f):
    return iw[at(EPA_IOFF + EPA_ALIVE + f)] == 1


@kernel(inline="always")
def _set_flag(iw, f, alive):
    """Face f's flag alone: _horizon marks the faces it collects, and keeps their keys until the
    expansion is made (_expand), so that undoing it (_revive) leaves them as they were."""
    iw[at(EPA_IOFF + EPA_ALIVE + f)] = 1 if alive else 0


@kernel(inline="always")
def _set_alive(work, iw, f, alive):
    """Face f's flag, and its key for _least_face: its certified offset while it lives, else +inf."""
    iw[at(EPA_IOFF + EPA_ALIVE + f)] = 1 if alive else 0
    work[at(EPA_ROW + EPA_CERTIFIED + f), 1] = certified(work, f) if alive else math.inf


@kernel(inline="always")
def _stamp(iw, f):
    return iw[at(EPA_IOFF + EPA_STAMP + f)]


@kernel(inline="always")
def _set_stamp(iw, f, s):
    iw[at(EPA_IOFF + EPA_STAMP + f)] = s


@kernel(inline="always")
def _vertex(work, i, w, pa, pb):
    """Store support point i: w = pa - pb, with its points of A and of B."""
    for c in range(3):
        work[EPA_ROW + EPA_W + i, c] = w[c]
        work[EPA_ROW + EPA_PA + i, c] = pa[c]
        work[EPA_ROW + EPA_PB + i, c] = pb[c]


@kernel(inline="always")
def _set_features(iw, i, fa, fb):
    iw[at(EPA_IOFF + EPA_FEATURES + 2 * i)] = fa
    iw[at(EPA_IOFF + EPA_FEATURES + 2 * i + 1)] = fb


@kernel(inline="always")
def feature(iw, i, side):
    """The support feature of A (side 0) or of B (side 1) that vertex i came from."""
    return iw[at(EPA_IOFF + EPA_FEATURES + 2 * i + side)]


@kernel(inline="always")
def _swap_vertices(work, iw, i, j):
    for base in (EPA_W, EPA_PA, EPA_PB):
        for c in range(3):
            x = work[EPA_ROW + base + i, c]
            work[EPA_ROW + base + i, c] = work[EPA_ROW + base + j, c]
            work[EPA_ROW + base + j, c] = x
    fa, fb = feature(iw, i, 0), feature(iw, i, 1)
    _set_features(iw, i, feature(iw, j, 0), feature(iw, j, 1))
    _set_features(iw, j, fa, fb)


@kernel(inline="always")
def _support_inline(pair, d0, d1, d2, warm, work):
    """Support point of D along d into the scratch rows (pa, pb, then w = pa - pb); returns h_D
    along the unit vector of d."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    pa = work[EPA_ROW + EPA_TMP]
    pb = work[EPA_ROW + EPA_TMP + 1]
    w = work[EPA_ROW + EPA_TMP + 2]
    minkowski_support(pair, d0, d1, d2, warm, pa, pb, w)
    for c in range(3):
        w[c] = pa[c] - pb[c]
    return (d0 * w[0] + d1 * w[1] + d2 * w[2]) / math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@kernel
def _support(pair, d0, d1, d2, warm, work):
    """_support_inline as a call (the initial tetrahedron's many supports need not be inlined)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    return _support_inline(pair, d0, d1, d2, warm, work)


@kernel(inline="always")
def _keep_support(work, iw, warm, i):
    """The support point in the scratch rows (its features in warm) as vertex i."""
    _vertex(work, i, work[EPA_ROW + EPA_TMP + 2], work[EPA_ROW + EPA_TMP], work[EPA_ROW + EPA_TMP + 1])
    _set_features(iw, i, warm[0], warm[1])


@kernel
def _is_vertex(work, nv, w):
    for i in range(nv):
        r = _row(i)
        if work[r, 0] == w[0] and work[r, 1] == w[1] and work[r, 2] == w[2]:
            return True
    return False


@kernel
def _size(work, nv):
    """Largest coordinate of the first nv vertices: the scale of rounding errors."""
    s = 0.0
    for i in range(nv):
        r = _row(i)
        s = max(s, abs(work[r, 0]), abs(work[r, 1]), abs(work[r, 2]))
    return s


# ------------------------------------------------------------------------------------------
# the initial tetrahedron
# ------------------------------------------------------------------------------------------
@kernel
def _span(work, iw, nv):
    """Reorder vertices 0..nv-1 so that the first m are affinely independent and span the others
    (within FLAT_REL of the size); returns m. Greedy: the farthest from vertex 0, then from the line,
    then from the plane."""
    eps = FLAT_REL * _size(work, nv)
    a = _row(0)
    if nv < 2:
        return nv
    best, bi = 0.0, -1
    for i in range(1, nv):
        r = _row(i)
        d = math.sqrt((work[r, 0] - work[a, 0]) ** 2 + (work[r, 1] - work[a, 1]) ** 2 + (work[r, 2] - work[a, 2]) ** 2)
        if d > best:
            best, bi = d, i
    if not (best > eps):
        return 1
    _swap_vertices(work, iw, 1, bi)
    if nv < 3:
        return 2
    best, bi = 0.0, -1
    for i in range(2, nv):
        d = _off_line(work, 0, 1, i)
        if d > best:
            best, bi = d, i
    if not (best > eps):
        return 2
    _swap_vertices(work, iw, 2, bi)
    if nv < 4:
        return 3
    best, bi = 0.0, -1
    for i in range(3, nv):
        d = abs(_off_plane(work, 0, 1, 2, _row(i)))
        if d > best:
            best, bi = d, i
    if not (best > eps):
        return 3
    _swap_vertices(work, iw, 3, bi)
    return 4


@kernel
def _off_line(work, i, j, k):
    """Distance of vertex k from the line through vertices i and j."""
    a, b, c = _row(i), _row(j), _row(k)
    e0, e1, e2 = work[b, 0] - work[a, 0], work[b, 1] - work[a, 1], work[b, 2] - work[a, 2]
    q0, q1, q2 = work[c, 0] - work[a, 0], work[c, 1] - work[a, 1], work[c, 2] - work[a, 2]
    x0, x1, x2 = e1 * q2 - e2 * q1, e2 * q0 - e0 * q2, e0 * q1 - e1 * q0
    return math.sqrt(x0 * x0 + x1 * x1 + x2 * x2) / math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)


@kernel
def _off_plane(work, i, j, k, row):
    """Signed distance of work[row] from the plane of vertices i, j, k (normal (j-i) x (k-i))."""
    n0, n1, n2 = _plane_normal(work, i, j, k)
    a = _row(i)
    return (n0 * (work[row, 0] - work[a, 0]) + n1 * (work[row, 1] - work[a, 1]) + n2 * (work[row, 2] - work[a, 2]))


@kernel
def _plane_normal(work, i, j, k):
    a, b, c = _row(i), _row(j), _row(k)
    u0, u1, u2 = work[b, 0] - work[a, 0], work[b, 1] - work[a, 1], work[b, 2] - work[a, 2]
    v0, v1, v2 = work[c, 0] - work[a, 0], work[c, 1] - work[a, 1], work[c, 2] - work[a, 2]
    n0, n1, n2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
    nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    return n0 / nn, n1 / nn, n2 / nn


@kernel(inline="always")
def _axis_direction(k):
    """The k-th of the six axis directions +-x, +-y, +-z."""
    s = 1.0 if k % 2 == 0 else -1.0
    return (s if k // 2 == 0 else 0.0), (s if k // 2 == 1 else 0.0), (s if k // 2 == 2 else 0.0)


@kernel
def _grow(pair, m, warm, work, iw):
    """Add support points to the m (< 4) independent vertices until they are four: the one farthest
    from vertex 0 of the six axis directions' supports, then of six directions around the segment,
    then the farther of the two along the triangle's normals. Returns (m, lower): m < 4 when D
    does not extend beyond the current line or plane (it is flat there), with lower the best bound
    sd >= -h_D(n) met on the way."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    lower = -math.inf
    size = _size(work, m)
    tmp = EPA_ROW + EPA_TMP + 2
    if m == 1:
        best, bk = -1.0, 0
        for k in range(6):
            d0, d1, d2 = _axis_direction(k)
            lower = max(lower, -_support(pair, d0, d1, d2, warm, work))
            a = _row(0)
            dist = math.sqrt((work[tmp, 0] - work[a, 0]) ** 2 + (work[tmp, 1] - work[a, 1]) ** 2
                             + (work[tmp, 2] - work[a, 2]) ** 2)
            size = max(size, abs(work[tmp, 0]), abs(work[tmp, 1]), abs(work[tmp, 2]))
            if dist > best:
                best, bk = dist, k
        if not (best > FLAT_REL * size):
            return 1, lower
        d0, d1, d2 = _axis_direction(bk)
        _support(pair, d0, d1, d2, warm, work)
        _keep_support(work, iw, warm, 1)
        m = 2
    if m == 2:
        a, b = _row(0), _row(1)
        e0, e1, e2 = work[b, 0] - work[a, 0], work[b, 1] - work[a, 1], work[b, 2] - work[a, 2]
        en = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        e0, e1, e2 = e0 / en, e1 / en, e2 / en
        if abs(e0) < 0.6:
            x0, x1, x2 = 0.0, e2, -e1
        else:
            x0, x1, x2 = -e2, 0.0, e0
        xn = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        x0, x1, x2 = x0 / xn, x1 / xn, x2 / xn
        y0, y1, y2 = e1 * x2 - e2 * x1, e2 * x0 - e0 * x2, e0 * x1 - e1 * x0
        best, bk = -1.0, 0
        for k in range(6):  # six directions around the segment, 60 degrees apart
            c, s = math.cos(k * math.pi / 3.0), math.sin(k * math.pi / 3.0)
            lower = max(lower, -_support(pair, c * x0 + s * y0, c * x1 + s * y1,
                                         c * x2 + s * y2, warm, work))
            _keep_support(work, iw, warm, 2)
            size = max(size, abs(work[tmp, 0]), abs(work[tmp, 1]), abs(work[tmp, 2]))
            dist = _off_line(work, 0, 1, 2)
            if dist > best:
                best, bk = dist, k
        if not (best > FLAT_REL * size):
            return 2, lower
        c, s = math.cos(bk * math.pi / 3.0), math.sin(bk * math.pi / 3.0)
        _support(pair, c * x0 + s * y0, c * x1 + s * y1, c * x2 + s * y2, warm, work)
        _keep_support(work, iw, warm, 2)
        m = 3
    if m == 3:
        n0, n1, n2 = _plane_normal(work, 0, 1, 2)
        hp = _support(pair, n0, n1, n2, warm, work)
        above = _off_plane(work, 0, 1, 2, tmp)
        size = max(size, abs(work[tmp, 0]), abs(work[tmp, 1]), abs(work[tmp, 2]))
        hm = _support(pair, -n0, -n1, -n2, warm, work)
        below = -_off_plane(work, 0, 1, 2, tmp)
        size = max(size, abs(work[tmp, 0]), abs(work[tmp, 1]), abs(work[tmp, 2]))
        lower = max(lower, -hp, -hm)
        if not (max(above, below) > FLAT_REL * size):
            return 3, lower
        if above > below:
            _support(pair, n0, n1, n2, warm, work)
        _keep_support(work, iw, warm, 3)
        m = 4
    return m, lower


@kernel(inline="always")
def _plane_of(work, a, b, c, c0, c1, c2):
    """(PLANE_*, unit normal, offset) of the triangle of vertices a, b, c (counter-clockwise from
    outside): PLANE_SLIVER if it is a sliver, PLANE_INWARD if it faces the interior point
    c = (c0, c1, c2)."""
    ra, rb, rc = _row(a), _row(b), _row(c)
    ab = (work[rb, 0] - work[ra, 0]) ** 2 + (work[rb, 1] - work[ra, 1]) ** 2 + (work[rb, 2] - work[ra, 2]) ** 2
    bc = (work[rc, 0] - work[rb, 0]) ** 2 + (work[rc, 1] - work[rb, 1]) ** 2 + (work[rc, 2] - work[rb, 2]) ** 2
    ca = (work[ra, 0] - work[rc, 0]) ** 2 + (work[ra, 1] - work[rc, 1]) ** 2 + (work[ra, 2] - work[rc, 2]) ** 2
    # The normal from the two sides at the largest angle (opposite the longest side), whose sine
    # bounds its rounding error, about eps / sine: a needle (a new support point 1e-9 from a vertex,
    # near-duplicate hull points) has a right angle there and a well-defined plane, as its short side,
    # a difference of nearby floats, is exact. Only a flat triangle, its largest angle near pi, is a sliver.
    # corner o, sides o -> p and o -> q, counter-clockwise: (ra, rb, rc) turned once where ab is the
    # longest side, twice where ca is; in arithmetic, as the longest side falls at random (branches on
    # it: 33 simulated misses over a PCH-PCH overlap's 46 fan faces, docs/notes/speed-45.md, stop 93)
    s1 = int(ab >= bc) & int(ab >= ca)
    s2 = (1 - s1) & int(ca >= bc)
    o = ra + s1 * (rc - ra) + s2 * (rb - ra)
    p = rb + s1 * (ra - rb) + s2 * (rc - rb)
    q = rc + s1 * (rb - rc) + s2 * (ra - rc)
    u0, u1, u2 = work[p, 0] - work[o, 0], work[p, 1] - work[o, 1], work[p, 2] - work[o, 2]
    v0, v1, v2 = work[q, 0] - work[o, 0], work[q, 1] - work[o, 1], work[q, 2] - work[o, 2]
    n0, n1, n2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
    nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    sides = (u0 * u0 + u1 * u1 + u2 * u2) * (v0 * v0 + v1 * v1 + v2 * v2)
    if not (nn * nn > SLIVER_SIN * SLIVER_SIN * sides):
        return PLANE_SLIVER, 0.0, 0.0, 0.0, 0.0
    # (divisions, not a reciprocal's products: those cost a second rounding, which moved the touching
    # poses' largest error against the exact reference from 8.4e-16 to 3.6e-15 m for 4% of an overlap)
    n0, n1, n2 = n0 / nn, n1 / nn, n2 / nn
    off = (n0 * (work[ra, 0] + work[rb, 0] + work[rc, 0]) + n1 * (work[ra, 1] + work[rb, 1] + work[rc, 1])
           + n2 * (work[ra, 2] + work[rb, 2] + work[rc, 2])) / 3.0
    if not (n0 * c0 + n1 * c1 + n2 * c2 < off):
        return PLANE_INWARD, 0.0, 0.0, 0.0, 0.0
    return PLANE_OK, n0, n1, n2, off


@kernel
def _sliver_plane(work, g, a, b, c, c0, c1, c2):
    """A plane for the sliver fan face (a, b, c) whose corner c lies on the line of its horizon edge
    (a, b), within rounding of live face g across that edge (a rounded ridge of D sharper than
    floating point resolves): g's normal, with the least offset of the three corners along it. Every
    point of the triangle lies on or beyond that plane, so its offset still bounds their distance from
    the origin, and a point beyond the true face lies beyond it too (module docstring). The triangle
    is a face of the convex hull (c lies on g's inner side, bending the hull as convexity does), where
    taking g in too would dent it. PLANE_INWARD if the interior point is not inside it."""
    row = EPA_ROW + EPA_PLANES + g
    n0, n1, n2 = work[row, 0], work[row, 1], work[row, 2]
    off = min(n0 * work[_row(a), 0] + n1 * work[_row(a), 1] + n2 * work[_row(a), 2],
              n0 * work[_row(b), 0] + n1 * work[_row(b), 1] + n2 * work[_row(b), 2],
              n0 * work[_row(c), 0] + n1 * work[_row(c), 1] + n2 * work[_row(c), 2])
    if not (n0 * c0 + n1 * c1 + n2 * c2 < off):
        return PLANE_INWARD, 0.0, 0.0, 0.0, 0.0
    return PLANE_OK, n0, n1, n2, off


@kernel
def _new_face(work, iw, top, a, b, c, n0, n1, n2, off):
    """A face slot (a free one if any, else slot ``top``) with corners a, b, c and its plane.
    Returns (face, new top)."""
    nfree = iw[EPA_IOFF + EPA_NFREE]
    if nfree > 0:
        f = iw[EPA_IOFF + EPA_FREE + nfree - 1]
        iw[EPA_IOFF + EPA_NFREE] = nfree - 1
    else:
        f = top
        top += 1
    iw[at(EPA_IOFF + EPA_CORNERS + 3 * f)] = a
    iw[at(EPA_IOFF + EPA_CORNERS + 3 * f + 1)] = b
    iw[at(EPA_IOFF + EPA_CORNERS + 3 * f + 2)] = c
    iw[at(EPA_IOFF + EPA_ALIVE + f)] = 1  # (set_certified below sets its key)
    _set_stamp(iw, f, 0)
    row = at(EPA_ROW + EPA_PLANES + f)
    work[row, 0], work[row, 1], work[row, 2], work[row, 3] = n0, n1, n2, off
    set_certified(work, f, certified_offset(work, a, b, c, n0, n1, n2, off) if iw[EPA_IOFF + EPA_CAPS] else off)
    set_tried(work, f, False)
    return f, top


@kernel
def _tetrahedron(work, iw, c0, c1, c2):
    """The four faces of the tetrahedron of vertices 0..3, outward, with their neighbours. Returns
    (ok, number of face slots used); not ok if a face is a sliver."""
    iw[EPA_IOFF + EPA_NFREE] = 0
    iw[EPA_IOFF + EPA_CLOCK] = 0
    iw[EPA_IOFF + EPA_CAPS] = 0  # the simplex's vertices carry none
    top = 0
    for m in range(4):  # the face opposite corner m
        i = 1 if m == 0 else 0
        j = 2 if m <= 1 else 1
        k = 3 if m <= 2 else 2
        code, n0, n1, n2, off = _plane_of(work, i, j, k, c0, c1, c2)
        if code != PLANE_OK:
            j, k = k, j
            code, n0, n1, n2, off = _plane_of(work, i, j, k, c0, c1, c2)
            if code != PLANE_OK:
                return False, top
        f, top = _new_face(work, iw, top, i, j, k, n0, n1, n2, off)
    # face m lies in slot m (no free slots yet) and holds every vertex but m, so the other face on
    # its edge from corner e to corner e + 1 is the one without corner e + 2: the face opposite it
    # (a search over the faces' edges for the reversed edge cost about 4% of an overlap)
    for f in range(4):
        for e in range(3):
            _set_adj(iw, f, e, _corner(iw, f, _next_edge(_next_edge(e))))
    return True, top


# ------------------------------------------------------------------------------------------
# expansion
# ------------------------------------------------------------------------------------------
@kernel(inline="always")
def _next_edge(e):
    """(e + 1) % 3 for e in -1..2, without the signed modulo's multiply and fix-ups."""
    return e + 1 if e < 2 else 0


@kernel(inline="always")
def _edge_towards(iw, g, f):
    """The edge of face g across which face f lies (-1 if none)."""
    # in arithmetic, not a loop's early return: which edge it is varies at random (the early
    # return's branches: 26 simulated misses an overlap, stop 93)
    m0, m1, m2 = int(_adj(iw, g, 0) == f), int(_adj(iw, g, 1) == f), int(_adj(iw, g, 2) == f)
    return (1 - m0) * (m1 + (1 - m1) * (3 * m2 - 1))


@kernel(inline="always")
def _height(work, g, w):
    row = at(EPA_ROW + EPA_PLANES + g)
    return work[row, 0] * w[0] + work[row, 1] * w[1] + work[row, 2] * w[2] - work[row, 3]


@kernel(inline="always")
def _horizon(work, iw, f0, w, stamp, eps):
    """Mark dead the faces that see w (w above their plane by more than eps), walking from f0 (which
    does), list them, and list the horizon: the edges between a dead face and a live one, in the
    dead faces' counter-clockwise order. Returns (horizon edges, dead faces); the edge count is -1
    if they do not form one closed loop."""
    base = EPA_IOFF
    nh = 0
    nd = 1
    sp = 0
    _set_stamp(iw, f0, stamp)
    _set_flag(iw, f0, False)
    iw[at(base + EPA_DEAD)] = f0
    iw[at(base + EPA_STACK)] = f0
    iw[at(base + EPA_STACK + 1)] = 0
    iw[at(base + EPA_STACK + 2)] = 3
    while sp >= 0:
        top = base + EPA_STACK + 3 * sp
        if iw[at(top + 2)] == 0:
            sp -= 1
            continue
        f = iw[at(top)]
        e = iw[at(top + 1)]
        iw[at(top + 1)] = _next_edge(e)
        iw[at(top + 2)] -= 1
        g = _adj(iw, f, e)
        if _stamp(iw, g) == stamp and not _alive(iw, g):
            continue  # both sides dead: an inner edge
        if _stamp(iw, g) != stamp and _height(work, g, w) > eps:
            _set_stamp(iw, g, stamp)
            _set_flag(iw, g, False)
            iw[at(base + EPA_DEAD + nd)] = g
            nd += 1
            sp += 1
            nxt = base + EPA_STACK + 3 * sp
            iw[at(nxt)] = g
            iw[at(nxt + 1)] = _next_edge(_edge_towards(iw, g, f))
            iw[at(nxt + 2)] = 2
            continue
        _set_stamp(iw, g, stamp)
        h = base + EPA_HORIZON + 4 * nh
        iw[at(h)] = _corner(iw, f, e)
        iw[at(h + 1)] = _corner(iw, f, _next_edge(e))
        iw[at(h + 2)] = g
        iw[at(h + 3)] = _edge_towards(iw, g, f)
        nh += 1
    if nh < 3:
        return -1, nd
    # each edge ends where the next begins, the last where the first begins (the wrap outside the loop:
    # a select of the next index inside it compiled to a branch, missed at each loop's end)
    for i in range(nh - 1):
        if iw[at(base + EPA_HORIZON + 4 * i + 1)] != iw[at(base + EPA_HORIZON + 4 * i + 4)]:
            return -1, nd
    if iw[at(base + EPA_HORIZON + 4 * nh - 3)] != iw[at(base + EPA_HORIZON)]:
        return -1, nd
    return nh, nd


@kernel
def _revive(iw, nd):
    """Undo _horizon: the nd faces it marked dead live again, their keys untouched (a face set aside
    stays aside)."""
    for i in range(nd):
        _set_flag(iw, iw[EPA_IOFF + EPA_DEAD + i], True)


@kernel(inline="always")
def _expand(work, iw, f0, wv, stamp, top, eps, c0, c1, c2):
    """Replace the faces that vertex wv sees (from face f0, which sees it) by a fan from the horizon
    to wv. Returns (0, new top), or (STOP_*, top) with the polytope left as it was: a broken horizon,
    no face slots left, or a fan face that would be a sliver or face inwards."""
    w = work[_row(wv)]
    nh, nd = _horizon(work, iw, f0, w, stamp, eps)
    if nh < 0:
        _revive(iw, nd)
        return STOP_HORIZON, top
    if iw[EPA_IOFF + EPA_NFREE] + nd + EPA_MAX_FACES - top < nh:
        _revive(iw, nd)
        return STOP_FACE_SLOTS, top
    for i in range(nh):  # every fan face must have a well-defined outward plane
        h = EPA_IOFF + EPA_HORIZON + 4 * i
        code, n0, n1, n2, off = _plane_of(work, iw[h], iw[h + 1], wv, c0, c1, c2)
        if code == PLANE_SLIVER:
            code, n0, n1, n2, off = _sliver_plane(work, iw[h + 2], iw[h], iw[h + 1], wv, c0, c1, c2)
        if code != PLANE_OK:
            _revive(iw, nd)
            return STOP_FAN_SLIVER if code == PLANE_SLIVER else STOP_FAN_INWARD, top
        row = EPA_ROW + EPA_FAN + i
        work[row, 0], work[row, 1], work[row, 2], work[row, 3] = n0, n1, n2, off
    for i in range(nd):  # the dead faces' slots become free
        f = iw[EPA_IOFF + EPA_DEAD + i]
        _set_alive(work, iw, f, False)
        nfree = iw[EPA_IOFF + EPA_NFREE]
        iw[EPA_IOFF + EPA_FREE + nfree] = f
        iw[EPA_IOFF + EPA_NFREE] = nfree + 1
        iw[EPA_IOFF + EPA_CORNERS + 3 * f] = -1
    first = prev = -1
    for i in range(nh):
        h = EPA_IOFF + EPA_HORIZON + 4 * i
        a, b, g, j = iw[h], iw[h + 1], iw[h + 2], iw[h + 3]
        row = EPA_ROW + EPA_FAN + i
        fn, top = _new_face(work, iw, top, a, b, wv, work[row, 0], work[row, 1], work[row, 2], work[row, 3])
        _set_stamp(iw, fn, stamp)
        _set_adj(iw, fn, 0, g)
        _set_adj(iw, g, j, fn)
        if prev >= 0:
            _set_adj(iw, prev, 1, fn)
            _set_adj(iw, fn, 2, prev)
        else:
            first = fn
        prev = fn
    _set_adj(iw, prev, 1, first)
    _set_adj(iw, first, 2, prev)
    return 0, top


@kernel
def _carve_inward(work, iw, f0, wv, top, eps, size, c):
    """A lenient expansion of face f0 to vertex wv refused because a fan face would face the interior
    point c (STOP_FAN_INWARD), tried again with the faces across the horizon edges of those fan faces
    replaced too: eps lowered to just below the deepest of those faces' heights of the point, while that
    stays within CARVE_REL of the polytope's size. Along a ridge of D traced by two near-lines of support
    points (a polytope's edge tied against a superellipsoid), degenerate faces of one line leave the
    point just under a neighbour's plane, which the fan from the horizon then cuts across; taking that
    neighbour in dents P by less than the point's depth under it. P still lies in D and its boundary is
    still a closed surface of D's points about the origin, so its faces still bound the depth (as a
    lenient expansion's, module docstring). Returns (stop, top) as _expand."""
    c0, c1, c2 = c
    w = work[_row(wv)]
    stop = STOP_FAN_INWARD
    for _ in range(CARVE_TRIES):
        iw[EPA_IOFF + EPA_CLOCK] += 1
        nh, nd = _horizon(work, iw, f0, w, iw[EPA_IOFF + EPA_CLOCK], eps)
        _revive(iw, nd)
        deepest = eps
        for i in range(max(nh, 0)):
            h = EPA_IOFF + EPA_HORIZON + 4 * i
            code, n0, n1, n2, off = _plane_of(work, iw[h], iw[h + 1], wv, c0, c1, c2)
            if code == PLANE_SLIVER:
                code, n0, n1, n2, off = _sliver_plane(work, iw[h + 2], iw[h], iw[h + 1], wv, c0, c1, c2)
            if code == PLANE_INWARD:
                deepest = min(deepest, _height(work, iw[h + 2], w))
        if not deepest < eps:
            break
        eps = deepest - NOISE_REL * size
        if -eps > CARVE_REL * size:
            break
        iw[EPA_IOFF + EPA_CLOCK] += 1
        stop, top = _expand(work, iw, f0, wv, iw[EPA_IOFF + EPA_CLOCK], top, eps, c0, c1, c2)
        if stop != STOP_FAN_INWARD:
            break
    return stop, top


@kernel(inline="always")
def _least_face(work, iw, top):
    """The live face of least certified offset (spq.kernels.epa_caps), and that offset."""
    # over the keys, +inf for a dead face: no test of the flag, whose branch the predictor missed
    # (the scan held about an eighth of a deep STP-PCH overlap's time, perf)
    best, bf = math.inf, -1
    for f in range(top):
        o = work[at(EPA_ROW + EPA_CERTIFIED + f), 1]
        if o < best:
            best, bf = o, f
    return bf, best


@kernel(inline="always")
def _block(work, f):
    """Set live face f aside: _least_face no longer picks it (its key +inf), while its certified
    offset still bounds the depth (_blocked_least). An expansion that sees it replaces it as any
    face; _unblock_all takes it back."""
    work[at(EPA_ROW + EPA_CERTIFIED + f), 1] = math.inf


@kernel
def _blocked_least(work, iw, top):
    """The least bound of the blocked faces (live, key +inf) on the depth, +inf if none: each face's
    certified offset or the distance from the origin to its triangle, whichever is larger.

    The distance is a bound too: a point of B(0, r) outside P leaves P through some face's triangle
    at a point no farther than r, so a face whose triangle lies farther than r from the origin needs
    no certificate at r. It matters here because a face that cannot be expanded is typically a
    sliver along a ridge, whose plane passes near the origin while its triangle lies far from it."""
    best = math.inf
    for f in range(top):
        if _alive(iw, f) and work[at(EPA_ROW + EPA_CERTIFIED + f), 1] == math.inf:
            best = min(best, max(certified(work, f), _face_distance(work, iw, f)))
    return best


@kernel(inline="always")
def _take_lenient(lenient, closed, off, upper, lower, tol_abs, blocked, stop):
    """Whether a run about to stop goes on in lenient mode (LENIENT_REL): once, when expansions that
    floating point could not make stopped it and the bounds have not met even the stall's slack."""
    if lenient or closed or not off >= 0.0:
        return False
    if not (blocked > 0 or stop == STOP_HORIZON or stop == STOP_FAN_SLIVER or stop == STOP_FAN_INWARD):
        return False
    return not upper - lower <= STALL_SLACK * abs(upper) + tol_abs


@kernel
def _unblock_all(work, iw, top):
    for f in range(top):
        if _alive(iw, f):
            work[at(EPA_ROW + EPA_CERTIFIED + f), 1] = certified(work, f)


# ------------------------------------------------------------------------------------------
# witness points
# ------------------------------------------------------------------------------------------
@kernel(inline="always")
def _signed_area(work, i, j, p0, p1, p2, n):
    """Twice the area of triangle (w_i, w_j, p), signed along the normal in row n."""
    u0, u1, u2 = work[i, 0] - p0, work[i, 1] - p1, work[i, 2] - p2
    v0, v1, v2 = work[j, 0] - p0, work[j, 1] - p1, work[j, 2] - p2
    return (u1 * v2 - u2 * v1) * work[n, 0] + (u2 * v0 - u0 * v2) * work[n, 1] + (u0 * v1 - u1 * v0) * work[n, 2]


@kernel
def _barycentric(work, iw, f, p0, p1, p2):
    """Barycentric coordinates of point p (on face f's plane) in face f's triangle."""
    a, b, c = _row(_corner(iw, f, 0)), _row(_corner(iw, f, 1)), _row(_corner(iw, f, 2))
    n = EPA_ROW + EPA_PLANES + f
    la = _signed_area(work, b, c, p0, p1, p2, n)
    lb = _signed_area(work, c, a, p0, p1, p2, n)
    lc = _signed_area(work, a, b, p0, p1, p2, n)
    s = la + lb + lc
    return la / s, lb / s, lc / s


@kernel
def _witness(work, iw, f, out):
    """Witness points and normal from face f: the origin's projection onto its plane, located in f
    or, where D is flat and split into coplanar triangles, in the neighbour reached across the edge
    it lies beyond; its barycentric weights (clamped if the walk ends outside) combine the corners'
    points of A and of B."""
    row = EPA_ROW + EPA_PLANES + f
    n0, n1, n2, off = work[row, 0], work[row, 1], work[row, 2], work[row, 3]
    la = lb = lc = 0.0
    for _ in range(WALK_STEPS):
        la, lb, lc = _barycentric(work, iw, f, off * n0, off * n1, off * n2)
        worst = min(la, lb, lc)
        if worst >= 0.0:
            break
        e = 1 if la == worst else (2 if lb == worst else 0)  # the edge opposite the negative corner
        g = _adj(iw, f, e)
        gr = EPA_ROW + EPA_PLANES + g
        if work[gr, 0] * n0 + work[gr, 1] * n1 + work[gr, 2] * n2 < 1.0 - 1e-12:
            break  # not coplanar: the projection is at f's edge
        f = g
    la, lb, lc = max(la, 0.0), max(lb, 0.0), max(lc, 0.0)
    s = la + lb + lc
    la, lb, lc = la / s, lb / s, lc / s
    ia, ib, ic = _corner(iw, f, 0), _corner(iw, f, 1), _corner(iw, f, 2)
    for c in range(3):
        out[OUT_POINT_A + c] = (la * work[EPA_ROW + EPA_PA + ia, c] + lb * work[EPA_ROW + EPA_PA + ib, c]
                                + lc * work[EPA_ROW + EPA_PA + ic, c])
        out[OUT_POINT_B + c] = (la * work[EPA_ROW + EPA_PB + ia, c] + lb * work[EPA_ROW + EPA_PB + ib, c]
                                + lc * work[EPA_ROW + EPA_PB + ic, c])
    out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2] = n0, n1, n2


@kernel(inline="always")
def _off_the_bound(out, sd, tol_abs):
    """Whether out's witness points, B's less A's, miss sd times the normal by more than tol_abs."""
    g = 0.0
    for c in range(3):
        g = max(g, abs(out[OUT_POINT_B + c] - out[OUT_POINT_A + c] - sd * out[OUT_NORMAL + c]))
    return g > tol_abs


@kernel(inline="always")
def _exact_side(sides):
    """The side whose point a support pair kept for a witness takes as exact (keep_best's core): B where
    only B is an STP-BV's core, else A (a polytope's support along the normal is as exact)."""
    return 2 if sides == 2 else 1


@kernel
def _best_witness(work, sd, out):
    """Witness points and normal of the exact deepest support kept (by _exact_deepest, or along a
    curved set's deepest normal), sd the signed distance.

    Along a curved set's normal only its core's support point is the witness: the core is strictly
    convex there, the other side need not be (a polytope's support set is an edge or a face, whose
    vertex the support returns, off the normal's line by up to the edge's length; another core's is
    its point for a normal that is not quite D's deepest). Its witness is then the core's point moved
    by sd along the normal, on the other side's support plane within the bounds' gap."""
    for c in range(3):
        out[OUT_POINT_A + c] = work[EPA_ROW + EPA_BEST, c]
        out[OUT_POINT_B + c] = work[EPA_ROW + EPA_BEST + 1, c]
        out[OUT_NORMAL + c] = work[EPA_ROW + EPA_BEST + 2, c]
    sides = work[EPA_ROW + EPA_BEST + 1, 3]
    if sides == 1:  # A is the core
        for c in range(3):
            out[OUT_POINT_B + c] = out[OUT_POINT_A + c] + sd * out[OUT_NORMAL + c]
    elif sides == 2:
        for c in range(3):
            out[OUT_POINT_A + c] = out[OUT_POINT_B + c] - sd * out[OUT_NORMAL + c]


@kernel
def _exact_deepest(pair, i, lower, warm, work):
    """The bound sd >= lower, improved by the support along vertex i's deepest sphere normal u* if
    its cap holds u* and its depth there beats the bound (spq.kernels.epa_caps); that support is
    then kept as the exact witness. Returns the bound."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    ok, v0, v1, v2, depth = deepest_normal(work, i)
    if not ok or not -depth > lower:
        return lower
    h = _support_inline(pair, v0, v1, v2, warm, work)
    if -h > lower:
        keep_best(work, work[EPA_ROW + EPA_TMP], work[EPA_ROW + EPA_TMP + 1], v0, v1, v2, 0)
        return -h
    return lower


@kernel
def _face_distance(work, iw, f):
    """Distance from the origin to a point of face f's triangle, nearest up to rounding: an upper
    bound on the distance to D, whose weights (corners 0, 1, 2, summing to 1) are left in row
    EPA_NEAR + 3.

    The norm of the weights' point, not closest_on_triangle's squared distance: that comes from
    the triangle's plane, whose normal a sliver's cross product (two corners 1e-6 apart on a curved
    body, the third a metre away) turns by 1e-10 rad, so it fell below the distance to D (8.5e-13 m
    under it, fuzz seed 85). The weights' own rounding (their sum missed 1 by 3e-11 there) is taken
    out by dividing by their sum; what is left moves the point along the triangle, which changes its
    distance to second order only."""
    W = work[EPA_ROW + EPA_NEAR:EPA_ROW + EPA_NEAR + 3]
    for k in range(3):
        v = _row(_corner(iw, f, k))
        for c in range(3):
            W[k, c] = work[v, c]
    lam = work[EPA_ROW + EPA_NEAR + 3]
    closest_on_triangle(W, 0, 1, 2, lam, work[EPA_ROW + EPA_NEAR + 4])
    total = lam[0] + lam[1] + lam[2]
    d2 = 0.0
    for k in range(3):
        lam[k] /= total
    for c in range(3):
        x = lam[0] * W[0, c] + lam[1] * W[1, c] + lam[2] * W[2, c]
        d2 += x * x
    return math.sqrt(d2)


@kernel
def _near_witness(work, iw, f, size, out):
    """Witness points and normal of an origin outside P, nearest face f (weights from
    _face_distance, summing to 1, so that the points lie in the bodies): the nearest point p = a - b
    of the face, normal -p / |p| (A to B), or the
    face's outward normal where |p| is rounding noise of the polytope's size."""
    lam = work[EPA_ROW + EPA_NEAR + 3]
    for c in range(3):
        sa = 0.0
        sb = 0.0
        for k in range(3):
            v = _corner(iw, f, k)
            sa += lam[k] * work[EPA_ROW + EPA_PA + v, c]
            sb += lam[k] * work[EPA_ROW + EPA_PB + v, c]
        out[OUT_POINT_A + c] = sa
        out[OUT_POINT_B + c] = sb
    g0 = out[OUT_POINT_B] - out[OUT_POINT_A]
    g1 = out[OUT_POINT_B + 1] - out[OUT_POINT_A + 1]
    g2 = out[OUT_POINT_B + 2] - out[OUT_POINT_A + 2]
    gn = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
    if gn > NOISE_REL * size:
        out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2] = g0 / gn, g1 / gn, g2 / gn
    else:
        row = EPA_ROW + EPA_PLANES + f
        out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2] = work[row, 0], work[row, 1], work[row, 2]


# ------------------------------------------------------------------------------------------
# the algorithm
# ------------------------------------------------------------------------------------------
@kernel(inline="always")
def tie_side(kA, kB):
    """1 (B) or 0 (A): the polytope side of a polytope and a superellipsoid, whose EPA may take
    _tie_partners; -1 for any other pair."""
    if kA == SUPERELLIPSOID and kB == POLYTOPE:
        return 1
    if kA == POLYTOPE and kB == SUPERELLIPSOID:
        return 0
    return -1


@kernel
def _tied_vertices(f, e0, e1, e2, rel):
    """The two vertices of polytope f (vertices in its own frame) farthest along e, and whether the
    second lies within rel (times the largest |coordinate|) of the first along it."""
    best = second = -math.inf
    i1 = i2 = -1
    scale = 0.0
    for i in range(f.shape[0] // 3):
        x0, x1, x2 = f[at(3 * i)], f[at(3 * i + 1)], f[at(3 * i + 2)]
        scale = max(scale, abs(x0), abs(x1), abs(x2))
        v = e0 * x0 + e1 * x1 + e2 * x2
        if v > best:
            second, i2 = best, i1
            best, i1 = v, i
        elif v > second:
            second, i2 = v, i
    return i1, i2, i2 >= 0 and best - second <= rel * scale


@kernel
def _tie_partners(pair, side, n, nv, top, eps, c, work, iw):
    """Where the polytope side's support along the unit normal n (A's frame) of P's least face ties
    between two vertices v and v' (an edge of the polytope faces the superellipsoid), every vertex of
    P that came from v gets a partner from v': the same superellipsoid point with v' for v, a point of D
    (so P stays in D); and likewise from v' to v. A run that stalls short of the tolerance there has
    its support points on two near-lines of D's ruled strip (the superellipsoid's points less either
    end of the edge), and its faces joining three points of one line are slivers whose planes floating
    point cannot place; the partners make faces across the strip, whose planes it can. Of 400 poses
    within 1e-6 m of fuzz case cse-signed-failed-14, 175 failed without them and 54 with them; the
    kind's other cases (12, 13) still fail where degenerate faces of one end refuse the fan from the
    next support point (docs/notes/speed-45.md, stop 126). c: the run's interior point, eps: its visibility
    threshold. Returns (nv, top, partners added)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    n0, n1, n2 = n
    c0, c1, c2 = c
    if side == 1:  # B's support is along -n, in B's frame
        e0 = -(R[0, 0] * n0 + R[1, 0] * n1 + R[2, 0] * n2)
        e1 = -(R[0, 1] * n0 + R[1, 1] * n1 + R[2, 1] * n2)
        e2 = -(R[0, 2] * n0 + R[1, 2] * n1 + R[2, 2] * n2)
        fp = fB
    else:
        e0, e1, e2 = n0, n1, n2
        fp = fA
    v, v2, tied = _tied_vertices(fp, e0, e1, e2, TIE_REL)
    if not tied:
        return nv, top, 0
    added = 0
    m = nv
    for i in range(m):
        if nv >= EPA_MAX_VERTICES:
            break
        own = feature(iw, i, side)
        if own != v and own != v2:
            continue
        other = v2 if own == v else v
        q0, q1, q2 = fp[at(3 * other)], fp[at(3 * other + 1)], fp[at(3 * other + 2)]
        if side == 1:  # into A's frame
            q0, q1, q2 = (R[0, 0] * q0 + R[0, 1] * q1 + R[0, 2] * q2 + t[0],
                          R[1, 0] * q0 + R[1, 1] * q1 + R[1, 2] * q2 + t[1],
                          R[2, 0] * q0 + R[2, 1] * q1 + R[2, 2] * q2 + t[2])
        r = _row(nv)
        for c in range(3):
            if side == 1:
                work[EPA_ROW + EPA_PA + nv, c] = work[EPA_ROW + EPA_PA + i, c]
                work[EPA_ROW + EPA_PB + nv, c] = (q0, q1, q2)[c]
            else:
                work[EPA_ROW + EPA_PA + nv, c] = (q0, q1, q2)[c]
                work[EPA_ROW + EPA_PB + nv, c] = work[EPA_ROW + EPA_PB + i, c]
            work[r, c] = work[EPA_ROW + EPA_PA + nv, c] - work[EPA_ROW + EPA_PB + nv, c]
        if _is_vertex(work, nv, work[r]):
            continue
        g = -1
        for h in range(top):  # a live face that sees it (none: it lies in P already)
            if _alive(iw, h) and _height(work, h, work[r]) > eps:
                g = h
                break
        if g < 0:
            continue
        if side == 1:
            _set_features(iw, nv, feature(iw, i, 0), other)
        else:
            _set_features(iw, nv, other, feature(iw, i, 1))
        clear_sphere(work, nv)
        iw[EPA_IOFF + EPA_CLOCK] += 1
        stop, top = _expand(work, iw, g, nv, iw[EPA_IOFF + EPA_CLOCK], top, eps, c0, c1, c2)
        if stop == 0:
            nv += 1
            added += 1
    return nv, top, added


@kernel
def epa_start(pair, k, simplex, warm, work, iw, out):
    """The initial polytope: the k simplex points (rows of SW = SPA - SPB, their support features in
    the columns of SFI), reduced to independent ones and grown into a tetrahedron.

    Returns (nv, top, c0, c1, c2, lower): vertices, face slots used, a point strictly inside the
    polytope (its centroid: the polytope only grows), and the bound sd >= lower met on the way.
    nv < 4: D is flat (no tetrahedron), and out's normal is one across it (see _flat_normal)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    SW, SPA, SPB, SFI = simplex
    nv = 0
    for i in range(k):
        if not _is_vertex(work, nv, SW[i]):
            _vertex(work, nv, SW[i], SPA[i], SPB[i])
            _set_features(iw, nv, int(SFI[0, i]), int(SFI[1, i]))
            nv += 1
    lower = -math.inf
    nv = _span(work, iw, nv)
    if nv < 4:
        nv, lower = _grow(pair, nv, warm, work, iw)
        if nv < 4:
            _flat_normal(work, nv, out)
            return nv, 0, 0.0, 0.0, 0.0, lower
    for i in range(nv):  # the simplex's directions are not kept: no caps
        clear_sphere(work, i)
    clear_best(work)
    c0 = c1 = c2 = 0.0
    for i in range(4):
        c0 += 0.25 * work[_row(i), 0]
        c1 += 0.25 * work[_row(i), 1]
        c2 += 0.25 * work[_row(i), 2]
    ok, top = _tetrahedron(work, iw, c0, c1, c2)
    if not ok:
        _flat_normal(work, 3, out)
        return 3, 0, 0.0, 0.0, 0.0, lower
    return nv, top, c0, c1, c2, lower


@kernel
def epa_run(pair, tol, nv, top, c, upper, lower, warm,
            work, iw, out):
    """Grow the polytope of epa_start (nv vertices, top face slots, interior point c) on the supports
    of cores A and B until the bounds upper (sd <= upper) and lower close, from the given ones.

    While the origin lies outside P, the distance to the face it lies farthest beyond bounds sd from
    above too (P lies in D), so that a descent stalled within about tol_abs of touching (a smooth
    body's) is settled from either side.

    Returns (outcome, closed, upper, lower, iterations, nv, top). EPA_RESULT: the result
    (distance = upper, witness points, normal, bounds, status: FAILED if not closed) is in out,
    A's frame, margins not included. EPA_OUTSIDE: out's normal is the outward normal of the face
    the origin lies beyond; nothing else is written."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    c0, c1, c2 = c
    size = _size(work, nv)
    it = 0
    steps = min(EPA_STEPS_PER_ITERATION * max_iter, EPA_MAX_STEPS)
    # the caps cost about a fifth of a step: only a run still open after CAPS_AFTER steps takes them
    # (most close before), and only between bodies that can carry them; every face made without
    # them has its offset as its certified offset, every vertex no cap
    cappable = can_cap(kA) and can_cap(kB)
    balls = ball_sides(kA, kB) != NO_BALLS
    caps = False
    iw[EPA_IOFF + EPA_CAPS] = 0
    closed = False
    stop = STOP_CLOSED
    # an STP-BV's core against a polytope: the least face is certified from curved sets in D before it
    # is expanded (spq.kernels.epa_curved), from the run's own supports (vertices from nv on)
    sides = certifying_sides(kA, kB)
    first = nv
    clear_set(work)
    # the depth of the deepest curved set that certified a face: its support along its deepest normal
    # is taken when it is found, and closes the gap where that set is D's deepest part
    pd = -math.inf
    f, off = _least_face(work, iw, top)
    near = False  # whether upper is the distance to P (the origin outside it), witnesses in out
    blocked = 0
    lenient = False  # the last resort of a run stopped by expansions floating point could not make
    # a polytope against a superellipsoid that stalls short of the tolerance takes _tie_partners once
    ties = tie_side(kA, kB)
    polished = ties < 0
    while True:
        while True:
            f, off = _least_face(work, iw, top)
            least = off
            if blocked > 0:
                if f < 0:  # every live face set aside: take them back and stop
                    _unblock_all(work, iw, top)
                    f, off = _least_face(work, iw, top)
                    if _take_lenient(lenient, closed, off, upper, lower, tol_abs, blocked, STOP_FAN_INWARD):
                        lenient, blocked = True, 0
                        continue
                    break
                least = min(off, _blocked_least(work, iw, top))
            if sides != 0 and off > 0.0 and off >= -lower * (1.0 - CERT_WINDOW) and not tried(work, f) and \
                    may_certify(pair, sides, work, iw, f, first):
                set_tried(work, f, True)
                row = at(EPA_ROW + EPA_PLANES + f)
                r, u0, u1, u2, depth, core = face_certificate(pair, sides, work, iw, f, first, work[row, 0],
                                                              work[row, 1], work[row, 2], work[row, 3])
                if r > off and depth > pd:
                    # a set deeper than any before: its support along its deepest normal at once, which
                    # bounds the depth from above at the set's own depth where the set is D's deepest part
                    # (taken later, once the polytope had caught up with the set, a set short of that let
                    # every face in reach be lifted to its depth and expanded all the same: kuka_link_4's
                    # STP-STP overlaps took twice the scans, stop 94)
                    pd = depth
                    h = _support_inline(pair, u0, u1, u2, warm, work)
                    if -h > lower:
                        lower = -h
                        keep_best(work, work[EPA_ROW + EPA_TMP], work[EPA_ROW + EPA_TMP + 1], u0, u1, u2, core)
                # a lift short of the depth's upper bound less the tolerance would only delay the face's
                # expansion: such lifts are not taken
                gap = tol_abs + tol_rel * abs(lower)
                if r > off and r >= -lower - gap:
                    set_certified(work, f, r)
                    continue
            if off >= 0.0:
                upper = min(upper, -least)  # (only faces of offset >= 0 are set aside)
                near = False
            else:
                d = _face_distance(work, iw, f)
                if d < upper:
                    upper = d
                    near = True
                    _near_witness(work, iw, f, size, out)
            if bounds_closed(upper, lower, tol_abs, tol_rel):
                closed = True
                break
            if it >= steps or nv >= EPA_MAX_VERTICES:
                stop = STOP_ITERATIONS if it >= steps else STOP_VERTICES
                break
            if (it == CENTRES_AFTER or it == CENTRES_AFTER_BALLS) and balls and off >= 0.0 and nv <= SLOT0 and \
                    top <= FACE0 and (it == CENTRES_AFTER or ball_sides(kA, kB) == BOTH_BALLS) and settle_from_centres(
                    pair, (tol_abs, tol_rel, CENTRES_CUTS, math.inf if it == CENTRES_AFTER else CENTRES_EARLY_WIDTH),
                    upper, it, warm, work, iw, out):
                # (the origin in P, which lies in the lower halves of its blocks: the run goes on if they do not
                # close, from the same polytope; only the descent's rows and the support hints are overwritten)
                work[EPA_ROW + EPA_TMP, 3] = STOP_CENTRES
                return EPA_RESULT, True, out[OUT_UPPER], out[OUT_LOWER], int(out[OUT_ITERATIONS]), nv, top
            it += 1
            if cappable and it == CAPS_AFTER + 1:
                caps = True
                iw[EPA_IOFF + EPA_CAPS] = 1
            row = at(EPA_ROW + EPA_PLANES + f)
            h = _support_inline(pair, work[row, 0], work[row, 1], work[row, 2], warm, work)
            if -h > lower:
                lower = -h
                if sides != 0:  # the support pair that bounds the depth: a lifted last face's witness
                    keep_best(work, work[EPA_ROW + EPA_TMP], work[EPA_ROW + EPA_TMP + 1], work[row, 0], work[row, 1],
                              work[row, 2], _exact_side(sides))
            if bounds_closed(upper, lower, tol_abs, tol_rel):
                closed = True
                break
            w = work[EPA_ROW + EPA_TMP + 2]
            size = max(size, abs(w[0]), abs(w[1]), abs(w[2]))
            eps = VISIBLE_REL * size
            # (a point above the face's plane cannot be a vertex already: the polytope is convex)
            if h - work[row, 3] <= eps:
                # nothing of D beyond this face: the bounds are as good as this precision allows
                closed = off >= 0.0 and upper - lower <= STALL_SLACK * abs(upper) + tol_abs
                stop = STOP_NO_PROGRESS
                if _take_lenient(lenient, closed, off, upper, lower, tol_abs, blocked, stop):
                    lenient, blocked = True, 0
                    _unblock_all(work, iw, top)
                    continue
                break
            _keep_support(work, iw, warm, nv)
            if caps:
                support_sphere(pair, work[row, 0], work[row, 1], work[row, 2], warm[0], warm[1],
                               work, nv)
            else:
                clear_sphere(work, nv)
            iw[EPA_IOFF + EPA_CLOCK] += 1  # stamps are unique across runs on the same polytope
            stop, top = _expand(work, iw, f, nv, iw[EPA_IOFF + EPA_CLOCK], top, eps, c0, c1, c2)
            if stop != 0 and stop != STOP_FACE_SLOTS and lenient:
                # the point lies within rounding of the planes of faces that do not see it (a nearly flat
                # stretch of D): replace those too. Their corners off the horizon leave P's boundary, which
                # passes below them: P shrinks, still lies in D, and its faces still bound the depth
                iw[EPA_IOFF + EPA_CLOCK] += 1
                stop, top = _expand(work, iw, f, nv, iw[EPA_IOFF + EPA_CLOCK], top, -LENIENT_REL * size, c0, c1, c2)
                if stop == STOP_FAN_INWARD:
                    stop, top = _carve_inward(work, iw, f, nv, top, -LENIENT_REL * size, size, (c0, c1, c2))
            if stop != 0:
                stalled = off >= 0.0 and upper - lower <= STALL_SLACK * abs(upper) + tol_abs
                if not stalled and stop != STOP_FACE_SLOTS and off >= 0.0 and blocked < MAX_BLOCKED:
                    # the polytope stays as it was: go on from the other faces, one of which may see
                    # this support point from a better-conditioned side and replace the face
                    _block(work, f)
                    blocked += 1
                    continue
                if _take_lenient(lenient, closed, off, upper, lower, tol_abs, blocked, stop):
                    lenient, blocked = True, 0
                    _unblock_all(work, iw, top)
                    continue
                break
            nv += 1
            if caps:
                lower = _exact_deepest(pair, nv - 1, lower, warm, work)
        if closed or polished:
            break
        polished = True
        if blocked > 0:
            _unblock_all(work, iw, top)
            blocked = 0
        f, off = _least_face(work, iw, top)
        if f < 0 or off < 0.0:
            break
        row = at(EPA_ROW + EPA_PLANES + f)
        nv, top, added = _tie_partners(pair, ties, (work[row, 0], work[row, 1], work[row, 2]), nv, top,
                                       VISIBLE_REL * size, (c0, c1, c2), work, iw)
        if added == 0:
            break
        stop = STOP_CLOSED
    if not closed and (blocked > 0 or stop == STOP_HORIZON or stop == STOP_FAN_SLIVER or stop == STOP_FAN_INWARD):
        # an expansion that floating point cannot make (a support point on a horizon edge's line) is
        # a stall as much as a support point on the face: the same slack settles it, here or at the
        # end of a run that set such faces aside (a run within it at the failure stops there)
        closed = off >= 0.0 and upper - lower <= STALL_SLACK * abs(upper) + tol_abs
    work[EPA_ROW + EPA_TMP, 3] = STOP_CLOSED if closed else stop
    if off < 0.0 and not near:
        row = EPA_ROW + EPA_PLANES + f
        out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2] = work[row, 0], work[row, 1], work[row, 2]
        return EPA_OUTSIDE, closed, upper, lower, it, nv, top
    if not near:
        # the face's own points miss the bound where it was lifted, where an expanded lifted face left it
        # below the bound (upper keeps the least offset's best), or where the origin's projection falls
        # off it beside a lifted neighbour (its weights clamped): then the support pair along the
        # normal whose support bounds the depth within the tolerance (kept with every bound it set)
        row = at(EPA_ROW + EPA_PLANES + f)
        off_f = work[row, 3]
        best = certified(work, f) > off_f or (sides != 0 and upper < -off_f)
        if not best:
            _witness(work, iw, f, out)
            best = sides != 0 and _off_the_bound(out, upper, tol_abs)
        if best:
            if not has_best(work):
                _support_inline(pair, work[row, 0], work[row, 1], work[row, 2], warm, work)
                keep_best(work, work[EPA_ROW + EPA_TMP], work[EPA_ROW + EPA_TMP + 1], work[row, 0], work[row, 1],
                          work[row, 2], _exact_side(sides))
            _best_witness(work, upper, out)
    out[OUT_DISTANCE] = upper
    out[OUT_UPPER] = upper
    out[OUT_LOWER] = min(lower, upper)  # rounding may cross them by an ulp
    out[OUT_ITERATIONS] = it
    out[OUT_STATUS] = FAILED
    if closed:
        out[OUT_STATUS] = OVERLAPPING if upper < -tol_abs else (TOUCHING if upper <= tol_abs else SEPARATED)
    return EPA_RESULT, closed, upper, lower, it, nv, top


@kernel
def epa(pair, tol, k, simplex, upper0, lower0, warm,
        work, iw, out):
    """Signed distance of cores A and B (B at (R, t) in A's frame) from a GJK simplex of k support
    points (rows of SW = SPA - SPB, their support features in the columns of SFI) that ended with
    the origin in it or within tol_abs of it.

    upper0: the GJK's upper bound on sd (0 if it proved overlap, else its distance); lower0: a known
    lower bound (-inf if none). warm: int64 (2,) support features (in/out). work, iw: the query's
    scratch. Returns (outcome, closed, upper, lower, iterations): closed when the bounds met the
    tolerance. EPA_RESULT and EPA_OUTSIDE: see epa_run. EPA_FLAT: D has no tetrahedron; out's
    normal is one across it (NaN: any direction).
    """
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    SW, SPA, SPB, SFI = simplex
    nv, top, c0, c1, c2, low = epa_start(pair, k, simplex, warm, work, iw, out)
    lower = max(lower0, low)
    if nv < 4:
        return EPA_FLAT, False, upper0, lower, 0
    outcome, closed, upper, lower, it, nv, top = epa_run(pair, tol, nv,
                                                         top, (c0, c1, c2), upper0, lower, warm, work, iw, out)
    return outcome, closed, upper, lower, it


@kernel
def _flat_normal(work, m, out):
    """Into out's normal: a unit vector across the flat set spanned by vertices 0..m-1 (the normal of
    a triangle's plane, one orthogonal to a segment), or NaN for a point (any direction is)."""
    if m >= 3:
        n0, n1, n2 = _plane_normal(work, 0, 1, 2)
    elif m == 2:
        a, b = _row(0), _row(1)
        e0, e1, e2 = work[b, 0] - work[a, 0], work[b, 1] - work[a, 1], work[b, 2] - work[a, 2]
        if abs(e0) < 0.6 * math.sqrt(e0 * e0 + e1 * e1 + e2 * e2):
            n0, n1, n2 = 0.0, e2, -e1
        else:
            n0, n1, n2 = -e2, 0.0, e0
        nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        n0, n1, n2 = n0 / nn, n1 / nn, n2 / nn
    else:
        n0 = n1 = n2 = math.nan
    out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2] = n0, n1, n2
