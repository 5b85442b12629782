"""Coherent finish of an STP-BV patch against a polytope, in the polytope's frame.

Along a smooth trajectory an STP-BV-against-polytope pair nearly always keeps, from one query to the
next, the patch of the STP-BV that faces the polytope and the polytope's feature (a vertex, an edge
or a face: up to three vertex ids) nearest to that patch's ball. The distance is then the ball's to
that feature, found by a GJK between the ball's centre and the polytope started from the feature
(one support call when the feature holds), and certified as in query.finish_on_patches: the
polytope's support along the normal m bounds the slab, and the patch's own support along -m is a
point of the STP-BV when the patch owns -m. A sphere patch's ball is the sphere; a torus's is the
ball centred on its circle point farthest from the feature, solved on the feature found.

Everything here runs in the polytope's own frame (no vertex is transformed) with no support
dispatch, and gives up (nothing written) as soon as a step of the proof fails, leaving the general
finish to run as before.
"""

from __future__ import annotations

import math

from spq.kernels.frames import rot_to_a, rot_to_b, to_a, to_b
from spq.kernels.gjk import (
    OUT_DISTANCE,
    OUT_LOWER,
    OUT_NORMAL,
    OUT_POINT_A,
    OUT_POINT_B,
    OUT_STATUS,
    SEPARATED,
    TOUCHING,
    WARM_COUNT,
    WARM_FEATURE_A,
    WARM_SIMPLEX_A,
    WARM_SIMPLEX_B,
    reduce_simplex,
)
from spq.kernels.indexing import at
from spq.kernels.jit import kernel
from spq.kernels.kinds import POLYTOPE, STP
from spq.kernels.stp_support import IDX_E, IDX_F, IDX_V, _offsets, ball_of_patch, march_step
from spq.kernels.support import polytope_support_index
from spq.kernels.torus_ball import far_ball_centre, torus_against_segment

PATCH_STEPS = 4  # patch changes (guided-march steps) before giving up to the general finish


@kernel(inline="always")
def _s_to_p(stp_a, R, t, x0, x1, x2):
    """A point of the STP side's frame in the polytope's."""
    return to_b(R, t, x0, x1, x2) if stp_a else to_a(R, t, x0, x1, x2)


@kernel(inline="always")
def _p_to_s(stp_a, R, t, x0, x1, x2):
    """A point of the polytope's frame in the STP side's."""
    return to_a(R, t, x0, x1, x2) if stp_a else to_b(R, t, x0, x1, x2)


@kernel(inline="always")
def _rot_p_to_s(stp_a, R, x0, x1, x2):
    """A direction of the polytope's frame in the STP side's."""
    return rot_to_a(R, x0, x1, x2) if stp_a else rot_to_b(R, x0, x1, x2)


@kernel(inline="always")
def _put_vertex(fP, v, c0, c1, c2, W, FI, k):
    """Row k of the simplex of (polytope - centre c): vertex v minus c, id v."""
    W[k, 0] = fP[at(3 * v)] - c0
    W[k, 1] = fP[at(3 * v + 1)] - c1
    W[k, 2] = fP[at(3 * v + 2)] - c2
    FI[0, k] = v
    FI[1, k] = 0


@kernel(inline="always")
def _recentre(fP, c0, c1, c2, W, FI, k):
    """The simplex's k rows for a new centre c (same vertex ids)."""
    for i in range(k):
        _put_vertex(fP, int(FI[0, i]), c0, c1, c2, W, FI, i)


