"""Support function of an STP-BV: find the patch whose vector Voronoi region (VVR) holds the
direction, then take that sphere's or torus's support point (paper section III, NOTES section 1).

Layout (kind STP, see kinds.py):
fdata = [r, R, rho, vertices (3V), face centres (3F), tori (7E: centre m, axis e, circle radius a),
         record planes (4 per record: axis, cos), hull-vertex table (H rows of S records of
         TABLE_RECORD), underlying-hull vertices (3H)]
idata = [V, F, E, number of records, method, H, then offsets below, S (header of IDX_* entries),
         patch offsets (P + 1), records (2 per record: side, neighbour patch),
         hull vertex -> small sphere, underlying-hull polytope idata (to the end)]
The underlying hull comes last in both arrays, so a robot scene can store it once, shared with the
body's own PCH (spq.scene).
Patches are numbered small spheres 0..V-1, big spheres V..V+F-1, tori V+F..V+F+E-1.
A record (plane, side, q) of patch p says: p's region lies where g = v.axis - cos >= 0 (side +1)
or g < 0 (side -1), and q lies across. Each region boundary is the plane of two records, one per
patch, with opposite sides, so every direction has exactly one owner. The plane is stored with each
record, next to its patch's others, rather than once: a region test then reads one contiguous run
instead of a boundary index and a scattered boundary per record, a chain of cache misses that held
most of the test's time.

The hull-vertex table repeats, for each underlying-hull vertex h, its small sphere's records as
(side * axis, side * cos, neighbour patch), padded to the body's largest count S with records
(0, 0, 0, -1, -1) that every direction satisfies. A search on the hull ends on a hull vertex, and
the certificates then ask whether its small sphere owns a direction (small_sphere_owns) or which
torus it hands over to (hull_vertex_step): the table answers from one row found from h alone, where
the records take three dependent reads (hull vertex -> small sphere -> its records -> their planes),
three cache misses in a robot scene's all-pairs loop. The side is folded into the sign, which only
moves a direction lying exactly on a boundary (g = 0) to the other patch, where the two patches'
supports coincide.
"""

from __future__ import annotations

import math

from spq.kernels.indexing import at
from spq.kernels.jit import kernel
from spq.kernels.kinds import POLYTOPE, STP
from spq.kernels.support import polytope_support_index

METHOD_NAIVE = 0
METHOD_MARCH = 1
METHOD_HULL = 2
METHOD_NAMES = ("naive", "march", "hull")

# idata header
IDX_V, IDX_F, IDX_E, IDX_NREC, IDX_METHOD, IDX_H = 0, 1, 2, 3, 4, 5
IDX_PATCH_OFFSETS, IDX_RECORDS, IDX_HULL, IDX_HULL_MAP, IDX_TABLE_STRIDE = 6, 7, 8, 9, 10
HEADER_SIZE = 11
TABLE_RECORD = 5  # floats per hull-vertex table record: side * axis (3), side * cos, neighbour patch
# fdata offsets
F_R, F_BIG_R, F_RHO, F_VERTICES = 0, 1, 2, 3


@kernel
def _offsets(ix):
    V, F, E = ix[IDX_V], ix[IDX_F], ix[IDX_E]
    o_faces = F_VERTICES + 3 * V
    o_tori = o_faces + 3 * F
    o_planes = o_tori + 7 * E
    o_hull = _table_offset(ix) + TABLE_RECORD * ix[IDX_TABLE_STRIDE] * ix[IDX_H]
    return o_faces, o_tori, o_planes, o_hull


@kernel(inline="always")
def plane_offset(ix):
    """Where the record planes start in fdata."""
    return F_VERTICES + 3 * (ix[IDX_V] + ix[IDX_F]) + 7 * ix[IDX_E]


@kernel(inline="always")
def _table_offset(ix):
    """Where the hull-vertex table starts in fdata."""
    return F_VERTICES + 3 * (ix[IDX_V] + ix[IDX_F]) + 7 * ix[IDX_E] + 4 * ix[IDX_NREC]


@kernel(inline="always")
def small_sphere_owns(f, ix, h, u0, u1, u2):
    """Whether the small sphere of underlying-hull vertex h owns unit direction u (local frame), from
    the hull-vertex table (in_region's answer for that sphere, but at g = 0)."""
    S = ix[IDX_TABLE_STRIDE]
    k = _table_offset(ix) + TABLE_RECORD * S * h
    for _ in range(S):
        if f[at(k + 4)] < 0.0:  # padding: the row's records are done
            break
        if u0 * f[at(k)] + u1 * f[at(k + 1)] + u2 * f[at(k + 2)] - f[at(k + 3)] < 0.0:
            return False
        k += TABLE_RECORD
    return True


