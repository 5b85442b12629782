"""The curved sets that certify the EPA's faces (spq.kernels.epa_curved), against independent checks:
every point sampled from the certified cap lies in the set, tested by its own definition (a point of
the circular segment swept along the polytope's edge; a point of the ball segment), and the bound
reaches the set's depth where the face's normal is the deepest one."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from spq.kernels.epa_curved import ball_segment_reach, cylinder_reach, halfspace_reach

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


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_ball_segment_cap_lies_in_the_segment(seed):
    rng = np.random.default_rng(seed)
    u = _unit(rng.normal(size=3))
    alpha = rng.uniform(1e-3, 0.3)
    depth = rng.uniform(0.002, 0.05)
    C = -(RHO - depth) * _unit(u + rng.normal(size=3) * rng.uniform(0, alpha))
    n = _unit(-C + rng.normal(size=3) * rng.choice([0.0, 1e-3, 1e-2]) * np.linalg.norm(C))
    d = (RHO - np.linalg.norm(C)) * 0.999 * (n @ _unit(-C))
    r, v0, v1, v2, set_depth = ball_segment_reach(tuple(C), RHO, tuple(u), math.cos(alpha), n[0], n[1], n[2], d, d)
    assert set_depth <= RHO - np.linalg.norm(C)
    if r > d:
        z = _cap_points(rng, n, d, r)
        assert (np.linalg.norm(z - C, axis=1) <= RHO + 1e-12).all()
        assert (z @ u >= u @ C + RHO * math.cos(alpha) - 1e-12).all()


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