@kernel(inline="hot")  # a robot scene's coherent sweep spends about a third of its time here (spq profile --coherent)
def _centre_gjk(fP, iP, mP, c0, c1, c2, rad, k, s, tol, work):
    """GJK between the point c and the polytope (its frame) from the simplex of k vertex ids in
    work's FI rows (rows as _put_vertex's); the stop rule is the certificate's, on the distance
    minus rad and the margin mP. Returns (ok, k, v = nearest point - c, |v|, last support vertex,
    iterations); not ok when the point is within rad + mP + tol_abs, or the search stalls."""
    tol_abs, tol_rel, max_iter = tol
    W = work[0:4]
    lam = work[12]
    FI = work[20:22]
    it = 0
    while it < max_iter:
        it += 1
        k, inside = reduce_simplex(W, work[4:8], work[8:12], FI, k, lam, work[16:20])
        v0 = v1 = v2 = 0.0
        for i in range(k):
            v0 += lam[i] * W[i, 0]
            v1 += lam[i] * W[i, 1]
            v2 += lam[i] * W[i, 2]
        core = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if inside or not (core - rad - mP > tol_abs):
            break
        s = polytope_support_index(fP, iP, -v0, -v1, -v2)
        gap = (v0 * (v0 - (fP[at(3 * s)] - c0)) + v1 * (v1 - (fP[at(3 * s + 1)] - c1))
               + v2 * (v2 - (fP[at(3 * s + 2)] - c2)))
        if gap <= (tol_abs + tol_rel * (core - rad - mP)) * core:
            return True, k, v0, v1, v2, core, s, it
        for i in range(k):
            if FI[0, i] == s:
                return False, k, v0, v1, v2, core, s, it
        _put_vertex(fP, s, c0, c1, c2, W, FI, k)
        k += 1
    return False, k, 0.0, 0.0, 0.0, 0.0, s, it


@kernel
def _torus_ball_facing(torus, fP, FI, k, c0, c1, c2, u0, u1, u2):
    """Centre (polytope's frame) of torus patch's ball facing the polytope feature of k vertex ids in
    FI (a vertex, an edge, or a face, whose ball is the one along u, the STP side's frame, taken
    as the face's normal towards it); c: the current centre."""
    fS, iS, patch, stp_a, R, t = torus
    if k == 1:
        v = int(FI[0, 0])
        q0, q1, q2 = _p_to_s(stp_a, R, t, fP[at(3 * v)], fP[at(3 * v + 1)], fP[at(3 * v + 2)])
        d0, d1, d2 = _p_to_s(stp_a, R, t, c0, c1, c2)
        x0, x1, x2 = far_ball_centre(fS, iS, patch, d0, d1, d2, q0, q1, q2)
    elif k == 2:
        v, w = int(FI[0, 0]), int(FI[0, 1])
        s0, s1, s2 = _p_to_s(stp_a, R, t, fP[at(3 * v)], fP[at(3 * v + 1)], fP[at(3 * v + 2)])
        e0, e1, e2 = _p_to_s(stp_a, R, t, fP[at(3 * w)], fP[at(3 * w + 1)], fP[at(3 * w + 2)])
        g0, g1, g2, y0, y1, y2 = torus_against_segment(fS, iS, patch, s0, s1, s2, e0, e1, e2, 0.5)
        x0, x1, x2 = y0 - g0, y1 - g1, y2 - g2
    else:
        x0, x1, x2, _ = ball_of_patch(fS, iS, patch, u0, u1, u2)
    return _s_to_p(stp_a, R, t, x0, x1, x2)


@kernel(inline="always")
def _same_feature(FI, k, a0, a1, a2, ka):
    """Whether the simplex's k vertex ids in FI are the ka ids a0, a1, a2 (in any order)."""
    if k != ka:
        return False
    for i in range(k):
        v = FI[0, i]
        if not (v == a0 or (ka > 1 and v == a1) or (ka > 2 and v == a2)):
            return False
    return True


TORUS_ROUNDS = 4  # ball-facing-feature rounds on one torus before giving up to the general finish


