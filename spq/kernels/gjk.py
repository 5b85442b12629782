"""GJK distance between two convex cores, with a certificate-based stop.

The steps of the algorithm are small functions named after them: the support of the Minkowski
difference, the closest point of a simplex to the origin (signed volumes, Montanari et al. 2017,
on the dominant projection), the termination test, and the overlap certification.

Everything runs in body A's frame: B's pose relative to A is (R, t). Working near A's origin keeps
absolute thresholds meaningful when both bodies are far from the world origin (NOTES section 5).

Stop rule: the search keeps the best lower bound, the separating-plane distance v.w/|v|, and stops
when upper - lower <= tol_abs + tol_rel * upper, where upper = |v| is the distance of the current
simplex point. The reported distance is upper; the true distance lies in [lower, upper]. A search
that rounding stalls with the gap still open (near touching, where v's direction is off by about
eps / distance) takes the bound along the normal of the facet or edge of D it stalled on
(spq.kernels.facet_bound) before it reports FAILED.
Overlap is declared only when a non-degenerate tetrahedron of support points holds the origin
strictly inside; a distance within tol_abs of zero that cannot be so certified is "touching".
"""

from __future__ import annotations

import math

import numpy as np
from spq.kernels.indexing import at
from spq.kernels.jit import kernel

from spq.kernels.kinds import POINT, POLYTOPE, STP, STP_CORE, SUPERELLIPSOID
from spq.kernels.dispatch import support_local
from spq.kernels.epa_layout import EPA_FLOAT_ROWS, EPA_INT_SIZE
from spq.kernels.facet_bound import facet_lower_bound

SEPARATED = 0
TOUCHING = 1
OVERLAPPING = 2
FAILED = 3
STATUS_NAMES = ("separated", "touching", "overlapping", "failed")

# The descent's support-points gap test (below in descend) runs where a side is curved, or the tolerance is
# at least this loose (the searches that only aim a finish: an STP-BV pair's hulls at 1e-3, a
# superellipsoid's inscribed polytopes at 1e-2 and 5e-2), where a support pair near the closest one passes
# it before the simplex settles. Between flat sides at a tighter tolerance (a polytope pair's 1e-10, an
# STP-BV's hull against a polytope at 1e-6) the simplex point reaches the answer in finitely many steps
# and the test ended a descent sooner only where it had started along the answer (0.1% of JVRC-1's cold
# pairs, one iteration each); skipped there, it saves 3% to 4% of a polytope pair's query (a square root,
# and a branch taken at random: |w| < |v| holds in 27% of a separated kuka_link_4 pair's iterations).
SUPPORT_GAP_REL_TOL = 1e-4
DEGENERATE_AREA = 1e-24  # |n|^2 / scale^4 below which a triangle is treated as a segment set
DEGENERATE_VOLUME = 1e-14  # |V| / scale^3 below which a tetrahedron is treated as its faces
STALL_SLACK = 1e-9  # a stalled search still counts as converged if its gap is within this, relative
STALLED = -1  # descend's own: a stall with the gap still open (never returned)

# Layout of the result vector written by gjk_query (all in body A's frame).
OUT_DISTANCE = 0
OUT_POINT_A = 1  # 1..3
OUT_POINT_B = 4  # 4..6
OUT_NORMAL = 7  # 7..9, unit, from A to B
OUT_LOWER = 10
OUT_ITERATIONS = 11
OUT_STATUS = 12
OUT_UPPER = 13  # certified upper bound: the distance itself, or in a signed query the signed distance's
OUT_SIZE = 14
DESCENT_ROWS = 22  # rows 0-21 of the scratch array: the descent's (simplex, weights, support points, ids)
# Rows of a descent's last support points s_A(-v), s_B(v) (A's frame), and the cell that is 1.0 when
# they were taken along the final v: the supports along the final normal, which a certificate re-uses.
SUPPORT_ROW_A, SUPPORT_ROW_B = 13, 14
FRESH_ROW, FRESH_COL = 15, 3
PATCH_ROWS = 4  # rows after the descent's: the patch finish's scratch
PROBE_ROW = DESCENT_ROWS + PATCH_ROWS  # first row of certify_overlap's scratch (a descent's, then 2 rows)
PROBE_END = PROBE_ROW + DESCENT_ROWS + 2
EPA_ROW = PROBE_END  # first row of a signed query's expanding polytope (spq.kernels.epa_layout)
WORK_ROWS = EPA_ROW + EPA_FLOAT_ROWS  # rows of the (WORK_ROWS, 4) scratch gjk_query takes