@kernel
def hull_vertex_step(f, ix, h, u0, u1, u2):
    """march_step from the small sphere of underlying-hull vertex h, from the hull-vertex table: the
    patch across its most violated boundary along unit u, or -1 if it owns u."""
    S = ix[IDX_TABLE_STRIDE]
    k = _table_offset(ix) + TABLE_RECORD * S * h
    nxt = -1
    worst = 0.0
    for _ in range(S):
        if f[at(k + 4)] < 0.0:
            break
        viol = f[at(k + 3)] - (u0 * f[at(k)] + u1 * f[at(k + 1)] + u2 * f[at(k + 2)])
        if viol > worst:
            worst, nxt = viol, int(f[at(k + 4)])
        k += TABLE_RECORD
    return nxt


@kernel
def record_violation(f, ix, o_planes, rec, u0, u1, u2):
    """How far unit direction u is on the wrong side of record rec (<= 0: on its patch's side)."""
    side = ix[at(ix[IDX_RECORDS] + 2 * rec)]
    k = o_planes + 4 * rec
    g = u0 * f[at(k)] + u1 * f[at(k + 1)] + u2 * f[at(k + 2)] - f[at(k + 3)]
    if side > 0:
        return -g  # inside when g >= 0
    # inside when g < 0: g == 0 belongs to the other patch, so it counts as a (zero) violation
    return g if g > 0.0 else (1e-300 if g == 0.0 else g)


@kernel
def in_region(f, ix, o_planes, p, u0, u1, u2):
    """True if unit direction u is in patch p's VVR."""
    po = ix[IDX_PATCH_OFFSETS]
    for rec in range(ix[at(po + p)], ix[at(po + p + 1)]):
        if record_violation(f, ix, o_planes, rec, u0, u1, u2) > 0.0:
            return False
    return True


@kernel
def find_naive(f, ix, o_planes, u0, u1, u2):
    """Scan all patches (O(n)); if rounding leaves u unowned, the least-violated patch."""
    P = ix[IDX_V] + ix[IDX_F] + ix[IDX_E]
    po = ix[IDX_PATCH_OFFSETS]
    best, best_viol = 0, math.inf
    for p in range(P):
        worst = 0.0
        for rec in range(ix[at(po + p)], ix[at(po + p + 1)]):
            worst = max(worst, record_violation(f, ix, o_planes, rec, u0, u1, u2))
        if worst <= 0.0:
            return p
        if worst < best_viol:
            best, best_viol = p, worst
    return best


@kernel
def march_step(f, ix, o_planes, p, u0, u1, u2):
    """The next patch of the guided march from p, or -1 if u is in p's region (paper III.C.2).

    Small sphere: the torus across the most violated cone. Big sphere: across the first violated
    boundary. Torus: a violated face plane first, else the small sphere across a violated cone."""
    V, F = ix[IDX_V], ix[IDX_F]
    po = ix[IDX_PATCH_OFFSETS]
    nxt = -1
    worst = 0.0
    is_torus = p >= V + F
    for rec in range(ix[at(po + p)], ix[at(po + p + 1)]):
        viol = record_violation(f, ix, o_planes, rec, u0, u1, u2)
        if viol <= 0.0:
            continue
        q = ix[at(ix[IDX_RECORDS] + 2 * rec + 1)]
        if p < V:
            if viol > worst:
                worst, nxt = viol, q
        elif not is_torus:
            return q
        elif q >= V:  # a torus's plane towards a big sphere: take it at once
            return q
        elif nxt < 0:
            nxt = q
    return nxt


@kernel
def find_march(f, ix, o_planes, start, u0, u1, u2):
    """Guided march from patch ``start``; capped at the patch count, then the naive scan.

    Returns (patch, steps)."""
    P = ix[IDX_V] + ix[IDX_F] + ix[IDX_E]
    p = start if 0 <= start < P else 0
    for steps in range(P):
        q = march_step(f, ix, o_planes, p, u0, u1, u2)
        if q < 0:
            return p, steps
        p = q
    return find_naive(f, ix, o_planes, u0, u1, u2), P


