"""A stalled descent's lower bound from the facet or edge of D = A - B it stalled on (polytope-like cores).

Near touching, the descent's direction v is the simplex's nearest point to the origin, a combination
of support points that are differences of vertices, each rounded to about eps L for bodies of size
L. At a distance d that leaves v's direction off D's true normal by about eps L / d. Where D's
nearest point lies inside a facet (a face of one body against a vertex of the other, or two edges
crossing) or on an edge (a vertex against an edge), the support along a direction that far off
jumps to a corner of the facet or an end of the edge, and the
separating-plane bound falls short of the distance by that angle times the facet's size: about
1e-9 m for unit boxes 1e-8 m apart, ten times the default tolerance, so the query ends FAILED with
the right distance (2% to 7% of randomly rotated boxes placed 1e-9 to 1e-7 m apart).

The facet's own normal is a cross product of vertex differences, accurate to eps relative whatever
d is. The vertices whose value along v comes within a few times that error of their body's support
are the facet's (each body's part of it: a face, an edge or a vertex), so the normals of the faces
and of the edge pair among them give the bound to rounding. Where the nearest point lies on an edge
of D (a vertex against an edge), v less its part along the edge lies inside the edge's wedge of
normals, where the angle costs nothing. Any unit normal n bounds the distance from below by min over
D of n.x, so a normal from the wrong vertices only gives a weaker bound.
"""

from __future__ import annotations

import math

from spq.kernels.dispatch import support_local
from spq.kernels.frames import rot_to_b, to_a
from spq.kernels.indexing import at
from spq.kernels.jit import kernel
from spq.kernels.kinds import BOX, POINT, POLYTOPE, SEGMENT

# A vertex counts as the facet's where its value along v lies within this many times the direction's
# error across the facet of its body's support: the larger of the gap (upper - lower) and the spread
# of the simplex's points (which lie on the facet) along v.
FACET_SLACK = 4.0


@kernel(inline="always")
def _vertex_count(kind, ix):
    """The vertices of a polytope-like core (0 for a curved one)."""
    if kind == POLYTOPE:
        return ix[0]
    if kind == BOX:
        return 8
    if kind == SEGMENT:
        return 2
    if kind == POINT:
        return 1
    return 0


@kernel(inline="always")
def _vertex(kind, f, i):
    """Vertex i of a polytope-like core, in its local frame."""
    if kind == POLYTOPE:
        return f[at(3 * i)], f[at(3 * i + 1)], f[at(3 * i + 2)]
    if kind == BOX:
        return (f[0] if i & 1 else -f[0]), (f[1] if i & 2 else -f[1]), (f[2] if i & 4 else -f[2])
    if kind == SEGMENT:
        return 0.0, 0.0, (f[0] if i else -f[0])
    return 0.0, 0.0, 0.0


@kernel(inline="always")
def _placed_vertex(kind, f, i, R, t, moved):
    """Vertex i in A's frame: moved by (R, t) when ``moved`` (a vertex of B)."""
    x0, x1, x2 = _vertex(kind, f, i)
    if moved:
        return to_a(R, t, x0, x1, x2)
    return x0, x1, x2


@kernel
def _facet_part(kind, f, ix, R, t, moved, u0, u1, u2, slack):
    """(count, three points): the first three vertices (A's frame: moved by (R, t) when ``moved``) whose
    value along u lies within slack of the largest, and how many there are (up to 3)."""
    n = _vertex_count(kind, ix)
    best = -math.inf
    for i in range(n):
        x0, x1, x2 = _placed_vertex(kind, f, i, R, t, moved)
        best = max(best, u0 * x0 + u1 * x1 + u2 * x2)
    count = 0
    p = (0.0, 0.0, 0.0)
    q = (0.0, 0.0, 0.0)
    s = (0.0, 0.0, 0.0)
    for i in range(n):
        x0, x1, x2 = _placed_vertex(kind, f, i, R, t, moved)
        if u0 * x0 + u1 * x1 + u2 * x2 >= best - slack:
            if count == 0:
                p = (x0, x1, x2)
            elif count == 1:
                q = (x0, x1, x2)
            else:
                s = (x0, x1, x2)
            count += 1
            if count == 3:
                break
    return count, p, q, s


