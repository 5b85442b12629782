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

from spq.kernels.gjk import (
    DESCENT_ROWS,
    OUT_DISTANCE,
    OUT_ITERATIONS,
    OUT_LOWER,
    OUT_NORMAL,
    OUT_POINT_A,
    OUT_POINT_B,
    FAILED,
    OUT_STATUS,
    WARM_COUNT,
    WARM_FEATURE_A,
    WARM_SIMPLEX_A,
    WARM_SIMPLEX_B,
    WORK_ROWS,
    OVERLAPPING,
    SEPARATED,
    TOUCHING,
    _finish,
    certify_overlap,
    descend,
)
from spq.kernels.dispatch import support_local
from spq.kernels.jit import kernel
from spq.kernels.kinds import POINT, POLYTOPE, STP
from spq.kernels.stp_support import (
    F_R,
    IDX_F,
    IDX_H,
    IDX_HULL,
    IDX_HULL_MAP,
    IDX_METHOD,
    IDX_V,
    METHOD_HULL,
    _offsets,
    ball_of_patch,
    find_march,
    find_patch,
    in_region,
    march_step,
    patch_support,
)

LOOSE_REL_TOL = 1e-3  # relative tolerance of the first descent, which only has to find the patches
FINISH_ROUNDS = 8  # patch-pair corrections before falling back to the full descent


@kernel
def next_patch(f, ix, p, hint, march, d0, d1, d2):
    """The patch owning direction d: p itself, or p's neighbour across the boundary d violates (one
    guided-march step, which reaches the torus between two small spheres instead of jumping it);
    p < 0: a fresh search, starting from patch ``hint`` if >= 0 (the last query's), by a guided
    march from it if ``march`` (a hint close to d: the hull vertex the loose search ended on)."""
    n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    u0, u1, u2 = d0 / n, d1 / n, d2 / n
    if p < 0:
        if march and hint >= 0:
            q, _ = find_march(f, ix, _offsets(ix)[2], hint, u0, u1, u2)
        else:
            q, _ = find_patch(f, ix, ix[IDX_METHOD], hint, u0, u1, u2)
        return q
    q = march_step(f, ix, _offsets(ix)[2], p, u0, u1, u2)
    return p if q < 0 else q


@kernel
def _hull_hint(ix, h):
    """The small sphere of hull vertex h (where the loose search on the hull ended), or -1 if the
    STP-BV has no hull or searches by another method than METHOD_HULL."""
    if ix[IDX_METHOD] != METHOD_HULL or ix[IDX_H] == 0 or h < 0 or h >= ix[IDX_H]:
        return -1
    return ix[ix[IDX_HULL_MAP] + h]


@kernel
def far_ball_centre(f, ix, p, c0, c1, c2, q0, q1, q2):
    """Centre of patch p's ball facing the point q (local frame): a sphere's own centre (c), or for
    a torus the point of its centre circle farthest from q. The STP-BV lies in every ball of radius
    R centred on the torus's circle arc, so facing q its distance is largest, and exact, there."""
    V, F = ix[IDX_V], ix[IDX_F]
    if p < V + F:
        return c0, c1, c2
    k = _offsets(ix)[1] + 7 * (p - V - F)
    m0, m1, m2, e0, e1, e2, a = f[k], f[k + 1], f[k + 2], f[k + 3], f[k + 4], f[k + 5], f[k + 6]
    w0, w1, w2 = q0 - m0, q1 - m1, q2 - m2
    we = w0 * e0 + w1 * e1 + w2 * e2
    w0, w1, w2 = w0 - we * e0, w1 - we * e1, w2 - we * e2
    wn = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if wn == 0.0:
        return c0, c1, c2
    return m0 - a * w0 / wn, m1 - a * w1 / wn, m2 - a * w2 / wn


@kernel
def _to_a(R, t, x0, x1, x2):
    return (R[0, 0] * x0 + R[0, 1] * x1 + R[0, 2] * x2 + t[0], R[1, 0] * x0 + R[1, 1] * x1 + R[1, 2] * x2 + t[1],
            R[2, 0] * x0 + R[2, 1] * x1 + R[2, 2] * x2 + t[2])


@kernel
def _to_b(R, t, x0, x1, x2):
    y0, y1, y2 = x0 - t[0], x1 - t[1], x2 - t[2]
    return (R[0, 0] * y0 + R[1, 0] * y1 + R[2, 0] * y2, R[0, 1] * y0 + R[1, 1] * y1 + R[2, 1] * y2,
            R[0, 2] * y0 + R[1, 2] * y1 + R[2, 2] * y2)


