"""The curved sets that certify the EPA's faces (spq.kernels.epa_curved), against independent checks:
every point sampled from the certified cap lies in the set, tested by its own definition (a point of
the circular segment swept along the polytope's edge); every normal a ball segment must lift has its
support, found numerically over the segment's cap (its rim sampled ever finer), at least the certified
offset; every normal two tori (or a torus and a ball, or two balls) must lift has their support, found
numerically over the torus patches (and over their arcs' or caps' sampled points), at least the certified
offset; and the bounds reach the set's depth where the face's normal is the deepest one."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from scipy.optimize import minimize

from spq.kernels.epa_curved import (ball_segment_reach, cylinder_reach, halfspace_reach, tight_pair_lift,
                                     torus_pair_set, with_room)

RHO = 2.0


def _unit(v):
    return v / np.linalg.norm(v)


def _cap_points(rng, n, d, r, count=300):
    """Points of {|z| <= r, n.z >= d}: its rim, its top r n, random points of its spherical surface
    (where a cap thinner than the ball's scale leaves the set first), and random points of the ball
    kept where they lie in it."""
    q1 = _unit(np.cross(n, rng.normal(size=3)))
    q2 = np.cross(n, q1)
    t = np.linspace(0.0, 2.0 * math.pi, count)
    rim = d * n + math.sqrt(max(r * r - d * d, 0.0)) * (np.cos(t)[:, None] * q1 + np.sin(t)[:, None] * q2)
    # the sphere's part beyond the plane: uniform in its height (Archimedes), hence in area
    h = rng.uniform(min(d / r, 1.0), 1.0, size=count)
    phi = rng.uniform(0.0, 2.0 * math.pi, size=count)
    side = np.sqrt(np.maximum(1.0 - h * h, 0.0))
    sphere = r * (h[:, None] * n + side[:, None] * (np.cos(phi)[:, None] * q1 + np.sin(phi)[:, None] * q2))
    ball = rng.normal(size=(20 * count, 3))
    ball = r * ball / np.linalg.norm(ball, axis=1)[:, None] * rng.uniform(0, 1, size=(20 * count, 1)) ** (1 / 3)
    return np.vstack([rim, sphere, ball[ball @ n >= d], [d * n, r * n]])


def _in_swept_segment(z, m, e, a, y1, y2, w, slack=1e-12):
    """Whether z = s - y1 - t (y2 - y1) for some t in [0, 1] and s in the circular segment of the arc of
    radius RHO from m - L/2 e to m + L/2 e in the plane of e and w (centre m - a w)."""
    nu = np.cross(e, w)
    E = y2 - y1
    c = m - a * w
    t = nu @ (c - y1 - z) / (nu @ E)
    s = z + y1 + t * E
    return -slack <= t <= 1 + slack and np.linalg.norm(s - c) <= RHO + slack and (s - m) @ w >= -slack


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), tilt=st.sampled_from([0.0, 1e-4, 1e-3, 1e-2]))
def test_cylinder_cap_lies_in_the_swept_segment_and_reaches_its_depth(seed, tilt):
    rng = np.random.default_rng(seed)
    L = rng.uniform(0.01, 0.06)
    a = math.sqrt(RHO ** 2 - (L / 2) ** 2)
    e = _unit(rng.normal(size=3))
    m = rng.normal(size=3) * 0.05
    w = rng.normal(size=3)
    w = _unit(w - (w @ e) * e)
    nu = np.cross(e, w)
    # D's deepest normal k: in the arc's plane, across the sweep E, near w (on the short arc)
    ang = rng.uniform(-0.8, 0.8) * L / (2 * RHO)
    k = math.cos(ang) * w + math.sin(ang) * e
    phi = rng.uniform(0.05, 1.5)
    E = rng.uniform(0.01, 0.05) * (math.cos(phi) * nu + math.sin(phi) * np.cross(k, nu)) * rng.choice([-1, 1])
    depth = rng.uniform(0.002, 0.05)
    y1 = (m - a * w + RHO * k) - rng.uniform(0.2, 0.8) * E - depth * k  # the origin lies depth below the foot
    y2 = y1 + E
    n = _unit(k + rng.normal(size=3) * tilt)
    d = depth * (n @ k) - rng.uniform(0.0, 3e-5)
    r, u0, u1, u2, set_depth = cylinder_reach(tuple(m), tuple(e), a, RHO, y1, y2, tuple(n), n[0], n[1], n[2], d, d)
    assert set_depth <= depth + 1e-12  # the set lies in D, whose depth is `depth`
    cphi = np.cross(e, w) @ E / np.linalg.norm(E)
    if tilt == 0.0 and depth < RHO * cphi ** 2:
        # the arc in the deepest normal's plane touches D at the foot, and the cylinder (radius
        # RHO cos^2 phi) holds the origin on the foot's side of its axis (a cylinder thinner than the
        # depth, E nearly in the arc's plane, holds no ball that deep: about 3% of these examples)
        assert set_depth >= depth - 1e-11
        assert np.allclose((u0, u1, u2), k, atol=1e-6)
        d_near = depth - 1e-10  # a face just below the foot: its narrow cap is certified to the depth
        assert cylinder_reach(tuple(m), tuple(e), a, RHO, y1, y2, tuple(n), n[0], n[1], n[2], d_near, d_near)[0] >= \
            depth - 1e-11
    if r > d:
        wn = _unit(n - (n @ e) * e)  # the arc's plane: that of the face's normal
        assert all(_in_swept_segment(z, m, e, a, y1, y2, wn) for z in _cap_points(rng, n, d, r))


def _segment_support(C, s, alpha, V, rho=RHO):
    """max of z.v over the ball segment's cap {C + rho w : angle(w, s) <= alpha}, numerically, for each row v
    of V: w = v where v lies in the cap's cone (Cauchy-Schwarz), else the best of the cap's rim sampled at 721
    angles, then twice more at 721 angles about the best so far (the last spacing 2e-8 rad, well below the
    assertions' 1e-13 m)."""
    V = np.atleast_2d(V)
    q1 = _unit(np.cross(s, [1.0, 0.0, 0.0] if abs(s[0]) < 0.9 else [0.0, 1.0, 0.0]))
    q2 = np.cross(s, q1)
    base = V @ C + rho * math.cos(alpha) * (V @ s)
    a1, a2 = rho * math.sin(alpha) * (V @ q1), rho * math.sin(alpha) * (V @ q2)
    centre, half = np.zeros(len(V)), math.pi
    for _ in range(3):
        t = centre[:, None] + np.linspace(-half, half, 721)[None, :]
        rim = base[:, None] + a1[:, None] * np.cos(t) + a2[:, None] * np.sin(t)
        k = np.argmax(rim, axis=1)
        best = rim[np.arange(len(V)), k]
        centre, half = t[np.arange(len(V)), k], 2.0 * half / 720
    return np.where(V @ s >= math.cos(alpha), V @ C + rho, best)


def _least_over_cap(support, n, gamma, starts):
    """The least of ``support`` (a function of a unit normal) over the normals within gamma of the unit n, searched
    with Nelder-Mead from each normal in ``starts`` (the cap's normals as n + x q1 + y q2, |(x, y)| <= tan gamma)."""
    q1 = _unit(np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0]))
    q2 = np.cross(n, q1)
    lim = math.tan(gamma)

    def h(xy):
        x, y = xy
        rr = math.hypot(x, y)
        if rr > lim:
            x, y = x * lim / rr, y * lim / rr
        return support(_unit(n + x * q1 + y * q2))

    return min(minimize(h, [(u @ q1) / (u @ n), (u @ q2) / (u @ n)], method="Nelder-Mead",
                        options={"xatol": 1e-12, "fatol": 1e-16, "maxiter": 400}).fun for u in starts)