@kernel(inline="always")
def _cross(a, b, c, d):
    """(b - a) x (d - c)."""
    e0, e1, e2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    g0, g1, g2 = d[0] - c[0], d[1] - c[1], d[2] - c[2]
    return e1 * g2 - e2 * g1, e2 * g0 - e0 * g2, e0 * g1 - e1 * g0


@kernel(inline="always")
def _across(a, b, v0, v1, v2):
    """v less its part along b - a."""
    e0, e1, e2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    ee = e0 * e0 + e1 * e1 + e2 * e2
    if not ee > 0.0:
        return 0.0, 0.0, 0.0
    s = (v0 * e0 + v1 * e1 + v2 * e2) / ee
    return v0 - s * e0, v1 - s * e1, v2 - s * e2


@kernel
def _plane_bound(pair, n0, n1, n2, v0, v1, v2, lower, tmp):
    """max(lower, min over D of n.x) for the unit direction along n oriented towards v (lower itself
    where n is degenerate)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if not nn > 0.0:
        return lower
    if n0 * v0 + n1 * v1 + n2 * v2 < 0.0:
        nn = -nn
    n0, n1, n2 = n0 / nn, n1 / nn, n2 / nn
    support_local(kA, fA, iA, -n0, -n1, -n2, 0, tmp)
    a0, a1, a2 = tmp[0], tmp[1], tmp[2]
    e0, e1, e2 = rot_to_b(R, n0, n1, n2)
    support_local(kB, fB, iB, e0, e1, e2, 0, tmp)
    b0, b1, b2 = to_a(R, t, tmp[0], tmp[1], tmp[2])
    return max(lower, n0 * (a0 - b0) + n1 * (a1 - b1) + n2 * (a2 - b2))


@kernel
def facet_lower_bound(pair, W, k, v0, v1, v2, upper, lower, tmp):
    """A lower bound on the cores' distance at least ``lower``, from the normals of the facet of D that
    a descent stalled on with simplex W (k points of D, A's frame) and nearest point v (|v| = upper):
    its face on either body, and the cross product of an edge of each. ``lower`` itself where a core
    is curved. tmp: a scratch row of 3 or more."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    if _vertex_count(kA, iA) == 0 or _vertex_count(kB, iB) == 0 or not upper > 0.0:
        return lower
    u0, u1, u2 = v0 / upper, v1 / upper, v2 / upper
    # the simplex's points lie on the facet: their spread along v is the direction's error across it
    lo, hi = math.inf, -math.inf
    for i in range(k):
        x = u0 * W[i, 0] + u1 * W[i, 1] + u2 * W[i, 2]
        lo, hi = min(lo, x), max(hi, x)
    slack = FACET_SLACK * max(upper - lower, hi - lo)
    # D = A - B lies beyond the plane along v: A's part of the facet maximises -v, B's part v
    ca, a0, a1, a2 = _facet_part(kA, fA, iA, R, t, False, -u0, -u1, -u2, slack)
    cb, b0, b1, b2 = _facet_part(kB, fB, iB, R, t, True, u0, u1, u2, slack)
    if ca >= 3:
        n0, n1, n2 = _cross(a0, a1, a0, a2)
        lower = _plane_bound(pair, n0, n1, n2, v0, v1, v2, lower, tmp)
    if cb >= 3:
        n0, n1, n2 = _cross(b0, b1, b0, b2)
        lower = _plane_bound(pair, n0, n1, n2, v0, v1, v2, lower, tmp)
    if ca >= 2 and cb >= 2:
        n0, n1, n2 = _cross(a0, a1, b0, b1)
        lower = _plane_bound(pair, n0, n1, n2, v0, v1, v2, lower, tmp)
    # a vertex against an edge: D's nearest point is on an edge of D, whose normals form a wedge across
    # it; v less its part along the edge lies in the wedge, where rounding's angle costs nothing
    if ca >= 2:
        n0, n1, n2 = _across(a0, a1, v0, v1, v2)
        lower = _plane_bound(pair, n0, n1, n2, v0, v1, v2, lower, tmp)
    if cb >= 2:
        n0, n1, n2 = _across(b0, b1, v0, v1, v2)
        lower = _plane_bound(pair, n0, n1, n2, v0, v1, v2, lower, tmp)
    return lower