# Warm-start state, an int64 array: the last support features of A and B, then the final simplex
# of the previous query as (count, 4 feature ids of A, 4 of B), re-evaluated at the new poses; then
# whether an STP-BV query last found the bodies overlapping (its simplex is then the hulls', see
# query.gjk_query).
WARM_FEATURE_A, WARM_FEATURE_B, WARM_COUNT, WARM_SIMPLEX_A, WARM_SIMPLEX_B, WARM_HULL_OVERLAP = 0, 1, 2, 3, 7, 11
WARM_SIZE = 12
EPA_IOFF = 2 * WARM_SIZE  # int64 scratch of gjk_query: the STP search's simplex ids, the probes' warm start,
IWORK_SIZE = EPA_IOFF + EPA_INT_SIZE  # then a signed query's polytope (spq.kernels.epa_layout)


@kernel(inline="always")
def clear_warm(warm):
    """Zero a warm-start state (WARM_SIZE entries) with stores of constant length. A slice fill,
    warm[:] = 0, is a call to libc's memset, whose masked stores (for a fill under 32 bytes) no
    later load can take its value from before they are written out: the query's first reads of
    its state then wait (about 3% of a cold robot-scene sweep, perf)."""
    for i in range(WARM_SIZE):
        warm[i] = 0


# ------------------------------------------------------------------------------------------
# closest point of a simplex to the origin
# ------------------------------------------------------------------------------------------
@kernel
def _zero(lam):
    lam[0] = 0.0
    lam[1] = 0.0
    lam[2] = 0.0
    lam[3] = 0.0


@kernel
def closest_on_segment(W, i, j, lam):
    """Closest point of segment W[i]W[j] to the origin: barycentric weights into lam (slots i, j).

    Returns (mask of the slots used, squared distance)."""
    # the slots as unsigned indices (spq.kernels.indexing): numba would wrap these arguments as if
    # they could be negative at every read; the masks take the signed ones
    ui, uj = at(i), at(j)
    _zero(lam)
    t0 = W[uj, 0] - W[ui, 0]
    t1 = W[uj, 1] - W[ui, 1]
    t2 = W[uj, 2] - W[ui, 2]
    tt = t0 * t0 + t1 * t1 + t2 * t2
    pt = W[ui, 0] * t0 + W[ui, 1] * t1 + W[ui, 2] * t2
    if tt <= 0.0 or pt >= 0.0:
        lam[ui] = 1.0
        return 1 << i, W[ui, 0] ** 2 + W[ui, 1] ** 2 + W[ui, 2] ** 2
    s = -pt / tt
    if s >= 1.0:
        lam[uj] = 1.0
        return 1 << j, W[uj, 0] ** 2 + W[uj, 1] ** 2 + W[uj, 2] ** 2
    lam[ui] = 1.0 - s
    lam[uj] = s
    x0 = W[ui, 0] + s * t0
    x1 = W[ui, 1] + s * t1
    x2 = W[ui, 2] + s * t2
    return (1 << i) | (1 << j), x0 * x0 + x1 * x1 + x2 * x2


@kernel
def _copy4(src, dst):
    dst[0] = src[0]
    dst[1] = src[1]
    dst[2] = src[2]
    dst[3] = src[3]


@kernel
def _best_edge(W, i, j, lam, scratch, mask, d2, edge_mask, ei, ej):
    """Keep the better of the current best (mask, d2, lam) and edge (ei, ej)."""
    m, e2 = closest_on_segment(W, ei, ej, scratch)
    if e2 < d2:
        _copy4(scratch, lam)
        return m, e2
    return mask, d2


