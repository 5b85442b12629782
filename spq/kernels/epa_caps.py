"""The EPA's bound from sphere caps: where D = A - B is locally a sphere, a coarse polytope suffices.

The EPA bounds the depth from below by the least offset of its polytope P's faces (P lies in D).
Between two round bodies, D is nearly a sphere around the origin and that bound closes only as the
faces shrink everywhere: two nearly concentric STP-BVs with R near its minimum took more than
16,000 expansions to reach 1e-10 (fuzz family stp-min-R, 'contained' poses).

But D's boundary is often exactly a sphere over a whole cap of normals. Where A's support along the
normals within angle alpha of u stays on one sphere of A (an STP-BV's small or big sphere, a point)
and B's along their opposites on one of B's, D's support is C + rho v there, with C the difference
of the two centres and rho the sum of the radii, so D holds the convex hull of that cap: the ball
segment Seg = B(C, rho) cut by the plane u.x >= u.C + rho cos alpha. Each vertex of P found along
such a u carries its Seg (support_sphere); then B(0, r) lies in P and the Segs, hence in D, when
every face F (unit normal n, offset d) with d < r has a vertex whose Seg holds the part of B(0, r)
beyond F's plane, Cap_F(r) = {|x| <= r, n.x > d}. Cap_F(r) lies in B(C, rho) when r <= rho - |C|,
and above Seg's plane when its lowest point along u, d cos g - sqrt(r^2 - d^2) sin g (g the angle
between n and u), is at least u.C + rho cos alpha. So the face's certified offset (certified_offset)
is the largest such r, at least d, and the depth is at least the least certified offset.

A run takes the caps once it is still open after epa.CAPS_AFTER expansions (they cost about a fifth
of a step; most runs close before, unchanged), and from then on expands the face of least
certified offset, so it refines P only where no cap certifies it:
along the edges of the regions, and around the deepest normal. There the exact support along
u* = -C / |C| (the deepest normal of the sphere, if its cap holds it) gives the depth's upper bound
rho - |C| and witness points that meet it exactly (exact_deepest).

Other kinds (polytopes, superellipsoids, an STP-BV's tori) carry no cap: their faces' certified
offset is their offset, as before.
"""

from __future__ import annotations

import math

from spq.kernels.epa_layout import EPA_BEST, EPA_CERTIFIED, EPA_SPHERES
from spq.kernels.gjk import EPA_ROW
from spq.kernels.indexing import at
from spq.kernels.jit import kernel
from spq.kernels.kinds import POINT, STP, STP_CORE
from spq.kernels.stp_support import F_R, IDX_F, IDX_PATCH_OFFSETS, IDX_RECORDS, IDX_V, ball_of_patch, plane_offset

NO_SPHERE = -1.0  # a vertex's radius when D's boundary is no fixed sphere around it
CAP_SLACK = 1e-7  # rad taken off a cap's half-angle: acos's rounding near 0 (about 1e-8)
ROUNDING = 1e-14  # relative slack on the certified offsets' arithmetic (a few dozen ulps)


@kernel
def sphere_around(kind, f, ix, feature, u0, u1, u2):
    """(centre x, y, z, radius, half-angle): the ball whose sphere is the body's boundary, in its local
    frame, for every unit normal within the half-angle of unit u, whose support was ``feature``; radius
    NO_SPHERE where there is none (a polytope's vertex, whose normal cone is not stored, a torus, a
    superellipsoid)."""
    if kind == POINT:
        return 0.0, 0.0, 0.0, 0.0, math.pi
    if (kind != STP and kind != STP_CORE) or feature < 0 or feature >= ix[IDX_V] + ix[IDX_F]:
        return 0.0, 0.0, 0.0, NO_SPHERE, 0.0
    c0, c1, c2, rad = ball_of_patch(f, ix, feature, u0, u1, u2)
    if kind == STP_CORE:
        rad -= f[F_R]  # the core's: a small sphere's is a point
    o_planes = plane_offset(ix)
    po = ix[IDX_PATCH_OFFSETS]
    alpha = math.pi
    for rec in range(ix[at(po + feature)], ix[at(po + feature + 1)]):
        k = o_planes + 4 * rec
        ax0, ax1, ax2 = f[at(k)], f[at(k + 1)], f[at(k + 2)]
        norm = math.sqrt(ax0 * ax0 + ax1 * ax1 + ax2 * ax2)
        if not norm > 0.0:
            return 0.0, 0.0, 0.0, NO_SPHERE, 0.0
        cu = min(1.0, max(-1.0, (u0 * ax0 + u1 * ax1 + u2 * ax2) / norm))
        cb = min(1.0, max(-1.0, f[at(k + 3)] / norm))
        # the region is where angle(v, axis) <= acos(cos) (side +1), or >= (side -1)
        room = math.acos(cb) - math.acos(cu)
        if ix[at(ix[IDX_RECORDS] + 2 * rec)] < 0:
            room = -room
        alpha = min(alpha, room)
    return c0, c1, c2, rad, alpha - CAP_SLACK


