"""The balls of a torus patch of an STP-BV: the ball of radius R centred on the torus's centre circle
that holds the patch and touches what faces it.

A torus patch lies in every ball of radius R centred on its circle arc (the big spheres' radius),
and along a direction in its region its support is that of the ball centred at the circle point
opposite the direction. Facing a point or a segment, the ball whose distance is the patch's is the
one centred at the circle point farthest from it, found here in closed form or by a safeguarded
Newton solve on the segment.
"""

from __future__ import annotations

import math

from spq.kernels.indexing import at
from spq.kernels.jit import kernel
from spq.kernels.stp_support import IDX_F, IDX_V, _offsets


@kernel
def _circle_point(f, ix, p, x0, x1, x2, side):
    """The point of torus p's centre circle in the direction of x (side 1) or opposite it (side -1),
    seen from the circle's centre in its plane; (False, 0, 0, 0) if x is on the axis."""
    k = _offsets(ix)[1] + 7 * (p - ix[IDX_V] - ix[IDX_F])
    m0, m1, m2 = f[at(k)], f[at(k + 1)], f[at(k + 2)]
    e0, e1, e2, a = f[at(k + 3)], f[at(k + 4)], f[at(k + 5)], f[at(k + 6)]
    w0, w1, w2 = x0 - m0, x1 - m1, x2 - m2
    we = w0 * e0 + w1 * e1 + w2 * e2
    w0, w1, w2 = w0 - we * e0, w1 - we * e1, w2 - we * e2
    wn = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if not (wn > 0.0):
        return False, 0.0, 0.0, 0.0
    s = side * a / wn
    return True, m0 + s * w0, m1 + s * w1, m2 + s * w2


@kernel
def far_ball_centre(f, ix, p, c0, c1, c2, q0, q1, q2):
    """Centre of patch p's ball facing the point q (local frame): a sphere's own centre (c), or for
    a torus the point of its centre circle farthest from q. The STP-BV lies in every ball of radius
    R centred on the torus's circle arc, so facing q its distance is largest, and exact, there."""
    if p < ix[IDX_V] + ix[IDX_F]:
        return c0, c1, c2
    ok, y0, y1, y2 = _circle_point(f, ix, p, q0, q1, q2, -1.0)
    return (y0, y1, y2) if ok else (c0, c1, c2)


@kernel
def aitken_on_circle(f, ix, p, x0, x1, x2, y0, y1, y2, z0, z1, z2):
    """The limit of a linearly converging sequence x, y, z of points on torus p's centre circle,
    by Aitken's extrapolation along the last step, put back on the circle; z if the steps do not
    contract."""
    d0, d1, d2 = y0 - x0, y1 - x1, y2 - x2
    g0, g1, g2 = z0 - y0, z1 - y1, z2 - y2
    dd = d0 * d0 + d1 * d1 + d2 * d2
    if not (dd > 0.0):
        return z0, z1, z2
    lam = (g0 * d0 + g1 * d1 + g2 * d2) / dd
    if not (abs(lam) < 0.9):
        return z0, z1, z2
    s = lam / (1.0 - lam)
    ok, w0, w1, w2 = _circle_point(f, ix, p, z0 + s * g0, z1 + s * g1, z2 + s * g2, 1.0)
    return (w0, w1, w2) if ok else (z0, z1, z2)


SEGMENT_NEWTON_STEPS = 60  # safeguarded Newton steps of the torus-segment solve (a handful in practice)
SEGMENT_PARAMETER_TOL = 1e-15  # step of the segment parameter at which it stops


@kernel
def _phi_slope(a, dg, gg, pp, pq, qq, lam):
    """(phi'/2, phi''/2) at segment parameter lam, phi as in torus_against_segment, from the dot
    products of d = s - m, g = t - s and their in-plane parts p, q."""
    ww = max(0.0, pp + 2.0 * lam * pq + lam * lam * qq)  # |w(lam)|^2
    if not (ww > 0.0):
        return dg + lam * gg, gg
    wn = math.sqrt(ww)
    wq = pq + lam * qq
    return dg + lam * gg + a * wq / wn, gg + a * (qq * ww - wq * wq) / (ww * wn)