@kernel
def closest_on_triangle(W, i, j, k, lam, scratch):
    """Closest point of triangle W[i]W[j]W[k] to the origin (signed areas on the dominant plane).

    Returns (mask, squared distance); weights go to lam."""
    ui, uj, uk = at(i), at(j), at(k)  # unsigned, as in closest_on_segment
    u0 = W[uj, 0] - W[ui, 0]
    u1 = W[uj, 1] - W[ui, 1]
    u2 = W[uj, 2] - W[ui, 2]
    w0 = W[uk, 0] - W[ui, 0]
    w1 = W[uk, 1] - W[ui, 1]
    w2 = W[uk, 2] - W[ui, 2]
    n0 = u1 * w2 - u2 * w1
    n1 = u2 * w0 - u0 * w2
    n2 = u0 * w1 - u1 * w0
    nn = n0 * n0 + n1 * n1 + n2 * n2
    scale2 = max(u0 * u0 + u1 * u1 + u2 * u2, w0 * w0 + w1 * w1 + w2 * w2)
    inf = np.inf
    if nn <= DEGENERATE_AREA * scale2 * scale2:
        mask, d2 = 0, inf
        mask, d2 = _best_edge(W, i, j, lam, scratch, mask, d2, 0, i, j)
        mask, d2 = _best_edge(W, i, j, lam, scratch, mask, d2, 0, j, k)
        mask, d2 = _best_edge(W, i, j, lam, scratch, mask, d2, 0, i, k)
        return mask, d2
    # projection of the origin on the plane, then 2D signed areas on the dominant axis
    h = (W[ui, 0] * n0 + W[ui, 1] * n1 + W[ui, 2] * n2) / nn
    p0 = h * n0
    p1 = h * n1
    p2 = h * n2
    a0, a1, a2 = abs(n0), abs(n1), abs(n2)
    if a0 >= a1 and a0 >= a2:
        x, y, mu = 1, 2, n0
        px, py = p1, p2
    elif a1 >= a2:
        x, y, mu = 2, 0, n1
        px, py = p2, p0
    else:
        x, y, mu = 0, 1, n2
        px, py = p0, p1
    ix_, iy = W[ui, at(x)] - px, W[ui, at(y)] - py
    jx, jy = W[uj, at(x)] - px, W[uj, at(y)] - py
    kx, ky = W[uk, at(x)] - px, W[uk, at(y)] - py
    c_i = jx * ky - jy * kx  # area (p, j, k)
    c_j = kx * iy - ky * ix_  # area (i, p, k)
    c_k = ix_ * jy - iy * jx  # area (i, j, p)
    if c_i * mu >= 0.0 and c_j * mu >= 0.0 and c_k * mu >= 0.0:
        _zero(lam)
        lam[ui] = c_i / mu
        lam[uj] = c_j / mu
        lam[uk] = c_k / mu
        return (1 << i) | (1 << j) | (1 << k), h * h * nn
    mask, d2 = 0, inf
    if c_i * mu < 0.0:
        mask, d2 = _best_edge(W, i, j, lam, scratch, mask, d2, 0, j, k)
    if c_j * mu < 0.0:
        mask, d2 = _best_edge(W, i, j, lam, scratch, mask, d2, 0, i, k)
    if c_k * mu < 0.0:
        mask, d2 = _best_edge(W, i, j, lam, scratch, mask, d2, 0, i, j)
    return mask, d2


@kernel
def _triple(W, a, b, c):
    """W[a] . (W[b] x W[c])"""
    return (
        W[a, 0] * (W[b, 1] * W[c, 2] - W[b, 2] * W[c, 1])
        + W[a, 1] * (W[b, 2] * W[c, 0] - W[b, 0] * W[c, 2])
        + W[a, 2] * (W[b, 0] * W[c, 1] - W[b, 1] * W[c, 0])
    )


@kernel
def tetrahedron_volumes(W):
    """Signed volumes (x6) of the tetrahedron and of the four with one corner replaced by the origin.

    Returns (V, V0, V1, V2, V3); V = V0 + V1 + V2 + V3, and Vm / V is the barycentric weight of
    corner m for the origin."""
    v0 = _triple(W, 1, 2, 3)
    v1 = -_triple(W, 0, 2, 3)
    v2 = _triple(W, 0, 1, 3)
    v3 = -_triple(W, 0, 1, 2)
    return v0 + v1 + v2 + v3, v0, v1, v2, v3


@kernel
def _simplex_scale(W, k):
    s = 0.0
    for i in range(k):
        s = max(s, abs(W[i, 0]), abs(W[i, 1]), abs(W[i, 2]))
    return s


_TET_FACES = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])  # the face opposite each corner


