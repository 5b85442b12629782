"""One distance query: GJK descent, overlap certification and, for STP-BVs, patch finishing.

Patch finishing. An STP-BV is made of sphere patches (and tori): along any direction in a sphere
patch's region the body's support is that of a ball, i.e. of the ball's centre with a margin. So once
the search knows which patches face each other, the distance is that between the patch centres (or
between one centre and the other body's core), minus the radii, which GJK finds exactly in a few
steps. It is certified when the resulting normal lies in both patches' regions: the two support
planes with that normal then separate the bodies by exactly the distance found. If the check fails
(a torus faces, or the loose search picked a neighbouring patch), the patches at the new normal are
tried again, and after a few rounds the plain descent runs to full tolerance.
"""

from __future__ import annotations

import math

import numpy as np

from spq.kernels.gjk import (
    OUT_DISTANCE,
    OUT_ITERATIONS,
    OUT_LOWER,
    OUT_NORMAL,
    OUT_POINT_A,
    OUT_POINT_B,
    FAILED,
    OUT_STATUS,
    OVERLAPPING,
    SEPARATED,
    TOUCHING,
    WORK_ROWS,
    _finish,
    certify_overlap,
    descend,
    minkowski_support,
)
from spq.kernels.jit import kernel
from spq.kernels.kinds import POINT, POLYTOPE, STP
from spq.kernels.stp_support import (
    F_BIG_R,
    F_R,
    F_VERTICES,
    IDX_F,
    IDX_H,
    IDX_HULL,
    IDX_HULL_MAP,
    IDX_METHOD,
    IDX_V,
    _offsets,
    find_patch,
    march_step,
)

LOOSE_REL_TOL = 1e-3  # relative tolerance of the first descent, which only has to find the patches
FINISH_ROUNDS = 8  # patch-pair corrections before falling back to the full descent


@kernel
def ball_of_patch(f, ix, p, d0, d1, d2):
    """(ball centre x, y, z, ball radius) whose support is patch p's along directions d in its region:
    a small or big sphere, or for a torus the big ball centred at the circle point opposite d."""
    V, F = ix[IDX_V], ix[IDX_F]
    o_faces, o_tori, o_bound, o_hull = _offsets(ix)
    if p < V:
        k = F_VERTICES + 3 * p
        return f[k], f[k + 1], f[k + 2], f[F_R]
    if p < V + F:
        k = o_faces + 3 * (p - V)
        return f[k], f[k + 1], f[k + 2], f[F_BIG_R]
    k = o_tori + 7 * (p - V - F)
    e0, e1, e2, a = f[k + 3], f[k + 4], f[k + 5], f[k + 6]
    de = d0 * e0 + d1 * e1 + d2 * e2
    w0, w1, w2 = d0 - de * e0, d1 - de * e1, d2 - de * e2
    wn = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if wn > 0.0:
        w0, w1, w2 = w0 / wn, w1 / wn, w2 / wn
    return f[k] - a * w0, f[k + 1] - a * w1, f[k + 2] - a * w2, f[F_BIG_R]


@kernel
def next_patch(f, ix, p, d0, d1, d2):
    """The patch owning direction d: p itself, or p's neighbour across the boundary d violates (one
    guided-march step, which reaches the torus between two small spheres instead of jumping it);
    p < 0: a fresh search."""
    n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    u0, u1, u2 = d0 / n, d1 / n, d2 / n
    if p < 0:
        q, _ = find_patch(f, ix, ix[IDX_METHOD], -1, u0, u1, u2)
        return q
    q = march_step(f, ix, _offsets(ix)[2], p, u0, u1, u2)
    return p if q < 0 else q