@kernel
def _torus_centre_gjk(torus, poly, c0, c1, c2, rad, k, s, u, tol, work):
    """_centre_gjk for torus patch, whose ball depends on the feature it faces: the ball facing
    the simplex's feature (k ids in work's FI rows; along u, the STP side's frame, for a face), the
    search from it, and again while the search ends on another feature. Returns _centre_gjk's
    results, then the centre (polytope's frame); not ok if the feature has not settled within
    TORUS_ROUNDS. Along a trajectory the feature is the last query's, and one search settles it."""
    tol_abs, tol_rel, max_iter = tol
    fS, iS, patch, stp_a, R, t = torus
    fP, iP, mP = poly
    u0, u1, u2 = u
    W = work[0:4]
    FI = work[20:22]
    it = 0
    for r in range(TORUS_ROUNDS):
        c0, c1, c2 = _torus_ball_facing(torus, fP, FI, k, c0, c1, c2, u0, u1, u2)
        _recentre(fP, c0, c1, c2, W, FI, k)
        ka, a0, a1, a2 = k, FI[0, 0], FI[0, 1], FI[0, 2]
        ok, k, v0, v1, v2, core, s, used = _centre_gjk(fP, iP, mP, c0, c1, c2, rad, k, s, tol, work)
        it += used
        if not ok:
            break
        u0, u1, u2 = _rot_p_to_s(stp_a, R, v0 / core, v1 / core, v2 / core)
        # a face's ball was taken along the last normal, not the face's own, unless a round on the
        # face itself gave it
        if _same_feature(FI, k, a0, a1, a2, ka) and (k < 3 or r > 0):
            return True, k, v0, v1, v2, core, s, it, c0, c1, c2
    return False, k, 0.0, 0.0, 0.0, 0.0, s, it, c0, c1, c2


