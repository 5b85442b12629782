"""The EPA's bound from curved sets: where an STP-BV's core meets a polytope, a coarse polytope
suffices.

The EPA bounds the depth from below by the least offset of its polytope P's faces (P lies in D =
A - B). Between an STP-BV's core and a polytope, D's boundary near the deepest point is curved at
radius rho = R - r (a torus of the core swept along an edge of the polytope, or a big sphere moved
by a vertex), and P's faces must shrink to chords of about 4e-5 m before their offsets come within
1e-10 of the depth: on kuka_link_4's overlapping poses, 17 expansions after the hulls' 15.

Curved sets inside D close the bound instead:

- The core is the ball hull of the STP-BV's points at radius rho (the intersection of the balls of
  that radius that hold them), so it holds the spindle of any two of its points, and with it every
  arc of radius rho between them and that arc's circular segment S (between arc and chord). The
  torus of edge (p1, p2) is that spindle's boundary: its arc in the plane of the torus axis e and a
  direction w across it has centre m - a w (m the edge's midpoint, a the torus circle's radius). So D
  holds K = S - [y1, y2] for any two points y1, y2 of the polytope: the circular segment swept along
  E = y2 - y1, an oblique cylinder cut by the chord's plane and by the planes of the sweep's ends.
  Across E its section is an ellipse with semi-axes rho (along k, the arc plane's direction across E)
  and rho |cos phi| (phi the angle between E and the arc plane's normal). The ellipse holds its circle
  of curvature at the end of its major axis (radius rho cos^2 phi, its least radius of curvature:
  Blaschke's rolling theorem), so K holds the right circular cylinder of that radius along E through
  (m - a w) + rho sin^2 phi k, cut by the same three planes (cylinder_reach). Where the arc is taken in
  the plane of D's deepest normal, that cylinder touches D's boundary along the line of that normal.
- A big sphere's support along every normal within alpha of u is its centre c plus rho times the
  normal (alpha: the room to its region's planes), so the core holds that cap's hull, the ball
  segment of B(c, rho) beyond the plane u.x = u.c + rho cos alpha, and D holds it moved by -y for any
  point y of the other body (a polytope, or the other core). It is taken about the ball's own deepest
  normal, and it certifies a face by its support, not by holding a cap (ball_segment_reach, below).
  (epa_caps does the same between two spheres, once a run is long; here the other side's point needs
  no region of its own.)
- Between two cores, a torus of each: each spindle holds its meridian arcs, so D holds the difference
  of A's arc and B's in the planes of their axes and a normal s, s found by Newton's steps toward that
  set's deepest normal (torus_pair_set). A big sphere takes an arc's place as its cap of normals about s
  (or -s), which loses nothing across s. On the tangent plane at s, each arc's support grows as a convex,
  Huber-like term along its tangent, and a cap's along every direction, so D's support is bounded below
  out to a face's cone step by step (tight_pair_lift). On kuka_link_4's 2,036 overlapping STP-STP poses
  (two fifths of them end between two curved patches) the iterations fall from 36.1 without it to 23.0
  (docs/notes/speed-45.md, stops 95 to 98). At such a corner the sphere's segment less the other's point
  is not tried.

A face F (unit normal n, offset d) is certified to offset r when D's support is at least r along
every normal of its cone (the EPA's bound is then the least certified offset). The cylinder does it
by holding the part of B(0, r) beyond F's plane, Cap_F(r) = {|z| <= r, n.z >= d}: B(0, r) within the
cylinder, and Cap_F(r) on the inner side of each cutting plane (its least value along the plane's
normal, on its rim unless the ball's own least point lies in it: halfspace_reach). The ball segment
does it by its support along the normals that the ray through F leaves below r (ball_segment_reach),
which reaches faces about a thousand times farther below the depth at R = 2 m. Points are taken as
z = s - y, s on the core's side, so a core as B is the mirror image (z = -x).

The EPA (epa_run) certifies a face this way only when it is about to expand it as the least face,
within CERT_WINDOW of the depth's upper bound, once per face (face_certificate): first from the
deepest set found so far, then from the patches its corners came from (the run's own supports, not
the hulls'): a big sphere less the corner's own point of the other side, or a torus swept between
two distinct polytope points among the corners (its arc taken about the face's normal). The support
along a new deepest set's deepest normal is taken at once: it bounds the depth from above, at the
set's own depth where the set is D's deepest part, and gives the witness points (the core's support
point, unique as the core is strictly convex, and the other side's along the normal:
epa._best_witness). A lift is taken only where it reaches the depth's upper bound less the tolerance.
On kuka_link_4's overlapping STP-PCH poses (random_poses seed 0, 20,000 pairs) this takes the EPA's
iterations from 30.5 to 22.0 and a batched query from 9.88 to 8.90 us (same-process A/B, stop 64).
"""

from __future__ import annotations

import math

from spq.kernels.epa_caps import CAP_SLACK
from spq.kernels.epa_layout import EPA_CERTIFIED, EPA_CORNERS, EPA_FEATURES, EPA_PA, EPA_PB, EPA_SET, EPA_TORI
from spq.kernels.gjk import EPA_IOFF, EPA_ROW
from spq.kernels.indexing import at
from spq.kernels.jit import kernel
from spq.kernels.kinds import POLYTOPE, STP_CORE
from spq.kernels.stp_support import F_BIG_R, F_R, F_VERTICES, IDX_F, IDX_PATCH_OFFSETS, IDX_RECORDS, IDX_V, plane_offset

STP_IS_A, STP_IS_B = 1, -1  # which side is the STP-BV's core (z = x, or z = -x)
MIN_COS = 1e-3  # least |cos phi|: below, the cylinder (radius rho cos^2 phi) is too thin to certify
SLACK = 1e-13  # relative: the sets' radii are taken this much (of the scale) smaller, for rounding


@kernel(inline="always")
def certifying_sides(kA, kB):
    """1 where A is an STP-BV's core and B a polytope, 2 the other way round, 3 for two cores (each
    side's big spheres against the other's points, and a torus of each; the cylinders need a
    polytope), else 0 (no curved sets).

    Between two cores the ball segments that held a cap of B(0, r) cut kuka_link_4's overlaps'
    iterations 43.6 -> 38.5 but cost more than that saved (11.96 -> 12.69 us a pose); by their support
    (ball_segment_reach) they reach much farther (docs/notes/speed-45.md, stop 94)."""
    if kA == STP_CORE and kB == POLYTOPE:
        return 1
    if kB == STP_CORE and kA == POLYTOPE:
        return 2
    if kA == STP_CORE and kB == STP_CORE:
        return 3
    return 0