@kernel
def _rot_to_b(R, x0, x1, x2):
    return (R[0, 0] * x0 + R[1, 0] * x1 + R[2, 0] * x2, R[0, 1] * x0 + R[1, 1] * x1 + R[2, 1] * x2,
            R[0, 2] * x0 + R[1, 2] * x1 + R[2, 2] * x2)


@kernel
def _torus_frame(f, ix, p):
    """Axis e and two unit vectors b1, b2 completing it to an orthonormal frame, of torus patch p."""
    k = _offsets(ix)[1] + 7 * (p - ix[IDX_V] - ix[IDX_F])
    e0, e1, e2 = f[k + 3], f[k + 4], f[k + 5]
    if abs(e0) < 0.9:  # b1 = e x (1, 0, 0)
        b0, b1, b2 = 0.0, e2, -e1
    else:  # b1 = e x (0, 1, 0)
        b0, b1, b2 = -e2, 0.0, e0
    bn = math.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
    b0, b1, b2 = b0 / bn, b1 / bn, b2 / bn
    return e0, e1, e2, b0, b1, b2, e1 * b2 - e2 * b1, e2 * b0 - e0 * b2, e0 * b1 - e1 * b0


@kernel
def torus_angle(f, ix, p, d0, d1, d2):
    """Angle about torus p's axis of direction d (local frame): it alone fixes the torus's ball."""
    e0, e1, e2, b0, b1, b2, c0, c1, c2 = _torus_frame(f, ix, p)
    return math.atan2(d0 * c0 + d1 * c1 + d2 * c2, d0 * b0 + d1 * b1 + d2 * b2)


@kernel
def torus_turn(f, ix, p, d0, d1, d2, angle):
    """Direction d (local frame) turned about torus p's axis to the given angle."""
    e0, e1, e2, b0, b1, b2, c0, c1, c2 = _torus_frame(f, ix, p)
    de = d0 * e0 + d1 * e1 + d2 * e2
    w = math.sqrt(max(0.0, d0 * d0 + d1 * d1 + d2 * d2 - de * de))
    ca, sa = w * math.cos(angle), w * math.sin(angle)
    return de * e0 + ca * b0 + sa * c0, de * e1 + ca * b1 + sa * c1, de * e2 + ca * b2 + sa * c2


@kernel
def _wrapped(x):
    if x > math.pi:
        return x - 2.0 * math.pi
    if x < -math.pi:
        return x + 2.0 * math.pi
    return x


@kernel
def _secant_turn(f, ix, p, d0, d1, d2, m0, m1, m2, prev_patch, prev_angle, prev_h):
    """Next search direction (local frame) for torus patch p, whose ball was taken along d and
    gave the normal m. Against a polytope edge the plain update m is a fixed-point iteration on
    the angle about the torus axis that contracts only by about 1 - (rho + distance) / R per round,
    so the angle's residual h = angle(m) - angle(d) is driven to zero by secant steps instead
    (superlinear), from the previous round's (angle, h) on the same patch.
    Returns (direction, patch, angle(d), h) for the next call."""
    an = torus_angle(f, ix, p, d0, d1, d2)
    h = _wrapped(torus_angle(f, ix, p, m0, m1, m2) - an)
    target = an + h
    if prev_patch == p:
        den = h - prev_h
        if den != 0.0:
            step = -h * _wrapped(an - prev_angle) / den
            if abs(step) <= SECANT_MAX_GAIN * abs(h):
                target = an + step
    x0, x1, x2 = torus_turn(f, ix, p, m0, m1, m2, target)
    return x0, x1, x2, p, an, h


@kernel
def _rot_to_a(R, x0, x1, x2):
    return (R[0, 0] * x0 + R[0, 1] * x1 + R[0, 2] * x2, R[1, 0] * x0 + R[1, 1] * x1 + R[1, 2] * x2,
            R[2, 0] * x0 + R[2, 1] * x1 + R[2, 2] * x2)


@kernel
def _support_of_side(k, f, ix, p, d0, d1, d2, warm, slot, out):
    """Core support along d (local frame) into out; for an STP-BV, patch p's if p owns d."""
    if k == STP and p >= 0:
        n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        u0, u1, u2 = d0 / n, d1 / n, d2 / n
        if in_region(f, ix, _offsets(ix)[2], p, u0, u1, u2):
            patch_support(f, ix, p, u0, u1, u2, out)
            return
    warm[slot] = support_local(k, f, ix, d0, d1, d2, warm[slot], out)


