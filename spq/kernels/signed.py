"""The end of a signed query: from the GJK's descent to a signed distance with certified bounds.

Bodies are cores grown by margins (a sphere is a point grown by its radius), so the signed
distance of the bodies is the cores' minus the margins: sd = sd_core - (mA + mB), with the same
normal, the witness points moved out by the margins along it, and the bounds shifted alike.

- Cores apart by more than tol_abs: the descent's result is exact; only the margins may make it
  negative.
- Cores overlapping, or within tol_abs of each other (the descent cannot tell which): the EPA
  (spq.kernels.epa) from the descent's simplex. It either settles the overlap, or certifies that
  |sd_core| <= tol_abs with the origin outside its polytope, where the descent's witness points
  stand, or finds that the cores' difference is flat (two segments, a point and a segment, ...), so
  that sd_core >= 0 and the descent's points stand, with a normal across the flat set if they meet.

Results go to the query's out vector (A's frame) with distance = upper bound = the signed distance,
lower bound below it, status by sd: 'separated' > tol_abs, 'touching' within, 'overlapping' below;
'failed' with the bounds reached if the EPA did not close them.
"""

from __future__ import annotations

import math

import numpy as np

from spq.kernels.ball_hull_depth import MAX_CUTS, is_ball_hull, settle_from_centres
from spq.kernels.epa import EPA_FLAT, EPA_RESULT, bounds_closed, epa
from spq.kernels.gjk import (
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
    _combine,
    minkowski_support,
)
from spq.kernels.jit import kernel
from spq.kernels.newton_normal import step_on_sphere, tangent_basis
from spq.kernels.signed_out import set_result, status_of

# how signed_from_hulls ended, kept in the scratch (work[EPA_ROW + EPA_TMP + 1, 3]) for diagnostics
HULL_SETTLED, HULL_CONTINUED, HULL_RESTARTED, HULL_PATCHES, HULL_CORES = 1, 2, 3, 4, 5


@kernel
def add_margins(mA, mB, tol_abs, out):
    """The cores' signed result in out becomes the bodies': points moved out by the margins along the
    normal, distance and bounds less mA + mB, status from the new distance (failed stays failed)."""
    m = mA + mB
    for c in range(3):
        out[OUT_POINT_A + c] += mA * out[OUT_NORMAL + c]
        out[OUT_POINT_B + c] -= mB * out[OUT_NORMAL + c]
    out[OUT_DISTANCE] -= m
    out[OUT_UPPER] -= m
    out[OUT_LOWER] -= m
    if out[OUT_STATUS] != FAILED:
        out[OUT_STATUS] = status_of(out[OUT_DISTANCE], tol_abs)


@kernel
def unsigned_of_signed(out):
    """A signed result in out as an unsigned query gives it: an overlap has distance and lower bound 0
    and no witness points or normal; otherwise negative values (within tol_abs of touching) become 0.
    Returns the status code."""
    if out[OUT_STATUS] == OVERLAPPING:
        for c in range(OUT_POINT_A, OUT_NORMAL + 3):
            out[c] = np.nan
        out[OUT_DISTANCE] = 0.0
        out[OUT_LOWER] = 0.0
    else:
        out[OUT_DISTANCE] = max(out[OUT_DISTANCE], 0.0)
        out[OUT_LOWER] = max(out[OUT_LOWER], 0.0)
    return int(out[OUT_STATUS])


@kernel(inline="always")
def _points_gap(k, lam, PA, PB, out):
    """The descent's closest points (k simplex points, weights lam) into out, and p_B - p_A with its
    length: an upper bound on the distance where |v| is not, as the weights of a sliver simplex miss
    a sum of 1 by rounding and scale v with them."""
    _combine(PA, lam, k, out, OUT_POINT_A)
    _combine(PB, lam, k, out, OUT_POINT_B)
    dx = out[OUT_POINT_B] - out[OUT_POINT_A]
    dy = out[OUT_POINT_B + 1] - out[OUT_POINT_A + 1]
    dz = out[OUT_POINT_B + 2] - out[OUT_POINT_A + 2]
    return dx, dy, dz, math.sqrt(dx * dx + dy * dy + dz * dz)