@kernel(inline="always")
def tried(work, face):
    return work[at(EPA_ROW + EPA_CERTIFIED + face), 2] != 0.0


@kernel(inline="always")
def set_tried(work, face, value):
    work[at(EPA_ROW + EPA_CERTIFIED + face), 2] = 1.0 if value else 0.0


@kernel(inline="always")
def halfspace_reach(n0, n1, n2, d, l0, l1, l2, beta):
    """The largest r such that Cap(r) = {|z| <= r, n.z >= d} (unit n, d > 0) lies in {l.z >= beta}
    (l of any length): inf if every r does, below d if none does."""
    ln = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
    if not ln > 0.0:
        return math.inf if beta <= 0.0 else -math.inf
    l0, l1, l2, beta = l0 / ln, l1 / ln, l2 / ln, beta / ln
    c = n0 * l0 + n1 * l1 + n2 * l2
    margin = d * c - beta  # at r = d the cap is the point d n
    if margin < 0.0:
        return -math.inf
    x0, x1, x2 = n1 * l2 - n2 * l1, n2 * l0 - n0 * l2, n0 * l1 - n1 * l0
    s2 = x0 * x0 + x1 * x1 + x2 * x2  # sin^2 of the angle between n and l
    if not s2 > 0.0:
        return math.inf if c > 0.0 else -beta
    # the least value on the rim {|z| = r, n.z = d} is d c - sqrt(r^2 - d^2) sin
    r = math.sqrt(d * d + margin * margin / s2)
    if c < 0.0:
        r = min(r, d / -c)  # beyond, the ball's own least point -r l lies in the cap
    return r


@kernel
def _torus(f, ix, p, side, R, t):
    """(m, e, a) of torus patch p of the core, in A's frame (side STP_IS_B: rotated and moved by
    (R, t)); a < 0 if p is no torus."""
    V, F = ix[IDX_V], ix[IDX_F]
    if p < V + F:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0
    k = F_VERTICES + 3 * (V + F) + 7 * (p - V - F)
    m0, m1, m2 = f[at(k)], f[at(k + 1)], f[at(k + 2)]
    e0, e1, e2, a = f[at(k + 3)], f[at(k + 4)], f[at(k + 5)], f[at(k + 6)]
    if side == STP_IS_B:
        m0, m1, m2 = (R[0, 0] * m0 + R[0, 1] * m1 + R[0, 2] * m2 + t[0],
                      R[1, 0] * m0 + R[1, 1] * m1 + R[1, 2] * m2 + t[1],
                      R[2, 0] * m0 + R[2, 1] * m1 + R[2, 2] * m2 + t[2])
        e0, e1, e2 = (R[0, 0] * e0 + R[0, 1] * e1 + R[0, 2] * e2,
                      R[1, 0] * e0 + R[1, 1] * e1 + R[1, 2] * e2,
                      R[2, 0] * e0 + R[2, 1] * e1 + R[2, 2] * e2)
    return m0, m1, m2, e0, e1, e2, a


@kernel
def cylinder_reach(m, e, a, rho, y1, y2, az, n0, n1, n2, d, floor):
    """(r, u0, u1, u2, depth): the largest r with Cap(r) = {|z| <= r, n.z >= d} inside the cylinder
    Z of the module docstring, for the torus (centre m, unit axis e, circle radius a, ball radius
    rho) and the sweep from y1 to y2 (all in z's frame), n the face's unit normal in z; u the
    cylinder's deepest normal (unit) and depth its radius less the axis's distance from the origin.
    r = -inf where Z is degenerate, and where its radius bound is at most ``floor`` (the planes are
    then not tried)."""
    m0, m1, m2 = m
    e0, e1, e2 = e
    fail = (-math.inf, 0.0, 0.0, 0.0, -math.inf)
    # the arc's plane holds e and w, az's unit part across e: the torus's ball along az
    ne = az[0] * e0 + az[1] * e1 + az[2] * e2
    w0, w1, w2 = az[0] - ne * e0, az[1] - ne * e1, az[2] - ne * e2
    wn = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if not (wn > 1e-6 and rho > a):
        return fail
    w0, w1, w2 = w0 / wn, w1 / wn, w2 / wn
    v0, v1, v2 = e1 * w2 - e2 * w1, e2 * w0 - e0 * w2, e0 * w1 - e1 * w0  # nu, the arc plane's normal
    E0, E1, E2 = y2[0] - y1[0], y2[1] - y1[1], y2[2] - y1[2]
    En = math.sqrt(E0 * E0 + E1 * E1 + E2 * E2)
    scale = rho + abs(m0) + abs(m1) + abs(m2) + abs(y1[0]) + abs(y1[1]) + abs(y1[2]) + En
    if not En > 1e-9 * scale:
        return fail
    q = v0 * E0 + v1 * E1 + v2 * E2  # nu.E
    cphi = q / En
    if not abs(cphi) >= MIN_COS:
        return fail
    # circle centre less y1: the oblique cylinder's axis point
    c0, c1, c2 = m0 - a * w0 - y1[0], m1 - a * w1 - y1[1], m2 - a * w2 - y1[2]
    k0, k1, k2 = v1 * E2 - v2 * E1, v2 * E0 - v0 * E2, v0 * E1 - v1 * E0  # nu x E, across E in the plane
    kn = math.sqrt(k0 * k0 + k1 * k1 + k2 * k2)
    s2 = 1.0 - cphi * cphi
    if kn > 0.0:
        k0, k1, k2 = k0 / kn, k1 / kn, k2 / kn
        if k0 * n0 + k1 * n1 + k2 * n2 < 0.0:
            k0, k1, k2 = -k0, -k1, -k2
        c0, c1, c2 = c0 + rho * s2 * k0, c1 + rho * s2 * k1, c2 + rho * s2 * k2
    radius = rho * cphi * cphi - SLACK * scale
    # the origin's offset from the axis
    ce = (c0 * E0 + c1 * E1 + c2 * E2) / (En * En)
    o0, o1, o2 = ce * E0 - c0, ce * E1 - c1, ce * E2 - c2
    dist = math.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
    if not dist > 0.0:
        return fail
    depth = radius - dist
    if not depth > floor:
        return fail
    r = depth
    # the chord's plane: the point of the arc's plane reached along E lies on w's side of m
    we = (w0 * E0 + w1 * E1 + w2 * E2) / q
    vy = v0 * (m0 - y1[0]) + v1 * (m1 - y1[1]) + v2 * (m2 - y1[2])  # nu.(centre - y1) = nu.(m - y1)
    beta0 = w0 * (y1[0] - m0) + w1 * (y1[1] - m1) + w2 * (y1[2] - m2) + we * vy
    r = min(r, halfspace_reach(n0, n1, n2, d, w0 - we * v0, w1 - we * v1, w2 - we * v2,
                               -beta0 + SLACK * scale))
    # the sweep's ends: t = (nu.(centre - y1) - nu.z) / q within [0, 1]
    r = min(r, halfspace_reach(n0, n1, n2, d, -v0 / q, -v1 / q, -v2 / q, -vy / q + SLACK * scale / abs(q)))
    r = min(r, halfspace_reach(n0, n1, n2, d, v0 / q, v1 / q, v2 / q, vy / q - 1.0 + SLACK * scale / abs(q)))
    return r, o0 / dist, o1 / dist, o2 / dist, depth