@kernel
def closest_on_tetrahedron(W, lam, scratch, scratch2):
    """Closest point of tetrahedron W[0..3] to the origin.

    Returns (mask, squared distance, strictly_inside)."""
    V, v0, v1, v2, v3 = tetrahedron_volumes(W)
    s = _simplex_scale(W, 4)
    degenerate = abs(V) <= DEGENERATE_VOLUME * s * s * s
    if not degenerate and v0 * V > 0.0 and v1 * V > 0.0 and v2 * V > 0.0 and v3 * V > 0.0:
        lam[0] = v0 / V
        lam[1] = v1 / V
        lam[2] = v2 / V
        lam[3] = v3 / V
        return 15, 0.0, True
    vols = (v0, v1, v2, v3)
    mask, d2 = 0, np.inf
    for m in range(4):  # the face opposite corner m, if the origin is on its far side
        if degenerate or vols[m] * V <= 0.0:
            f = _TET_FACES[m]
            fm, e = closest_on_triangle(W, f[0], f[1], f[2], scratch, scratch2)
            if e < d2:
                mask, d2 = fm, e
                _copy4(scratch, lam)
    return mask, d2, False


@kernel(inline="always")
def reduce_simplex(W, PA, PB, FI, k, lam, scratch):
    """Replace the simplex (k points) by the smallest face holding its point closest to the origin.

    Rows of W, PA, PB and columns of FI (support feature ids) are compacted in place; returns
    (new k, strictly_inside)."""
    s1 = scratch[0]
    s2 = scratch[1]
    if k == 1:
        _zero(lam)
        lam[0] = 1.0
        mask, inside = 1, False
    elif k == 2:
        mask, _ = closest_on_segment(W, 0, 1, lam)
        inside = False
    elif k == 3:
        mask, _ = closest_on_triangle(W, 0, 1, 2, lam, s1)
        inside = False
    else:
        mask, _, inside = closest_on_tetrahedron(W, lam, s1, s2)
    n = 0
    for i in range(k):
        if mask & (1 << i):
            if n != i:
                r = at(n)
                for c in range(3):
                    W[r, c] = W[i, c]
                    PA[r, c] = PA[i, c]
                    PB[r, c] = PB[i, c]
                FI[0, r] = FI[0, i]
                FI[1, r] = FI[1, i]
                lam[r] = lam[i]
            n += 1
    return n, inside


# ------------------------------------------------------------------------------------------
# support of the Minkowski difference A - B, in A's frame
# ------------------------------------------------------------------------------------------
@kernel(inline="always")
def minkowski_support(pair, d0, d1, d2, warm, pa, pb, tmp):
    """pa = s_A(d), pb = s_B(-d) (both in A's frame); warm[0], warm[1] updated with the features."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    warm[0] = support_local(kA, fA, iA, d0, d1, d2, warm[0], pa)
    # -d in B's frame is -R^T d
    e0 = -(R[0, 0] * d0 + R[1, 0] * d1 + R[2, 0] * d2)
    e1 = -(R[0, 1] * d0 + R[1, 1] * d1 + R[2, 1] * d2)
    e2 = -(R[0, 2] * d0 + R[1, 2] * d1 + R[2, 2] * d2)
    warm[1] = support_local(kB, fB, iB, e0, e1, e2, warm[1], tmp)
    for r in range(3):
        pb[r] = R[r, 0] * tmp[0] + R[r, 1] * tmp[1] + R[r, 2] * tmp[2] + t[r]


@kernel(inline="always")
def _push(W, PA, PB, FI, k, pa, pb, warm):
    r = at(k)
    for c in range(3):
        PA[r, c] = pa[c]
        PB[r, c] = pb[c]
        W[r, c] = pa[c] - pb[c]
    FI[0, r] = warm[WARM_FEATURE_A]
    FI[1, r] = warm[WARM_FEATURE_B]


@kernel(inline="always")
def is_curved(kind):
    """Whether a body of this kind has curved faces (an STP-BV, its core, a superellipsoid), on which the
    descent's simplex point converges only in the limit."""
    return kind == STP or kind == STP_CORE or kind == SUPERELLIPSOID


@kernel(inline="always")
def rebuildable(kind):
    """Whether a warm-start simplex can be re-evaluated for this kind from feature ids alone."""
    return kind == POLYTOPE or kind == POINT