@kernel
def descent_result(status, k, lam, PA, PB, lower, it, tol_abs, n0, n1, n2, out):
    """The descent's closest points (k simplex points, weights lam) as a signed core result: distance
    |p_B - p_A| (its upper bound), lower bound ``lower``, normal along p_B - p_A, or n where they
    coincide. status FAILED is kept; otherwise it follows the distance."""
    dx, dy, dz, d = _points_gap(k, lam, PA, PB, out)
    if d > 0.0:
        out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2] = dx / d, dy / d, dz / d
    else:
        out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2] = n0, n1, n2
    out[OUT_DISTANCE] = d
    out[OUT_UPPER] = d
    out[OUT_LOWER] = min(lower, d)
    out[OUT_ITERATIONS] = it
    out[OUT_STATUS] = FAILED if status == FAILED else status_of(d, tol_abs)


@kernel(inline="always")
def _unit_or_x(d):
    """d (3,) as a unit vector, (1, 0, 0) if it is zero: the normal of last resort."""
    dn = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    if dn > 0.0:
        return d[0] / dn, d[1] / dn, d[2] / dn
    return 1.0, 0.0, 0.0


@kernel(inline="always")
def separated_result(k, lower, it, tol_abs, mA, mB, dir_io, work, out):
    """signed_finish's result for a descent that ended SEPARATED (most signed queries), without its
    call: the descent's points, margins included (see descent_result, add_margins)."""
    n0, n1, n2 = _unit_or_x(dir_io)
    descent_result(SEPARATED, k, work[12], work[4:8], work[8:12], lower, it, tol_abs, n0, n1, n2, out)
    add_margins(mA, mB, tol_abs, out)
    return int(out[OUT_STATUS])