def _normals_near(rng, n, gamma, toward, count=200):
    """Unit normals within gamma of n: its rim circle, the rim's point farthest from ``toward``, random ones inside."""
    q1 = _unit(np.cross(n, rng.normal(size=3)))
    q2 = np.cross(n, q1)
    t = np.linspace(0.0, 2.0 * math.pi, count)
    rim = math.cos(gamma) * n + math.sin(gamma) * (np.cos(t)[:, None] * q1 + np.sin(t)[:, None] * q2)
    away = toward - (toward @ n) * n
    # (where toward lies within rounding of n, away has no direction: its unit vector would not be across n)
    far = [math.cos(gamma) * n - math.sin(gamma) * _unit(away)] if np.linalg.norm(away) > 1e-9 else []
    ang = gamma * np.sqrt(rng.uniform(0, 1, size=count))
    phi = rng.uniform(0.0, 2.0 * math.pi, size=count)
    inside = np.cos(ang)[:, None] * n + np.sin(ang)[:, None] * (np.cos(phi)[:, None] * q1 + np.sin(phi)[:, None] * q2)
    V = np.vstack([rim, inside] + ([np.array(far)] if far else []))
    return V / np.linalg.norm(V, axis=1)[:, None]


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), tilt=st.sampled_from([0.0, 1e-3, 1e-2, 5e-2]),
       below=st.sampled_from([1e-8, 1e-5, 1e-3, 1e-2]))
