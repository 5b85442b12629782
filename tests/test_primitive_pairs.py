"""Closed-form queries between spheres and capsules, and between a box and a sphere
(spq.kernels.primitive_pairs), against oracles that share none of their code: scipy's bounded least
squares for the cores' distance, and coal's own primitive distances."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import lsq_linear
from scipy.spatial.transform import Rotation

import spq


def _pose(rot, t):
    T = np.eye(4)
    T[:3, :3] = rot
    T[:3, 3] = t
    return T


def _core(shape):
    """(kind, half length or half extents, margin) of a primitive's core in its own frame."""
    if isinstance(shape, spq.Sphere):
        return "segment", 0.0, shape.radius
    if isinstance(shape, spq.Capsule):
        return "segment", shape.half_length, shape.radius
    return "box", shape.half_extents, 0.0


def core_distance(A, pose_a, B, pose_b):
    """The cores' distance in the world: min |x_a - x_b| over the cores' points, as a bounded linear
    least-squares problem in the cores' own coordinates (scipy's BVLS)."""
    columns, lo, hi = [], [], []
    offset = pose_b[:3, 3] - pose_a[:3, 3]
    for sign, shape, T in ((1.0, A, pose_a), (-1.0, B, pose_b)):
        kind, h, _ = _core(shape)
        axes = [2] if kind == "segment" else [0, 1, 2]
        bounds = [h] if kind == "segment" else list(h)
        for axis, half in zip(axes, bounds):
            if half > 0.0:
                columns.append(sign * T[:3, axis])
                lo.append(-half)
                hi.append(half)
    if not columns:
        return float(np.linalg.norm(offset))
    M = np.column_stack(columns)
    sol = lsq_linear(M, offset, bounds=(lo, hi), method="bvls", tol=1e-15)
    return float(np.linalg.norm(M @ sol.x - offset))


def _margins(A, B):
    return _core(A)[2] + _core(B)[2]


def _primitive(kind, draw):
    if kind == "sphere":
        return spq.Sphere(draw(st.floats(0.01, 0.3)))
    if kind == "capsule":
        return spq.Capsule(draw(st.floats(0.01, 0.2)), draw(st.floats(0.01, 0.5)))
    return spq.Box(draw(st.floats(0.01, 0.4)), draw(st.floats(0.01, 0.4)), draw(st.floats(0.01, 0.4)))


KINDS = [("sphere", "sphere"), ("sphere", "capsule"), ("capsule", "sphere"), ("capsule", "capsule"),
         ("box", "sphere"), ("sphere", "box")]


@st.composite
def _pairs(draw):
    ka, kb = draw(st.sampled_from(KINDS))
    A, B = _primitive(ka, draw), _primitive(kb, draw)
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    pose_a = _pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-1, 1, 3))
    rot_b = Rotation.random(random_state=rng).as_matrix()
    if draw(st.booleans()):  # B's axis along A's, or nearly: parallel capsules
        tilt = draw(st.sampled_from([0.0, 1e-13, 1e-9, 1e-6, 1e-3]))
        rot_b = pose_a[:3, :3] @ Rotation.from_rotvec([tilt, 0.0, 0.0]).as_matrix()
    pose_b = _pose(rot_b, pose_a[:3, 3] + rng.uniform(-1, 1, 3) * draw(st.sampled_from([0.05, 0.3, 1.0])))
    return A, B, pose_a, pose_b


@settings(max_examples=400, deadline=None)
@given(case=_pairs(), signed=st.booleans())
def test_the_closed_forms_meet_the_least_squares_oracle(case, signed):
    """Distance, bounds, witness points and normal, unsigned and signed, on random poses with parallel
    and nearly parallel capsules among them: the distance within 1e-9 m of the oracle's cores'
    distance less the margins (exact while the cores are apart), the oracle inside the bounds, the
    witness points on the bodies' surfaces (each the other's distance from its own core) and their
    difference the distance along the normal."""
    A, B, pose_a, pose_b = case
    core = core_distance(A, pose_a, B, pose_b)
    r = spq.distance(A, B, pose_a, pose_b, signed=signed)
    sd = core - _margins(A, B)
    assert r.status != "failed"
    if core < 1e-6:  # the cores meet: the general path's answer, checked elsewhere
        return
    want = sd if signed else max(sd, 0.0)
    assert abs(r.distance - want) <= 1e-9, (r, want)
    assert r.lower_bound - 1e-12 <= want <= r.upper_bound + 1e-12, (r, want)
    if not signed and sd < -1e-10:
        assert r.status == "overlapping" and np.isnan(r.point_a).all()
        return
    assert np.linalg.norm(r.normal) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(r.point_b - r.point_a, sd * r.normal, atol=1e-9)
    for point, shape, T in ((r.point_a, A, pose_a), (r.point_b, B, pose_b)):
        # the point's distance from the core is the margin: the point is on the body's surface
        local = np.linalg.solve(T, np.append(point, 1.0))[:3]
        kind, h, margin = _core(shape)
        nearest = np.array([0.0, 0.0, np.clip(local[2], -h, h)]) if kind == "segment" else np.clip(local, -h, h)
        assert np.linalg.norm(local - nearest) == pytest.approx(margin, abs=1e-9)