@kernel
def find_hull(f, ix, o_planes, o_hull, start, u0, u1, u2):
    """The warm patch if it still holds u; else hill climb on the underlying convex hull to the
    farthest small sphere and march from it (paper III.C.3). Returns (patch, steps)."""
    P = ix[IDX_V] + ix[IDX_F] + ix[IDX_E]
    if 0 <= start < P and in_region(f, ix, o_planes, start, u0, u1, u2):
        return start, 0
    H = ix[IDX_H]
    if H == 0:  # no underlying hull (fewer than 4 or coplanar centres): march from the start
        p, steps = find_march(f, ix, o_planes, start, u0, u1, u2)
        return p, steps
    hull_f = f[o_hull:o_hull + 3 * H]
    hull_ix = ix[ix[IDX_HULL]:ix.shape[0]]
    h = polytope_support_index(hull_f, hull_ix, u0, u1, u2)
    p, steps = find_march(f, ix, o_planes, ix[at(ix[IDX_HULL_MAP] + h)], u0, u1, u2)
    return p, steps + 1


@kernel
def find_patch(f, ix, method, start, u0, u1, u2):
    """(patch, steps) owning unit direction u, by METHOD_NAIVE, METHOD_MARCH or METHOD_HULL."""
    o_faces, o_tori, o_planes, o_hull = _offsets(ix)
    if method == METHOD_NAIVE:
        p = find_naive(f, ix, o_planes, u0, u1, u2)
        return p, p + 1  # patches scanned
    if method == METHOD_MARCH:
        return find_march(f, ix, o_planes, start, u0, u1, u2)
    return find_hull(f, ix, o_planes, o_hull, start, u0, u1, u2)


@kernel(inline="always")
def find_patch_near(f, ix, start, u0, u1, u2):
    """The patch owning unit direction u, by a guided march from patch ``start`` where it is valid (and
    the STP-BV does not search by METHOD_NAIVE), else by the STP-BV's own search. For a start close
    to u: a Newton method's normals move little between its evaluations, so the last patch or one a
    step or two away owns the next, where find_hull would search the hull anew whenever the last patch
    no longer holds (CSE-STP 1.01x to 1.07x, bit-identical: docs/notes/speed-45.md, stop 125)."""
    if ix[IDX_METHOD] != METHOD_NAIVE and 0 <= start < ix[IDX_V] + ix[IDX_F] + ix[IDX_E]:
        p, _ = find_march(f, ix, _offsets(ix)[2], start, u0, u1, u2)
        return p
    p, _ = find_patch(f, ix, ix[IDX_METHOD], start, u0, u1, u2)
    return p


@kernel(inline="always")
def ball_of_patch(f, ix, p, d0, d1, d2):
    """(ball centre x, y, z, ball radius) whose support is patch p's along directions d in its region:
    a small or big sphere, or for a torus the big ball centred at the circle point opposite d."""
    V, F = ix[IDX_V], ix[IDX_F]
    o_faces, o_tori, o_planes, o_hull = _offsets(ix)
    if p < V:
        k = F_VERTICES + 3 * p
        return f[at(k)], f[at(k + 1)], f[at(k + 2)], f[F_R]
    if p < V + F:
        k = o_faces + 3 * (p - V)
        return f[at(k)], f[at(k + 1)], f[at(k + 2)], f[F_BIG_R]
    k = o_tori + 7 * (p - V - F)
    e0, e1, e2, a, w0, w1, w2, wn = torus_direction(f, k, d0, d1, d2)
    return f[at(k)] - a * w0, f[at(k + 1)] - a * w1, f[at(k + 2)] - a * w2, f[F_BIG_R]


@kernel(inline="always")
def torus_direction(f, k, d0, d1, d2):
    """(axis e, circle radius a, w, |d - (d.e) e|) of the torus stored at fdata offset k, w the unit
    part of direction d across the axis (left unnormalised when d lies along it)."""
    e0, e1, e2, a = f[at(k + 3)], f[at(k + 4)], f[at(k + 5)], f[at(k + 6)]
    de = d0 * e0 + d1 * e1 + d2 * e2
    w0, w1, w2 = d0 - de * e0, d1 - de * e1, d2 - de * e2
    wn = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if wn > 0.0:
        w0, w1, w2 = w0 / wn, w1 / wn, w2 / wn
    return e0, e1, e2, a, w0, w1, w2, wn


@kernel
def patch_support(f, ix, p, u0, u1, u2, out):
    """Support point of patch p along unit u into out[0:3]: its ball's, centre + radius u."""
    c0, c1, c2, rad = ball_of_patch(f, ix, p, u0, u1, u2)
    out[0] = c0 + rad * u0
    out[1] = c1 + rad * u1
    out[2] = c2 + rad * u2