def test_ball_segment_reach_holds_every_normal_the_ray_bound_leaves(seed, tilt, below):
    """Where the face is certified to r, every normal v within gamma = acos(d / r) of the face's (those the
    ray through the face does not lift to r) has the segment's support, found numerically, at least r;
    where it is not (and r would exceed the face), the normal gamma from n away from s falls short."""
    rng = np.random.default_rng(seed)
    s = _unit(rng.normal(size=3))
    alpha = rng.choice([1e-3, 1e-2, 0.1]) * rng.uniform(0.5, 1.0)
    depth = rng.uniform(0.002, 0.05)
    C = -(RHO - depth) * s
    n = _unit(s + rng.normal(size=3) * tilt)
    d = depth * (n @ s) * (1.0 - below)
    r, v0, v1, v2, set_depth = ball_segment_reach(tuple(C), RHO, math.cos(alpha), n[0], n[1], n[2], d, d)
    assert set_depth <= RHO - np.linalg.norm(C)
    if r == -math.inf:
        r = set_depth - 1e-12 * (RHO + np.abs(C).sum())
        if r <= d:
            return
        gamma = math.acos(d / r)
        far = math.cos(gamma) * n - math.sin(gamma) * _unit(s - (s @ n) * n)
        if np.arccos(np.clip(n @ s, -1, 1)) + gamma < math.pi / 2:
            assert _segment_support(C, s, alpha, far)[0] < r + 1e-12
        return
    assert np.allclose((v0, v1, v2), s)
    gamma = math.acos(min(d / r, 1.0))
    assert (_segment_support(C, s, alpha, _normals_near(rng, n, gamma, s)) >= r - 1e-13).all()


def test_ball_segment_reach_lifts_a_face_well_below_the_depth():
    """The support bound reaches faces about gamma^2 / 2 of the depth below it (here 5e-5 of 5 cm, a
    segment of rim radius 2 mm, normals within 0.01 of its deepest), where a ball segment 1e-6 m thick could
    hold no cap of B(0, r) beyond the face."""
    s = _unit(np.array([0.3, -0.2, 0.9]))
    depth, alpha = 0.05, 1e-3
    C = -(RHO - depth) * s
    n = _unit(s + 0.01 * _unit(np.cross(s, [1.0, 0.0, 0.0])))
    d = depth * (n @ s) - 5e-5
    r = ball_segment_reach(tuple(C), RHO, math.cos(alpha), n[0], n[1], n[2], d, d)[0]
    assert r >= depth - 1e-11


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_halfspace_reach_is_the_largest_cap_on_the_planes_side(seed):
    rng = np.random.default_rng(seed)
    n = _unit(rng.normal(size=3))
    l = rng.normal(size=3) * rng.uniform(0.1, 10)
    d = rng.uniform(0.01, 0.1)
    beta = (d * (n @ l)) - rng.uniform(0.0, 0.05) * np.linalg.norm(l)
    r = halfspace_reach(n[0], n[1], n[2], d, l[0], l[1], l[2], beta)
    if not math.isfinite(r):
        return
    assert r >= d
    assert (_cap_points(rng, n, d, r) @ l >= beta - 1e-12 * np.linalg.norm(l)).all()
    # a little larger and the cap's rim point least along l crosses the plane (for l not opposite n, where
    # the bound may be the ball's own least point)
    if n @ l >= 0.0:
        q = -_unit(l - (l @ n) * n)
        bigger = r * (1 + 1e-6) + 1e-9
        assert (d * n + math.sqrt(bigger ** 2 - d ** 2) * q) @ l < beta