@kernel
def _corner(kind, f, i, c):
    """Coordinate c of feature i of a rebuildable core (local frame): a vertex, or the origin."""
    return f[at(3 * i + c)] if kind == POLYTOPE else 0.0


@kernel
def _rebuild_simplex(kA, fA, kB, fB, R, t, W, PA, PB, FI, warm):
    """The previous query's simplex, from its feature ids, at the current poses (repeats dropped)."""
    k = 0
    for i in range(warm[WARM_COUNT]):
        ia = warm[WARM_SIMPLEX_A + i] if kA == POLYTOPE else 0
        ib = warm[WARM_SIMPLEX_B + i] if kB == POLYTOPE else 0
        repeated = False
        for j in range(k):
            if FI[0, j] == ia and FI[1, j] == ib:
                repeated = True
        if repeated:
            continue
        b0, b1, b2 = _corner(kB, fB, ib, 0), _corner(kB, fB, ib, 1), _corner(kB, fB, ib, 2)
        for c in range(3):
            PA[k, c] = _corner(kA, fA, ia, c)
            PB[k, c] = R[c, 0] * b0 + R[c, 1] * b1 + R[c, 2] * b2 + t[c]
            W[k, c] = PA[k, c] - PB[k, c]
        FI[0, k] = ia
        FI[1, k] = ib
        k += 1
    return k


@kernel(inline="always")
def _save_simplex(FI, k, warm):
    warm[WARM_COUNT] = k
    for i in range(k):
        warm[WARM_SIMPLEX_A + i] = int(FI[0, i])
        warm[WARM_SIMPLEX_B + i] = int(FI[1, i])


@kernel(inline="always")
def _is_duplicate(PA, PB, k, pa, pb):
    for i in range(k):
        if (
            PA[i, 0] == pa[0] and PA[i, 1] == pa[1] and PA[i, 2] == pa[2]
            and PB[i, 0] == pb[0] and PB[i, 1] == pb[1] and PB[i, 2] == pb[2]
        ):
            return True
    return False


# ------------------------------------------------------------------------------------------
# overlap certification when the distance reaches zero
# ------------------------------------------------------------------------------------------
# Unit vectors to the corners of a regular tetrahedron: its inscribed ball has radius 1/3.
_PROBES = np.array([
    [1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0], [-1.0, -1.0, 1.0],
]) / math.sqrt(3.0)
PROBE_RADIUS_IN_TOL = 4.0  # probe tetrahedron circumradius, in units of tol_abs (> 3 so it certifies)


@kernel
def certify_overlap(pair, tol, warm, work, iwork):
    """OVERLAPPING if the origin is certainly inside A - B, else TOUCHING.

    The origin is inside A - B by at least s/3 - tol_abs if the four corners q of a regular
    tetrahedron of circumradius s around it all are (distance(q, A - B) <= tol_abs): A - B is
    convex, so it then holds the tetrahedron's inscribed ball. Each corner is one plain descent
    with B shifted by q, since distance(q, A - B) = distance(A, B + q). work: (DESCENT_ROWS + 2, 4)
    and iwork: int64 (WARM_SIZE,) scratch.
    """
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    s = PROBE_RADIUS_IN_TOL * tol_abs
    tq = work[DESCENT_ROWS, 0:3]
    zero = work[DESCENT_ROWS + 1, 0:3]
    for i in range(WARM_SIZE):  # the probes must not replace the query's own warm-start simplex
        iwork[i] = warm[i]
    for p in range(4):
        for c in range(3):
            tq[c] = t[c] + s * _PROBES[p, c]
            zero[c] = 0.0
        st, k, v0, v1, v2, vv, lower, it = descend((kA, mA, fA, iA, kB, mB, fB, iB, R, tq), tol,
                                                   zero, iwork, work)
        if st != OVERLAPPING and st != TOUCHING:
            return TOUCHING
    return OVERLAPPING


# ------------------------------------------------------------------------------------------
# the query
# ------------------------------------------------------------------------------------------
@kernel(inline="always")
def _combine(P, lam, k, out, offset):
    """out[offset:offset + 3] = the point of weights lam[:k] on P[:k], as P[0] + sum lam_i (P_i - P[0]):
    weights that miss a sum of 1 by rounding (a needle simplex's, 1e-13) then still give a point of the
    simplex, where sum lam_i P_i would be scaled towards the frame's origin, out of the body."""
    for c in range(3):
        s = 0.0
        for i in range(1, k):
            s += lam[i] * (P[i, c] - P[0, c])
        out[offset + c] = P[0, c] + s