@kernel
def torus_far_normal(f, ix, p, q0, q1, q2, toward):
    """Unit normal between q and the point c of torus p's centre circle farthest from q (local frame):
    from c to q if toward, else from q to c; zeros if p is not a torus or q is on the axis.

    The STP-BV lies in every ball of radius R centred on the torus's circle arc, so facing a point q
    its distance is largest, and exact, for the ball centred farthest from q."""
    V, F = ix[IDX_V], ix[IDX_F]
    if p < V + F:
        return 0.0, 0.0, 0.0
    k = _offsets(ix)[1] + 7 * (p - V - F)
    m0, m1, m2, e0, e1, e2, a = f[k], f[k + 1], f[k + 2], f[k + 3], f[k + 4], f[k + 5], f[k + 6]
    w0, w1, w2 = q0 - m0, q1 - m1, q2 - m2
    we = w0 * e0 + w1 * e1 + w2 * e2
    w0, w1, w2 = w0 - we * e0, w1 - we * e1, w2 - we * e2
    wn = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if wn == 0.0:
        return 0.0, 0.0, 0.0
    c0, c1, c2 = m0 - a * w0 / wn, m1 - a * w1 / wn, m2 - a * w2 / wn
    d0, d1, d2 = q0 - c0, q1 - c1, q2 - c2
    dn = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    s = 1.0 / dn if toward else -1.0 / dn
    return d0 * s, d1 * s, d2 * s