@kernel
def stp_support(f, ix, method, d0, d1, d2, start, inset, out):
    """Support point of the STP-BV along direction d (any length) into out, less inset along the
    unit direction (inset = r: the support of its core, the ball hull at R - r); returns the patch."""
    n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if n == 0.0:
        d0, n = 1.0, 1.0
    u0, u1, u2 = d0 / n, d1 / n, d2 / n
    p, _ = find_patch(f, ix, method, start, u0, u1, u2)
    c0, c1, c2, rad = ball_of_patch(f, ix, p, u0, u1, u2)
    rad -= inset
    out[0] = c0 + rad * u0
    out[1] = c1 + rad * u1
    out[2] = c2 + rad * u2
    return p


@kernel(inline="always")
def hull_core(k, m, f, ix):
    """(kind, margin, fdata, idata) of the shape to search first: for an STP-BV its underlying
    convex hull grown by r (a polytope, which the STP-BV contains and hugs within O(L^2 / rho));
    any other shape unchanged."""
    if k == STP and ix[IDX_H] > 0:
        o_hull = _offsets(ix)[3]
        return POLYTOPE, f[F_R], f[o_hull:o_hull + 3 * ix[IDX_H]], ix[ix[IDX_HULL]:ix.shape[0]]
    return k, m, f[0:f.shape[0]], ix[0:ix.shape[0]]


@kernel(inline="always")  # into Newton on the normal's evaluation, its hot caller
def stp_support_curvature(f, ix, u0, u1, u2, start, out):
    """Support point along the unit direction u into out[0:3], and its derivative on the unit sphere
    in compact form: returns (patch, rad, s, t0, t1, t2), the derivative being
    rad (I - u u^T) - s t t^T (see stp_support_jacobian; s = 0 and t = 0 off the tori). The patch is
    the next call's ``start``.

    Across u (x, y orthogonal to u) the derivative's quadratic form is then rad x.y - s (t.x)(t.y):
    Newton on the normal needs only that, three dot products where the full matrix took two 3 x 3
    quadratic forms a side. The patch is found from ``start`` by find_patch_near."""
    p = find_patch_near(f, ix, start, u0, u1, u2)
    V, F = ix[IDX_V], ix[IDX_F]
    if p < V + F:
        c0, c1, c2, rad = ball_of_patch(f, ix, p, u0, u1, u2)
        out[0] = c0 + rad * u0
        out[1] = c1 + rad * u1
        out[2] = c2 + rad * u2
        return p, rad, 0.0, 0.0, 0.0, 0.0
    k = _offsets(ix)[1] + 7 * (p - V - F)
    e0, e1, e2, a, w0, w1, w2, wn = torus_direction(f, k, u0, u1, u2)
    rad = f[F_BIG_R]
    out[0] = f[at(k)] - a * w0 + rad * u0
    out[1] = f[at(k + 1)] - a * w1 + rad * u1
    out[2] = f[at(k + 2)] - a * w2 + rad * u2
    if not (wn > 0.0):
        return p, rad, 0.0, 0.0, 0.0, 0.0
    return p, rad, a / wn, e1 * w2 - e2 * w1, e2 * w0 - e0 * w2, e0 * w1 - e1 * w0


@kernel
def stp_support_jacobian(f, ix, u0, u1, u2, start, out, jac):
    """Support point along the unit direction u into out[0:3] and its derivative on the unit
    sphere into jac (3, 3) (jac[i, j] = d out_i / d u_j, zero along u); returns the patch (the next
    call's ``start``).

    A patch's support is its ball's, c + rad u: a sphere's centre is fixed, so the derivative is
    rad (I - u u^T); a torus's ball centre m - a w turns with w, the unit part of u across the
    torus axis e, which subtracts (a / |u - (u.e) e|) t t^T, t = e x w, along the circle. Both are
    positive semi-definite on the patch's region (the torus's radius of curvature along its circle
    is at least r there), and they jump where the patch changes. (stp_support_curvature's compact
    form, as a matrix.)"""
    p, rad, s, t0, t1, t2 = stp_support_curvature(f, ix, u0, u1, u2, start, out)
    u = (u0, u1, u2)
    tv = (t0, t1, t2)
    for i in range(3):
        for j in range(3):
            jac[i, j] = rad * ((1.0 if i == j else 0.0) - u[i] * u[j]) - s * tv[i] * tv[j]
    return p