@kernel(inline="always")
def coherent_ball_finish(pair, tol, dir_in, warm, work, out):
    """Settle an STP-BV-against-polytope query on the last query's patch and polytope feature.

    dir_in: the last normal (A's frame, A to B), along which a torus's first ball is taken.
    warm: the pair's warm-start state (the STP side's feature is its patch, the polytope side's
    simplex ids its feature's vertices). R, t: B's pose in A's frame. work: (>= 22, 4) scratch.
    Returns the GJK iterations used, out then holding the result in A's frame (as gjk_query's) and
    warm the new feature; or -1, nothing written to out or warm."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    stp_a = kA == STP
    if stp_a == (kB == STP):
        return -1
    if stp_a:
        kP, mP, fP, iP, mS, fS, iS = kB, mB, fB, iB, mA, fA, iA
        n0, n1, n2 = dir_in[0], dir_in[1], dir_in[2]
    else:
        kP, mP, fP, iP, mS, fS, iS = kA, mA, fA, iA, mB, fB, iB
        n0, n1, n2 = rot_to_b(R, -dir_in[0], -dir_in[1], -dir_in[2])
    count = warm[WARM_COUNT]
    side_p = 1 if stp_a else 0
    patch = warm[WARM_FEATURE_A + 1 - side_p]
    if kP != POLYTOPE or mS != 0.0 or not (1 <= count <= 3):
        return -1
    if not (0 <= patch < iS[IDX_V] + iS[IDX_F] + iS[IDX_E]):
        return -1
    c0, c1, c2, rad = ball_of_patch(fS, iS, patch, n0, n1, n2)
    c0, c1, c2 = _s_to_p(stp_a, R, t, c0, c1, c2)
    W = work[0:4]
    FI = work[20:22]
    base = WARM_SIMPLEX_B if stp_a else WARM_SIMPLEX_A
    n = iP[0]
    k = 0
    for i in range(count):
        v = warm[base + i]
        if not (0 <= v < n):
            return -1
        repeated = False
        for j in range(k):
            if FI[0, j] == v:
                repeated = True
        if not repeated:
            _put_vertex(fP, v, c0, c1, c2, W, FI, k)
            k += 1
    s = warm[WARM_FEATURE_A + side_p]
    it = 0
    o_planes = _offsets(iS)[2]
    n_spheres = iS[IDX_V] + iS[IDX_F]
    u0, u1, u2 = n0, n1, n2  # the direction a torus's first ball is taken along, for a face (STP side's frame)
    for step in range(PATCH_STEPS + 1):
        if step == PATCH_STEPS:
            return -1
        if patch >= n_spheres:
            ok, k, v0, v1, v2, core, s, used, c0, c1, c2 = _torus_centre_gjk((fS, iS, patch, stp_a, R, t), (fP, iP, mP),
                                                                            c0, c1, c2, rad, k, s, (u0, u1, u2),
                                                                            tol, work)
        else:
            ok, k, v0, v1, v2, core, s, used = _centre_gjk(fP, iP, mP, c0, c1, c2, rad, k, s, tol, work)
        it += used
        if not ok:
            return -1
        # the patch must own the direction to the polytope, -m (STP side's frame); else its neighbour
        # across the boundary it violates is tried, from the feature found
        u0, u1, u2 = _rot_p_to_s(stp_a, R, v0 / core, v1 / core, v2 / core)
        nxt = march_step(fS, iS, o_planes, patch, u0, u1, u2)
        if nxt < 0:
            break
        patch = nxt
        c0, c1, c2, rad = ball_of_patch(fS, iS, patch, u0, u1, u2)
        c0, c1, c2 = _s_to_p(stp_a, R, t, c0, c1, c2)
        _recentre(fP, c0, c1, c2, W, FI, k)
    m0, m1, m2 = -v0 / core, -v1 / core, -v2 / core  # polytope to ball, polytope's frame
    # the certificate: the patch's own support along -m closes the gap
    b0, b1, b2, rad = ball_of_patch(fS, iS, patch, u0, u1, u2)
    b0, b1, b2 = _s_to_p(stp_a, R, t, b0 + rad * u0, b1 + rad * u1, b2 + rad * u2)  # the STP side's support
    a0, a1, a2 = c0 + v0 + mP * m0, c1 + v1 + mP * m1, c2 + v2 + mP * m2  # the polytope's witness
    g0, g1, g2 = b0 - a0, b1 - a1, b2 - a2
    upper = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
    slab = m0 * (b0 - fP[at(3 * s)]) + m1 * (b1 - fP[at(3 * s + 1)]) + m2 * (b2 - fP[at(3 * s + 2)]) - mP
    if not (slab > 0.0 and upper - slab <= tol_abs + tol_rel * upper):
        return -1
    g0, g1, g2 = g0 / upper, g1 / upper, g2 / upper  # polytope to STP side
    if stp_a:  # the polytope is B: its frame to A's; the normal A to B is -g
        a0, a1, a2 = to_a(R, t, a0, a1, a2)
        b0, b1, b2 = to_a(R, t, b0, b1, b2)
        g0, g1, g2 = rot_to_a(R, -g0, -g1, -g2)
        a0, a1, a2, b0, b1, b2 = b0, b1, b2, a0, a1, a2
    out[OUT_POINT_A], out[OUT_POINT_A + 1], out[OUT_POINT_A + 2] = a0, a1, a2
    out[OUT_POINT_B], out[OUT_POINT_B + 1], out[OUT_POINT_B + 2] = b0, b1, b2
    out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2] = g0, g1, g2
    out[OUT_DISTANCE] = upper
    out[OUT_LOWER] = min(slab, upper)  # the two may cross by rounding (a few ulps)
    out[OUT_STATUS] = TOUCHING if upper <= tol_abs else SEPARATED
    # the new warm start: the patch, the last support vertex and the simplex's vertices (the centre's ids 0)
    warm[WARM_FEATURE_A + 1 - side_p] = patch
    warm[WARM_FEATURE_A + side_p] = s
    other = WARM_SIMPLEX_A if stp_a else WARM_SIMPLEX_B
    for i in range(k):
        warm[base + i] = int(FI[0, i])
        warm[other + i] = 0
    warm[WARM_COUNT] = k
    return it