@kernel
def big_sphere_cap(f, ix, p, u0, u1, u2):
    """(centre x, y, z, cos alpha) of big sphere p of the core (local frame): its support along every
    unit normal within alpha of unit u is centre + (R - r) v. cos alpha = 2 where u is not in its
    region. As epa_caps.sphere_around, with the cosine of the least room to a record's plane taken
    without acos: cos(acos cb - acos cu) = cb cu + sqrt((1 - cb^2)(1 - cu^2))."""
    V = ix[IDX_V]
    k = F_VERTICES + 3 * V + 3 * (p - V)
    c0, c1, c2 = f[at(k)], f[at(k + 1)], f[at(k + 2)]
    o_planes = plane_offset(ix)
    po = ix[IDX_PATCH_OFFSETS]
    cos_alpha = -1.0
    for rec in range(ix[at(po + p)], ix[at(po + p + 1)]):
        k = o_planes + 4 * rec
        ax0, ax1, ax2 = f[at(k)], f[at(k + 1)], f[at(k + 2)]
        norm = math.sqrt(ax0 * ax0 + ax1 * ax1 + ax2 * ax2)
        if not norm > 0.0:
            return c0, c1, c2, 2.0
        cu = min(1.0, max(-1.0, (u0 * ax0 + u1 * ax1 + u2 * ax2) / norm))
        cb = min(1.0, max(-1.0, f[at(k + 3)] / norm))
        # the region is where angle(v, axis) <= acos(cb) (side +1), or >= (side -1)
        if not (cu > cb if ix[at(ix[IDX_RECORDS] + 2 * rec)] > 0 else cu < cb):
            return c0, c1, c2, 2.0
        cos_alpha = max(cos_alpha, cb * cu + math.sqrt((1.0 - cb * cb) * (1.0 - cu * cu)))
    # alpha less CAP_SLACK, and the cosine's own rounding
    return c0, c1, c2, min(1.0, cos_alpha + CAP_SLACK * math.sqrt(max(0.0, 1.0 - cos_alpha * cos_alpha)) + 1e-15)


SUPPORT_SLACK = 1e-12  # relative: taken off a support test's lift, for the rounding of its angles
NEWTON_STEPS = 2  # torus_pair_set's steps toward two tori's deepest normal from a face's


@kernel(inline="always")
def _support_lift(C, rho, n0, n1, n2, d, floor):
    """The geometric part of ball_segment_reach, before the cap's width is known: (r, |C|, s, cos Phi,
    sin Phi, depth), r = -inf where the test cannot lift the face above ``floor`` whatever the cap."""
    C0, C1, C2 = C
    cn = math.sqrt(C0 * C0 + C1 * C1 + C2 * C2)
    scale = rho + abs(C0) + abs(C1) + abs(C2)
    depth = rho - cn - SLACK * scale
    r = depth - SUPPORT_SLACK * scale
    if not (cn > 0.0 and d > 0.0 and r > d and r > floor):
        return -math.inf, cn, 0.0, 0.0, 0.0, 0.0, 0.0, depth
    s0, s1, s2 = -C0 / cn, -C1 / cn, -C2 / cn
    cg = d / r
    sg = math.sqrt((r - d) * (r + d)) / r  # (no cancellation as in 1 - cg^2)
    cp = n0 * s0 + n1 * s1 + n2 * s2
    x0, x1, x2 = n1 * s2 - n2 * s1, n2 * s0 - n0 * s2, n0 * s1 - n1 * s0
    sp = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    cphi = cp * cg - sp * sg  # Phi = psi + gamma
    sphi = sp * cg + cp * sg
    # beta(Phi) is at most rho - |C| cos Phi (a cap as wide as Phi): no need to find the cap otherwise
    if not (cp > 0.0 and cphi > 0.0 and rho - cn * cphi >= r):
        return -math.inf, cn, s0, s1, s2, 0.0, 0.0, depth
    return r, cn, s0, s1, s2, cphi, sphi, depth


@kernel(inline="always")
def _beta_holds(rho, cn, cphi, sphi, cos_alpha, r):
    """Whether beta(Phi) = rho cos(max(0, Phi - alpha)) - |C| cos Phi >= r (ball_segment_reach)."""
    if not cos_alpha < 1.0:
        return False
    if cphi >= cos_alpha:  # Phi <= alpha: the cap's own normals
        return rho - cn * cphi >= r
    sa = math.sqrt(max(0.0, (1.0 - cos_alpha) * (1.0 + cos_alpha)))
    return rho * (cphi * cos_alpha + sphi * sa) - cn * cphi >= r


@kernel
def ball_segment_reach(C, rho, cos_alpha, n0, n1, n2, d, floor):
    """(r, s0, s1, s2, depth): r the ball's depth rho - |C| (less slack) if the face (unit normal n,
    offset d) is certified to it by the ball segment about the ball's own deepest normal s = -C / |C|
    (the hull of B(C, rho)'s cap of normals within alpha of s), else -inf where r would not exceed
    ``floor``, or the segment does not reach.

    For a normal v of the face's cone, D's support is at least d / (n.v) (the ray through the
    face), which is r or more where angle(v, n) >= gamma = acos(d / r); the other normals lie within
    Phi = angle(n, s) + gamma of s, and there the segment's support is exactly
    beta(phi) = rho cos(max(0, phi - alpha)) - |C| cos(phi) at phi = angle(v, s), at least
    min(beta(0), beta(Phi)): beta rises on [0, alpha] and is one sinusoid on [alpha, pi / 2], whose
    least value on an interval lies at an end. So the face holds r where Phi <= pi / 2 and
    beta(Phi) >= r. At a depth d, a segment of rim radius l holds the normals within about 2 l / d
    of s: far wider than the segment's own cap of normals (about 1e-3 rad at R = 2 m), where the
    ball beyond the face would have to lie inside the segment, which is about 1e-6 m thick."""
    r, cn, s0, s1, s2, cphi, sphi, depth = _support_lift(C, rho, n0, n1, n2, d, floor)
    if r == -math.inf or not _beta_holds(rho, cn, cphi, sphi, cos_alpha, r):
        return -math.inf, 0.0, 0.0, 0.0, -math.inf
    return r, s0, s1, s2, depth