def _spindle_support(m, e, a, V):
    """max of x.v over the torus patch of edge (m, e) at ball radius RHO (its points m - a w + RHO (cos tau w +
    sin tau e), w any unit across e, |tau| <= t0 with cos t0 = a / RHO), for each unit row v: w along v's part
    across e is best for every tau (the coefficient RHO cos tau - a is >= 0), and tau is searched on a grid of
    4001 then twice more about the best (the last spacing about 1e-11 rad)."""
    V = np.atleast_2d(V)
    x = V @ e
    p = np.linalg.norm(V - x[:, None] * e, axis=1)
    t0 = math.acos(a / RHO)
    centre, half = np.zeros(len(V)), t0
    for _ in range(3):
        t = np.clip(centre[:, None] + np.linspace(-half, half, 4001)[None, :], -t0, t0)
        f = (RHO * np.cos(t) - a) * p[:, None] + RHO * np.sin(t) * x[:, None]
        k = np.argmax(f, axis=1)
        best = f[np.arange(len(V)), k]
        centre, half = t[np.arange(len(V)), k], 2.0 * half / 4000
    return V @ m + best


def _tori_support(A, B, V):
    """The support of spindle (or ball) A less spindle (or ball) B (each (m, e, a)) along the unit rows of V."""
    V = np.atleast_2d(V)
    return _patch_support(A, V) + _patch_support(B, -V)


def _crossing_tori(rng, s, depth, cos_planes, lat_a, lat_b, balls=(False, False), rhos=(RHO, RHO)):
    """Tori A and B (m, e, a) whose difference's support point along the unit s is depth s (so that s is its
    deepest normal), their arcs through s at latitudes lat (fractions of their half-angles), the arcs'
    planes at angle acos(cos_planes); edges 2 to 20 cm (at most 1.6 rho); ball radii ``rhos``. A side with
    ``balls`` True is instead the ball of its radius about m (e = 0, a = -1)."""
    q = _unit(np.cross(s, rng.normal(size=3)))
    q2 = math.sqrt(1.0 - cos_planes ** 2) * np.cross(s, q) + cos_planes * q
    out = []
    for side, lat, qq, rho in ((1.0, lat_a, q, rhos[0]), (-1.0, lat_b, q2, rhos[1])):
        L = rng.uniform(0.02, min(0.2, 1.6 * rho))
        a = math.sqrt(rho ** 2 - (L / 2) ** 2)
        tau = lat * math.acos(a / rho)
        e = math.sin(tau) * side * s + math.cos(tau) * qq  # e.(side s) = sin tau
        out.append((e, a, tau))
    (eA, aA, tA), (eB, aB, tB) = out
    mB = rng.normal(size=3) * 0.05
    wB = _unit(-s - (-s @ eB) * eB)
    cB = mB if balls[1] else mB - aB * wB
    wA = _unit(s - (s @ eA) * eA)
    cA = depth * s + cB - (rhos[0] + rhos[1]) * s  # (cA + rho_A s) - (cB - rho_B s) = depth s
    A = (cA, np.zeros(3), -1.0) if balls[0] else (cA + aA * wA, eA, aA)
    B = (mB, np.zeros(3), -1.0) if balls[1] else (mB, eB, aB)
    return A, B


def _patch_support(T, V):
    """The support of a torus patch (_spindle_support) or of the ball T = (m, 0, -1) along the unit rows of V."""
    V = np.atleast_2d(V)
    return V @ T[0] + RHO if T[2] < 0 else _spindle_support(*T, V)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), tilt=st.sampled_from([0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2]),
       below=st.sampled_from([1e-8, 1e-6, 1e-5, 1e-4, 1e-3]), cos_planes=st.sampled_from([0.0, 0.5, 0.9, 0.99]),
       steps=st.sampled_from([0, 2]), balls=st.sampled_from([(False, False), (False, True), (True, False),
                                                               (True, True)]))