@kernel
def signed_finish(pair, tol, status, k, vv, lower, it,
                  dir_io, warm, work, iwork, out):
    """Signed result (A's frame, margins included) from a descent between the cores that ended with
    ``status`` (k simplex points and weights in work, |v|^2 = vv, lower bound ``lower`` on the
    distance, it iterations). dir_io: a direction from A towards B, the normal of last resort."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    tol_abs, tol_rel, max_iter = tol
    lam = work[12]
    PA = work[4:8]
    PB = work[8:12]
    d0, d1, d2 = _unit_or_x(dir_io)
    if status == OVERLAPPING or status == TOUCHING or (status == FAILED and k > 0):
        # a descent that stalled (a smooth body within about tol_abs of touching) hands its simplex
        # on too: the polytope settles the side of the boundary the origin is on
        upper0 = 0.0 if status == OVERLAPPING else _points_gap(k, lam, PA, PB, out)[3]
        lower0 = lower if (status != OVERLAPPING and lower > 0.0) else -math.inf
        outcome, closed, upper, low, eit = epa(pair, tol, k, (work[0:4], PA, PB, work[20:22]), upper0, lower0, warm,
                                               work, iwork, out)
        if outcome == EPA_RESULT:
            out[OUT_ITERATIONS] = it + eit
        else:
            # the origin is outside the polytope, or D is flat: the descent's points stand, with the
            # EPA's normal where they coincide (a face the origin lies beyond, or across the flat set)
            n0, n1, n2 = out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2]
            if not (n0 == n0):
                n0, n1, n2 = d0, d1, d2
            elif outcome == EPA_FLAT and n0 * d0 + n1 * d1 + n2 * d2 < 0.0:
                n0, n1, n2 = -n0, -n1, -n2
            descent_result(TOUCHING, k, lam, PA, PB, low, it + eit, tol_abs, n0, n1, n2, out)
            if not closed and (outcome != EPA_FLAT or status == FAILED) and not bounds_closed(
                    out[OUT_UPPER], out[OUT_LOWER], tol_abs, tol_rel):
                # (a stalled descent between two nearly parallel segments, D flat, may still have
                # met its bounds: the plane across D bounds sd from below)
                out[OUT_STATUS] = FAILED
        settle_by_centres(pair, tol_abs, tol_rel, warm, work, iwork, out)
        if out[OUT_STATUS] == FAILED and outcome == EPA_RESULT and out[OUT_UPPER] < -tol_abs:
            # (tested here: a call passes the pair's arrays even to return at once)
            settle_by_search(pair, tol_abs, tol_rel, min(SEARCH_EVALUATIONS, 32 * max_iter), warm, work, out)
    else:
        descent_result(status, k, lam, PA, PB, lower, it, tol_abs, d0, d1, d2, out)
        if status == FAILED and not lower > 0.0:
            # a descent that proved no separation has lower bound 0 on the distance, which bounds no
            # signed distance; -h_D(n) does, for any unit n (sd = -min over n of h_D(n))
            n0, n1, n2 = out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2]
            low = -core_support(pair, n0, n1, n2, warm, work)
            out[OUT_LOWER] = min(low, out[OUT_UPPER])
    add_margins(mA, mB, tol_abs, out)
    return int(out[OUT_STATUS])


@kernel
def settle_by_centres(pair, tol_abs, tol_rel, warm, work, iwork, out):
    """A failed result where a side is a ball hull (an STP-BV, its core, a sphere: cores, A's frame)
    settled from its set of centres where that bounds sd to the tolerance (spq.kernels.ball_hull_depth:
    against the other's set of centres, or against the other body by point queries); any other result
    stays as it is."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    if out[OUT_STATUS] != FAILED or not (is_ball_hull(kA) or is_ball_hull(kB)):
        return
    settle_from_centres(pair, (tol_abs, tol_rel, MAX_CUTS, math.inf), out[OUT_UPPER], out[OUT_ITERATIONS], warm, work,
                        iwork, out)


SEARCH_FIRST_STEP = 1e-4  # rad: the search's first step about the normal
SEARCH_LAST_STEP = 1e-13  # rad: it stops below this step (a unit vector resolves about 1e-16)
SEARCH_EVALUATIONS = 512  # support pairs at most (about 50 us, on a result that would have failed)
# the compass's eight directions in the normal's tangent plane, in the order they are tried: the axes, then
# the diagonals
COMPASS_X = (1.0, -1.0, 0.0, 0.0, 1.0, -1.0, 1.0, -1.0)
COMPASS_Y = (0.0, 0.0, 1.0, -1.0, 1.0, -1.0, -1.0, 1.0)


@kernel
def settle_by_search(pair, tol_abs, tol_rel, evaluations_left, warm, work, out):
    """A failed overlap (the EPA's result, its bounds open) settled by a better lower bound, where that
    closes its bounds, within evaluations_left support pairs (the caller's: at most SEARCH_EVALUATIONS,
    and 32 per max_iter as the EPA's expansions, so that max_iter still caps a query): sd >= -h_D(n)
    for every unit n, so a compass search about the result's normal (eight directions in its tangent
    plane, the step halved when none raises the bound) may find one the EPA did not. Where a
    superellipsoid's nearly flat side meets a polytope, D is nearly flat about its deepest point and
    the EPA's faces can come within the tolerance of the depth while its support normals stay short
    (fuzz case cse-signed-failed-11: the lower bound 1.6e-11 m short of the depth oracle's, the gap
    1.1e-10 m against a tolerance of 1.0e-10 m). Newton's method on the normal does not reach it:
    the support's derivative is 3.2e6 m/rad along the flat side and 1.7e-3 across, and the normal
    sits where the polytope's support changes vertex. The upper bound, witness points and normal
    stand; any other result stays as it is."""
    if out[OUT_STATUS] != FAILED:
        return
    n0, n1, n2 = out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2]
    upper = out[OUT_UPPER]
    if not (n0 == n0 and upper == upper):
        return
    lower = out[OUT_LOWER]
    best = -core_support(pair, n0, n1, n2, warm, work)
    evaluations = 1
    step = SEARCH_FIRST_STEP
    while step >= SEARCH_LAST_STEP and evaluations < evaluations_left:
        if bounds_closed(upper, max(lower, best), tol_abs, tol_rel):
            set_result(upper, max(lower, best), out[OUT_ITERATIONS] + evaluations, tol_abs, out)
            return
        b0, b1, b2, e0, e1, e2 = tangent_basis(n0, n1, n2)
        moved = False
        for k in range(8):
            if evaluations >= evaluations_left:
                break
            c0, c1, c2 = step_on_sphere(n0, n1, n2, b0, b1, b2, e0, e1, e2, COMPASS_X[k] * step, COMPASS_Y[k] * step)
            value = -core_support(pair, c0, c1, c2, warm, work)
            evaluations += 1
            if value > best:
                best, n0, n1, n2, moved = value, c0, c1, c2, True
                break
        if not moved:
            step *= 0.5
    if bounds_closed(upper, max(lower, best), tol_abs, tol_rel):
        set_result(upper, max(lower, best), out[OUT_ITERATIONS] + evaluations, tol_abs, out)


@kernel
def core_support(pair, n0, n1, n2, warm, work):
    """h_D(n) of the cores along unit n (A's frame)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    pa = work[16]
    pb = work[17]
    tmp = work[18]
    minkowski_support(pair, n0, n1, n2, warm, pa, pb, tmp)
    return n0 * (pa[0] - pb[0]) + n1 * (pa[1] - pb[1]) + n2 * (pa[2] - pb[2])