@kernel
def descend(pair, tol, dir_in, warm, work):
    """The GJK descent: shrink the simplex towards the origin until the certificate closes.

    Returns (status, k, v0, v1, v2, |v|^2, lower bound, iterations); the simplex (k points) and
    its weights stay in work. TOUCHING here means |v| <= tol_abs, overlap not yet decided.
    """
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    W = work[0:4]
    PA = work[4:8]
    PB = work[8:12]
    lam = work[12]
    pa = work[13]
    pb = work[14]
    tmp = work[15]
    scratch = work[16:20]

    FI = work[20:22]
    work[FRESH_ROW, FRESH_COL] = 0.0
    lower = 0.0
    status = FAILED
    it = 0
    if warm[WARM_COUNT] > 0 and rebuildable(kA) and rebuildable(kB):
        k = _rebuild_simplex(kA, fA, kB, fB, R, t, W, PA, PB, FI, warm)
        k, inside = reduce_simplex(W, PA, PB, FI, k, lam, scratch)
        if inside:
            _save_simplex(FI, k, warm)
            return OVERLAPPING, k, 0.0, 0.0, 0.0, 0.0, 0.0, it
        v0 = v1 = v2 = 0.0
        for i in range(k):
            v0 += lam[i] * W[i, 0]
            v1 += lam[i] * W[i, 1]
            v2 += lam[i] * W[i, 2]
    else:
        d0, d1, d2 = dir_in[0], dir_in[1], dir_in[2]
        if d0 * d0 + d1 * d1 + d2 * d2 == 0.0:
            d0, d1, d2 = t[0], t[1], t[2]
            if d0 * d0 + d1 * d1 + d2 * d2 == 0.0:
                d0 = 1.0
        minkowski_support(pair, d0, d1, d2, warm, pa, pb, tmp)
        _push(W, PA, PB, FI, 0, pa, pb, warm)
        k = 1
        lam[0] = 1.0
        v0, v1, v2 = W[0, 0], W[0, 1], W[0, 2]
    vv = v0 * v0 + v1 * v1 + v2 * v2
    zero_tol = tol_abs if tol_abs > 0.0 else 1e-15 * math.sqrt(vv)
    gap_test = is_curved(kA) or is_curved(kB) or tol_rel >= SUPPORT_GAP_REL_TOL
    while it < max_iter:
        it += 1
        upper = math.sqrt(vv)
        if upper <= zero_tol:
            status = TOUCHING
            break
        minkowski_support(pair, -v0, -v1, -v2, warm, pa, pb, tmp)
        work[FRESH_ROW, FRESH_COL] = 1.0
        w0, w1, w2 = pa[0] - pb[0], pa[1] - pb[1], pa[2] - pb[2]
        vw = v0 * w0 + v1 * w1 + v2 * w2
        lower = max(lower, vw / upper)
        if upper - lower <= tol_abs + tol_rel * upper:
            status = TOUCHING if upper <= tol_abs else SEPARATED
            break
        # The support points are points of the bodies too: their distance |w| is an upper bound,
        # and on curved surfaces |w| - lower shrinks with the square of the direction's error,
        # long before the simplex point does. Stop on it, with them as witness points.
        # Skipped between flat sides at a tight tolerance (SUPPORT_GAP_REL_TOL says why).
        if gap_test:
            ww = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
            if ww < upper and ww - lower <= tol_abs + tol_rel * ww:
                for c in range(3):
                    PA[0, c] = pa[c]
                    PB[0, c] = pb[c]
                    W[0, c] = pa[c] - pb[c]
                FI[0, 0] = warm[WARM_FEATURE_A]
                FI[1, 0] = warm[WARM_FEATURE_B]
                k = 1
                lam[0] = 1.0
                v0, v1, v2, vv = w0, w1, w2, ww * ww
                work[FRESH_ROW, FRESH_COL] = 0.0
                status = TOUCHING if ww <= tol_abs else SEPARATED
                break
        if _is_duplicate(PA, PB, k, pa, pb):
            status = SEPARATED if upper - lower <= STALL_SLACK * upper + tol_abs else STALLED
            break
        _push(W, PA, PB, FI, k, pa, pb, warm)
        k += 1
        k, inside = reduce_simplex(W, PA, PB, FI, k, lam, scratch)
        work[FRESH_ROW, FRESH_COL] = 0.0
        if inside:
            status = OVERLAPPING
            v0 = v1 = v2 = vv = lower = 0.0
            break
        n0 = n1 = n2 = 0.0
        for i in range(k):
            n0 += lam[i] * W[i, 0]
            n1 += lam[i] * W[i, 1]
            n2 += lam[i] * W[i, 2]
        nv = n0 * n0 + n1 * n1 + n2 * n2
        if nv >= vv:
            # rounding stopped the descent: the bounds say whether the answer is good enough
            v0, v1, v2, vv = n0, n1, n2, nv
            upper = math.sqrt(vv)
            status = SEPARATED if upper - lower <= STALL_SLACK * upper + tol_abs else STALLED
            break
        v0, v1, v2, vv = n0, n1, n2, nv
    if status == STALLED:
        # rounding's angle on a facet or edge of D (near touching): bound along its own normal
        upper = math.sqrt(vv)
        lower = facet_lower_bound(pair, W, k, v0, v1, v2, upper, lower, tmp)
        status = SEPARATED if upper - lower <= STALL_SLACK * upper + tol_abs else FAILED
    _save_simplex(FI, k, warm)
    return status, k, v0, v1, v2, vv, lower, it