@kernel(inline="always")
def _arc_about(m0, m1, m2, e0, e1, e2, a, rho, u0, u1, u2):
    """The meridian arc of a core's torus (centre m, unit axis e, circle radius a, ball radius rho)
    whose plane holds the unit normal u: (its centre c = m - a w, b = its half-angle t0 less u's
    angle from the arc's middle, and e x u with its length), or b = -inf where u lies along e or the
    torus is degenerate. The arc's unit normals are cos(tau) w + sin(tau) e, |tau| <= t0 (cos t0 = a /
    rho), so u is one of them where b >= 0."""
    ue = u0 * e0 + u1 * e1 + u2 * e2
    w0, w1, w2 = u0 - ue * e0, u1 - ue * e1, u2 - ue * e2
    wn = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if not (wn > 1e-9 and 0.0 <= a < rho):
        return 0.0, 0.0, 0.0, -math.inf, 0.0, 0.0, 0.0
    w0, w1, w2 = w0 / wn, w1 / wn, w2 / wn
    b = math.acos(a / rho) - math.atan2(abs(ue), wn)
    # e x u = e x (wn w): the plane's normal, of length wn
    return m0 - a * w0, m1 - a * w1, m2 - a * w2, b, e1 * w2 - e2 * w1, e2 * w0 - e0 * w2, e0 * w1 - e1 * w0


@kernel(inline="always")
def _side_about(m0, m1, m2, e0, e1, e2, a, rho, u0, u1, u2):
    """A core's curved patch about the unit normal u, as _arc_about: a torus's meridian arc, or, where a < 0,
    the whole ball of radius rho about m (its centre, b = inf: no end, and no plane)."""
    if a < 0.0:
        return m0, m1, m2, math.inf, 0.0, 0.0, 0.0
    return _arc_about(m0, m1, m2, e0, e1, e2, a, rho, u0, u1, u2)


@kernel
def torus_pair_set(mA, eA, aA, rhoA, mB, eB, aB, rhoB, n0, n1, n2, steps):
    """The set two cores' curved patches give D about its deepest normal, A's patch (a torus: centre m, unit
    axis e, circle radius a, ball radius rho; or, where a < 0, the ball of radius rho about m) less B's (in A's
    frame), from a unit normal n near it (``steps`` Newton steps; with none, about n itself): (k, depth, slack),
    k = (s0, s1, s2, A0, B0, bA, bB, c2, cos bA, sin bA, cos bB, sin bB) the terms tight_pair_lift bounds the
    set's support by, depth its support along s less rounding slack, or -inf where the arcs or Newton's steps
    fail. A ball's b is inf (cos 1, sin 0): a big sphere's cap narrows it (with_room).

    Each torus's spindle holds its meridian arcs, so D holds K = (c_A + rho_A G_A) - (c_B + rho_B G_B),
    G_A the great-circle arc of A's unit normals in the plane of e_A and the unit s, G_B B's in the plane
    of e_B and -s (_arc_about), or the whole sphere of normals for a ball. K's support along s is A0 +
    rho_A cos(zeta_A) + rho_B cos(zeta_B), C = c_A - c_B, A0 = C.s, zeta_X = max(0, -b_X) the angle of s
    past an arc's end (b_X: the room from s to it); B0 = |C - A0 s| is K's gradient across s, and c2 =
    (nu_A.nu_B)^2 with the arcs' planes' unit normals nu_X across s.

    s is K's deepest normal, found by Newton's steps from n on the sphere (NEWTON_STEPS in the EPA; the
    tangential part of C is K's gradient there, rho_A T_A + rho_B T_B - h its Hessian, T_X = t_X t_X^T
    for an arc with tangent t_X at s, the identity for a ball): about n itself, B0 sin phi would cost
    about rho times the square of n's error, far more than the tolerance. Two balls' deepest normal is
    -C / |C|."""
    fail = ((0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0), -math.inf, 0.0)
    arcA, arcB = aA >= 0.0, aB >= 0.0
    s0, s1, s2 = n0, n1, n2
    for k in range(steps + 1):
        cA0, cA1, cA2, bA, xA0, xA1, xA2 = _side_about(mA[0], mA[1], mA[2], eA[0], eA[1], eA[2], aA, rhoA, s0, s1, s2)
        cB0, cB1, cB2, bB, xB0, xB1, xB2 = _side_about(mB[0], mB[1], mB[2], eB[0], eB[1], eB[2], aB, rhoB,
                                                       -s0, -s1, -s2)
        if not (bA > -0.5 and bB > -0.5):  # (-inf: no arc; far past an end: no use, and zeta < pi / 2)
            return fail
        C0, C1, C2 = cA0 - cB0, cA1 - cB1, cA2 - cB2
        if not (arcA or arcB):  # two balls: the centres' line, at once
            cn = math.sqrt(C0 * C0 + C1 * C1 + C2 * C2)
            if not cn > 0.0:
                return fail
            s0, s1, s2 = -C0 / cn, -C1 / cn, -C2 / cn
        A0 = C0 * s0 + C1 * s1 + C2 * s2
        p0, p1, p2 = C0 - A0 * s0, C1 - A0 * s1, C2 - A0 * s2
        if arcA:
            xa = math.sqrt(xA0 * xA0 + xA1 * xA1 + xA2 * xA2)
            xA0, xA1, xA2 = xA0 / xa, xA1 / xa, xA2 / xa
        if arcB:
            xb = math.sqrt(xB0 * xB0 + xB1 * xB1 + xB2 * xB2)
            xB0, xB1, xB2 = xB0 / xb, xB1 / xb, xB2 / xb
        if k == steps or not (arcA or arcB):
            break
        # tangent basis (t, nu) at s from the first arc (t = nu x s), and the other side's part of the Hessian
        h = A0 + rhoA + rhoB
        if arcA:
            v0, v1, v2, r1, r2, other = xA0, xA1, xA2, rhoA, rhoB, arcB
        else:
            v0, v1, v2, r1, r2, other = xB0, xB1, xB2, rhoB, rhoA, False
        t0, t1, t2 = v1 * s2 - v2 * s1, v2 * s0 - v0 * s2, v0 * s1 - v1 * s0
        if other:
            u0, u1, u2 = xB1 * s2 - xB2 * s1, xB2 * s0 - xB0 * s2, xB0 * s1 - xB1 * s0
            ga = u0 * t0 + u1 * t1 + u2 * t2
            gb = u0 * v0 + u1 * v1 + u2 * v2
            M11, M12, M22 = r1 + r2 * ga * ga - h, r2 * ga * gb, r2 * gb * gb - h
        else:
            M11, M12, M22 = r1 + r2 - h, 0.0, r2 - h
        det = M11 * M22 - M12 * M12
        if not (det > 0.0 and M11 > 0.0):
            return fail
        c1 = p0 * t0 + p1 * t1 + p2 * t2
        c2 = p0 * v0 + p1 * v1 + p2 * v2
        y1 = -(M22 * c1 - M12 * c2) / det
        y2 = -(M11 * c2 - M12 * c1) / det
        s0, s1, s2 = s0 + y1 * t0 + y2 * v0, s1 + y1 * t1 + y2 * v1, s2 + y1 * t2 + y2 * v2
        sn = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        s0, s1, s2 = s0 / sn, s1 / sn, s2 / sn
    B0 = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    c2 = 0.0
    if arcA and arcB:  # (rounded up: the arcs' least gain falls as c2 rises)
        ca = abs(xA0 * xB0 + xA1 * xB1 + xA2 * xB2)
        c2 = min(1.0, ca * ca + 1e-15)
    scale = rhoA + rhoB + abs(C0) + abs(C1) + abs(C2)
    depth = A0 + rhoA * math.cos(max(0.0, -bA)) + rhoB * math.cos(max(0.0, -bB)) - SLACK * scale
    k = (s0, s1, s2, A0, B0, bA, bB, c2, math.cos(bA) if arcA else 1.0, math.sin(bA) if arcA else 0.0,
         math.cos(bB) if arcB else 1.0, math.sin(bB) if arcB else 0.0)
    return k, depth, SUPPORT_SLACK * scale