@kernel
def finish_on_patches(kA, mA, fA, iA, kB, mB, fB, iB, R, t, n0, n1, n2, tol_abs, tol_rel, max_iter, warm, out):
    """Try to settle the query on the balls of the STP patches facing along n (A's frame, A to B).

    Each round solves the ball-centre problem exactly, then certifies with the bodies' own supports
    along the new normal m: upper = |p_B - p_A| for points on the bodies, lower = the width of the
    slab between the support planes with normal m. Writes the result into out (A's frame) and
    returns the descent iterations used, or -1 if no round closed the gap."""
    work = np.empty((WORK_ROWS, 4))
    inner_warm = np.zeros(warm.shape[0], dtype=np.int64)
    ident = np.eye(3)
    tb = np.empty(3)
    d = np.empty(3)
    sa = np.empty(3)
    sb = np.empty(3)
    tmp = np.empty(3)
    used = 0
    pa = pb = -1
    for _ in range(FINISH_ROUNDS):
        # side A: the facing patch's ball becomes a point at its centre with the radius as margin
        ca0 = ca1 = ca2 = 0.0
        core_a, margin_a = kA, mA
        if kA == STP:
            pa = next_patch(fA, iA, pa, n0, n1, n2)
            ca0, ca1, ca2, margin_a = ball_of_patch(fA, iA, pa, n0, n1, n2)
            warm[0] = pa
            core_a = POINT
        # side B, in A's frame shifted to A's ball centre
        core_b, margin_b = kB, mB
        rot = R
        for r in range(3):
            tb[r] = t[r]
        if kB == STP:
            e0 = -(R[0, 0] * n0 + R[1, 0] * n1 + R[2, 0] * n2)
            e1 = -(R[0, 1] * n0 + R[1, 1] * n1 + R[2, 1] * n2)
            e2 = -(R[0, 2] * n0 + R[1, 2] * n1 + R[2, 2] * n2)
            pb = next_patch(fB, iB, pb, e0, e1, e2)
            cb0, cb1, cb2, margin_b = ball_of_patch(fB, iB, pb, e0, e1, e2)
            warm[1] = pb
            core_b = POINT
            rot = ident
            for r in range(3):
                tb[r] = R[r, 0] * cb0 + R[r, 1] * cb1 + R[r, 2] * cb2 + t[r]
        tb[0] -= ca0
        tb[1] -= ca1
        tb[2] -= ca2
        d[0], d[1], d[2] = n0, n1, n2
        inner_warm[:] = 0
        status, k, v0, v1, v2, vv, lower, it = descend(core_a, fA, iA, core_b, fB, iB, rot, tb, tol_abs, tol_rel,
                                                       max_iter, d, inner_warm, work)
        used += it
        if status != SEPARATED:
            return -1
        _finish(status, k, work[12], work[4:8, 0:3], work[8:12, 0:3], v0, v1, v2, vv, lower, it, margin_a,
                margin_b, tol_abs, d, out)
        if out[OUT_STATUS] != SEPARATED:
            return -1
        m0, m1, m2 = out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2]
        # certificate from the true supports along m
        minkowski_support(kA, fA, iA, kB, fB, iB, R, t, m0, m1, m2, warm, sa, sb, tmp)
        for c in range(3):
            sa[c] += mA * (m0, m1, m2)[c]
            sb[c] -= mB * (m0, m1, m2)[c]
            pa_c = sa[c] if kA == STP else out[OUT_POINT_A + c] + (ca0, ca1, ca2)[c]
            pb_c = sb[c] if kB == STP else out[OUT_POINT_B + c] + (ca0, ca1, ca2)[c]
            out[OUT_POINT_A + c] = pa_c
            out[OUT_POINT_B + c] = pb_c
        gx = out[OUT_POINT_B] - out[OUT_POINT_A]
        gy = out[OUT_POINT_B + 1] - out[OUT_POINT_A + 1]
        gz = out[OUT_POINT_B + 2] - out[OUT_POINT_A + 2]
        upper = math.sqrt(gx * gx + gy * gy + gz * gz)
        slab = m0 * (sb[0] - sa[0]) + m1 * (sb[1] - sa[1]) + m2 * (sb[2] - sa[2])
        if slab > 0.0 and upper - slab <= tol_abs + tol_rel * upper:
            out[OUT_DISTANCE] = upper
            out[OUT_LOWER] = slab
            out[OUT_NORMAL] = gx / upper
            out[OUT_NORMAL + 1] = gy / upper
            out[OUT_NORMAL + 2] = gz / upper
            return used
        # next normal: towards the facing torus's best ball when the other side's feature is a point
        n0, n1, n2 = m0, m1, m2
        if kA == STP and (core_b == POINT or k == 1):
            q0 = (tb[0] if core_b == POINT else work[8, 0]) + ca0
            q1 = (tb[1] if core_b == POINT else work[8, 1]) + ca1
            q2 = (tb[2] if core_b == POINT else work[8, 2]) + ca2
            x0, x1, x2 = torus_far_normal(fA, iA, pa, q0, q1, q2, True)
            if x0 != 0.0 or x1 != 0.0 or x2 != 0.0:
                n0, n1, n2 = x0, x1, x2
        if kB == STP and (core_a == POINT or k == 1):
            # A's feature point, in B's local frame
            a0 = ca0 if core_a == POINT else work[4, 0]
            a1 = ca1 if core_a == POINT else work[4, 1]
            a2 = ca2 if core_a == POINT else work[4, 2]
            y0, y1, y2 = a0 - t[0], a1 - t[1], a2 - t[2]
            l0 = R[0, 0] * y0 + R[1, 0] * y1 + R[2, 0] * y2
            l1 = R[0, 1] * y0 + R[1, 1] * y1 + R[2, 1] * y2
            l2 = R[0, 2] * y0 + R[1, 2] * y1 + R[2, 2] * y2
            x0, x1, x2 = torus_far_normal(fB, iB, pb, l0, l1, l2, False)
            if x0 != 0.0 or x1 != 0.0 or x2 != 0.0:
                # B's normal -> A's frame: the direction from A's point to B's ball
                n0 = R[0, 0] * x0 + R[0, 1] * x1 + R[0, 2] * x2
                n1 = R[1, 0] * x0 + R[1, 1] * x1 + R[1, 2] * x2
                n2 = R[2, 0] * x0 + R[2, 1] * x1 + R[2, 2] * x2
    return -1


@kernel
def hull_core(k, m, f, ix):
    """(kind, margin, fdata, idata) of the shape to search first: for an STP-BV its underlying
    convex hull grown by r (a polytope, which the STP-BV contains and hugs within O(L^2 / rho));
    any other shape unchanged."""
    if k == STP and ix[IDX_H] > 0:
        o_hull = _offsets(ix)[3]
        return POLYTOPE, f[F_R], f[o_hull:o_hull + 3 * ix[IDX_H]], ix[ix[IDX_HULL]:ix[IDX_HULL_MAP]]
    return k, m, f[0:f.shape[0]], ix[0:ix.shape[0]]