def test_pair_lift_holds_the_spindles_support_over_the_face_cone(seed, tilt, below, cos_planes, steps, balls):
    """Two cores' tori crossing, or a torus and a ball, or two balls: where a face is certified to r, every
    normal within gamma = acos(d / r) of its own has the sets' support, found numerically over the torus
    patches (a ball's is exact), at least r (sampled over that cap, and its least value searched from the
    deepest normal and from the worst sample). The bound is taken about the face's normal itself (no Newton
    step: the sets' deepest normal lies off it) or about the deepest normal found by two steps; with these,
    where the face's cap lies within both arcs, it is certified to the depth."""
    rng = np.random.default_rng(seed)
    s = _unit(rng.normal(size=3))
    depth = rng.uniform(0.002, 0.1)
    A, B = _crossing_tori(rng, s, depth, cos_planes, rng.uniform(-0.9, 0.9), rng.uniform(-0.9, 0.9), balls)
    assert abs(_tori_support(A, B, s)[0] - depth) < 1e-12
    n = _unit(s + rng.normal(size=3) * tilt)
    d = depth * (n @ s) * (1.0 - below)
    k, set_depth, slack = torus_pair_set(tuple(A[0]), tuple(A[1]), A[2], RHO, tuple(B[0]), tuple(B[1]), B[2], RHO,
                                         n[0], n[1], n[2], steps)
    # (along nearly parallel edges, or from farther, two steps may fail or stop short)
    if steps == 2 and (cos_planes <= 0.5 or any(balls)) and tilt <= 1e-3:
        assert np.linalg.norm(np.array(k[:3]) - s) < 1e-7  # they found the deepest normal
        assert depth - 3e-12 <= set_depth <= depth  # (less the slack for rounding)
    if set_depth == -math.inf:
        return
    r = tight_pair_lift(k, RHO, RHO, not balls[0], not balls[1], set_depth, slack, n[0], n[1], n[2], d, d)
    # the face's cap within both arcs (their ends b from s) and across crossing ones: certified to the depth
    rooms = [math.inf if T[2] < 0 else math.acos(T[2] / RHO) - abs(math.asin(np.clip(T[1] @ (sg * s), -1, 1)))
             for T, sg in ((A, 1), (B, -1))]
    Phi = math.acos(np.clip(n @ s, -1, 1)) + math.acos(d / depth)
    if steps == 2 and Phi < min(rooms) and (cos_planes <= 0.5 or any(balls)):
        assert r >= depth - 2e-11  # (the slack for rounding: 1e-12 of the scale, about 12 m)
    if r == -math.inf:
        return
    assert r > d
    gamma = math.acos(min(d / r, 1.0))
    V = _normals_near(rng, n, gamma, s)
    H = _tori_support(A, B, V)
    assert (H >= r - 1e-13).all()
    assert _least_over_cap(lambda v: _tori_support(A, B, v)[0], n, gamma, (s, V[np.argmin(H)])) >= r - 1e-13


def test_pair_lift_reaches_faces_well_below_the_depth_and_refuses_parallel_edges():
    """Crossing edges (arcs' planes at 60 degrees): a face 1e-5 of the 5 cm depth below it, tilted 1e-3 rad,
    is certified to the depth; nearly parallel edges (planes within 8 degrees) give no lift there."""
    rng = np.random.default_rng(3)
    s = _unit(np.array([0.2, 0.7, -0.4]))
    depth = 0.05
    for cos_planes, lifted in ((0.5, True), (0.99, False)):
        A, B = _crossing_tori(rng, s, depth, cos_planes, 0.1, -0.2)
        n = _unit(s + 1e-3 * _unit(np.cross(s, [0.0, 0.0, 1.0])))
        d = depth * (n @ s) * (1.0 - 1e-5)
        k, set_depth, slack = torus_pair_set(tuple(A[0]), tuple(A[1]), A[2], RHO, tuple(B[0]), tuple(B[1]), B[2],
                                             RHO, n[0], n[1], n[2], 2)
        r = tight_pair_lift(k, RHO, RHO, True, True, set_depth, slack, n[0], n[1], n[2], d, d)
        assert (r >= depth - 2e-11) if lifted else (r < depth - 1e-6)