@kernel(inline="always")
def with_room(k, bA, bB):
    """torus_pair_set's terms k with the sides' ends b narrowed to bA, bB (>= 0; inf leaves a side as it
    is): a ball's to the cap of normals its big sphere holds about s (A's) or -s (B's)."""
    s0, s1, s2, A0, B0, kA, kB, c2, cA, sA, cB, sB = k
    if bA < kA:
        kA, cA, sA = bA, math.cos(bA), math.sin(bA)
    if bB < kB:
        kB, cB, sB = bB, math.cos(bB), math.sin(bB)
    return s0, s1, s2, A0, B0, kA, kB, c2, cA, sA, cB, sB


@kernel(inline="always")
def _far_angle(s0, s1, s2, n0, n1, n2, d, depth):
    """(cos Phi, sin Phi), Phi = angle(n, s) + acos(d / depth): the farthest a face's cone (unit normal n,
    offset 0 < d < depth) reaches from the unit s, past which the ray through the face gives depth or more;
    cos Phi = -2 where n faces away from s."""
    cp = n0 * s0 + n1 * s1 + n2 * s2
    if not cp > 0.0:
        return -2.0, 0.0
    q0, q1, q2 = n1 * s2 - n2 * s1, n2 * s0 - n0 * s2, n0 * s1 - n1 * s0
    sp = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
    cg = d / depth
    sg = math.sqrt((depth - d) * (depth + d)) / depth
    return cp * cg - sp * sg, sp * cg + cp * sg


TIGHT_STEPS = 40  # tight_pair_lift's most steps in tan(phi) beyond the arcs' quadratic part (more: refused)


@kernel(inline="always")
def _arc_gain(x, b, cb, sb):
    """H(x) = sigma(1, x) - 1 for x >= 0: the support of the unit normals within b of s (an arc or a cap, b >= 0)
    along s + x a (a unit, across s), less 1: sqrt(1 + x^2) - 1 while atan(x) <= b, then the end's cos b + x sin b
    - 1. H(sqrt(u)) is concave in u (two concave pieces, their slopes cos(b) / 2 alike where they meet)."""
    if b >= 0.5 * math.pi or x * cb <= sb:
        return x * x / (math.sqrt(1.0 + x * x) + 1.0)
    return x * sb - (1.0 - cb)


@kernel(inline="always")
def _least_gain(aA, aB, arcA, arcB, c2):
    """The least of aA (y.t_A)^2 + aB (y.t_B)^2 over unit y across s, an arc's term along its tangent t_X and a
    ball's aX |y|^2 (c2 = (t_A.t_B)^2 = (nu_A.nu_B)^2, t_X = nu_X x s): the least eigenvalue for two arcs (as
    det / the greater, without cancellation), the ball's weight against an arc, the sum for two balls."""
    if arcA and arcB:
        big = 0.5 * (aA + aB + math.sqrt((aA - aB) ** 2 + 4.0 * aA * aB * c2))
        return aA * aB * (1.0 - c2) / big if big > 0.0 else 0.0
    if arcA:
        return aB
    if arcB:
        return aA
    return aA + aB


