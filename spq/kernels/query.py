"""One distance query: GJK descent, overlap certification and, for STP-BVs, patch finishing.

Patch finishing. An STP-BV is made of sphere patches (and tori): along any direction in a sphere
patch's region the body's support is that of a ball, i.e. of the ball's centre with a margin. So once
the search knows which patches face each other, the distance is that between the patch centres (or
between one centre and the other body's core), minus the radii, which GJK finds exactly in a few
steps. It is certified when the resulting normal lies in both patches' regions: the two support
planes with that normal then separate the bodies by exactly the distance found. If the check fails
(a torus faces, or the loose search picked a neighbouring patch), the patches at the new normal are
tried again, and after a few rounds the plain descent runs to full tolerance.

Against a body that is not an STP-BV the first search on the hulls usually settles the query by
itself, with no round: when its simplex ends on one hull vertex whose small sphere owns the normal
(the hull's distance is then the STP-BV's), or on a vertex or an edge of the other body, to which the
nearest patch is found by a walk over the patches (march_to_feature).
"""

from __future__ import annotations

import math

from spq.kernels.gjk import (
    DESCENT_ROWS,
    FRESH_COL,
    FRESH_ROW,
    SUPPORT_ROW_A,
    SUPPORT_ROW_B,
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
    WARM_FEATURE_B,
    WARM_HULL_OVERLAP,
    WARM_SIMPLEX_A,
    WARM_SIMPLEX_B,
    EPA_IOFF,
    EPA_ROW,
    PROBE_END,
    PROBE_ROW,
    WARM_SIZE,
    OUT_UPPER,
    OVERLAPPING,
    SEPARATED,
    TOUCHING,
    _combine,
    _finish,
    certify_overlap,
    clear_warm,
    descend,
    descend_inline,
    minkowski_support,
)
from spq.kernels.coherent_ball import coherent_ball_finish
from spq.kernels.dispatch import support_local
from spq.kernels.primitive_pairs import closed_form_kinds, primitive_query
from spq.kernels.closest_points_newton import (PRIMAL_INNER_REL_TOL, PRIMAL_RESTART_REL_TOL, closest_points_newton,
                                               primal_pair)
from spq.kernels.newton_normal import INNER_REL_TOL, newton_normal, smooth_against_stp, smooth_pair
from spq.kernels.patch_newton import patch_newton, patch_newton_first, patch_newton_pair
from spq.kernels.epa import EPA_RESULT, bounds_closed, epa, epa_run, epa_start
from spq.kernels.epa_layout import EPA_TMP
from spq.kernels.signed import (
    HULL_CONTINUED,
    HULL_CORES,
    HULL_PATCHES,
    HULL_RESTARTED,
    HULL_SETTLED,
    add_margins,
    descent_result,
    separated_result,
    settle_by_centres,
    signed_finish,
    core_support,
    unsigned_of_signed,
)
from spq.kernels.signed_out import set_result, status_of, supports_as_witnesses
from spq.kernels.superellipsoid_support import FDATA_SIZE
from spq.kernels.indexing import at
from spq.kernels.jit import kernel
from spq.kernels.kinds import POINT, POLYTOPE, STP, STP_CORE, SUPERELLIPSOID
from spq.kernels.frames import rot_to_a, rot_to_b, to_a, to_b
from spq.kernels.torus_ball import aitken_on_circle, far_ball_centre, torus_against_segment
from spq.kernels.stp_support import (
    F_R,
    IDX_E,
    IDX_F,
    IDX_H,
    IDX_HULL_MAP,
    IDX_METHOD,
    IDX_V,
    METHOD_HULL,
    _offsets,
    ball_of_patch,
    hull_vertex_step,
    small_sphere_owns,
    find_march,
    find_patch,
    hull_core,
    in_region,
    march_step,
    patch_support,
)

# Relative tolerance of the first descent, on the hulls. Between two STP-BVs it only has to find the
# patches. Against another body it is nearly exact, because its simplex then mostly settles the query
# by itself (settle_on_small_spheres, settle_on_feature) and a loose one would not.
LOOSE_REL_TOL = 1e-3
LOOSE_REL_TOL_ONE_STP = 1e-6
FINISH_ROUNDS = 8  # patch-pair corrections before falling back to the full descent
# Two STP-BVs: both sides step at once, and near a boundary between a small sphere and its torus (or a
# big sphere and its torus) on each side the pair can cycle, each side's step undoing the other's (1%
# of kuka_link_4's separated pairs, each then paying the full descent, 36 iterations). After round
# TURNS_FROM (from 0), while neither patch owns the last normal, the sides take turns (one steps, the
# other keeps its patch), which breaks such a cycle; the rounds up to it are unchanged.
FINISH_ROUNDS_TWO_STP = 12
TURNS_FROM = 4


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
def _first_patch(ix, hint):
    """The last query's patch, if valid, taken as it is: along a trajectory it nearly always still
    owns the normal, and the certificate checks that it does (a search here would only repeat that
    check); -1 if there is none."""
    return hint if 0 <= hint < ix[IDX_V] + ix[IDX_F] + ix[IDX_E] else -1


@kernel
def _hull_hint(ix, h):
    """The small sphere of hull vertex h (where the loose search on the hull ended), or -1 if the
    STP-BV has no hull or searches by another method than METHOD_HULL."""
    if ix[IDX_METHOD] != METHOD_HULL:
        return -1
    return small_sphere_of_hull_vertex(ix, h)


@kernel(inline="always")
def small_sphere_of_hull_vertex(ix, h):
    """The small sphere of underlying-hull vertex h, or -1 if there is no such vertex."""
    if h < 0 or h >= ix[IDX_H]:
        return -1
    return ix[at(ix[IDX_HULL_MAP] + h)]


@kernel
def _torus_frame(f, ix, p):
    """Axis e and two unit vectors b1, b2 completing it to an orthonormal frame, of torus patch p."""
    k = _offsets(ix)[1] + 7 * (p - ix[IDX_V] - ix[IDX_F])
    e0, e1, e2 = f[at(k + 3)], f[at(k + 4)], f[at(k + 5)]
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
def _torus_step(f, ix, p, d, m, x0, x1, x2, exact, state):
    """Next search direction (local frame) for torus patch p, whose ball was taken along d and gave
    the normal m; x is the proposed direction (exact: the ball solved against this round's witness
    feature, a polytope vertex or edge; else the plain update).

    The torus's ball depends only on the angle about its axis, so the round is a step of a 1-D
    root search on the residual h = angle(m) - angle(d), which is continuous in angle(d) (at the
    arc's ends the ball is the neighbouring big sphere's). Against a polytope edge the plain update
    contracts only by about 1 - (rho + distance) / R per round, so it is replaced by a secant step
    from the last round on the same torus (superlinear). Against a vertex the closed form is exact,
    but when the closest vertex changes with the angle it jumps back and forth over the root: once
    two rounds on this torus had residuals of opposite signs, any step leaving that bracket is
    replaced by the interpolation between them (regula falsi, with the Illinois halving of the end
    that stays put, so that a curved h cannot stall it).

    State, carried between rounds: bp, the torus; (lt, lh), its last round's (angle, h); (pt, ph)
    and (nt, nh), its last rounds with h > 0 and h < 0 (NaN: none yet).
    Returns (direction, whether it is the exact proposal unchanged, new state)."""
    d0, d1, d2 = d
    m0, m1, m2 = m
    bp, lt, lh, pt, ph, nt, nh = state
    an = torus_angle(f, ix, p, d0, d1, d2)
    h = _wrapped(torus_angle(f, ix, p, m0, m1, m2) - an)
    if bp != p:
        bp, lt, lh, pt, ph, nt, nh = p, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan
    turn = not exact
    if exact:
        target = torus_angle(f, ix, p, x0, x1, x2)
    else:
        x0, x1, x2 = m0, m1, m2
        target = an + h
        den = h - lh
        if lt == lt and den != 0.0:
            step = -h * _wrapped(an - lt) / den
            if abs(step) <= SECANT_MAX_GAIN * abs(h):
                target = an + step
    if h > 0.0:
        if lh > 0.0 and nt == nt:
            nh *= 0.5  # (Illinois) the negative end stayed twice
        pt, ph = an, h
    elif h < 0.0:
        if lh < 0.0 and pt == pt:
            ph *= 0.5
        nt, nh = an, h
    lt, lh = an, h
    if pt == pt and nt == nt:
        w = _wrapped(nt - pt)
        s = _wrapped(target - pt)
        if w != 0.0 and not (0.0 < s / w < 1.0):
            target = pt + w * ph / (ph - nh)
            turn = True
    if turn:
        x0, x1, x2 = torus_turn(f, ix, p, x0, x1, x2, target)
    return x0, x1, x2, not turn, bp, lt, lh, pt, ph, nt, nh


@kernel
def _support_of_side(k, f, ix, p, d0, d1, d2, warm, slot, out):
    """Core support along d (local frame) into out; for an STP-BV, patch p's. Returns False (out
    unset) if p does not own d: another patch's support would lie farther along d than p's ball
    reaches, so the caller's certificate fails anyway, and the next round moves to that patch."""
    if k == STP and p >= 0:
        n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        u0, u1, u2 = d0 / n, d1 / n, d2 / n
        if not in_region(f, ix, _offsets(ix)[2], p, u0, u1, u2):
            return False
        patch_support(f, ix, p, u0, u1, u2, out)
        return True
    warm[slot] = support_local(k, f, ix, d0, d1, d2, warm[slot], out)
    return True