def test_coal_agrees_on_random_poses():
    """coal's own primitive distances (an external engine) on 3,000 random poses of each kind pair,
    the separated ones: within 1e-7 m."""
    import coal  # a dependency of spq's tests: its absence fails the test
    rng = np.random.default_rng(3)
    spq_shapes = {"sphere": spq.Sphere(0.08), "capsule": spq.Capsule(0.05, 0.2), "box": spq.Box(0.1, 0.05, 0.15)}
    coal_shapes = {"sphere": coal.Sphere(0.08), "capsule": coal.Capsule(0.05, 0.4), "box": coal.Box(0.2, 0.1, 0.3)}
    for ka, kb in KINDS:
        pa = np.stack([_pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-0.5, 0.5, 3))
                       for _ in range(3000)])
        pb = np.stack([_pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-0.5, 0.5, 3))
                       for _ in range(3000)])
        r = spq.distances(spq_shapes[ka], spq_shapes[kb], pa, pb)
        judged = 0
        for i in np.flatnonzero(r.status == "separated"):
            req, res = coal.DistanceRequest(), coal.DistanceResult()
            d = coal.distance(coal_shapes[ka], coal.Transform3s(pa[i, :3, :3], pa[i, :3, 3]),
                              coal_shapes[kb], coal.Transform3s(pb[i, :3, :3], pb[i, :3, 3]), req, res)
            assert abs(r.distance[i] - d) <= 1e-7, (ka, kb, i, r.distance[i], d)
            judged += 1
        assert judged > 1500, (ka, kb, judged)


def test_crossing_capsules_go_to_the_general_path():
    """Two capsules whose segments cross: the cores meet, so the closed form leaves the pair to the
    descent and its EPA; the depth is the sum of the radii (the segments' difference is flat)."""
    cap = spq.Capsule(0.05, 0.3)
    across = Rotation.from_euler("x", 90, degrees=True).as_matrix()
    r = spq.distance(cap, cap, np.eye(4), _pose(across, (0.0, 0.0, 0.1)), signed=True)
    assert r.status == "overlapping"
    assert r.distance == pytest.approx(-0.1, abs=1e-9)


def test_a_sphere_centred_inside_a_box_goes_to_the_general_path():
    """A sphere whose centre is inside a box: depth = the radius plus the centre's least distance to a
    face, along that face's normal."""
    box, ball = spq.Box(0.3, 0.2, 0.1), spq.Sphere(0.05)
    r = spq.distance(box, ball, np.eye(4), _pose(np.eye(3), (0.1, 0.05, 0.07)), signed=True)
    assert r.distance == pytest.approx(-(0.05 + 0.03), abs=1e-9)
    np.testing.assert_allclose(np.abs(r.normal), [0, 0, 1], atol=1e-9)


def test_nearly_touching_cores_keep_their_normal():
    """Two capsules whose segments pass 1e-8 m apart, crossing: the closed form's normal is the
    segments' common perpendicular, and the depth is the radii less that gap."""
    cap = spq.Capsule(0.05, 0.3)
    across = Rotation.from_euler("x", 90, degrees=True).as_matrix()
    for gap in (1e-8, 1e-6, 1e-3):
        r = spq.distance(cap, cap, np.eye(4), _pose(across, (gap, 0.0, 0.1)), signed=True)
        assert r.distance == pytest.approx(gap - 0.1, abs=1e-12)
        np.testing.assert_allclose(r.normal, [1, 0, 0], atol=1e-6)


def test_the_closed_form_answers_wherever_the_cores_are_apart():
    """The kernel itself, called directly: on random poses (axes at random, and exactly parallel) whose
    cores are at least 1e-6 m apart it closes its bounds (it does not hand the pair to the descent),
    and the public call's answer is its answer, bit for bit."""
    from numba import njit

    from spq.kernels.batch import relative_pose
    from spq.kernels.gjk import OUT_DISTANCE, OUT_SIZE
    from spq.kernels.primitive_pairs import primitive_query

    @njit
    def closed(kA, mA, fA, kB, mB, fB, TA, TB, signed, out):
        R, t = np.empty((3, 3)), np.empty(3)
        relative_pose(TA, TB, R, t)  # B in A's frame, as the entry points make it
        no_ints = np.zeros(1, dtype=np.int32)
        return primitive_query((kA, mA, fA, no_ints, kB, mB, fB, no_ints, R, t), (1e-10, 1e-10, 100), signed,
                               np.zeros(3), out)

    rng = np.random.default_rng(8)
    shapes = [spq.Sphere(0.05), spq.Capsule(0.03, 0.2), spq.Capsule(0.06, 0.05), spq.Box(0.1, 0.04, 0.2)]
    answered = 0
    for _ in range(3000):
        A, B = shapes[rng.integers(4)], shapes[rng.integers(3)]
        if isinstance(A, spq.Box) and isinstance(B, spq.Capsule):
            continue
        if rng.random() < 0.5 and isinstance(B, spq.Box):
            A, B = B, A
        pose_a = _pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-1, 1, 3))
        rot_b = pose_a[:3, :3] if rng.random() < 0.2 else Rotation.random(random_state=rng).as_matrix()
        pose_b = _pose(rot_b, pose_a[:3, 3] + rng.uniform(-0.4, 0.4, 3))
        core = core_distance(A, pose_a, B, pose_b)
        if core < 1e-6:
            continue
        ka, kb = A.kernel_data(), B.kernel_data()
        signed = bool(rng.integers(2))
        out = np.zeros(OUT_SIZE)
        status = closed(ka.kind, ka.margin, ka.fdata, kb.kind, kb.margin, kb.fdata, pose_a, pose_b, signed, out)
        assert status >= 0, (A, B, pose_a, pose_b)
        sd = core - _margins(A, B)
        assert abs(out[OUT_DISTANCE] - (sd if signed else max(sd, 0.0))) <= 1e-9, (A, B, out[OUT_DISTANCE], sd)
        # the public call's answer is the kernel's (the world's witness points are A's frame's moved)
        assert spq.distance(A, B, pose_a, pose_b, signed=signed).distance == out[OUT_DISTANCE]
        answered += 1
    assert answered > 2000