def _arc_set_support(T, s, side, V, rho=RHO):
    """max of x.v over side * (c + rho G), G the arc of unit normals of torus T = (m, e, a) in the plane of e
    and side * s (|tau| <= t0 about w, the unit part of side * s across e; c = m - a w), for each row v: its
    points sampled at 4001 latitudes, then twice more about the best."""
    m, e, a = T
    u = side * s
    w = _unit(u - (u @ e) * e)
    c = m - a * w
    t0 = math.acos(a / rho)
    V = np.atleast_2d(V) * side
    centre, half = np.zeros(len(V)), t0
    for _ in range(3):
        t = np.clip(centre[:, None] + np.linspace(-half, half, 4001)[None, :], -t0, t0)
        f = rho * (np.cos(t) * (V @ w)[:, None] + np.sin(t) * (V @ e)[:, None])
        k = np.argmax(f, axis=1)
        best = f[np.arange(len(V)), k]
        centre, half = t[np.arange(len(V)), k], 2.0 * half / 4000
    return V @ c + best


def _set_support(A, B, s, room, V, rhos=(RHO, RHO)):
    """The support of the set torus_pair_set gives, K = (A's arc, or its ball's cap of normals within ``room`` of
    s) less (B's arc, or its ball's cap within ``room`` of -s), ball radii ``rhos``, along the unit rows of V
    (points sampled)."""
    V = np.atleast_2d(V)

    def cap(m, u, W, rho):  # (a whole ball's support is exact)
        return W @ m + rho if room == math.inf else _segment_support(m, u, room, W, rho)

    hA = cap(A[0], s, V, rhos[0]) if A[2] < 0 else _arc_set_support(A, s, 1.0, V, rhos[0])
    hB = cap(B[0], -s, -V, rhos[1]) if B[2] < 0 else _arc_set_support(B, s, -1.0, V, rhos[1])
    return hA + hB


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), tilt=st.sampled_from([0.0, 1e-4, 1e-3, 1e-2, 5e-2]),
       below=st.sampled_from([1e-7, 1e-5, 1e-4, 1e-3, 1e-2]), cos_planes=st.sampled_from([0.0, 0.5, 0.9, 0.99]),
       balls=st.sampled_from([(False, False), (False, True), (True, False), (True, True)]),
       room=st.sampled_from([0.0, 2e-3, 0.02, math.inf]), steps=st.sampled_from([0, 1, 2]),
       rhos=st.sampled_from([(RHO, RHO), (RHO, 0.3), (0.1, RHO), (0.2, 0.6)]))
def test_tight_pair_lift_holds_every_normal_the_ray_bound_leaves(seed, tilt, below, cos_planes, balls, room, steps,
                                                                 rhos):
    """Where tight_pair_lift certifies a face to r, every normal within gamma = acos(d / r) of its own has the
    support of the set itself (the two arcs, or a ball's cap of normals: their points sampled, not the spindles)
    at least r, sampled over that cap and its least value searched from the worst sample. With fewer Newton
    steps the set is taken about a normal off its deepest one (B0 > 0), which the bound must pay for; the two
    sides' radii differ."""
    rng = np.random.default_rng(seed)
    s_true = _unit(rng.normal(size=3))
    depth = rng.uniform(0.002, 0.1)
    A, B = _crossing_tori(rng, s_true, depth, cos_planes, rng.uniform(-0.95, 0.95), rng.uniform(-0.95, 0.95), balls,
                          rhos)
    n = _unit(s_true + rng.normal(size=3) * tilt)
    d = depth * (n @ s_true) * (1.0 - below)
    k, set_depth, slack = torus_pair_set(tuple(A[0]), tuple(A[1]), A[2], rhos[0], tuple(B[0]), tuple(B[1]), B[2],
                                         rhos[1], n[0], n[1], n[2], steps)
    if set_depth == -math.inf:
        return
    k = with_room(k, room if balls[0] else math.inf, room if balls[1] else math.inf)
    r = tight_pair_lift(k, rhos[0], rhos[1], not balls[0], not balls[1], set_depth, slack, n[0], n[1], n[2], d, d)
    if r == -math.inf:
        return
    assert r > d
    s = np.array(k[:3])
    gamma = math.acos(min(d / r, 1.0))
    V = _normals_near(rng, n, gamma, s)
    H = _set_support(A, B, s, room, V, rhos)
    assert (H >= r - 1e-13).all()
    assert _least_over_cap(lambda v: _set_support(A, B, s, room, v, rhos)[0], n, gamma, (V[np.argmin(H)],)) >= r - 1e-13