@kernel
def torus_against_segment(f, ix, p, s0, s1, s2, t0, t1, t2, guess):
    """Torus p's ball nearest to the segment s-t (local frame): (x, y), y the segment's point nearest
    to the patch and x = y - the ball's centre, the circle point farthest from y. guess: where on the
    segment (parameter in (0, 1)) the Newton solve starts, e.g. where a search on the underlying
    hull ended, next to the patch; the middle if it is outside.

    A torus patch lies in every ball of radius R centred on its circle, so its distance to a point
    y is that to the farthest circle point, minus R: sqrt(phi), phi(y) = |y - m|^2 + 2 a |w| + a^2
    (m, a: the circle's centre and radius; w: y - m within the circle's plane). phi is convex along
    the segment, so its minimum there is found by Newton steps on the segment parameter, kept in a
    bracket where phi' changes sign (bisection when a step leaves it)."""
    k = _offsets(ix)[1] + 7 * (p - ix[IDX_V] - ix[IDX_F])
    m0, m1, m2 = f[at(k)], f[at(k + 1)], f[at(k + 2)]
    e0, e1, e2, a = f[at(k + 3)], f[at(k + 4)], f[at(k + 5)], f[at(k + 6)]
    d0, d1, d2 = s0 - m0, s1 - m1, s2 - m2
    g0, g1, g2 = t0 - s0, t1 - s1, t2 - s2
    de = d0 * e0 + d1 * e1 + d2 * e2
    ge = g0 * e0 + g1 * e1 + g2 * e2
    p0, p1, p2 = d0 - de * e0, d1 - de * e1, d2 - de * e2  # in-plane parts of y(lam) - m = d + lam g
    q0, q1, q2 = g0 - ge * e0, g1 - ge * e1, g2 - ge * e2
    dg = d0 * g0 + d1 * g1 + d2 * g2
    gg = g0 * g0 + g1 * g1 + g2 * g2
    pq = p0 * q0 + p1 * q1 + p2 * q2
    qq = q0 * q0 + q1 * q1 + q2 * q2
    pp = p0 * p0 + p1 * p1 + p2 * p2
    lam = 0.0
    if gg > 0.0 and _phi_slope(a, dg, gg, pp, pq, qq, 0.0)[0] < 0.0:
        lam = 1.0
        if _phi_slope(a, dg, gg, pp, pq, qq, 1.0)[0] > 0.0:  # the minimum is inside: phi' = 0 there
            lo, hi = 0.0, 1.0
            lam = guess if 0.0 < guess < 1.0 else 0.5
            for _ in range(SEGMENT_NEWTON_STEPS):
                slope, curve = _phi_slope(a, dg, gg, pp, pq, qq, lam)
                if slope > 0.0:
                    hi = lam
                else:
                    lo = lam
                if curve > 0.0 and abs(slope) <= SEGMENT_PARAMETER_TOL * curve:
                    # converged: tested before the bracket, which a last step this small may leave
                    # by rounding alone (lam is then an end of it), and bisection would throw away
                    lam = min(hi, max(lo, lam - slope / curve))
                    break
                nxt = lam - slope / curve if curve > 0.0 else 0.5 * (lo + hi)
                if not (lo < nxt < hi):
                    nxt = 0.5 * (lo + hi)
                lam = nxt
    y0, y1, y2 = s0 + lam * g0, s1 + lam * g1, s2 + lam * g2
    ok, c0, c1, c2 = _circle_point(f, ix, p, y0, y1, y2, -1.0)
    if not ok:
        c0, c1, c2 = m0, m1, m2
    return y0 - c0, y1 - c1, y2 - c2, y0, y1, y2