SECANT_MAX_GAIN = 100.0  # cap of a secant step on a torus angle, in plain-update steps
BALL_ALTERNATIONS = 60  # far-point alternations between two tori; each shrinks the error about 4x


@kernel
def finish_on_patches(kA, mA, fA, iA, kB, mB, fB, iB, R, t, n0, n1, n2, tol_abs, tol_rel, max_iter, warm, work,
                      iscratch, fscratch, coherent, out):
    """Try to settle the query on the balls of the STP patches facing along n (A's frame, A to B).

    Each round takes the facing patches (one guided-march step from the last ones), solves the
    problem between their balls (closed form between two balls; an exact GJK between a ball centre
    and a polytope), and certifies with the bodies' own supports along the new normal m: upper =
    |p_B - p_A| for points on the bodies, lower = the width of the slab between the support planes.
    Writes the result into out (A's frame) and returns the descent iterations used, or -1 if no
    round closed the gap. work: (WORK_ROWS, 4) scratch for the inner descent; iscratch: int64
    (WARM_SIZE,) and fscratch: (4, 3) scratch of this function's own. coherent: the first search
    starts from the patches in warm (the last query's); otherwise by a guided march from the small
    spheres of the hull vertices in iscratch[0:2] (where the loose search on the hulls ended)."""
    used = 0
    pa = pb = -1
    hint_a = warm[0] if coherent and kA == STP else _hull_hint(iA, iscratch[0]) if kA == STP else -1
    hint_b = warm[1] if coherent and kB == STP else _hull_hint(iB, iscratch[1]) if kB == STP else -1
    sa = fscratch[0]
    sb = fscratch[1]
    tmp = fscratch[2]
    dirv = fscratch[3]
    prev_patch, prev_angle, prev_h = -1, 0.0, 0.0  # the secant's last torus round
    for _ in range(FINISH_ROUNDS):
        o0, o1, o2 = n0, n1, n2
        ca0 = ca1 = ca2 = cb0 = cb1 = cb2 = 0.0
        margin_a = margin_b = 0.0
        if kA == STP:
            pa = next_patch(fA, iA, pa, hint_a, not coherent, n0, n1, n2)
            ca0, ca1, ca2, margin_a = ball_of_patch(fA, iA, pa, n0, n1, n2)
            warm[0] = pa
        e0, e1, e2 = _rot_to_b(R, -n0, -n1, -n2)
        if kB == STP:
            pb = next_patch(fB, iB, pb, hint_b, not coherent, e0, e1, e2)
            cb0, cb1, cb2, margin_b = ball_of_patch(fB, iB, pb, e0, e1, e2)
            warm[1] = pb
        k = 0  # the ball-ball case has no core simplex
        if kA == STP and kB == STP:
            # two balls: alternate the tori's far points, then the normal joins the centres
            qa0, qa1, qa2 = _to_b(R, t, ca0, ca1, ca2)
            for _ in range(BALL_ALTERNATIONS):
                cb0n, cb1n, cb2n = far_ball_centre(fB, iB, pb, cb0, cb1, cb2, qa0, qa1, qa2)
                x0, x1, x2 = _to_a(R, t, cb0n, cb1n, cb2n)
                ca0n, ca1n, ca2n = far_ball_centre(fA, iA, pa, ca0, ca1, ca2, x0, x1, x2)
                moved = abs(ca0n - ca0) + abs(ca1n - ca1) + abs(ca2n - ca2) + abs(cb0n - cb0) + abs(cb1n - cb1) \
                    + abs(cb2n - cb2)
                ca0, ca1, ca2, cb0, cb1, cb2 = ca0n, ca1n, ca2n, cb0n, cb1n, cb2n
                qa0, qa1, qa2 = _to_b(R, t, ca0, ca1, ca2)
                if moved <= 1e-15:
                    break
            x0, x1, x2 = _to_a(R, t, cb0, cb1, cb2)
            g0, g1, g2 = x0 - ca0, x1 - ca1, x2 - ca2
            gn = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
            if gn <= margin_a + margin_b + tol_abs:
                return -1
            m0, m1, m2 = g0 / gn, g1 / gn, g2 / gn
        else:
            # a ball centre against the other body's core, exactly by GJK (shifted to the centre)
            core_a, margin_a2, core_b, margin_b2 = kA, mA, kB, mB
            tb0, tb1, tb2 = t[0], t[1], t[2]
            if kA == STP:
                core_a, margin_a2 = POINT, margin_a
            else:
                core_b, margin_b2 = POINT, margin_b
                tb0, tb1, tb2 = _to_a(R, t, cb0, cb1, cb2)
            tmp[0], tmp[1], tmp[2] = tb0 - ca0, tb1 - ca1, tb2 - ca2
            dirv[0], dirv[1], dirv[2] = n0, n1, n2
            # warm start: the polytope side's last support vertex and last simplex with the ball centre
            point_side = 0 if kA == STP else 1
            copy_point_simplex(warm, iscratch, point_side)
            status, k, v0, v1, v2, vv, lower, it = descend(core_a, fA, iA, core_b, fB, iB, R, tmp, tol_abs, tol_rel,
                                                           max_iter, dirv, iscratch, work)
            copy_point_simplex(iscratch, warm, point_side)
            used += it
            if status != SEPARATED or math.sqrt(vv) <= margin_a2 + margin_b2 + tol_abs:
                return -1
            m0, m1, m2 = -v0 / math.sqrt(vv), -v1 / math.sqrt(vv), -v2 / math.sqrt(vv)
            # the polytope side's witness: the descent's convex combination, back in A's frame
            for c in range(3):
                acc_a = 0.0
                acc_b = 0.0
                for i in range(k):
                    acc_a += work[12, i] * work[4 + i, c]
                    acc_b += work[12, i] * work[8 + i, c]
                out[OUT_POINT_A + c] = acc_a + (ca0, ca1, ca2)[c]
                out[OUT_POINT_B + c] = acc_b + (ca0, ca1, ca2)[c]
            if kA != STP:
                for c in range(3):
                    out[OUT_POINT_A + c] += mA * (m0, m1, m2)[c]
            if kB != STP:
                for c in range(3):
                    out[OUT_POINT_B + c] -= mB * (m0, m1, m2)[c]
        # certificate from the true supports along m (an STP side's patch gives it at once if it owns m)
        _support_of_side(kA, fA, iA, pa, m0, m1, m2, warm, 0, sa)
        e0, e1, e2 = _rot_to_b(R, -m0, -m1, -m2)
        _support_of_side(kB, fB, iB, pb, e0, e1, e2, warm, 1, tmp)
        sb[0], sb[1], sb[2] = _to_a(R, t, tmp[0], tmp[1], tmp[2])
        for c in range(3):
            sa[c] += mA * (m0, m1, m2)[c]
            sb[c] -= mB * (m0, m1, m2)[c]
            if kA == STP:
                out[OUT_POINT_A + c] = sa[c]
            if kB == STP:
                out[OUT_POINT_B + c] = sb[c]
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
            out[OUT_STATUS] = TOUCHING if upper <= tol_abs else SEPARATED
            return used
        n0, n1, n2 = m0, m1, m2
        if k == 1:
            # against a polytope vertex q: a torus's best ball is centred at its circle point farthest
            # from q, in closed form (measured: for edge and face witnesses the plain normal update
            # converges faster)
            if kA == STP:
                q0 = out[OUT_POINT_B] + mB * m0
                q1 = out[OUT_POINT_B + 1] + mB * m1
                q2 = out[OUT_POINT_B + 2] + mB * m2
                c0, c1, c2 = far_ball_centre(fA, iA, pa, ca0, ca1, ca2, q0, q1, q2)
                g0, g1, g2 = q0 - c0, q1 - c1, q2 - c2
            else:
                q0 = out[OUT_POINT_A] - mA * m0
                q1 = out[OUT_POINT_A + 1] - mA * m1
                q2 = out[OUT_POINT_A + 2] - mA * m2
                l0, l1, l2 = _to_b(R, t, q0, q1, q2)
                c0, c1, c2 = far_ball_centre(fB, iB, pb, cb0, cb1, cb2, l0, l1, l2)
                x0, x1, x2 = _to_a(R, t, c0, c1, c2)
                g0, g1, g2 = x0 - q0, x1 - q1, x2 - q2
            gn = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
            if gn > 0.0:
                n0, n1, n2 = g0 / gn, g1 / gn, g2 / gn
        elif k >= 2 and kA == STP and pa >= iA[IDX_V] + iA[IDX_F]:
            n0, n1, n2, prev_patch, prev_angle, prev_h = _secant_turn(fA, iA, pa, o0, o1, o2, m0, m1, m2,
                                                                      prev_patch, prev_angle, prev_h)
        elif k >= 2 and kB == STP and pb >= iB[IDX_V] + iB[IDX_F]:
            d0, d1, d2 = _rot_to_b(R, -o0, -o1, -o2)
            e0, e1, e2 = _rot_to_b(R, -m0, -m1, -m2)
            x0, x1, x2, prev_patch, prev_angle, prev_h = _secant_turn(fB, iB, pb, d0, d1, d2, e0, e1, e2,
                                                                      prev_patch, prev_angle, prev_h)
            n0, n1, n2 = _rot_to_a(R, -x0, -x1, -x2)
    return -1