def test_tight_pair_lift_reaches_faces_past_an_arcs_end():
    """Two tori whose arcs cross at 60 degrees, the deepest normal 1e-3 rad from B's arc's end: a face 1e-4 of
    the 5 cm depth below it, tilted 2e-2 rad (its cone reaching 20 times past B's end), is certified to the
    depth (a bound taking the angle past both ends and the loss across both planes at once refused it:
    docs/notes/speed-45.md, stop 97)."""
    s = _unit(np.array([0.3, -0.5, 0.8]))
    depth = 0.05
    m, e, a = _crossing_tori(np.random.default_rng(5), s, depth, 0.5, 0.2, 0.0)[1]
    t0 = math.acos(a / RHO)  # (the same draws again: B's latitude 1e-3 rad from its arc's end)
    A, B = _crossing_tori(np.random.default_rng(5), s, depth, 0.5, 0.2, (t0 - 1e-3) / t0)
    n = _unit(s + 2e-2 * _unit(np.cross(s, [0.0, 0.0, 1.0])))
    d = depth * (n @ s) * (1.0 - 1e-4)
    k, set_depth, slack = torus_pair_set(tuple(A[0]), tuple(A[1]), A[2], RHO, tuple(B[0]), tuple(B[1]), B[2],
                                         RHO, n[0], n[1], n[2], 2)
    assert abs(k[6] - 1e-3) < 1e-6  # B's room to its arc's end
    assert tight_pair_lift(k, RHO, RHO, True, True, set_depth, slack, n[0], n[1], n[2], d, d) >= depth - 2e-11


def test_tight_pair_lift_reaches_the_depth_with_unequal_radii_and_caps():
    """The lift is not only sound but reaches: crossing arcs of unequal radii, a big sphere's cap against an arc
    (either side) and two caps, each a face 1e-5 of the 5 cm depth below it and tilted 1e-3 rad, are certified
    to the depth (less rounding), and every normal of the face's cone has the set's sampled support at least
    that (the independent check of the hypothesis test above, on the cases that must certify)."""
    s = _unit(np.array([0.2, 0.7, -0.4]))
    depth = 0.05
    cases = (((0.2, 0.6), (False, False), math.inf), ((0.3, 2.0), (True, False), 0.02),
             ((2.0, 0.3), (False, True), 0.02), ((0.6, 0.2), (True, True), 0.02))
    for rhos, balls, room in cases:
        rng = np.random.default_rng(3)
        A, B = _crossing_tori(rng, s, depth, 0.5, 0.1, -0.2, balls, rhos)
        n = _unit(s + 1e-3 * _unit(np.cross(s, [0.0, 0.0, 1.0])))
        d = depth * (n @ s) * (1.0 - 1e-5)
        k, set_depth, slack = torus_pair_set(tuple(A[0]), tuple(A[1]), A[2], rhos[0], tuple(B[0]), tuple(B[1]), B[2],
                                             rhos[1], n[0], n[1], n[2], 2)
        k = with_room(k, room if balls[0] else math.inf, room if balls[1] else math.inf)
        r = tight_pair_lift(k, rhos[0], rhos[1], not balls[0], not balls[1], set_depth, slack, n[0], n[1], n[2], d, d)
        assert depth - 2e-11 <= r <= depth, (rhos, balls)
        sk = np.array(k[:3])
        gamma = math.acos(d / r)
        V = _normals_near(rng, n, gamma, sk)
        assert (_set_support(A, B, sk, room, V, rhos) >= r - 1e-13).all(), (rhos, balls)