# The same descent, inlined into hot entry points (spq.kernels.jit) at the two call sites of
# spq.kernels.query.gjk_query where a call's cost shows: the search on the hulls of an STP-BV pair,
# where passing nine arrays through the call cost 30 to 80 cycles of the 800 of a cold JVRC-1 query
# that the hulls' simplex settles at once, and the polytope pairs' search (a cold JVRC-1 pch pair:
# 2,927 -> 2,765 instructions, 1.05x to 1.09x faster). Elsewhere the call stays, to keep the compiled
# code (and compile time) small.
descend_inline = kernel(inline="hot")(getattr(descend, "py_func", descend))  # plain with NUMBA_DISABLE_JIT


@kernel
def _finish(status, k, simplex, v, vv, lower, it, mA, mB, tol_abs, dir_io, out):
    """Witness points, normal, margins and the final status into out."""
    v0, v1, v2 = v
    lam, PA, PB = simplex
    _combine(PA, lam, k, out, OUT_POINT_A)
    _combine(PB, lam, k, out, OUT_POINT_B)
    dx = out[OUT_POINT_B] - out[OUT_POINT_A]
    dy = out[OUT_POINT_B + 1] - out[OUT_POINT_A + 1]
    dz = out[OUT_POINT_B + 2] - out[OUT_POINT_A + 2]
    core = math.sqrt(dx * dx + dy * dy + dz * dz)
    if core > 0.0:
        out[OUT_NORMAL] = dx / core
        out[OUT_NORMAL + 1] = dy / core
        out[OUT_NORMAL + 2] = dz / core
    else:
        out[OUT_NORMAL] = out[OUT_NORMAL + 1] = out[OUT_NORMAL + 2] = np.nan
    dist = core - (mA + mB)
    if status != OVERLAPPING and status != FAILED:
        if dist < -tol_abs:
            status = OVERLAPPING
        elif dist <= tol_abs:
            status = TOUCHING
        else:
            status = SEPARATED
    if status == OVERLAPPING:
        dist = 0.0
        lower = 0.0
        for c in range(1, 10):
            out[c] = np.nan  # no witness points without a penetration query
    else:
        lower = max(lower - mA - mB, 0.0)
        if core > 0.0:
            for c in range(3):
                out[OUT_POINT_A + c] += mA * out[OUT_NORMAL + c]
                out[OUT_POINT_B + c] -= mB * out[OUT_NORMAL + c]
        if status == FAILED and not (core > 0.0):
            dist = np.nan
    out[OUT_DISTANCE] = max(dist, 0.0) if dist == dist else dist
    out[OUT_LOWER] = lower
    out[OUT_ITERATIONS] = it
    out[OUT_STATUS] = status
    if vv > 0.0 and status != OVERLAPPING:
        dir_io[0], dir_io[1], dir_io[2] = -v0, -v1, -v2