SECANT_MAX_GAIN = 100.0  # cap of a secant step on a torus angle, in plain-update steps
BALL_ALTERNATIONS = 60  # far-point alternations between two tori; each shrinks the error about 4x
# Alternations stop once the centres move less than this times their distance: the normal is then off
# by about 1e-6 rad where they contract 4x a step (the certificate checks it either way), and the
# slab's gap grows with that error's square times about the balls' radii (R, 2 m on kuka_link_4):
# about 2e-12 m there, far below the tolerance (1e-10 m). 1e-10 took 8.8 alternations a query that
# alternates, against 7.6, for nothing (STP-STP signed 1.009x to 1.015x, same process; stop 112).
BALL_SETTLED = 1e-6


KNOWN_A, KNOWN_B = 1, 2  # _certify's ``known`` bits: that side's support along the normal is given


@kernel(inline="always")
def _owned_support(known, k, f, ix, p, u0, u1, u2, warm, slot, out):
    """A side's part of the certificate along unit u (local frame): with its support known, whether
    its patch p (if an STP side's) owns u; otherwise _support_of_side's (support into out)."""
    if known:
        return not (k == STP and p >= 0) or in_region(f, ix, _offsets(ix)[2], p, u0, u1, u2)
    return _support_of_side(k, f, ix, p, u0, u1, u2, warm, slot, out)