@kernel
def tight_pair_lift(k, rhoA, rhoB, arcA, arcB, depth, slack, n0, n1, n2, d, floor):
    """The offset r to which a face (unit normal n, offset d > 0) is certified by the support of K itself
    (torus_pair_set's set: arcA, arcB whether each side is a torus's arc or a big sphere's cap), or -inf where
    that is not above d and ``floor``: the set's depth less slack, or less where the gradient B0 that Newton's
    steps leave at s needs it.

    The bound works on the tangent plane at s (v = s + y, |y| = x = tan phi): h_K(s + y) >= depth0 - B0 x + rho_A
    H_A(y.t_A) + rho_B H_B(y.t_B) (depth0 = A0 + rho_A + rho_B; a cap's term takes |y|), and as H(sqrt(u)) is
    concave with H(0) = 0, H(y.t) >= H(x) (y.t)^2 / x^2, so the two terms hold mu(x) = _least_gain(rho_A H_A(x),
    rho_B H_B(x)), which grows with x. h_K(v) = h_K(s + y) / sqrt(1 + x^2) >= r + slack where mu(x) >= B0 x + depth0
    x^2 / 2 - eps, eps = depth0 - r - slack (sqrt(1 + x^2) <= 1 + x^2 / 2; the slack is for rounding). Up to the
    first arc's end (x1) the arcs' terms are at least x^2 / (1 + sqrt(1 + x1^2)), a quadratic checked in closed
    form; beyond, as mu grows with x and so does the right side, each step goes from x to where the right side
    reaches mu(x), out to tan Phi. Phi = angle(n, s) + acos(d / depth) (_far_angle): the ray through the face gives
    D's support r or more beyond gamma = acos(d / r) from n, and the rest of the face's cone lies within Phi of s (a
    smaller r only narrows it). Across two arcs the bound grows as (rho (1 - c) - depth) x^2 / 2 (c = |nu_A.nu_B|),
    so it reaches faces far below the depth where the edges cross, and little along nearly parallel ones."""
    fail = -math.inf
    s0, s1, s2, A0, B0, bA, bB, c2, cbA, sbA, cbB, sbB = k
    lim = max(d, floor)
    if not (bA >= 0.0 and bB >= 0.0 and d > 0.0 and depth - slack > lim):
        return fail
    cF, sF = _far_angle(s0, s1, s2, n0, n1, n2, d, depth)
    if not cF > 0.8775:  # Phi < 0.5
        return fail
    T = sF / cF
    depth0 = A0 + rhoA + rhoB
    tA = math.inf if bA >= 0.5 * math.pi else sbA / cbA
    tB = math.inf if bB >= 0.5 * math.pi else sbB / cbB
    x = min(tA, tB, T)
    kap = 1.0 / (1.0 + math.sqrt(1.0 + x * x))
    a = _least_gain(kap * rhoA, kap * rhoB, arcA, arcB, c2) - 0.5 * depth0
    # eps = depth0 - (r + slack): the set's own rounding (depth0 - depth), or what the quadratic needs to stay >= 0
    if a > 0.0 and B0 < 2.0 * a * x:  # its least value inside [0, x]
        need = B0 * B0 / (4.0 * a)
    else:
        need = B0 * x - a * x * x
    eps = max(depth0 - depth, need)
    r = depth0 - eps - slack
    if not (r > lim and eps > 0.0):
        return fail
    for _ in range(TIGHT_STEPS):
        if x >= T:
            return r
        mu = _least_gain(rhoA * _arc_gain(x, bA, cbA, sbA), rhoB * _arc_gain(x, bB, cbB, sbB), arcA, arcB, c2)
        # mu holds up to where the right side reaches it (B0 x + depth0 x^2 / 2 = mu + eps)
        x2 = 2.0 * (mu + eps) / (B0 + math.sqrt(B0 * B0 + 2.0 * depth0 * (mu + eps)))
        if not x2 > x * (1.0 + 1e-3):  # (no progress: the bound falls short, or barely holds)
            return fail
        x = x2
    return fail


@kernel
def _keep_set(work, kind, sgn, depth, p1, s1, p2, s2, p3, y1, y2):
    """The deepest set found: a cylinder (kind 1: m, a, e, rho, azimuth, y1, y2) or a ball segment (kind 2:
    C, rho, u, cos alpha), in z = sgn x. (Two cores' curved patches, kind 3, are kept by face_certificate.)"""
    row = EPA_ROW + EPA_SET
    work[row, 0], work[row, 1], work[row, 2] = kind, sgn, depth
    for c in range(3):
        work[row + 1, c] = p1[c]
        work[row + 2, c] = p2[c]
        work[row + 3, c] = p3[c]
        work[row + 4, c] = y1[c]
        work[row + 5, c] = y2[c]
    work[row + 1, 3], work[row + 2, 3] = s1, s2


@kernel(inline="always")
def clear_set(work):
    work[EPA_ROW + EPA_SET, 0] = 0.0
    work[EPA_ROW + EPA_SET, 2] = -math.inf
    work[EPA_ROW + EPA_TORI, 0] = -1.0


@kernel(inline="always")
def _put_tori(work, row, k):
    """Rows row + 1 .. row + 3: a torus_pair_set bound's terms k."""
    for c in range(4):
        work[row + 1, c] = k[c]
        work[row + 2, c] = k[4 + c]
        work[row + 3, c] = k[8 + c]


@kernel(inline="always")
def _tori_at(work, row):
    """The terms k of the torus_pair_set bound stored from row + 1 on (_put_tori)."""
    return (work[row + 1, 0], work[row + 1, 1], work[row + 1, 2], work[row + 1, 3], work[row + 2, 0],
            work[row + 2, 1], work[row + 2, 2], work[row + 2, 3], work[row + 3, 0], work[row + 3, 1],
            work[row + 3, 2], work[row + 3, 3])


@kernel
def _curved(f, ix, p, side, R, t):
    """(m, e, a) of curved patch p of the core in A's frame, as _torus, or, for a big sphere, its centre
    with a = -1 (torus_pair_set's ball)."""
    V, F = ix[IDX_V], ix[IDX_F]
    if p >= V + F:
        return _torus(f, ix, p, side, R, t)
    k = F_VERTICES + 3 * V + 3 * (p - V)
    c0, c1, c2 = f[at(k)], f[at(k + 1)], f[at(k + 2)]
    if side == STP_IS_B:
        c0, c1, c2 = (R[0, 0] * c0 + R[0, 1] * c1 + R[0, 2] * c2 + t[0],
                      R[1, 0] * c0 + R[1, 1] * c1 + R[1, 2] * c2 + t[1],
                      R[2, 0] * c0 + R[2, 1] * c1 + R[2, 2] * c2 + t[2])
    return c0, c1, c2, 0.0, 0.0, 0.0, -1.0


@kernel(inline="always")
def _cap_room(f, ix, p, u0, u1, u2):
    """The angle about the unit u (the core's local frame) within which big sphere p's normals lie in
    its region (its cap), or -inf where u is not in it."""
    ca = big_sphere_cap(f, ix, p, u0, u1, u2)[3]
    return math.acos(max(-1.0, ca)) if ca <= 1.0 else -math.inf


@kernel
def _tori_set(work, pair, p, q, rhoA, rhoB, n0, n1, n2):
    """torus_pair_set for curved patches p of A and q of B (tori or big spheres, ball radii rho; a big
    sphere's ball narrowed to its cap about the set's deepest normal) about n, or the last one's (kept in
    EPA_TORI: p, q, depth, slack, then the terms): a set depends on its face only through Newton's start,
    so a face of the same pair reuses it."""
    row = EPA_ROW + EPA_TORI
    if work[row, 0] == p and work[row, 1] == q:
        return _tori_at(work, row), work[row, 2], work[row, 3]
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    m0, m1, m2, e0, e1, e2, a = _curved(fA, iA, p, STP_IS_A, R, t)
    g0, g1, g2, h0, h1, h2, b = _curved(fB, iB, q, STP_IS_B, R, t)
    k, depth, slack = torus_pair_set((m0, m1, m2), (e0, e1, e2), a, rhoA, (g0, g1, g2), (h0, h1, h2), b, rhoB,
                                     n0, n1, n2, NEWTON_STEPS)
    if depth > -math.inf and (a < 0.0 or b < 0.0):
        s0, s1, s2 = k[0], k[1], k[2]
        bA = _cap_room(fA, iA, p, s0, s1, s2) if a < 0.0 else math.inf
        bB = math.inf
        if b < 0.0:  # B's normal -s in B's frame
            bB = _cap_room(fB, iB, q, -(R[0, 0] * s0 + R[1, 0] * s1 + R[2, 0] * s2),
                           -(R[0, 1] * s0 + R[1, 1] * s1 + R[2, 1] * s2), -(R[0, 2] * s0 + R[1, 2] * s1 + R[2, 2] * s2))
        if bA == -math.inf or bB == -math.inf:
            depth = -math.inf
        else:
            k = with_room(k, bA, bB)
    work[row, 0], work[row, 1], work[row, 2], work[row, 3] = p, q, depth, slack
    _put_tori(work, row, k)
    return k, depth, slack