@kernel
def gjk_query(kA, mA, fA, iA, kB, mB, fB, iB, R, t, tol_abs, tol_rel, max_iter, dir_io, warm, work, out):
    """Distance between core A (+ margin mA) and core B (+ margin mB), B at (R, t) in A's frame.

    dir_io: (3,) initial search direction (zero: from A's origin to B's), overwritten with the final
    closest-point direction for the next warm start. warm: int64 (WARM_SIZE,) warm-start state
    (in/out; zeros for a cold start). work: (WORK_ROWS, 4) scratch. out: (OUT_SIZE,) result vector,
    in A's frame. Returns the status code.

    With an STP-BV on either side: first the patches that faced each other in the last query; then
    a loose search on the underlying hulls grown by r, whose overlap is the STP-BVs' overlap and
    whose normal points at the facing patches, settled exactly on those patches; if that fails, the
    plain descent on the STP-BVs themselves.
    """
    extra = 0
    if kA == STP or kB == STP:
        n = math.sqrt(dir_io[0] ** 2 + dir_io[1] ** 2 + dir_io[2] ** 2)
        if n > 0.0:  # coherence: the patches that faced each other last time
            used = finish_on_patches(kA, mA, fA, iA, kB, mB, fB, iB, R, t, dir_io[0] / n, dir_io[1] / n,
                                     dir_io[2] / n, tol_abs, tol_rel, max_iter, warm, out)
            if used >= 0:
                return _done(out, used, dir_io)
        ka, ma, fa, ia = hull_core(kA, mA, fA, iA)
        kb, mb, fb, ib = hull_core(kB, mB, fB, iB)
        hull_warm = np.zeros(warm.shape[0], dtype=np.int64)
        status, k, v0, v1, v2, vv, lower, it = descend(ka, fa, ia, kb, fb, ib, R, t, tol_abs,
                                                       max(tol_rel, LOOSE_REL_TOL), max_iter, dir_io, hull_warm, work)
        extra = it
        gap = math.sqrt(vv) - ma - mb
        if status == OVERLAPPING or (status != FAILED and gap < -tol_abs):
            # the grown hulls overlap, and each STP-BV contains its grown hull
            _finish(OVERLAPPING, k, work[12], work[4:8, 0:3], work[8:12, 0:3], v0, v1, v2, vv, lower, it, ma, mb,
                    tol_abs, dir_io, out)
            return int(out[OUT_STATUS])
        if status == SEPARATED and vv > 0.0:
            n = math.sqrt(vv)
            used = finish_on_patches(kA, mA, fA, iA, kB, mB, fB, iB, R, t, -v0 / n, -v1 / n, -v2 / n, tol_abs,
                                     tol_rel, max_iter, warm, out)
            if used >= 0:
                return _done(out, used + extra, dir_io)
            dir_io[0], dir_io[1], dir_io[2] = -v0, -v1, -v2
    status, k, v0, v1, v2, vv, lower, it = descend(kA, fA, iA, kB, fB, iB, R, t, tol_abs, tol_rel, max_iter,
                                                   dir_io, warm, work)
    if status == TOUCHING and tol_abs > 0.0:
        status = certify_overlap(kA, fA, iA, kB, fB, iB, R, t, tol_abs, tol_rel, max_iter, warm)
    _finish(status, k, work[12], work[4:8, 0:3], work[8:12, 0:3], v0, v1, v2, vv, lower, it + extra, mA, mB,
            tol_abs, dir_io, out)
    return int(out[OUT_STATUS])


@kernel
def _done(out, iterations, dir_io):
    out[OUT_ITERATIONS] = iterations
    for c in range(3):
        dir_io[c] = out[OUT_NORMAL + c]
    return int(out[OUT_STATUS])