@kernel
def support_sphere(pair, d0, d1, d2, fa, fb, work, i):
    """Vertex i's cap: D's support along unit normals within alpha of d, whose support features were
    fa (A) and fb (B), is C + rho v. Stored as rows (C, rho) and (u, cos alpha), A's frame."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    row = EPA_ROW + EPA_SPHERES + 2 * i
    work[row, 3] = NO_SPHERE
    n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if not n > 0.0:
        return
    u0, u1, u2 = d0 / n, d1 / n, d2 / n
    a0, a1, a2, ra, alpha_a = sphere_around(kA, fA, iA, fa, u0, u1, u2)
    if ra < 0.0 or not alpha_a > 0.0:
        return
    e0 = -(R[0, 0] * u0 + R[1, 0] * u1 + R[2, 0] * u2)  # -u in B's frame
    e1 = -(R[0, 1] * u0 + R[1, 1] * u1 + R[2, 1] * u2)
    e2 = -(R[0, 2] * u0 + R[1, 2] * u1 + R[2, 2] * u2)
    b0, b1, b2, rb, alpha_b = sphere_around(kB, fB, iB, fb, e0, e1, e2)
    if rb < 0.0 or not alpha_b > 0.0:
        return
    work[row, 0] = a0 - (R[0, 0] * b0 + R[0, 1] * b1 + R[0, 2] * b2 + t[0])
    work[row, 1] = a1 - (R[1, 0] * b0 + R[1, 1] * b1 + R[1, 2] * b2 + t[1])
    work[row, 2] = a2 - (R[2, 0] * b0 + R[2, 1] * b1 + R[2, 2] * b2 + t[2])
    work[row, 3] = ra + rb
    work[row + 1, 0], work[row + 1, 1], work[row + 1, 2] = u0, u1, u2
    work[row + 1, 3] = math.cos(min(alpha_a, alpha_b))


@kernel(inline="always")
def can_cap(kind):
    """Whether a body of this kind can carry a cap: an STP-BV or its core (their spheres) or a point (a
    sphere)."""
    return kind == STP or kind == STP_CORE or kind == POINT


@kernel(inline="always")
def clear_sphere(work, i):
    work[EPA_ROW + EPA_SPHERES + 2 * i, 3] = NO_SPHERE


@kernel
def certified_offset(work, a, b, c, n0, n1, n2, d):
    """The largest r >= d such that the part of B(0, r) beyond the plane (n, d) of the face with
    corners a, b, c lies in one corner's cap segment (module docstring); d if none holds it."""
    best = d
    if not d > 0.0:
        return d
    for corner in (a, b, c):
        row = EPA_ROW + EPA_SPHERES + 2 * corner
        rho = work[row, 3]
        if rho <= 0.0:
            continue
        C0, C1, C2 = work[row, 0], work[row, 1], work[row, 2]
        u0, u1, u2 = work[row + 1, 0], work[row + 1, 1], work[row + 1, 2]
        cos_alpha = work[row + 1, 3]
        cnorm = math.sqrt(C0 * C0 + C1 * C1 + C2 * C2)
        ball = (rho - cnorm) - ROUNDING * (rho + cnorm)  # B(0, r) within B(C, rho)
        if not ball > best:
            continue
        cg = n0 * u0 + n1 * u1 + n2 * u2
        if not cg > 0.0:
            continue
        uc = u0 * C0 + u1 * C1 + u2 * C2
        beta = uc + rho * cos_alpha
        margin = d * cg - beta - ROUNDING * (d + abs(uc) + rho)
        if not margin >= 0.0:
            continue
        x0, x1, x2 = n1 * u2 - n2 * u1, n2 * u0 - n0 * u2, n0 * u1 - n1 * u0
        sg2 = x0 * x0 + x1 * x1 + x2 * x2  # sin^2 g, accurate for small angles, unlike 1 - cg^2
        if sg2 <= 0.0:
            r = ball
        else:
            r = min(ball, math.sqrt(d * d + margin * margin / sg2) * (1.0 - ROUNDING))
        best = max(best, r)
    return best


@kernel(inline="always")
def set_certified(work, face, value):
    """A live face's certified offset, and its key for the least-face scan (epa._least_face)."""
    work[at(EPA_ROW + EPA_CERTIFIED + face), 0] = value
    work[at(EPA_ROW + EPA_CERTIFIED + face), 1] = value


@kernel(inline="always")
def certified(work, face):
    return work[at(EPA_ROW + EPA_CERTIFIED + face), 0]


@kernel(inline="always")
def deepest_normal(work, i):
    """(ok, u*, the depth rho - |C| there) of vertex i's sphere, ok if its cap holds u* = -C / |C|."""
    row = EPA_ROW + EPA_SPHERES + 2 * i
    rho = work[row, 3]
    C0, C1, C2 = work[row, 0], work[row, 1], work[row, 2]
    cnorm = math.sqrt(C0 * C0 + C1 * C1 + C2 * C2)
    if rho <= 0.0 or not cnorm > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0
    v0, v1, v2 = -C0 / cnorm, -C1 / cnorm, -C2 / cnorm
    inside = v0 * work[row + 1, 0] + v1 * work[row + 1, 1] + v2 * work[row + 1, 2] >= work[row + 1, 3]
    return inside, v0, v1, v2, rho - cnorm


@kernel(inline="always")
def keep_best(work, pa, pb, n0, n1, n2, core):
    """The support points pa, pb along unit n as the witness (see exact_deepest). core: 0 where both are
    exact (two spheres' caps about their deepest normal), else the side (1 A, 2 B) whose point is, the
    other's then found from it (epa._best_witness)."""
    for c in range(3):
        work[EPA_ROW + EPA_BEST, c] = pa[c]
        work[EPA_ROW + EPA_BEST + 1, c] = pb[c]
    work[EPA_ROW + EPA_BEST + 2, 0], work[EPA_ROW + EPA_BEST + 2, 1], work[EPA_ROW + EPA_BEST + 2, 2] = n0, n1, n2
    work[EPA_ROW + EPA_BEST, 3] = 1.0
    work[EPA_ROW + EPA_BEST + 1, 3] = core


@kernel(inline="always")
def has_best(work):
    return work[EPA_ROW + EPA_BEST, 3] == 1.0


@kernel(inline="always")
def clear_best(work):
    work[EPA_ROW + EPA_BEST, 3] = 0.0