@kernel(inline="always")
def _same(a, b):
    return a[0] == b[0] and a[1] == b[1] and a[2] == b[2]


@kernel(inline="always")
def may_certify(pair, sides, work, iw, face, first):
    """Whether face_certificate could lift the face: a deepest set is kept, or a corner from ``first`` on
    has a big sphere on a certifying side, a torus against a polytope, or a torus on each of two cores.
    (Inlined into the EPA, so that the faces with none of these skip the call: about three in five of
    kuka_link_4's STP-STP tries before the tori's bound.)"""
    if work[EPA_ROW + EPA_SET, 0] != 0.0:
        return True
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    for ci in range(3):
        v = iw[at(EPA_IOFF + EPA_CORNERS + 3 * face + ci)]
        if v < first:
            continue
        if sides & 1:
            p = iw[at(EPA_IOFF + EPA_FEATURES + 2 * v)]
            if p >= iA[IDX_V] and (p < iA[IDX_V] + iA[IDX_F] or kB == POLYTOPE):
                return True
        if sides & 2:
            q = iw[at(EPA_IOFF + EPA_FEATURES + 2 * v + 1)]
            if q >= iB[IDX_V] and (q < iB[IDX_V] + iB[IDX_F] or kA == POLYTOPE):
                return True
        if sides == 3 and p >= iA[IDX_V] + iA[IDX_F] and q >= iB[IDX_V] + iB[IDX_F]:
            return True
    return False