@kernel
def copy_point_simplex(src, dst, point_side):
    """Copy warm-start state src -> dst for a ball centre (side point_side, 0 = A) against a core:
    the core side's support feature and the simplex, with the point side's ids set to 0. The point
    side's own feature (an STP patch in ``warm``) is left alone."""
    core_side = 1 - point_side
    dst[WARM_FEATURE_A + core_side] = src[WARM_FEATURE_A + core_side]
    k = src[WARM_COUNT]
    dst[WARM_COUNT] = k
    p0 = WARM_SIMPLEX_B if point_side else WARM_SIMPLEX_A
    c0 = WARM_SIMPLEX_A if point_side else WARM_SIMPLEX_B
    for i in range(k):
        dst[p0 + i] = 0
        dst[c0 + i] = src[c0 + i]


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
def gjk_query(kA, mA, fA, iA, kB, mB, fB, iB, R, t, tol_abs, tol_rel, max_iter, dir_io, warm, iwork, work, out):
    """Distance between core A (+ margin mA) and core B (+ margin mB), B at (R, t) in A's frame.

    dir_io: (3,) initial search direction (zero: from A's origin to B's), overwritten with the final
    closest-point direction for the next warm start. warm: int64 (WARM_SIZE,) warm-start state
    (in/out; zeros for a cold start). iwork: int64 (WARM_SIZE,) scratch. work: (WORK_ROWS, 4)
    scratch. out: (OUT_SIZE,) result vector, in A's frame. Returns the status code.

    With an STP-BV on either side: first the patches that faced each other in the last query; then
    a loose search on the underlying hulls grown by r, whose overlap is the STP-BVs' overlap and
    whose normal points at the facing patches, settled exactly on those patches; if that fails, the
    plain descent on the STP-BVs themselves.
    """
    extra = 0
    if kA == STP or kB == STP:
        scratch = iwork
        scratch[:] = 0
        fscratch = work[DESCENT_ROWS:WORK_ROWS, 0:3]
        n = math.sqrt(dir_io[0] ** 2 + dir_io[1] ** 2 + dir_io[2] ** 2)
        if n > 0.0:  # coherence: the patches that faced each other last time
            used = finish_on_patches(kA, mA, fA, iA, kB, mB, fB, iB, R, t, dir_io[0] / n, dir_io[1] / n,
                                     dir_io[2] / n, tol_abs, tol_rel, max_iter, warm, work, scratch, fscratch, True,
                                     out)
            if used >= 0:
                return _done(out, used, dir_io)
        ka, ma, fa, ia = hull_core(kA, mA, fA, iA)
        kb, mb, fb, ib = hull_core(kB, mB, fB, iB)
        scratch[:] = 0
        status, k, v0, v1, v2, vv, lower, it = descend(ka, fa, ia, kb, fb, ib, R, t, tol_abs,
                                                       max(tol_rel, LOOSE_REL_TOL), max_iter, dir_io, scratch, work)
        extra = it
        if (kA == STP) != (kB == STP):  # its simplex on the polytope side seeds the patch finish
            copy_point_simplex(scratch, warm, 0 if kA == STP else 1)
        gap = math.sqrt(vv) - ma - mb
        if status == OVERLAPPING or (status != FAILED and gap < -tol_abs):
            # the grown hulls overlap, and each STP-BV contains its grown hull
            _finish(OVERLAPPING, k, work[12], work[4:8, 0:3], work[8:12, 0:3], v0, v1, v2, vv, lower, it, ma, mb,
                    tol_abs, dir_io, out)
            return int(out[OUT_STATUS])
        if status == SEPARATED and vv > 0.0:
            n = math.sqrt(vv)
            used = finish_on_patches(kA, mA, fA, iA, kB, mB, fB, iB, R, t, -v0 / n, -v1 / n, -v2 / n, tol_abs,
                                     tol_rel, max_iter, warm, work, scratch, fscratch, False, out)
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