@kernel(inline="hot")
def _certify(pair, pa, pb, m0, m1, m2, tol_abs, tol_rel, warm, fscratch, known, out):
    """Whether the bodies' own supports along the unit normal m (A's frame, A to B) close the gap:
    upper = |p_B - p_A| for the witness points in out (a non-STP side's must be set, margin
    included; an STP side's is its support, written here), lower = the width of the slab between
    the two support planes. If so, the result is written to out. pa, pb: the STP sides' patches,
    whose own support is taken if they own m. known: KNOWN_A / KNOWN_B bits of the sides whose
    support along m (margin included, A's frame) the caller put in fscratch[0] / fscratch[1], as a
    descent's last support points are when taken along its final direction; an STP side's patch
    must still own m, as it does not when another patch reaches farther."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    sa = fscratch[0]
    sb = fscratch[1]
    tmp = fscratch[2]
    if not _owned_support(known & KNOWN_A, kA, fA, iA, pa, m0, m1, m2, warm, 0, sa):
        return False
    if not known & KNOWN_A:
        for c in range(3):
            sa[c] += mA * (m0, m1, m2)[c]
    e0, e1, e2 = rot_to_b(R, -m0, -m1, -m2)
    if not _owned_support(known & KNOWN_B, kB, fB, iB, pb, e0, e1, e2, warm, 1, tmp):
        return False
    if not known & KNOWN_B:
        sb[0], sb[1], sb[2] = to_a(R, t, tmp[0], tmp[1], tmp[2])
        for c in range(3):
            sb[c] -= mB * (m0, m1, m2)[c]
    return _close_gap(kA, kB, (sa[0], sa[1], sa[2]), (sb[0], sb[1], sb[2]), (m0, m1, m2), tol_abs, tol_rel, out)


@kernel(inline="always")
def _close_gap(kA, kB, sa, sb, m, tol_abs, tol_rel, out):
    """_certify's test, given the supports sa, sb (margins included, A's frame) along the unit normal m:
    whether the gap between the witness points in out (an STP side's set to its support here) and the
    slab between the support planes close; if so, the result is written to out."""
    sa0, sa1, sa2 = sa
    sb0, sb1, sb2 = sb
    m0, m1, m2 = m
    if kA == STP:
        out[OUT_POINT_A], out[OUT_POINT_A + 1], out[OUT_POINT_A + 2] = sa0, sa1, sa2
    if kB == STP:
        out[OUT_POINT_B], out[OUT_POINT_B + 1], out[OUT_POINT_B + 2] = sb0, sb1, sb2
    gx = out[OUT_POINT_B] - out[OUT_POINT_A]
    gy = out[OUT_POINT_B + 1] - out[OUT_POINT_A + 1]
    gz = out[OUT_POINT_B + 2] - out[OUT_POINT_A + 2]
    upper = math.sqrt(gx * gx + gy * gy + gz * gz)
    slab = m0 * (sb0 - sa0) + m1 * (sb1 - sa1) + m2 * (sb2 - sa2)
    if slab > 0.0 and upper - slab <= tol_abs + tol_rel * upper:
        out[OUT_DISTANCE] = upper
        out[OUT_LOWER] = min(slab, upper)  # the two may cross by rounding (a few ulps)
        out[OUT_NORMAL] = gx / upper
        out[OUT_NORMAL + 1] = gy / upper
        out[OUT_NORMAL + 2] = gz / upper
        out[OUT_STATUS] = TOUCHING if upper <= tol_abs else SEPARATED
        return True
    return False


@kernel
def _certify_overlap(pair, m0, m1, m2, tol_abs, tol_rel, warm, pwork, iprobe, out):
    """The certificate of an overlap along the unit normal m (A's frame, A to B), with an STP-BV on a
    side: 1 if it closes (result in out, margins included), 0 if not (out untouched), -1 if it
    cannot here.

    lower: the bodies' supports along m bound sd >= -h_D(m). upper: an STP-BV is the ball hull of its
    points at radius R - r grown by a ball of radius r, so for every direction the ball of radius r
    touching its support plane from inside, centred at s(m) - r m, lies in it; the signed distance
    of those balls (or of a ball and the other body's core, by an exact descent) bounds the bodies'
    from above. At the optimal normal the two meet while the overlap is shallower than r: the small
    balls then face the other body as the STP-BVs do (deeper, their centres pass into it: -1).
    pwork: (DESCENT_ROWS + 2, 4) and iprobe: int64 (WARM_SIZE,) scratch."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    sa = pwork[DESCENT_ROWS]
    sb = pwork[DESCENT_ROWS + 1]
    for i in range(WARM_SIZE):
        iprobe[i] = 0
    iprobe[WARM_FEATURE_A], iprobe[WARM_FEATURE_B] = warm[WARM_FEATURE_A], warm[WARM_FEATURE_B]
    if (kA == STP) != (kB == STP):
        # the small ball's centre lies near the facing patch's ball centre, whose descent against the
        # core left its simplex in warm: the centre's descent starts from it
        copy_point_simplex(warm, iprobe, 0 if kA == STP else 1)
    minkowski_support(pair, m0, m1, m2, iprobe, sa, sb, pwork[16])
    low = -(m0 * (sa[0] - sb[0]) + m1 * (sa[1] - sb[1]) + m2 * (sa[2] - sb[2]) + mA + mB)
    ra = fA[F_R] if kA == STP else 0.0
    rb = fB[F_R] if kB == STP else 0.0
    # the small balls' centres (for a side that is no STP-BV, its core's support: unused)
    a0, a1, a2 = sa[0] - ra * m0, sa[1] - ra * m1, sa[2] - ra * m2
    b0, b1, b2 = sb[0] + rb * m0, sb[1] + rb * m1, sb[2] + rb * m2
    ga, gb = ra + mA, rb + mB  # the radii around those centres (or cores)
    if kA == STP and kB == STP:
        g0, g1, g2 = b0 - a0, b1 - a1, b2 - a2
        gn = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        if not (gn > 0.0) or g0 * m0 + g1 * m1 + g2 * m2 <= 0.0:
            return -1
        u0, u1, u2 = g0 / gn, g1 / gn, g2 / gn
        upper = gn - ga - gb
    else:
        # a small ball's centre against the other body's core, exactly (the centre as the origin)
        point_a = kA == STP
        c0, c1, c2 = (a0, a1, a2) if point_a else (b0, b1, b2)
        tq = pwork[DESCENT_ROWS + 1]
        tq[0], tq[1], tq[2] = (t[0] - c0, t[1] - c1, t[2] - c2) if point_a else (c0, c1, c2)
        dirv = pwork[DESCENT_ROWS]
        dirv[0], dirv[1], dirv[2] = m0, m1, m2
        probe = (POINT if point_a else kA, 0.0, fA, iA, kB if point_a else POINT, 0.0, fB, iB, R, tq)
        status, k, v0, v1, v2, vv, lower, it = descend(probe, (tol_abs, tol_rel, FINISH_DESCENT_ITER), dirv,
                                                       iprobe, pwork)
        if status != SEPARATED:
            return -1  # the centre reaches the other core: the overlap is deeper than r
        gn = math.sqrt(vv)
        u0, u1, u2 = -v0 / gn, -v1 / gn, -v2 / gn
        # the core side's point: the descent's convex combination (shifted back for B)
        q0 = q1 = q2 = 0.0
        for i in range(k):
            row = 8 + i if point_a else 4 + i
            q0 += pwork[12, i] * pwork[row, 0]
            q1 += pwork[12, i] * pwork[row, 1]
            q2 += pwork[12, i] * pwork[row, 2]
        if point_a:
            a0, a1, a2 = c0, c1, c2
            b0, b1, b2 = q0 + c0, q1 + c1, q2 + c2
        else:
            a0, a1, a2 = q0, q1, q2
            b0, b1, b2 = c0, c1, c2
        upper = gn - ga - gb
    if not (upper - low <= tol_abs + tol_rel * abs(upper)):
        return 0
    out[OUT_POINT_A], out[OUT_POINT_A + 1], out[OUT_POINT_A + 2] = a0 + ga * u0, a1 + ga * u1, a2 + ga * u2
    out[OUT_POINT_B], out[OUT_POINT_B + 1], out[OUT_POINT_B + 2] = b0 - gb * u0, b1 - gb * u1, b2 - gb * u2
    out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2] = u0, u1, u2
    out[OUT_DISTANCE] = upper
    out[OUT_UPPER] = upper
    out[OUT_LOWER] = min(low, upper)
    out[OUT_STATUS] = status_of(upper, tol_abs)
    return 1


FINISH_DESCENT_ITER = 64  # iterations of a small ball's centre against a polytope (it takes a few)


@kernel
def _closest_on_segment(s0, s1, s2, t0, t1, t2, x0, x1, x2):
    """The point of segment s-t nearest to x."""
    g0, g1, g2 = t0 - s0, t1 - s1, t2 - s2
    gg = g0 * g0 + g1 * g1 + g2 * g2
    lam = 0.0
    if gg > 0.0:
        lam = min(1.0, max(0.0, ((x0 - s0) * g0 + (x1 - s1) * g1 + (x2 - s2) * g2) / gg))
    return s0 + lam * g0, s1 + lam * g1, s2 + lam * g2


@kernel
def finish_on_patches(pair, n, tol, warm, work,
                      iscratch, fscratch, coherent, out, overlap, iprobe):
    """Try to settle the query on the balls of the STP patches facing along n (A's frame, A to B).

    Each round takes the facing patches (one guided-march step from the last ones; between two
    STP-BVs, late rounds let one side step at a time, see TURNS_FROM), solves the
    problem between their balls (closed form between two balls; an exact GJK between a ball centre
    and a polytope), and certifies with the bodies' own supports along the new normal m: upper =
    |p_B - p_A| for points on the bodies, lower = the width of the slab between the support planes.
    Writes the result into out (A's frame) and returns the descent iterations used, or -1 if no
    round closed the gap. work: (WORK_ROWS, 4) scratch for the inner descent; iscratch: int64
    (WARM_SIZE,) and fscratch: (4, 3) scratch of this function's own. coherent: the first search
    starts from the patches in warm (the last query's); otherwise by a guided march from the small
    spheres of the hull vertices in iscratch[0:2] (where the loose search on the hulls ended).

    overlap: the bodies overlap (a signed query). The balls are then solved the same way (their
    centres lie outside the other body), but the certificate is _certify_overlap's, by the small
    balls inside the STP-BVs; iprobe: int64 (WARM_SIZE,) scratch for it. Stops at once (-1) where
    that certificate cannot hold (an overlap deeper than the small radius r)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    n0, n1, n2 = n
    used = 0
    pa = pb = -1
    hint_a = warm[0] if coherent and kA == STP else _hull_hint(iA, iscratch[0]) if kA == STP else -1
    hint_b = warm[1] if coherent and kB == STP else _hull_hint(iB, iscratch[1]) if kB == STP else -1
    tmp = fscratch[2]
    dirv = fscratch[3]
    bp, lt, lh, pt, ph, nt, nh = -1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0  # the torus search's state (_torus_step)
    two_stp = kA == STP and kB == STP
    keep = 0  # the side (KNOWN_A, KNOWN_B) that keeps its patch this round, its turn to wait
    for rnd in range(FINISH_ROUNDS_TWO_STP if two_stp else FINISH_ROUNDS):
        o0, o1, o2 = n0, n1, n2
        ca0 = ca1 = ca2 = cb0 = cb1 = cb2 = 0.0
        margin_a = margin_b = 0.0
        if kA == STP:
            q = _first_patch(iA, hint_a) if coherent and pa < 0 else -1
            if q >= 0:
                pa = q
            elif keep != KNOWN_A:
                pa = next_patch(fA, iA, pa, hint_a, not coherent, n0, n1, n2)
            ca0, ca1, ca2, margin_a = ball_of_patch(fA, iA, pa, n0, n1, n2)
            warm[0] = pa
        e0, e1, e2 = rot_to_b(R, -n0, -n1, -n2)
        if kB == STP:
            q = _first_patch(iB, hint_b) if coherent and pb < 0 else -1
            if q >= 0:
                pb = q
            elif keep != KNOWN_B:
                pb = next_patch(fB, iB, pb, hint_b, not coherent, e0, e1, e2)
            cb0, cb1, cb2, margin_b = ball_of_patch(fB, iB, pb, e0, e1, e2)
            warm[1] = pb
        k = 0  # the ball-ball case has no core simplex
        known = 0
        if kA == STP and kB == STP:
            # two balls: alternate the tori's far points, then the normal joins the centres
            qa0, qa1, qa2 = to_b(R, t, ca0, ca1, ca2)
            settled = BALL_SETTLED * math.sqrt((qa0 - cb0) ** 2 + (qa1 - cb1) ** 2 + (qa2 - cb2) ** 2)
            two_tori = pa >= iA[IDX_V] + iA[IDX_F] and pb >= iB[IDX_V] + iB[IDX_F]
            h0 = h1 = h2 = 0.0  # A's centre one alternation back (the current one: ca)
            for i in range(BALL_ALTERNATIONS):
                cb0n, cb1n, cb2n = far_ball_centre(fB, iB, pb, cb0, cb1, cb2, qa0, qa1, qa2)
                x0, x1, x2 = to_a(R, t, cb0n, cb1n, cb2n)
                ca0n, ca1n, ca2n = far_ball_centre(fA, iA, pa, ca0, ca1, ca2, x0, x1, x2)
                moved = abs(ca0n - ca0) + abs(ca1n - ca1) + abs(ca2n - ca2) + abs(cb0n - cb0) + abs(cb1n - cb1) \
                    + abs(cb2n - cb2)
                if two_tori and i % 2 == 1 and moved > settled:
                    # the alternation contracts linearly along the circle: extrapolate its limit
                    # from the last two steps (Aitken), back onto A's circle
                    ca0n, ca1n, ca2n = aitken_on_circle(fA, iA, pa, h0, h1, h2, ca0, ca1, ca2, ca0n, ca1n, ca2n)
                h0, h1, h2 = ca0, ca1, ca2
                ca0, ca1, ca2, cb0, cb1, cb2 = ca0n, ca1n, ca2n, cb0n, cb1n, cb2n
                qa0, qa1, qa2 = to_b(R, t, ca0, ca1, ca2)
                if moved <= settled or not two_tori:
                    # with a fixed centre on one side, the other's far point facing it is final at once
                    break
            x0, x1, x2 = to_a(R, t, cb0, cb1, cb2)
            g0, g1, g2 = x0 - ca0, x1 - ca1, x2 - ca2
            gn = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
            if (gn <= margin_a + margin_b + tol_abs and not overlap) or not (gn > 0.0):
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
                tb0, tb1, tb2 = to_a(R, t, cb0, cb1, cb2)
            tmp[0], tmp[1], tmp[2] = tb0 - ca0, tb1 - ca1, tb2 - ca2
            dirv[0], dirv[1], dirv[2] = n0, n1, n2
            # warm start: the polytope side's last support vertex and last simplex with the ball centre
            point_side = 0 if kA == STP else 1
            copy_point_simplex(warm, iscratch, point_side)
            status, k, v0, v1, v2, vv, lower, it = descend((core_a, 0.0, fA, iA, core_b, 0.0, fB, iB, R, tmp), tol,
                                                           dirv, iscratch, work)
            copy_point_simplex(iscratch, warm, point_side)
            used += it
            if status != SEPARATED or (math.sqrt(vv) <= margin_a2 + margin_b2 + tol_abs and not overlap):
                return -1
            m0, m1, m2 = -v0 / math.sqrt(vv), -v1 / math.sqrt(vv), -v2 / math.sqrt(vv)
            # the polytope side's witness: the descent's convex combination, back in A's frame
            simplex_witnesses(work, k, ca0, ca1, ca2, ca0, ca1, ca2, out)
            if kA != STP:
                for c in range(3):
                    out[OUT_POINT_A + c] += mA * (m0, m1, m2)[c]
            if kB != STP:
                for c in range(3):
                    out[OUT_POINT_B + c] -= mB * (m0, m1, m2)[c]
            if work[FRESH_ROW, FRESH_COL] == 1.0:  # the core side's last support was along -v = m's
                if kA == STP:
                    known = KNOWN_B
                    for c in range(3):
                        fscratch[1, c] = work[SUPPORT_ROW_B, c] + (ca0, ca1, ca2)[c] - mB * (m0, m1, m2)[c]
                else:
                    known = KNOWN_A
                    for c in range(3):
                        fscratch[0, c] = work[SUPPORT_ROW_A, c] + mA * (m0, m1, m2)[c]
        if overlap:
            verdict = _certify_overlap(pair, m0, m1, m2, tol_abs, tol_rel, warm,
                                       work[PROBE_ROW:PROBE_END], iprobe, out)
            if verdict != 0:
                return used if verdict > 0 else -1
        elif _certify(pair, pa, pb, m0, m1, m2, tol_abs, tol_rel, warm, fscratch,
                      known, out):
            return used
        keep = 0
        if two_stp and rnd >= TURNS_FROM and not overlap:
            mb0, mb1, mb2 = rot_to_b(R, -m0, -m1, -m2)
            if not in_region(fA, iA, _offsets(iA)[2], pa, m0, m1, m2) \
                    and not in_region(fB, iB, _offsets(iB)[2], pb, mb0, mb1, mb2):
                keep = KNOWN_A if rnd % 2 == 0 else KNOWN_B
        # the next direction, in the STP side's frame: its patch's ball against the other side's witness
        if kA == STP:
            p, fs, ist, c0, c1, c2 = pa, fA, iA, ca0, ca1, ca2
            d0, d1, d2, u0, u1, u2 = o0, o1, o2, m0, m1, m2
            q0 = out[OUT_POINT_B] + mB * m0
            q1 = out[OUT_POINT_B + 1] + mB * m1
            q2 = out[OUT_POINT_B + 2] + mB * m2
        else:
            p, fs, ist, c0, c1, c2 = pb, fB, iB, cb0, cb1, cb2
            d0, d1, d2 = rot_to_b(R, -o0, -o1, -o2)
            u0, u1, u2 = rot_to_b(R, -m0, -m1, -m2)
            q0, q1, q2 = to_b(R, t, out[OUT_POINT_A] - mA * m0, out[OUT_POINT_A + 1] - mA * m1,
                               out[OUT_POINT_A + 2] - mA * m2)
        x0, x1, x2 = u0, u1, u2
        y0, y1, y2 = q0, q1, q2  # the polytope side's witness for the new direction (local frame)
        torus = k >= 1 and p >= ist[IDX_V] + ist[IDX_F]
        if k == 1:
            # against a polytope vertex q: a torus's best ball is centred at its circle point
            # farthest from q, in closed form
            c0, c1, c2 = far_ball_centre(fs, ist, p, c0, c1, c2, q0, q1, q2)
            x0, x1, x2 = q0 - c0, q1 - c1, q2 - c2
        elif k == 2 and torus:
            # against a polytope edge: the torus's angle facing it, solved on the edge alone
            if kA == STP:
                s0, s1, s2 = work[8, 0] + ca0, work[8, 1] + ca1, work[8, 2] + ca2
                t0, t1, t2 = work[9, 0] + ca0, work[9, 1] + ca1, work[9, 2] + ca2
            else:
                s0, s1, s2 = to_b(R, t, work[4, 0], work[4, 1], work[4, 2])
                t0, t1, t2 = to_b(R, t, work[5, 0], work[5, 1], work[5, 2])
            x0, x1, x2, y0, y1, y2 = torus_against_segment(fs, ist, p, s0, s1, s2, t0, t1, t2, 0.5)
        kept = False
        if torus:
            x0, x1, x2, kept, bp, lt, lh, pt, ph, nt, nh = _torus_step(fs, ist, p, (d0, d1, d2), (u0, u1, u2),
                                                                       x0, x1, x2, k <= 2,
                                                                       (bp, lt, lh, pt, ph, nt, nh))
        xn = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        if not (xn > 0.0):
            x0, x1, x2, xn = u0, u1, u2, 1.0
            kept = False
        if kA == STP:
            n0, n1, n2 = x0 / xn, x1 / xn, x2 / xn
        else:
            n0, n1, n2 = rot_to_a(R, -x0 / xn, -x1 / xn, -x2 / xn)
        if kept:
            # the torus's ball solved exactly against this round's witness feature: if that is still
            # the witness along the new normal, the supports certify it without another descent
            if kA == STP:
                for c in range(3):
                    out[OUT_POINT_B + c] = (y0, y1, y2)[c] - mB * (n0, n1, n2)[c]
            else:
                w0, w1, w2 = to_a(R, t, y0, y1, y2)
                for c in range(3):
                    out[OUT_POINT_A + c] = (w0, w1, w2)[c] + mA * (n0, n1, n2)[c]
            if overlap:
                verdict = _certify_overlap(pair, n0, n1, n2, tol_abs, tol_rel, warm,
                                           work[PROBE_ROW:PROBE_END], iprobe, out)
                if verdict != 0:
                    return used if verdict > 0 else -1
            elif _certify(pair, pa, pb, n0, n1, n2, tol_abs, tol_rel, warm, fscratch, 0,
                          out):
                return used
    return -1


@kernel(inline="always")
def simplex_witnesses(work, k, a0, a1, a2, b0, b1, b2, out):
    """Witness points of a descent's simplex (k points, weights and support points in work) into
    out, A's shifted by a and B's by b."""
    for c in range(3):
        acc_a = 0.0
        acc_b = 0.0
        for i in range(k):
            acc_a += work[12, i] * work[4 + i, c]
            acc_b += work[12, i] * work[8 + i, c]
        out[OUT_POINT_A + c] = acc_a + (a0, a1, a2)[c]
        out[OUT_POINT_B + c] = acc_b + (b0, b1, b2)[c]


@kernel(inline="always")
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


@kernel(inline="always")
def hull_vertex_of_simplex(ix, ids, count):
    """The one underlying-hull vertex that all count ids (a side's points of a descent's simplex on
    the hull) share, or -1 if they differ or the STP-BV has no hull."""
    if count == 0 or ids[0] < 0 or ids[0] >= ix[IDX_H]:
        return -1
    for i in range(1, count):
        if ids[i] != ids[0]:
            return -1
    return ids[0]


@kernel(inline="hot")
def settle_on_small_spheres(pair, k, v0, v1, v2, vv, tol, warm, work,
                            scratch, fscratch, out):
    """Certify the loose search's result (simplex of k points in work, ids in scratch, closest point
    v of the hulls' difference) as the STP-BVs' own, without a patch finish; whether it did (result
    in out).

    Where an STP side's closest hull feature is a single vertex whose small sphere owns the normal,
    the STP-BV's support along it is that vertex plus r times the normal, which is exactly the grown
    hull's support: the hull's distance is the STP-BV's. The bodies' supports along the normal
    certify it (this is the commonest case: small spheres own most of the directions at small r)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    count = scratch[WARM_COUNT]
    ha = hb = -1
    if kA == STP:
        ha = hull_vertex_of_simplex(iA, scratch[WARM_SIMPLEX_A:WARM_SIMPLEX_A + count], count)
        if ha < 0:
            return False
    if kB == STP:
        hb = hull_vertex_of_simplex(iB, scratch[WARM_SIMPLEX_B:WARM_SIMPLEX_B + count], count)
        if hb < 0:
            return False
    n = math.sqrt(vv)
    m0, m1, m2 = -v0 / n, -v1 / n, -v2 / n
    simplex_witnesses(work, k, mA * m0, mA * m1, mA * m2, -mB * m0, -mB * m1, -mB * m2, out)
    pa = small_sphere_of_hull_vertex(iA, ha) if kA == STP else -1
    pb = small_sphere_of_hull_vertex(iB, hb) if kB == STP else -1
    if work[FRESH_ROW, FRESH_COL] == 1.0:
        # the descent's last supports were along m: the hulls' (grown by r on an STP side, where the
        # small sphere's support is its centre, the hull vertex, plus r m if it owns m, which the
        # hull-vertex table tells without the sphere's own records)
        if kA == STP and not small_sphere_owns(fA, iA, ha, m0, m1, m2):
            return False
        if kB == STP:
            e0, e1, e2 = rot_to_b(R, -m0, -m1, -m2)
            if not small_sphere_owns(fB, iB, hb, e0, e1, e2):
                return False
        grow_a = mA + (fA[F_R] if kA == STP else 0.0)
        grow_b = mB + (fB[F_R] if kB == STP else 0.0)
        sa = (work[SUPPORT_ROW_A, 0] + grow_a * m0, work[SUPPORT_ROW_A, 1] + grow_a * m1,
              work[SUPPORT_ROW_A, 2] + grow_a * m2)
        sb = (work[SUPPORT_ROW_B, 0] - grow_b * m0, work[SUPPORT_ROW_B, 1] - grow_b * m1,
              work[SUPPORT_ROW_B, 2] - grow_b * m2)
        if not _close_gap(kA, kB, sa, sb, (m0, m1, m2), tol_abs, tol_rel, out):
            return False
    else:
        if not _certify(pair, pa, pb, m0, m1, m2, tol_abs, tol_rel, warm, fscratch, 0,
                        out):
            return False
    if kA == STP:
        warm[0] = pa
    if kB == STP:
        warm[1] = pb
    return True


MARCH_TO_FEATURE_STEPS = 16  # walk steps of march_to_feature before giving up (it settles in a few)


@kernel
def ball_against_feature(f, ix, p, s0, s1, s2, t0, t1, t2, guess):
    """Patch p's ball facing the segment s-t (a point if s == t; local frame): (radius, x, y) with
    y the segment's point nearest to the ball and x = y - centre. A sphere's centre is fixed; a
    torus's is its circle point farthest from the segment's point nearest to the patch
    (torus_against_segment, from the segment parameter guess)."""
    c0, c1, c2, rad = ball_of_patch(f, ix, p, s0, s1, s2)
    if p < ix[IDX_V] + ix[IDX_F]:
        y0, y1, y2 = _closest_on_segment(s0, s1, s2, t0, t1, t2, c0, c1, c2)
        return rad, y0 - c0, y1 - c1, y2 - c2, y0, y1, y2
    x0, x1, x2, y0, y1, y2 = torus_against_segment(f, ix, p, s0, s1, s2, t0, t1, t2, guess)
    return rad, x0, x1, x2, y0, y1, y2


@kernel
def march_to_feature(f, ix, h, s0, s1, s2, t0, t1, t2, guess):
    """The patch of an STP-BV nearest to the outside segment s-t (a point if s == t; local frame),
    by a walk from the small sphere of underlying-hull vertex h: take the patch's ball facing the
    segment, and while the direction u from its centre to the segment's nearest point y leaves the
    patch's region, step across the boundary u violates (one guided-march step). Where the patch
    owns u, the ball's point along u is the body's support along u, so the segment is
    |y - centre| - radius from the body, exactly. Returns (patch, unit u, y, that distance), whence
    the body's support along u is y - distance u; patch -1 if the walk does not settle within
    MARCH_TO_FEATURE_STEPS steps or the segment meets a ball.

    guess: the segment parameter where the search on the hull ended, which starts a torus's solve.
    The first step is the hull vertex's: its small sphere is centred on the vertex, which the search
    on the hull has just read, and its region is in the hull-vertex table."""
    o_planes, o_hull = _offsets(ix)[2:]
    c0, c1, c2 = f[at(o_hull + 3 * h)], f[at(o_hull + 3 * h + 1)], f[at(o_hull + 3 * h + 2)]
    y0, y1, y2 = _closest_on_segment(s0, s1, s2, t0, t1, t2, c0, c1, c2)
    x0, x1, x2 = y0 - c0, y1 - c1, y2 - c2
    xn = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    if not (xn > f[F_R]):
        return -1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    u0, u1, u2 = x0 / xn, x1 / xn, x2 / xn
    p = hull_vertex_step(f, ix, h, u0, u1, u2)
    if p < 0:
        return small_sphere_of_hull_vertex(ix, h), u0, u1, u2, y0, y1, y2, xn - f[F_R]
    for _ in range(MARCH_TO_FEATURE_STEPS - 1):
        rad, x0, x1, x2, y0, y1, y2 = ball_against_feature(f, ix, p, s0, s1, s2, t0, t1, t2, guess)
        xn = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        if not (xn > rad):
            break
        u0, u1, u2 = x0 / xn, x1 / xn, x2 / xn
        nxt = march_step(f, ix, o_planes, p, u0, u1, u2)
        if nxt < 0:
            return p, u0, u1, u2, y0, y1, y2, xn - rad
        p = nxt
    return -1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0


@kernel(inline="always")
def _segment_of(P, lam, k):
    """(ok, s, t, w): the k rows of P (a side's points of a descent's simplex, weights lam) as a
    segment s-t (s == t: one point) and the simplex's point on it, s + w (t - s); not ok if they are
    more than two distinct points."""
    s0, s1, s2 = P[0, 0], P[0, 1], P[0, 2]
    t0, t1, t2 = s0, s1, s2
    w = 0.0
    for i in range(1, k):
        x0, x1, x2 = P[i, 0], P[i, 1], P[i, 2]
        if x0 == s0 and x1 == s1 and x2 == s2:
            continue
        if t0 != s0 or t1 != s1 or t2 != s2:
            if x0 == t0 and x1 == t1 and x2 == t2:
                w += lam[i]
                continue
            return False, s0, s1, s2, t0, t1, t2, w
        t0, t1, t2 = x0, x1, x2
        w += lam[i]
    return True, s0, s1, s2, t0, t1, t2, w


@kernel(inline="hot")
def settle_on_feature(pair, k, v, tol, warm, work, scratch, fscratch, out):
    """Certify the distance of an STP-BV to the other body's feature of the loose search's simplex
    (k points in work, ids in scratch; v: its closest point of the hulls' difference and |v|^2), a
    vertex or an edge: the distance is then that feature's to the STP-BV, which march_to_feature
    finds without any descent, if the feature is still the other body's nearest along the normal
    found (the bodies' supports certify it). Returns whether it did (result in out); otherwise the
    patch finish runs.

    Between two STP-BVs the feature is a side's simplex that is one hull vertex whose small sphere
    owns the search's normal m = -v / |v| (B's tried first): that side stands as the sphere, its
    centre the feature and r its margin, and the certificate checks that the sphere owns the
    march's normal too (near m, where such a sphere is the side's nearest patch). Any hull vertex of
    the simplex whose sphere owns m would do, but trying those too cost more than it saved
    (kuka_link_4, random poses: 1.08x against 1.11x unsigned, same process)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, _ = tol
    v0, v1, v2, vv = v
    if k < 1:
        return False
    if kA == STP and kB == STP:
        n = math.sqrt(vv)
        count = scratch[WARM_COUNT]
        e0, e1, e2 = rot_to_b(R, v0 / n, v1 / n, v2 / n)
        i = _owning_slot(fB, iB, scratch[WARM_SIMPLEX_B:WARM_SIMPLEX_B + count], count, e0, e1, e2)
        if i >= 0 and _march_a_to_feature(pair, k, i, tol_abs, tol_rel, warm, work, scratch, fscratch, out):
            return True
        i = _owning_slot(fA, iA, scratch[WARM_SIMPLEX_A:WARM_SIMPLEX_A + count], count, -v0 / n, -v1 / n, -v2 / n)
        return i >= 0 and _march_b_to_feature(pair, k, i, tol_abs, tol_rel, warm, work, scratch, fscratch, out)
    if kA == STP:
        return _march_a_to_feature(pair, k, -1, tol_abs, tol_rel, warm, work, scratch, fscratch, out)
    if kB == STP:
        return _march_b_to_feature(pair, k, -1, tol_abs, tol_rel, warm, work, scratch, fscratch, out)
    return False


@kernel(inline="always")
def _owning_slot(f, ix, ids, k, u0, u1, u2):
    """0 if a side's k simplex slots all hold one hull vertex whose small sphere owns unit u (local
    frame), else -1."""
    h = hull_vertex_of_simplex(ix, ids, k)
    return 0 if h >= 0 and small_sphere_owns(f, ix, h, u0, u1, u2) else -1


@kernel(inline="always")
def _feature_of(work, row, k, slot, ix, ids):
    """(ok, s, t, w, sphere): the feature march_to_feature goes to, of the side whose simplex points
    are work's rows row to row + k - 1 (A's frame): those points as a segment (see _segment_of),
    sphere -1; or, with slot >= 0 (that side an STP-BV), the hull vertex in that slot (ids: the
    side's simplex ids) as a point, and its small sphere."""
    if slot >= 0:
        s0, s1, s2 = work[row + slot, 0], work[row + slot, 1], work[row + slot, 2]
        return True, s0, s1, s2, s0, s1, s2, 0.0, small_sphere_of_hull_vertex(ix, ids[slot])
    ok, s0, s1, s2, t0, t1, t2, w = _segment_of(work[row:row + 4], work[12], k)
    return ok, s0, s1, s2, t0, t1, t2, w, -1


@kernel(inline="always")
def _kept(settled, warm, pa, pb):
    """settled; if so, the patches that settled it (-1: a side that is no STP-BV) seed the next query."""
    if settled:
        if pa >= 0:
            warm[0] = pa
        if pb >= 0:
            warm[1] = pb
    return settled


@kernel(inline="always")
def _march_a_to_feature(pair, k, slot, tol_abs, tol_rel, warm, work, scratch, fscratch, out):
    """settle_on_feature with A the STP-BV that marches to B's feature: B's simplex as a vertex or an
    edge, or, with B an STP-BV, the hull vertex in its simplex slot (slot >= 0, see _owning_slot),
    whose small sphere stands for B."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    ok, s0, s1, s2, t0, t1, t2, w, pb = _feature_of(work, 8, k, slot, iB, scratch[WARM_SIMPLEX_B:WARM_SIMPLEX_B + 4])
    h = scratch[0]
    if not ok or not 0 <= h < iA[IDX_H]:
        return False
    p, m0, m1, m2, y0, y1, y2, gap = march_to_feature(fA, iA, h, s0, s1, s2, t0, t1, t2, w)
    if p < 0:
        return False
    for c in range(3):
        out[OUT_POINT_B + c] = (y0, y1, y2)[c] - mB * (m0, m1, m2)[c]
        # the march's patch owns m: A's support along it is its ball's point
        fscratch[0, c] = (y0, y1, y2)[c] + (mA - gap) * (m0, m1, m2)[c]
    return _kept(_certify(pair, -1, pb, m0, m1, m2, tol_abs, tol_rel, warm, fscratch, KNOWN_A, out), warm, p, pb)


@kernel(inline="always")
def _march_b_to_feature(pair, k, slot, tol_abs, tol_rel, warm, work, scratch, fscratch, out):
    """settle_on_feature with B the STP-BV that marches to A's feature (as _march_a_to_feature)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    ok, s0, s1, s2, t0, t1, t2, w, pa = _feature_of(work, 4, k, slot, iA, scratch[WARM_SIMPLEX_A:WARM_SIMPLEX_A + 4])
    h = scratch[1]
    if not ok or not 0 <= h < iB[IDX_H]:
        return False
    s0, s1, s2 = to_b(R, t, s0, s1, s2)
    t0, t1, t2 = to_b(R, t, t0, t1, t2)
    p, u0, u1, u2, y0, y1, y2, gap = march_to_feature(fB, iB, h, s0, s1, s2, t0, t1, t2, w)
    if p < 0:
        return False
    m0, m1, m2 = rot_to_a(R, -u0, -u1, -u2)
    w0, w1, w2 = to_a(R, t, y0, y1, y2)
    b0, b1, b2 = to_a(R, t, y0 - gap * u0, y1 - gap * u1, y2 - gap * u2)  # B's support along -m
    for c in range(3):
        out[OUT_POINT_A + c] = (w0, w1, w2)[c] + mA * (m0, m1, m2)[c]
        fscratch[1, c] = (b0, b1, b2)[c] - mB * (m0, m1, m2)[c]
    return _kept(_certify(pair, pa, -1, m0, m1, m2, tol_abs, tol_rel, warm, fscratch, KNOWN_B, out), warm, pa, p)


@kernel(inline="always")
def gjk_query(pair, tol, dir_io, centres, warm, iwork, work,
              out, signed):
    """Distance between core A (+ margin mA) and core B (+ margin mB), B at (R, t) in A's frame.

    dir_io: (3,) initial search direction (zero: a cold start), overwritten with the final
    closest-point direction for the next warm start. centres: (6,) a point inside A (A's frame), then
    one inside B (B's frame): a cold start searches first along the line from A's to B's, which,
    for bodies whose frame origin lies far from their middle (a robot link's joint), saves about
    7% of the GJK iterations (JVRC-1, cold: 2.47 -> 2.29 per pair). warm: int64 (WARM_SIZE,) warm-start state
    (in/out; zeros for a cold start). iwork: int64 (IWORK_SIZE,) scratch. work: (WORK_ROWS, 4)
    scratch. out: (OUT_SIZE,) result vector, in A's frame. signed: an overlap gets its penetration
    depth as a negative distance, with witness points and certified bounds (spq.kernels.signed);
    otherwise distance 0 and NaN points. Returns the status code.

    Spheres and capsules against each other, and a box against a sphere, take a closed form
    (spq.kernels.primitive_pairs) unless their cores meet.

    With an STP-BV on either side: first the patches that faced each other in the last query (against
    a polytope by coherent_ball.coherent_ball_finish, else finish_on_patches); then a loose search on
    the underlying hulls grown by r, whose overlap is the STP-BVs' overlap and whose normal points at
    the facing patches; its simplex may settle the query at once (settle_on_small_spheres,
    settle_on_feature), else it is settled on those patches
    (finish_on_patches); if that fails, the plain descent on the STP-BVs themselves. A pair that
    overlapped last time goes straight to the hull search, from the hulls' last simplex (which, if
    the cores still overlap, confirms it without a support call).

    Inlined into its callers (and coherent_ball_finish into it): a compiled call passes every
    array as a struct of 7 to 9 words on the stack, and the two calls cost about a fifth of a
    coherent robot-scene query. A kernel with NRT must not inline it (see spq.kernels.jit).
    """
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    if closed_form_kinds(kA, kB):
        status = primitive_query(pair, tol, signed, dir_io, out)
        if status >= 0:
            return status
    extra = 0
    if kA == STP or kB == STP:
        n = math.sqrt(dir_io[0] ** 2 + dir_io[1] ** 2 + dir_io[2] ** 2)
        # bodies that overlapped last time most likely still do: no patch faces the other body then,
        # and the patch finishes would only fail before the hull search settles it (on a JVRC-1
        # trajectory, 2% of the pairs overlap, and those failures took 13% of the time)
        overlapped = warm[WARM_HULL_OVERLAP] != 0
        if n > 0.0 and not overlapped:  # coherence: the patches that faced each other last time
            used = coherent_ball_finish(pair, tol, dir_io,
                                        warm, work, out)
            if used >= 0:
                return _done(out, used, dir_io)
        scratch = iwork[0:WARM_SIZE]
        clear_warm(scratch)
        fscratch = work[DESCENT_ROWS:PROBE_ROW]
        if n > 0.0 and not overlapped:
            used = finish_on_patches(pair, (dir_io[0] / n, dir_io[1] / n, dir_io[2] / n), tol, warm, work, scratch,
                                     fscratch, True, out, False, scratch)
            if used >= 0:
                return _done(out, used, dir_io)
        ka, ma, fa, ia = hull_core(kA, mA, fA, iA)
        kb, mb, fb, ib = hull_core(kB, mB, fB, iB)
        newton_stp = smooth_against_stp(kA, fA, kB, fB)
        if not signed and newton_stp:
            # the superellipsoid's inscribed polytope: the search then ends in a few steps, as
            # between polytopes, and its rough normal is all Newton's method needs
            if ka == SUPERELLIPSOID:
                ka, fa = POLYTOPE, fA[FDATA_SIZE:]
            else:
                kb, fb = POLYTOPE, fB[FDATA_SIZE:]
        if overlapped:  # the hulls' last simplex
            for i in range(WARM_SIZE):
                scratch[i] = warm[i]
        else:
            clear_warm(scratch)
        if n == 0.0:
            cold_direction(R, t, centres, dir_io)
        loose = LOOSE_REL_TOL_ONE_STP if (kA == STP) != (kB == STP) else LOOSE_REL_TOL
        if newton_stp:
            loose = INNER_REL_TOL  # Newton's method settles it from a rough normal
        hulls = (ka, ma, fa, ia, kb, mb, fb, ib, R, t)
        status, k, v0, v1, v2, vv, lower, it = descend_inline(hulls, (tol_abs, max(tol_rel, loose), max_iter), dir_io,
                                                              scratch, work)
        extra = it
        if (kA == STP) != (kB == STP):  # its simplex on the polytope side seeds the patch finish
            copy_point_simplex(scratch, warm, 0 if kA == STP else 1)
        gap = math.sqrt(vv) - ma - mb
        if status == OVERLAPPING or (status != FAILED and gap < -tol_abs):
            # the grown hulls overlap, and each STP-BV contains its grown hull
            if signed:
                for i in range(WARM_SIZE):
                    warm[i] = scratch[i]
                warm[WARM_HULL_OVERLAP] = 1
                return signed_from_hulls(pair, tol, status, k,
                                         vv, extra, warm, work, iwork, out)
            _finish(OVERLAPPING, k, (work[12], work[4:8], work[8:12]), (v0, v1, v2), vv, lower, it, ma, mb,
                    tol_abs, dir_io, out)
            for i in range(WARM_SIZE):
                warm[i] = scratch[i]
            warm[WARM_HULL_OVERLAP] = 1
            return int(out[OUT_STATUS])
        warm[WARM_HULL_OVERLAP] = 0
        if status == SEPARATED and vv > 0.0 and newton_stp:
            used = newton_on_patches(pair, (v0, v1, v2), vv, tol, scratch, dir_io, warm, work, out)
            if used >= 0:
                return _done(out, used + extra, dir_io)
            extra -= used + 1
        elif status == SEPARATED and vv > 0.0:
            if settle_on_small_spheres(pair, k, v0, v1, v2, vv, tol, warm,
                                       work, scratch, fscratch, out):
                return _done(out, extra, dir_io)
            if settle_on_feature(pair, k, (v0, v1, v2, vv), tol, warm, work, scratch, fscratch, out):
                return _done(out, extra, dir_io)
            n = math.sqrt(vv)
            used = finish_on_patches(pair, (-v0 / n, -v1 / n, -v2 / n), tol, warm, work, scratch, fscratch, False, out,
                                     False, scratch)
            if used >= 0:
                return _done(out, used + extra, dir_io)
            if signed:
                # within about tol_abs of touching the separated certificate gives up (its slab must
                # be positive), while the small balls' bounds hold for either sign while |sd| < r
                used = finish_on_patches(pair, (-v0 / n, -v1 / n, -v2 / n), tol, warm, work, scratch, fscratch, False,
                                         out, True, iwork[WARM_SIZE:EPA_IOFF])
                if used >= 0:
                    return _done(out, used + extra, dir_io)
            dir_io[0], dir_io[1], dir_io[2] = -v0, -v1, -v2
    else:
        if dir_io[0] == 0.0 and dir_io[1] == 0.0 and dir_io[2] == 0.0:
            cold_direction(R, t, centres, dir_io)
        if smooth_pair(kA, fA, kB, fB):
            used = smooth_finish(pair, tol, dir_io, warm,
                                 work, out)
            if used >= 0:
                if signed and out[OUT_STATUS] == OVERLAPPING:
                    # the inscribed polytopes overlap: the EPA on the bodies, from their simplex
                    return signed_finish(pair, tol,
                                         OVERLAPPING, 4, 0.0, 0.0, used, dir_io, warm, work, iwork, out)
                return _done(out, used, dir_io)
            extra = -used - 1
    status, k, v0, v1, v2, vv, lower, it = descend_inline(pair, tol, dir_io, warm, work)
    if signed and status == SEPARATED:  # (signed_finish's and its callees' calls were 5% of such a query)
        return separated_result(k, lower, it + extra, tol_abs, mA, mB, dir_io, work, out)
    if signed or status == FAILED:
        # A stalled descent (rounding stops it about 1e-8 of the distance short, next to a boxy
        # superellipsoid's edge or between needle-thin bodies) gets the signed query's rescue either
        # way: the EPA from its simplex settles the side and closes the bounds.
        status = signed_finish(pair, tol, status, k, vv,
                               lower, it + extra, dir_io, warm, work, iwork, out)
        return status if signed else unsigned_of_signed(out)
    if status == TOUCHING and tol_abs > 0.0:
        status = certify_overlap(pair, tol, warm,
                                 work[PROBE_ROW:PROBE_END], iwork[WARM_SIZE:EPA_IOFF])
    _finish(status, k, (work[12], work[4:8], work[8:12]), (v0, v1, v2), vv, lower, it + extra, mA, mB,
            tol_abs, dir_io, out)
    return int(out[OUT_STATUS])


@kernel
def smooth_finish(pair, tol, dir_io, warm, work, out):
    """Two smooth bodies (see newton_normal.smooth_pair): GJK between their inner polytopes (an
    overlap there is theirs), then Newton's method on the closest points from the polytopes' where
    neither body is pointy (closest_points_newton.primal_pair), and once more from the polytopes'
    search carried on to PRIMAL_RESTART_REL_TOL if that fails, else (or if that fails too) Newton's
    method on the normal from the polytopes' normal. Returns the iterations used (result in out), or
    -1 - iterations when the plain descent has to finish (dir_io then holds the best normal found). The polytopes' simplex is the warm
    start kept in warm (the superellipsoids' own descent has none to keep)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    inner = (POLYTOPE, 0.0, fA[FDATA_SIZE:], iA, POLYTOPE, 0.0, fB[FDATA_SIZE:], iB, R, t)
    loose = PRIMAL_INNER_REL_TOL if primal_pair(kA, fA, kB, fB) else INNER_REL_TOL
    status, k, v0, v1, v2, vv, lower, it = descend(inner, (tol_abs, max(tol_rel, loose), max_iter), dir_io,
                                                   warm, work)
    PA = work[4:8]
    PB = work[8:12]
    lam = work[12]
    if status == OVERLAPPING:
        _finish(status, k, (lam, PA, PB), (v0, v1, v2), vv, lower, it, mA, mB, tol_abs, dir_io, out)
        return it
    upper = math.sqrt(vv)
    if status != SEPARATED or not (upper > tol_abs):
        return -1 - it
    if primal_pair(kA, fA, kB, fB):
        for attempt in range(2):
            if attempt == 1:
                # the same descent carried on to a tighter tolerance (its simplex kept in warm): a start
                # nearer the bodies' closest points, which most of the failed Newton runs converge from
                status, k, v0, v1, v2, vv, lower, more = descend(
                    inner, (tol_abs, max(tol_rel, PRIMAL_RESTART_REL_TOL), max_iter), dir_io, warm, work)
                it += more
                upper = math.sqrt(vv)
                if status != SEPARATED or not (upper > tol_abs):
                    return -1 - it
            # the inscribed polytopes' closest points start Newton on the bodies' own closest points
            xs, ys = work[13], work[14]  # (the descent's rows past its simplex: Newton's scratch below)
            _combine(PA, lam, k, xs, 0)
            _combine(PB, lam, k, ys, 0)
            ok, steps, up, lo = closest_points_newton(pair, (xs[0], xs[1], xs[2], ys[0], ys[1], ys[2]), tol_abs,
                                                      tol_rel, PA[0], PB[0], work[13:DESCENT_ROWS],
                                                      work[PROBE_ROW:PROBE_END], work[EPA_ROW:EPA_ROW + 2])
            it += steps
            if ok:
                _finish_at_points(PA, PB, lam, up, lo, it, mA, mB, tol_abs, dir_io, out)
                return it
    ok, evaluations, upper, lower, m0, m1, m2 = newton_normal(pair, (-v0 / upper, -v1 / upper, -v2 / upper),
                                                              0.0, tol_abs, tol_rel, PA[0], PB[0],
                                                              work[13:DESCENT_ROWS], warm)
    it += evaluations
    if not ok:
        dir_io[0], dir_io[1], dir_io[2] = m0, m1, m2
        return -1 - it
    _finish_at_points(PA, PB, lam, upper, lower, it, mA, mB, tol_abs, dir_io, out)
    return it


@kernel
def newton_on_patches(pair, v, vv, tol, scratch, dir_io, warm, work, out):
    """An STP-BV against a smooth superellipsoid (newton_normal.smooth_against_stp): Newton's method
    on the normal from the loose search on the STP-BV's grown hull (closest point v of the difference,
    |v|^2 = vv; its simplex's hull vertices in scratch), whose small spheres start the patch
    searches. Both sides are curved, where GJK converges only linearly (about 15 iterations to
    1e-10 on Table I's CSE-STP). Against a boxy superellipsoid (exponents at most 1.1) Newton on its
    point nearest the STP-BV's patch (patch_newton) takes over where Newton on the normal fails, and
    runs first where an exponent is at most 0.3. Returns the evaluations used (result in out, the
    facing patches in warm for the next query), or -1 - evaluations with the best normal in dir_io
    for the plain descent (the loose search's simplex in work is then overwritten)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    if kA == STP:
        warm[WARM_FEATURE_A] = _hull_hint(iA, scratch[WARM_FEATURE_A])
    if kB == STP:
        warm[WARM_FEATURE_B] = _hull_hint(iB, scratch[WARM_FEATURE_B])
    n = math.sqrt(vv)
    PA = work[4:8]
    PB = work[8:12]
    lam = work[12]
    e0 = 0
    if patch_newton_first(kA, fA, kB, fB):
        ok, e0, upper, lower, m0, m1, m2 = patch_newton(pair, (-v[0] / n, -v[1] / n, -v[2] / n), tol_abs, tol_rel,
                                                        PA[0], PB[0], work[13:DESCENT_ROWS], warm)
        if ok:
            _finish_at_points(PA, PB, lam, upper, lower, e0, mA, mB, tol_abs, dir_io, out)
            return e0
    ok, evaluations, upper, lower, m0, m1, m2 = newton_normal(pair, (-v[0] / n, -v[1] / n, -v[2] / n), 0.0, tol_abs,
                                                              tol_rel, PA[0], PB[0], work[13:DESCENT_ROWS], warm)
    evaluations += e0
    if not ok and patch_newton_pair(kA, fA, kB, fB):
        # a boxy superellipsoid, whose support map's derivative jumps near its faces' normals: Newton
        # on its point nearest the STP-BV's patch, from the best normal found
        ok, more, upper, lower, _, _, _ = patch_newton(pair, (m0, m1, m2), tol_abs, tol_rel, PA[0], PB[0],
                                                       work[13:DESCENT_ROWS], warm)
        evaluations += more
    if not ok:
        dir_io[0], dir_io[1], dir_io[2] = m0, m1, m2
        return -1 - evaluations
    _finish_at_points(PA, PB, lam, upper, lower, evaluations, mA, mB, tol_abs, dir_io, out)
    return evaluations


@kernel(inline="always")
def _finish_at_points(PA, PB, lam, upper, lower, it, mA, mB, tol_abs, dir_io, out):
    """The result of a Newton finish: the points PA[0] (on A) and PB[0] (on B, A's frame) upper apart,
    with the certified lower bound."""
    lam[0] = 1.0
    v0, v1, v2 = PA[0, 0] - PB[0, 0], PA[0, 1] - PB[0, 1], PA[0, 2] - PB[0, 2]
    _finish(SEPARATED, 1, (lam, PA, PB), (v0, v1, v2), upper * upper, lower, it, mA, mB, tol_abs, dir_io, out)


@kernel(inline="always")
def cold_direction(R, t, centres, dir_io):
    """dir_io = the direction from A's inner point to B's (centres, see gjk_query), in A's frame;
    from A's origin to B's if that is zero."""
    for r in range(3):
        dir_io[r] = R[r, 0] * centres[3] + R[r, 1] * centres[4] + R[r, 2] * centres[5] + t[r] - centres[r]
    if dir_io[0] == 0.0 and dir_io[1] == 0.0 and dir_io[2] == 0.0:
        dir_io[0], dir_io[1], dir_io[2] = t[0], t[1], t[2]


@kernel(inline="always")
def _done(out, iterations, dir_io):
    out[OUT_ITERATIONS] = iterations
    for c in range(3):
        dir_io[c] = out[OUT_NORMAL + c]
    return int(out[OUT_STATUS])


@kernel
def signed_from_hulls(pair, tol, status, k, vv, it, warm,
                      work, iwork, out):
    """Signed result of two bodies of which one at least is an STP-BV, whose underlying hulls'
    descent (k simplex points in work, |v|^2 = vv, ending with ``status``) found the hulls grown by
    r overlapping.

    First the EPA between the hulls, which converges in a few steps (polytopes), to a relative gap of
    HULLS_EPA_REL; the STP-BV contains its hull grown by r, so the hulls' depth plus the radii bounds
    the bodies' depth from below. Where the facing patch is a small sphere (on kuka_link_4's overlaps,
    about one STP-PCH overlap in six and no STP-STP one), the STP-BV's support along the hulls' normal
    is the grown hull's: the hulls' run goes on to the full tolerance, and the bodies' own supports
    close the certificate.
    Otherwise the patches facing along the hulls' normal settle it (finish_on_patches, with the
    small-ball certificate of _certify_overlap) while the overlap is shallower than r; else the EPA
    goes on from the hulls' polytope (its points lie inside the STP-BVs' cores, their ball hulls at
    R - r) on the cores' supports, r carried as margin (core_pair).

    Where the hulls lie apart (by less than the radii) and the patches at their normal do not settle
    it, the cores are searched from the hulls' normal: loosely, the patches at the cores' normal, and
    else to the full tolerance, with the EPA if they overlap (signed_finish on the cores)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    ka, ma, fa, ia = hull_core(kA, mA, fA, iA)
    kb, mb, fb, ib = hull_core(kB, mB, fB, iB)
    hulls = (ka, ma, fa, ia, kb, mb, fb, ib, R, t)
    grow = (ma - mA) + (mb - mB)  # the radii r of the STP sides: the hulls' grown part
    eit = 0
    if status != OVERLAPPING:
        # the hulls apart by less than the radii: their distance d to full tolerance first (from the
        # loose search's simplex in warm). The bodies contain the hulls grown by the radii, which
        # hold the ball of radius grow - d about the origin, so sd <= d - grow; where a small
        # sphere faces, the bodies' supports along the hulls' normal give sd >= d - grow too.
        lam = work[12]
        dirv = work[EPA_ROW + EPA_TMP]
        for c in range(3):
            x = 0.0
            for i in range(k):
                x -= lam[i] * work[i, c]
            dirv[c] = x
        # the patches facing along the loose search's normal settle most of these shallow overlaps
        # (where no small sphere faces, the hulls' full-tolerance distance below would not settle
        # them); their certificate holds for either sign while the depth is below r. On JVRC-1's
        # shallow STP-PCH overlaps the signed query's time over the unsigned one went 2.2 -> 1.4 us.
        dn = math.sqrt(dirv[0] ** 2 + dirv[1] ** 2 + dirv[2] ** 2)
        patches_tried = dn > 0.0
        if patches_tried:
            saved = iwork[EPA_IOFF:EPA_IOFF + WARM_SIZE]  # the hulls' simplex, for the descent below
            for i in range(WARM_SIZE):
                saved[i] = warm[i]
            if _patches_settle(pair, dirv[0] / dn, dirv[1] / dn, dirv[2] / dn,
                               tol, warm, work, iwork, out, it):
                return int(out[OUT_STATUS])
            for i in range(WARM_SIZE):
                warm[i] = saved[i]
        status, k, v0, v1, v2, vv, lower, more = descend(hulls, tol,
                                                         dirv, warm, work)
        eit += more
        if status == SEPARATED:
            d = math.sqrt(vv)
            n0, n1, n2 = -v0 / d, -v1 / d, -v2 / d
            upper = d - grow
            low = -core_support(pair, n0, n1, n2, warm, work)
            if bounds_closed(upper, low, tol_abs, tol_rel):
                descent_result(SEPARATED, k, work[12], work[4:8], work[8:12], lower, it + eit, tol_abs, n0, n1, n2,
                               out)
                return _hulls_settle(mA, mB, ma, mb, (n0, n1, n2), upper, low, it + eit, tol_abs, work, out)
            # (the patches were tried above unless the loose search gave no normal)
            if not patches_tried and _patches_settle(pair, n0, n1, n2, tol, warm, work, iwork, out, it + eit):
                return int(out[OUT_STATUS])
            # the cores from the hulls' normal (the STP-BVs' ball hulls at R - r, r as margin), not the
            # EPA on the bodies, whose surfaces curve at r (45 iterations on kuka_link_4): a loose
            # descent, whose normal the patches mostly settle; else the full descent (the cores' nearly
            # flat faces take it about 30 steps) and the EPA where they overlap (signed_finish). The
            # cores' search keeps its own warm state: warm keeps the hulls' simplex, the next coherent
            # query's start.
            core = core_pair(pair, hulls)
            cw = iwork[WARM_SIZE:EPA_IOFF]
            clear_warm(cw)
            cw[WARM_FEATURE_A], cw[WARM_FEATURE_B] = warm[WARM_FEATURE_A], warm[WARM_FEATURE_B]
            dirv[0], dirv[1], dirv[2] = n0, n1, n2
            status, k, v0, v1, v2, vv, lower, more = descend(core, (tol_abs, max(tol_rel, LOOSE_REL_TOL), max_iter),
                                                             dirv, cw, work)
            eit += more
            if status == SEPARATED and vv > 0.0:
                # the cores apart: the patches facing along their normal (the small balls' certificate)
                d = math.sqrt(vv)
                if _patches_settle(pair, -v0 / d, -v1 / d, -v2 / d, tol, warm, work, iwork, out, it + eit):
                    return int(out[OUT_STATUS])
                clear_warm(cw)
                cw[WARM_FEATURE_A], cw[WARM_FEATURE_B] = warm[WARM_FEATURE_A], warm[WARM_FEATURE_B]
                dirv[0], dirv[1], dirv[2] = -v0, -v1, -v2
                status, k, v0, v1, v2, vv, lower, more = descend(core, tol, dirv, cw, work)
                eit += more
            work[EPA_ROW + EPA_TMP + 1, 3] = HULL_CORES
            dirv[0], dirv[1], dirv[2] = n0, n1, n2
            return signed_finish(core, tol, status, k, vv, lower, it + eit, dirv, cw, work, iwork, out)
    upper0 = 0.0 if status == OVERLAPPING else math.sqrt(vv)
    nv = 0
    if status != SEPARATED and status != FAILED:
        nv, top, c0, c1, c2, low = epa_start(hulls, 4 if status == OVERLAPPING else k,
                                             (work[0:4], work[4:8], work[8:12], work[20:22]), warm, work, iwork, out)
    if nv == 4:
        loose = (tol_abs, max(tol_rel, HULLS_EPA_REL), max_iter)
        outcome, closed, upper, low, more, nv, top = epa_run(hulls, loose, nv, top, (c0, c1, c2), upper0, low, warm,
                                                             work, iwork, out)
        eit += more
        h = 0.0
        if outcome == EPA_RESULT:
            h = core_support(pair, out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2], warm, work)
            if _small_spheres_face(pair, warm) and not bounds_closed(upper, low, tol_abs, tol_rel):
                # small spheres face along the hulls' normal, so the bodies' depth is likely the hulls'
                # plus the radii, settled below: the hulls' run goes on to the full tolerance
                outcome, closed, upper, low, more, nv, top = epa_run(hulls, tol, nv, top, (c0, c1, c2), upper0, low,
                                                                     warm, work, iwork, out)
                eit += more
                h = core_support(pair, out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2], warm, work)
        if outcome == EPA_RESULT:
            # the hulls' witness points, pushed out by the radii, and their normal
            upper = upper - grow
            n0, n1, n2 = out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2]
            low = -h
            if bounds_closed(upper, low, tol_abs, tol_rel):
                return _hulls_settle(mA, mB, ma, mb, (n0, n1, n2), upper, low, it + eit, tol_abs, work, out)
            if _small_balls_reach(upper + grow, grow + mA + mB, tol_abs, tol_rel) and _patches_settle(
                    pair, n0, n1, n2, tol, warm, work, iwork,
                    out, it + eit):
                return int(out[OUT_STATUS])
            # the EPA goes on from the hulls' polytope (its own bound only: the result's witness points
            # are its face's) on the cores of the STP-BVs, their ball hulls at R - r (the polytope's
            # points lie in them), with r as margin: the EPA need not grow the polytope by r again,
            # and the cores' surfaces curve at R - r, not at r (tori and small spheres), so fewer
            # expansions close the bound (on kuka_link_4's overlapping poses, STP-PCH 37 -> 32 and
            # STP-STP 52 -> 44 on average)
            core = core_pair(pair, hulls)
            ra, rb = core[1] - mA, core[5] - mB  # the radii taken into the margins
            outcome, closed, upper, low, more, nv, top = epa_run(core, tol, nv, top, (c0, c1, c2), math.inf,
                                                                 low + (ra + rb), warm, work, iwork, out)
            eit += more
            if outcome == EPA_RESULT:
                work[EPA_ROW + EPA_TMP + 1, 3] = HULL_CONTINUED
                out[OUT_ITERATIONS] = it + eit
                add_margins(ra, rb, tol_abs, out)
                settle_by_centres(pair, tol_abs, tol_rel, warm, work, iwork, out)
                add_margins(mA, mB, tol_abs, out)
                return int(out[OUT_STATUS])
    # the hulls' polytope did not hold the origin: the EPA on the bodies from the descent's simplex
    # (the bodies overlap by more than tol_abs: their grown hulls do)
    outcome, closed, upper, low, more = epa(pair, tol, 4 if status == OVERLAPPING else k,
                                            (work[0:4], work[4:8], work[8:12], work[20:22]), math.inf, -math.inf, warm,
                                            work, iwork, out)
    eit += more
    work[EPA_ROW + EPA_TMP + 1, 3] = HULL_RESTARTED
    if outcome != EPA_RESULT:
        # |sd| <= tol_abs with the origin outside the polytope (or no tetrahedron): the supports
        # along the normal found, reported as failed unless the bounds closed
        set_result(upper, low, it + eit, tol_abs, out)
        if not closed:
            out[OUT_STATUS] = FAILED
        supports_as_witnesses(pair, warm, work, out)
    out[OUT_ITERATIONS] = it + eit
    settle_by_centres(pair, tol_abs, tol_rel, warm, work, iwork, out)
    add_margins(mA, mB, tol_abs, out)
    return int(out[OUT_STATUS])


@kernel(inline="always")
def _small_spheres_face(pair, warm):
    """Whether every STP-BV side's support along the last direction (its patch in warm) was a small
    sphere's."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    return (kA != STP or warm[0] < iA[IDX_V]) and (kB != STP or warm[1] < iB[IDX_V])


@kernel(inline="always")
def core_pair(pair, hulls):
    """The pair with the STP-BV sides that searched on their hulls (hull_core's polytope in hulls, whose
    points lie in the core) as their cores, kind STP_CORE, their small radii r added to the margins:
    the bodies' signed distance is the cores' less the margins. A side that searched on itself (an
    STP-BV with no hull table) stays as it is: its points need not lie in its core."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    ka, kb = hulls[0], hulls[4]
    core_a, ma = (STP_CORE, mA + fA[F_R]) if kA == STP and ka == POLYTOPE else (kA, mA)
    core_b, mb = (STP_CORE, mB + fB[F_R]) if kB == STP and kb == POLYTOPE else (kB, mB)
    return core_a, ma, fA, iA, core_b, mb, fB, iB, R, t


@kernel
def _hulls_settle(mA, mB, ma, mb, n, upper, low, iterations, tol_abs, work, out):
    """The hulls' witness points in out pushed out by the radii along unit n, the bounds (upper, low)
    and the margins: the result of signed_from_hulls settled on the hulls. Returns the status."""
    n0, n1, n2 = n
    work[EPA_ROW + EPA_TMP + 1, 3] = HULL_SETTLED
    for c in range(3):
        out[OUT_POINT_A + c] += (ma - mA) * (n0, n1, n2)[c]
        out[OUT_POINT_B + c] -= (mb - mB) * (n0, n1, n2)[c]
    set_result(upper, low, iterations, tol_abs, out)
    add_margins(mA, mB, tol_abs, out)
    return int(out[OUT_STATUS])


# Relative gap at which signed_from_hulls's EPA on the hulls stops: the hulls' depth plus the radii only
# settles an overlap where a small sphere faces, and otherwise the EPA goes on from the hulls' polytope
# on the cores, whose surfaces bulge over the hulls' faces (stop 100: 0.15% to 7.8% of the depth), so
# refining the hulls' polytope to the full tolerance was work the cores' run redid. Same process, on
# kuka_link_4's overlapping poses: 1e-2 took STP-STP 22.95 -> 21.54 expansions and 1.047x the speed,
# STP-PCH 1.02x; 1e-3 1.01x, 1e-1 and 1.0 no better than 1e-2 (fewer expansions, but the cores' cost more).
HULLS_EPA_REL = 1e-2
PATCH_REACH_SLACK = 2.0  # _small_balls_reach's margin over the certificate's tolerance, against rounding


@kernel(inline="always")
def _small_balls_reach(hulls_sd, radii, tol_abs, tol_rel):
    """Whether _certify_overlap may close where the hulls (cores, not grown) have signed distance
    hulls_sd; radii: the small balls' radii plus the margins, r_A + r_B + m_A + m_B.

    Its upper bound, from the small balls inside the bodies with their centres outside the other core
    (or apart, between two STP-BVs), is at least -radii, while the bodies overlap at least as deep
    as the hulls grown by the radii: sd <= hulls_sd - radii. So its gap is at least -hulls_sd, and
    where the hulls overlap by more than its tolerance the patch rounds can only fail, at the cost of
    a descent and an STP-BV support or more each (on JVRC-1, about a tenth of a deep STP-PCH overlap's time)."""
    return -hulls_sd <= PATCH_REACH_SLACK * (tol_abs + tol_rel * radii)


@kernel
def _patches_settle(pair, n0, n1, n2, tol, warm, work, iwork,
                    out, iterations):
    """Whether the patches facing along n settle a signed query (finish_on_patches with the overlap
    certificate); the result, iterations included, is then in out."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    used = finish_on_patches(pair, (n0, n1, n2), tol, warm, work,
                             iwork[0:WARM_SIZE], work[DESCENT_ROWS:PROBE_ROW], False, out, True,
                             iwork[WARM_SIZE:EPA_IOFF])
    if used < 0:
        return False
    work[EPA_ROW + EPA_TMP + 1, 3] = HULL_PATCHES
    out[OUT_ITERATIONS] = iterations + used
    return True