@kernel
def face_certificate(pair, sides, work, iw, face, first, n0, n1, n2, d):
    """(r, u0, u1, u2, depth, core): the face's certified offset r, at least d, from the curved sets in D
    that its corners give (module docstring): for each corner from ``first`` on (the run's own
    supports) whose support on an STP-BV core's side (``sides``: 1 A, 2 B, 3 both) was a big sphere,
    that sphere's segment less the corner's own point of the other side (a vertex's: where the other
    core's point is curved too, their pair's set below); where it was a torus and the other side is a
    polytope, the torus's cylinder swept between two distinct points of the polytope among the
    corners; where both of a corner's points lie on curved patches (two cores: tori or big spheres),
    their arcs' or caps' bound (tight_pair_lift; the last pair's set is reused, _tori_set). u (x's
    frame) and depth: the deepest normal and the depth of the set that gave r (depth -inf if none did);
    core: the side of its STP-BV (1 A, 2 B; 0 if none)."""
    kA, mA, fA, iA, kB, mB, fB, iB, R, t = pair
    best, bu0, bu1, bu2, bdepth, bcore = d, 0.0, 0.0, 0.0, -math.inf, 0
    if not d > 0.0:
        return best, bu0, bu1, bu2, bdepth, bcore
    kind = work[EPA_ROW + EPA_SET, 0]
    if kind != 0.0:  # the deepest set found so far first: it holds for any face
        row = EPA_ROW + EPA_SET
        sgn = work[row, 1]
        p1 = (work[row + 1, 0], work[row + 1, 1], work[row + 1, 2])
        p2 = (work[row + 2, 0], work[row + 2, 1], work[row + 2, 2])
        p3 = (work[row + 3, 0], work[row + 3, 1], work[row + 3, 2])
        if kind == 3.0:
            r = tight_pair_lift(_tori_at(work, row), fA[F_BIG_R] - fA[F_R], fB[F_BIG_R] - fB[F_R],
                                work[row + 4, 0] >= iA[IDX_V] + iA[IDX_F], work[row + 4, 1] >= iB[IDX_V] + iB[IDX_F],
                                work[row, 2], work[row, 3], n0, n1, n2, d, best)
            u0, u1, u2, depth = p1[0], p1[1], p1[2], work[row, 2]
        elif kind == 1.0:
            r, u0, u1, u2, depth = cylinder_reach(p1, p2, work[row + 1, 3], work[row + 2, 3],
                                                  (work[row + 4, 0], work[row + 4, 1], work[row + 4, 2]),
                                                  (work[row + 5, 0], work[row + 5, 1], work[row + 5, 2]), p3,
                                                  sgn * n0, sgn * n1, sgn * n2, d, best)
        else:
            r, u0, u1, u2, depth = ball_segment_reach(p1, work[row + 1, 3], work[row + 2, 3], sgn * n0, sgn * n1,
                                                      sgn * n2, d, best)
        if r > best:
            best, bu0, bu1, bu2, bdepth, bcore = r, sgn * u0, sgn * u1, sgn * u2, depth, 1 if sgn > 0.0 else 2
    corners = (iw[at(EPA_IOFF + EPA_CORNERS + 3 * face)], iw[at(EPA_IOFF + EPA_CORNERS + 3 * face + 1)],
               iw[at(EPA_IOFF + EPA_CORNERS + 3 * face + 2)])
    for side in (STP_IS_A, STP_IS_B):
        if not (sides & (1 if side == STP_IS_A else 2)):
            continue
        sgn = 1.0 if side == STP_IS_A else -1.0
        z0, z1, z2 = sgn * n0, sgn * n1, sgn * n2  # the face's normal in z = sgn x
        stp_f, stp_i = (fA, iA) if side == STP_IS_A else (fB, iB)
        other = EPA_PB if side == STP_IS_A else EPA_PA
        col = 0 if side == STP_IS_A else 1
        polytope_other = (kB if side == STP_IS_A else kA) == POLYTOPE
        V, F = stp_i[IDX_V], stp_i[IDX_F]
        V_other = (iB if side == STP_IS_A else iA)[IDX_V]
        rho = stp_f[F_BIG_R] - stp_f[F_R]
        ra, rb, rc = at(EPA_ROW + other + corners[0]), at(EPA_ROW + other + corners[1]), at(EPA_ROW + other + corners[2])
        ya = (work[ra, 0], work[ra, 1], work[ra, 2])  # (scalars, not views: a view costs a reference count)
        yb = (work[rb, 0], work[rb, 1], work[rb, 2])
        yc = (work[rc, 0], work[rc, 1], work[rc, 2])
        for ci in range(3):
            v = corners[ci]
            if v < first:
                continue
            p = iw[at(EPA_IOFF + EPA_FEATURES + 2 * v + col)]
            if V <= p < V + F:
                if sides == 3 and iw[at(EPA_IOFF + EPA_FEATURES + 2 * v + 1 - col)] >= V_other:
                    continue  # the other core's point on a curved patch: the pair's set, below
                # the sphere's segment less this corner's own point of the other side: the pair whose
                # difference the corner is (the other corners' points certified no more on kuka_link_4's
                # overlaps, for three times the tests)
                y = ya if ci == 0 else (yb if ci == 1 else yc)
                k0 = F_VERTICES + 3 * V + 3 * (p - V)
                c0, c1, c2 = stp_f[at(k0)], stp_f[at(k0 + 1)], stp_f[at(k0 + 2)]
                if side == STP_IS_B:
                    c0, c1, c2 = (R[0, 0] * c0 + R[0, 1] * c1 + R[0, 2] * c2 + t[0],
                                  R[1, 0] * c0 + R[1, 1] * c1 + R[1, 2] * c2 + t[1],
                                  R[2, 0] * c0 + R[2, 1] * c1 + R[2, 2] * c2 + t[2])
                C = (c0 - y[0], c1 - y[1], c2 - y[2])
                r, cn, s0, s1, s2, cphi, sphi, depth = _support_lift(C, rho, z0, z1, z2, d, best)
                if r == -math.inf:
                    continue
                # the sphere's cap of normals about s, in the STP-BV's frame (z = s - y: the core's
                # normal is s itself)
                l0, l1, l2 = s0, s1, s2
                if side == STP_IS_B:
                    l0 = R[0, 0] * s0 + R[1, 0] * s1 + R[2, 0] * s2
                    l1 = R[0, 1] * s0 + R[1, 1] * s1 + R[2, 1] * s2
                    l2 = R[0, 2] * s0 + R[1, 2] * s1 + R[2, 2] * s2
                ca = big_sphere_cap(stp_f, stp_i, p, l0, l1, l2)[3]
                if not _beta_holds(rho, cn, cphi, sphi, ca, r):
                    continue
                best, bu0, bu1, bu2, bdepth, bcore = r, sgn * s0, sgn * s1, sgn * s2, depth, 1 if sgn > 0.0 else 2
                if depth > work[EPA_ROW + EPA_SET, 2]:
                    _keep_set(work, 2.0, sgn, depth, C, rho, (s0, s1, s2), ca, (0.0, 0.0, 0.0), y, y)
                continue
            if (ci >= 1 and corners[0] >= first and iw[at(EPA_IOFF + EPA_FEATURES + 2 * corners[0] + col)] == p) or (
                    ci == 2 and corners[1] >= first and iw[at(EPA_IOFF + EPA_FEATURES + 2 * corners[1] + col)] == p):
                continue  # a torus already tried
            if p >= V + F and polytope_other:
                m0, m1, m2, e0, e1, e2, a = _torus(stp_f, stp_i, p, side, R, t)
                for k in range(3):  # the sweep between two corners' distinct points
                    y1 = ya if k == 0 else (yb if k == 1 else yc)
                    y2 = yb if k == 0 else (yc if k == 1 else ya)
                    if _same(y1, y2) or (k == 1 and (_same(ya, yb) or _same(ya, yc))) or (
                            k == 2 and (_same(yb, ya) or _same(yb, yc))):
                        continue  # the same point, or a sweep already tried (unless all three differ)
                    r, u0, u1, u2, depth = cylinder_reach((m0, m1, m2), (e0, e1, e2), a, rho, y1, y2, (z0, z1, z2),
                                                          z0, z1, z2, d, best)
                    if r > best:
                        best, bu0, bu1, bu2, bdepth, bcore = r, sgn * u0, sgn * u1, sgn * u2, depth, \
                            1 if sgn > 0.0 else 2
                        if depth > work[EPA_ROW + EPA_SET, 2]:
                            _keep_set(work, 1.0, sgn, depth, (m0, m1, m2), a, (e0, e1, e2), rho, (z0, z1, z2), y1, y2)
    if sides == 3:  # a curved patch of each core at the same corner: their arcs or caps (torus_pair_set)
        rhoA, rhoB = fA[F_BIG_R] - fA[F_R], fB[F_BIG_R] - fB[F_R]
        VA, VB = iA[IDX_V], iB[IDX_V]
        for ci in range(3):
            v = corners[ci]
            if v < first:
                continue
            p = iw[at(EPA_IOFF + EPA_FEATURES + 2 * v)]
            q = iw[at(EPA_IOFF + EPA_FEATURES + 2 * v + 1)]
            if p < VA or q < VB:
                continue
            if ci >= 1 and corners[0] >= first and iw[at(EPA_IOFF + EPA_FEATURES + 2 * corners[0])] == p and \
                    iw[at(EPA_IOFF + EPA_FEATURES + 2 * corners[0] + 1)] == q:
                continue
            if ci == 2 and corners[1] >= first and iw[at(EPA_IOFF + EPA_FEATURES + 2 * corners[1])] == p and \
                    iw[at(EPA_IOFF + EPA_FEATURES + 2 * corners[1] + 1)] == q:
                continue
            if kind == 3.0 and work[EPA_ROW + EPA_SET + 4, 0] == p and work[EPA_ROW + EPA_SET + 4, 1] == q:
                continue  # the kept set, tried above
            k, depth, slack = _tori_set(work, pair, p, q, rhoA, rhoB, n0, n1, n2)
            r = tight_pair_lift(k, rhoA, rhoB, p >= VA + iA[IDX_F], q >= VB + iB[IDX_F], depth, slack, n0, n1, n2, d,
                                best)
            if r > best:
                best, bu0, bu1, bu2, bdepth, bcore = r, k[0], k[1], k[2], depth, 1
                row = EPA_ROW + EPA_SET
                if depth > work[row, 2]:
                    work[row, 0], work[row, 1], work[row, 2], work[row, 3] = 3.0, 1.0, depth, slack
                    _put_tori(work, row, k)
                    work[row + 4, 0], work[row + 4, 1] = p, q
    return best, bu0, bu1, bu2, bdepth, bcore
