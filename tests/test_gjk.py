"""GJK distance: closed-form cases, the independent Minkowski-hull reference, statuses, bad input."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import spq
from harness.references.minkowski import reference_distance


def pose(rot=None, t=(0, 0, 0)):
    T = np.eye(4)
    if rot is not None:
        T[:3, :3] = rot
    T[:3, 3] = t
    return T


def random_pose(rng, spread=0.3):
    return pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-spread, spread, 3))


def hull(seed, n=60, scale=(0.2, 0.15, 0.1)):
    return spq.Polyhedron.from_points(np.random.default_rng(seed).normal(size=(n, 3)) * scale)


# --- closed forms ---------------------------------------------------------------------------
def test_box_box_face_gap():
    r = spq.distance(spq.Box(0.5, 0.5, 0.5), spq.Box(0.5, 0.5, 0.5), pose(), pose(t=(1.3, 0.2, -0.1)))
    assert r.status == "separated"
    assert r.distance == pytest.approx(0.3, abs=1e-14)
    np.testing.assert_allclose(r.normal, [1, 0, 0], atol=1e-14)
    assert r.point_a[0] == pytest.approx(0.5) and r.point_b[0] == pytest.approx(0.8)


def test_box_box_corner_to_corner():
    r = spq.distance(spq.Box(0.5, 0.5, 0.5), spq.Box(0.5, 0.5, 0.5), pose(), pose(t=(1.2, 1.2, 1.2)))
    assert r.distance == pytest.approx(np.sqrt(3) * 0.2, abs=1e-14)
    np.testing.assert_allclose(r.point_a, [0.5, 0.5, 0.5], atol=1e-14)


def test_the_fcl_progress_stop_case_gives_exactly_three():
    # two boxes with a 3.0 gap: a progress-based stop has reported 3.16 here (NOTES section 5)
    a = spq.Box.from_size(1, 1, 1)
    b = spq.Box.from_size(2, 2, 2)
    rot = Rotation.from_euler("z", 45, degrees=True).as_matrix()
    r = spq.distance(a, b, pose(), pose(rot, (0.5 + 3.0 + np.sqrt(2), 0, 0)))
    assert r.distance == pytest.approx(3.0, abs=1e-12)


def test_spheres_and_capsules_use_their_radii():
    s = spq.Sphere(0.2)
    r = spq.distance(s, spq.Sphere(0.3), pose(t=(1, 2, 3)), pose(t=(1, 2, 4)))
    assert r.distance == pytest.approx(0.5, abs=1e-14)
    np.testing.assert_allclose(r.point_a, [1, 2, 3.2], atol=1e-14)
    np.testing.assert_allclose(r.point_b, [1, 2, 3.7], atol=1e-14)
    cap = spq.Capsule(0.1, 0.5)  # axis z, segment from -0.5 to 0.5
    r = spq.distance(cap, spq.Sphere(0.1), pose(), pose(t=(1.0, 0, 0.3)))
    assert r.distance == pytest.approx(0.8, abs=1e-14)
    assert spq.distance(cap, spq.Sphere(0.1), pose(), pose(t=(0, 0, 0.75))).distance == pytest.approx(0.05, abs=1e-14)
    r = spq.distance(cap, spq.Sphere(0.1), pose(), pose(t=(0, 0, 0.65)))
    assert r.status == "overlapping" and r.distance == 0.0


def test_overlap_and_touching_statuses_on_boxes():
    a = spq.Box(0.5, 0.5, 0.5)
    for x, status in [(0.9, "overlapping"), (0.0, "overlapping"), (1.0 - 1e-8, "overlapping"),
                      (1.0, "touching"), (1.0 + 1e-8, "separated")]:
        r = spq.distance(a, a, pose(), pose(t=(x, 0, 0)))
        assert r.status == status, x
        if status == "overlapping":
            assert r.distance == 0.0 and np.isnan(r.point_a).all()


# --- the independent reference --------------------------------------------------------------
@pytest.mark.parametrize("seed", range(6))
def test_random_hulls_match_the_minkowski_reference(seed):
    rng = np.random.default_rng(seed)
    a, b = hull(seed), hull(seed + 100, n=200)
    for _ in range(40):
        pa, pb = random_pose(rng), random_pose(rng)
        ref = reference_distance(a, b, pa, pb)
        r = spq.distance(a, b, pa, pb)
        if ref.status == "separated" and ref.distance > 1e-9:
            assert r.status == "separated"
            assert abs(r.distance - ref.distance) <= 1e-9
            assert r.lower_bound <= ref.distance + 1e-12
            assert abs(np.linalg.norm(r.point_b - r.point_a) - r.distance) <= 1e-12
            # witness points on the surfaces, in each body's own frame
            la = np.linalg.solve(pa, np.r_[r.point_a, 1])[:3]
            lb = np.linalg.solve(pb, np.r_[r.point_b, 1])[:3]
            assert abs(a.signed_distance_to_surface(la)[0]) <= 1e-9
            assert abs(b.signed_distance_to_surface(lb)[0]) <= 1e-9
        elif ref.status == "overlapping" and ref.depth > 1e-9:
            assert r.status == "overlapping"


@pytest.mark.parametrize("kind", ["polyhedron", "box"])
def test_near_touching_boxes_are_certified_not_failed(kind):
    """Unit boxes randomly rotated and placed 1e-9 to 1e-7 m apart along the exact separation normal
    (the stability suite's touching family): the descent's direction is then off D's normal by about
    eps / d, and a stall used to end 2% to 7% of these FAILED with the right distance. The facet's (or
    edge's) own normal certifies them; the exact reference's distance lies within the bounds (to
    rounding) and the status is 'separated'."""
    from harness.suites.stability.hard_cases import box, place
    from harness.workloads.poses import random_rotations
    unit = box(1, 1, 1)
    shape = unit if kind == "polyhedron" else spq.Box(0.5, 0.5, 0.5)
    rng = np.random.default_rng(1)
    for d in (1e-9, 1e-8, 1e-7):
        for _ in range(40):
            rot = random_rotations(2, rng)
            u = rng.normal(size=3)
            pa, pb = place(unit, unit, rot[0], rot[1], np.zeros(3), u / np.linalg.norm(u), d)
            ref = reference_distance(unit, unit, pa, pb).distance
            for signed in (False, True):
                r = spq.distance(shape, shape, pa, pb, signed=signed)
                assert r.status == "separated", (d, signed, r)
                assert r.lower_bound - 1e-14 <= ref <= r.upper_bound + 1e-14
                assert r.upper_bound - r.lower_bound <= 1e-10 + 1e-10 * ref


def _box_surface_point(rng, half, where):
    """A point on a box's surface (its frame) and an outward unit normal there: inside a face, or on an
    edge with the normal strictly inside the edge's wedge, so the point is the box's nearest to any
    point along the normal."""
    p = rng.uniform(-0.8, 0.8, 3) * half
    n = np.zeros(3)
    axes = rng.permutation(3)
    signs = rng.choice([-1.0, 1.0], 3)
    p[axes[0]], n[axes[0]] = signs[0] * half[axes[0]], signs[0]
    if where == "edge":
        w = rng.uniform(0.1, 0.9)
        p[axes[1]], n[axes[0]], n[axes[1]] = signs[1] * half[axes[1]], signs[0] * w, signs[1] * (1 - w)
    return p, n / np.linalg.norm(n)


@pytest.mark.parametrize("core", ["sphere", "capsule"])
def test_margin_bodies_whose_cores_nearly_touch_a_box_are_certified(core):
    """A sphere's centre, or a capsule's segment lying across the normal, placed 1e-9 to 1e-7 m off a
    box's face or edge, queried signed: the overlap's depth is the margin less the cores' distance, so
    the cores' descent stalls near touching as two boxes' does, and the facet's normal bounds it,
    with the point's or the segment's part of the facet (facet_bound's POINT and SEGMENT kinds).
    Without the point's part, 20 of 90 sphere-on-edge queries ended FAILED; the capsule's stalls
    reach the segment's part too, but the EPA that follows a stall would also have closed them. The
    box's nearest point is the placed one by construction, so the signed distance is d - rho."""
    rng = np.random.default_rng(5)
    half, rho = np.array([0.5, 0.3, 0.4]), 0.05
    box = spq.Box(*half)
    other = spq.Sphere(rho) if core == "sphere" else spq.Capsule(rho, 0.4)
    for where in ("face", "edge"):
        for d in (1e-9, 1e-8, 1e-7):
            for _ in range(40):
                g = pose(Rotation.random(random_state=rng).as_matrix(), rng.uniform(-1, 1, 3))
                p, n = _box_surface_point(rng, half, where)
                # the capsule's axis (its z) at a random direction across n, so it crosses an edge
                t = np.cross(n, rng.normal(size=3))
                t /= np.linalg.norm(t)
                c = pose(np.column_stack([n, np.cross(t, n), t]), p + d * n)
                r = spq.distance(box, other, g, g @ c, signed=True)
                ref = d - rho
                assert r.status == "overlapping", (where, d, r)
                assert r.lower_bound - 1e-14 <= ref <= r.upper_bound + 1e-14, (where, d, r)
                assert r.upper_bound - r.lower_bound <= 1e-10 + 1e-10 * abs(ref)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), far=st.sampled_from([0.0, 1e2, 1e4]))
def test_distance_is_invariant_to_a_common_rigid_motion(seed, far):
    """Moving both bodies by one rigid motion (even 1e4 m away) leaves the distance unchanged."""
    rng = np.random.default_rng(seed)
    a, b = hull(seed % 7), hull(seed % 5 + 50)
    pa, pb = random_pose(rng), random_pose(rng)
    g = pose(Rotation.random(random_state=rng).as_matrix(), rng.normal(size=3) * far)
    r0 = spq.distance(a, b, pa, pb)
    r1 = spq.distance(a, b, g @ pa, g @ pb)
    assert r0.status == r1.status or min(r0.distance, r1.distance) < 1e-9
    assert abs(r0.distance - r1.distance) <= 1e-9 + 1e-15 * far


def test_batch_pair_and_single_agree_and_batch_is_cold_by_default():
    rng = np.random.default_rng(7)
    a, b = hull(1, n=300), hull(2, n=300)
    pa = np.stack([random_pose(rng) for _ in range(300)])
    pb = np.stack([random_pose(rng) for _ in range(300)])
    batch = spq.distances(a, b, pa, pb)
    pair = spq.Pair(a, b)
    for i in range(0, 300, 7):
        single = spq.distance(a, b, pa[i], pb[i])
        warm = pair.distance(pa[i], pb[i])
        assert batch.status[i] == single.status == warm.status
        assert batch.distance[i] == single.distance  # same cold start: bit-identical
        assert abs(warm.distance - single.distance) <= 1e-9


def test_a_batch_keeps_its_values_after_later_batches():
    """BatchDistances' points and normals are views into the batch's own result array: later batches
    (one Pair's, the plain call's, on threads) must not write into them. Each kept point pair is
    checked against the exact Minkowski reference after every batch has run."""
    rng = np.random.default_rng(11)
    a, b = hull(5, n=60), hull(6, n=60)
    pa = np.stack([random_pose(rng) for _ in range(64)])
    pb = np.stack([random_pose(rng) for _ in range(64)])
    pair = spq.Pair(a, b)
    first = pair.distances(pa, pb, coherent=False)
    kept = (first.point_a.copy(), first.point_b.copy(), first.normal.copy(), first.status.copy())
    pair.distances(pb, pa, coherent=False)
    spq.distances(a, b, pa[::-1], pb, workers=2)
    np.testing.assert_array_equal(first.point_a, kept[0])
    np.testing.assert_array_equal(first.point_b, kept[1])
    np.testing.assert_array_equal(first.normal, kept[2])
    assert (first.status == kept[3]).all()
    checked = 0
    for i in range(64):
        ref = reference_distance(a, b, pa[i], pb[i]).distance
        if first.status[i] == "separated":
            assert abs(np.linalg.norm(first.point_b[i] - first.point_a[i]) - ref) <= 1e-9, i
            checked += 1
        else:
            assert ref <= 1e-9, (i, first.status[i], ref)
    assert checked >= 3, checked  # the oracle must have judged some kept points


def test_warm_start_along_a_smooth_path_takes_fewer_iterations():
    a, b = hull(3, n=300), hull(4, n=300)
    n = 400
    angles = np.linspace(0, 1.0, n)
    pb = np.stack([pose(Rotation.from_rotvec([0, 0, th]).as_matrix(), (0.6, 0.1 * th, 0)) for th in angles])
    pa = np.eye(4)
    cold = spq.distances(a, b, pa, pb, coherent=False)
    warm = spq.distances(a, b, pa, pb, coherent=True)
    np.testing.assert_allclose(warm.distance, cold.distance, atol=1e-9)
    assert warm.iterations.mean() < cold.iterations.mean()


def test_is_curved_names_exactly_the_kinds_with_curved_faces():
    """descend stops on its support points' own gap where a side is curved (gjk.is_curved) or its
    tolerance is loose, and skips that test between flat sides at a tight one, whose simplex point
    reaches the answer in finitely many steps.
    Judged on each kind's own support function, not on is_curved's list: over 2,000 directions a flat
    kind's supports are its few vertices, a curved kind's many points (an STP-BV's core, sharp at its
    points, still has its big spheres' and arcs' supports between them)."""
    from spq.kernels.dispatch import support_many
    from spq.kernels.gjk import is_curved
    from spq.kernels.kinds import STP_CORE

    rng = np.random.default_rng(0)
    directions = rng.normal(size=(2000, 3))
    points = rng.normal(size=(30, 3))
    hull_ = spq.Polyhedron.from_points(points / np.linalg.norm(points, axis=1)[:, None] * [0.08, 0.06, 0.1])
    stp = spq.STPBV.from_points(hull_.vertices, 0.005, 2.0)
    shapes = [hull_, spq.Box(0.1, 0.2, 0.3), spq.Sphere(0.1), spq.Capsule(0.05, 0.2), stp,
              spq.Superellipsoid(0.1, 0.07, 0.05, 0.5, 1.2)]
    cases = [(type(s).__name__, s.kernel_data()) for s in shapes]
    cases = [(name, k.kind, k.fdata, k.idata) for name, k in cases]
    cases.append(("STP-BV core", STP_CORE, stp.kernel_data().fdata, stp.kernel_data().idata))
    for name, kind, f, ix in cases:
        distinct = len(np.unique(support_many(kind, f, ix, directions).round(12), axis=0))
        assert is_curved(kind) == (distinct > 100), (name, kind, distinct)


# --- bad input ------------------------------------------------------------------------------
@pytest.mark.parametrize("bad, what", [
    (np.full((4, 4), np.nan), "NaN"),
    (np.diag([1.0, 1.0, 1.0, 2.0]), "bottom row"),
    (np.diag([2.0, 1.0, 1.0, 1.0]), "not a rotation"),
    (np.diag([-1.0, 1.0, 1.0, 1.0]), "not a rotation"),  # a reflection
    (np.eye(3), "4x4"),
])
def test_bad_poses_raise_value_error(bad, what):
    a = spq.Box(1, 1, 1)
    with pytest.raises(ValueError, match=what):
        spq.distance(a, a, bad, np.eye(4))
    with pytest.raises(ValueError, match=what):
        spq.distance(a, a, np.eye(4), bad)
    if bad.shape == (4, 4):
        batch = np.stack([np.eye(4), bad])
        with pytest.raises(ValueError, match=what):
            spq.distances(a, a, batch, np.eye(4))


def test_a_pose_of_another_shape_raises_once_the_machine_code_is_taken():
    """After the first call a pair calls its kernel's machine code with any float64 2-D array, which
    must refuse (not read past) any that is not a C-ordered 4x4, so the caller raises the shape error.
    Oracle: two unit-half-extent boxes 3 m apart along x are 1 m apart."""
    a = spq.Box(1, 1, 1)
    pair = spq.Pair(a, a)
    far = pose(t=(3.0, 0.0, 0.0))
    assert pair.distance(np.eye(4), far).distance == pytest.approx(1.0)
    assert spq.distance(a, a, np.eye(4), far).distance == pytest.approx(1.0)
    for bad in (np.eye(3), np.zeros((4, 5)), np.zeros((0, 4)), np.eye(8)[:4], np.eye(4).ravel(), np.eye(4)[None]):
        with pytest.raises(ValueError, match="4x4"):
            pair.distance(np.eye(4), bad)
        with pytest.raises(ValueError, match="4x4"):
            pair.cold_distance(bad, far)
        with pytest.raises(ValueError, match="4x4"):
            spq.distance(a, a, bad, far)
        with pytest.raises(ValueError, match="4x4"):
            spq.distance(a, a, np.eye(4), bad)
    assert spq.distance(a, a, np.eye(4), far).distance == pytest.approx(1.0)


@pytest.mark.parametrize("signed", [False, True])
def test_a_bad_pose_value_raises_on_the_machine_code_path_too(signed):
    """Once a pair calls its kernel's machine code directly, a 4x4 float64 pose with bad values comes
    back as a NaN distance with its code in the result array, which must still raise the pose's own
    error (naming the pose), and a good pose must still give a float distance. Oracle: two
    unit-half-extent boxes 3 m apart along x are 1 m apart."""
    a = spq.Box(1, 1, 1)
    pair = spq.Pair(a, a, signed=signed)
    far = pose(t=(3.0, 0.0, 0.0))
    calls = {"Pair.distance": pair.distance, "Pair.cold_distance": pair.cold_distance,
             "spq.distance": lambda pa, pb: spq.distance(a, a, pa, pb, signed=signed)}
    for call in calls.values():  # the first calls take the machine code
        call(np.eye(4), far)
    for name, call in calls.items():
        for bad, what in ((np.full((4, 4), np.nan), "NaN"), (np.diag([1.0, 1.0, 1.0, 2.0]), "bottom row"),
                          (np.diag([2.0, 1.0, 1.0, 1.0]), "not a rotation")):
            with pytest.raises(ValueError, match=f"pose_b .*{what}"):
                call(np.eye(4), bad)
            with pytest.raises(ValueError, match=f"pose_a .*{what}"):
                call(bad, far)
        result = call(np.eye(4), far)
        assert type(result.distance) is float, name
        assert result.distance == pytest.approx(1.0, abs=1e-12), name
        assert result.distance == result.upper_bound, name


def _first_pose_problem(T):
    """The oracle for the kernel's pose check: numpy's classification, tested in the kernel's order."""
    from spq.kernels.batch import POSE_BAD_BOTTOM_ROW, POSE_NOT_FINITE, POSE_NOT_ROTATION, POSE_OK
    from spq.validation import ROTATION_TOL
    if not np.isfinite(T).all():
        return POSE_NOT_FINITE
    if not np.array_equal(T[3], [0.0, 0.0, 0.0, 1.0]):
        return POSE_BAD_BOTTOM_ROW
    R = T[:3, :3]
    if np.abs(R.T @ R - np.eye(3)).max() > ROTATION_TOL or abs(np.linalg.det(R) - 1.0) > ROTATION_TOL:
        return POSE_NOT_ROTATION
    return POSE_OK


def test_the_kernels_pose_check_classifies_as_numpy_does():
    """The compiled pose check (every query's first step) gives the code of a pose's first problem.
    Oracle: numpy's classification of rotations with one entry made NaN or inf,
    a bottom row moved, the rotation scaled, sheared or reflected by twice or half the tolerance
    (away from the boundary, where the two sums' rounding could differ)."""
    from spq.kernels.batch import check_pose
    from spq.validation import ROTATION_TOL
    rng = np.random.default_rng(7)
    poses = []
    for rot in Rotation.random(60, random_state=8).as_matrix():
        T = pose(rot, rng.uniform(-5, 5, 3))
        poses.append(T)
        for value in (np.nan, np.inf, -np.inf):
            for r, c in ((0, 0), (2, 1), (1, 3), (3, 2), (2, 3)):
                bad = T.copy()
                bad[r, c] = value
                poses.append(bad)
        for c in range(4):
            bad = T.copy()
            bad[3, c] += 1e-12
            poses.append(bad)
        for k in (0.5, 2.0, -0.5, -2.0):
            scaled = T.copy()
            scaled[:3, rng.integers(3)] *= 1.0 + k * ROTATION_TOL
            sheared = T.copy()
            sheared[:3, 0] += k * ROTATION_TOL * T[:3, 1]
            poses += [scaled, sheared]
        reflected = T.copy()
        reflected[:3, 2] *= -1.0
        poses.append(reflected)
    codes = [check_pose(T) for T in poses]
    assert codes == [_first_pose_problem(T) for T in poses]
    assert len(set(codes)) == 4  # every code reached


@pytest.mark.parametrize("kwargs", [dict(tol=-1), dict(tol=np.nan), dict(tol=0, rel_tol=0), dict(max_iter=0)])
def test_bad_tolerances_raise_value_error(kwargs):
    with pytest.raises(ValueError):
        spq.distance(spq.Box(1, 1, 1), spq.Box(1, 1, 1), np.eye(4), np.eye(4), **kwargs)


def test_bad_shapes_and_primitive_sizes_raise_value_error():
    with pytest.raises(ValueError, match="spq shape"):
        spq.distance(np.zeros((4, 3)), spq.Box(1, 1, 1), np.eye(4), np.eye(4))
    for make in (lambda: spq.Sphere(0), lambda: spq.Box(1, -1, 1), lambda: spq.Capsule(np.nan, 1)):
        with pytest.raises(ValueError):
            make()


def test_iteration_cap_returns_a_status_not_a_wrong_number():
    """max_iter=1 stops the descent at once; the rescue of a stalled descent (the EPA from its simplex,
    32 steps per max_iter) may still settle the query. Whatever the status, the certified interval
    holds the exact reference, and a status other than 'failed' is right."""
    a, b = hull(5, n=300), hull(6, n=300)
    statuses = set()
    for t in [(0.9, 0.2, 0.1), (1.2, 0.2, 0.1), (1.5, 0.2, 0.1), (2.0, 0.3, 0.1)]:
        ref = reference_distance(a, b, np.eye(4), pose(t=t)).signed_distance
        r = spq.distance(a, b, np.eye(4), pose(t=t), max_iter=1)
        statuses.add(r.status)
        assert r.lower_bound - 1e-12 <= max(ref, 0.0) <= r.upper_bound + 1e-12
        if r.status == "overlapping":
            assert ref < 0.0
        elif r.status != "failed":
            assert ref > 0.0 and abs(r.distance - ref) < 1e-9
    assert "failed" in statuses  # the cap does bind somewhere


def test_distance_takes_the_shapes_first_and_the_old_order_warns_once(monkeypatch):
    """One order, shapes then poses, as distances() and Pair take them; spq 0.1's distance(A, pose_a, B,
    pose_b) gives the same answer with one DeprecationWarning per process."""
    import warnings

    import spq.query as sq

    monkeypatch.setitem(sq._OLD_ORDER, "warned", False)
    a, b = spq.Box(0.5, 0.5, 0.5), spq.Sphere(0.25)
    pa, pb = np.eye(4), np.eye(4)
    pb[:3, 3] = [1.5, 0.25, 0.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new order does not warn
        new = spq.distance(a, b, pa, pb)
        batch = spq.distances(a, b, pa[None], pb[None])
    assert new.distance == pytest.approx(0.75, abs=1e-12)  # the ball's centre 1 m from the box's face, less 0.25
    assert batch.distance[0] == new.distance
    with pytest.warns(DeprecationWarning, match=r"spq\.distance\(A, B, pose_a, pose_b\)"):
        old = spq.distance(a, pa, b, pb)
    assert old.distance == new.distance and np.array_equal(old.point_b, new.point_b)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per process
        assert spq.distance(a, pa, b, pb).distance == new.distance


def test_plain_call_answers_as_a_new_pair_whatever_came_before():
    """spq.distance keeps each thread's packing of a shape pair (spq.query.PLAIN_PAIRS) but starts every
    call cold: its answer equals a new Pair's bit for bit, after other poses, the other mode and a
    full cache; the oracle for the values is the exact reference."""
    import spq.query as sq

    a, b, c = hull(11), hull(12), spq.STPBV.from_points(hull(13).vertices, 0.01, 2.0)
    poses = [pose(rot=Rotation.from_rotvec([0.3 * k, -0.2, 0.1 * k]).as_matrix(), t=(0.1 * k - 0.2, 0.05, 0.0))
             for k in range(6)]
    nudged = [p.copy() for p in poses]
    for p in nudged:
        p[0, 3] += 1e-5  # a warm start would keep the last simplex here and differ in its iterations
    for k, pb in enumerate(q for pair in zip(poses, nudged) for q in pair):
        for signed in (False, True):
            for B in (b, c):
                got = spq.distance(a, B, np.eye(4), pb, signed=signed)
                new = spq.Pair(a, B, signed=signed).distance(np.eye(4), pb)
                assert np.array_equal(got._out, new._out, equal_nan=True)
        ref = reference_distance(a, b, np.eye(4), pb).signed_distance
        sd = spq.distance(a, b, np.eye(4), pb, signed=True)
        assert sd.lower_bound - 1e-9 <= ref <= sd.upper_bound + 1e-9
    for k in range(sq.PLAIN_PAIRS + 3):  # the cache stays bounded
        spq.distance(a, b, np.eye(4), poses[1], tol=1e-10 * (1 + k))
    assert len(sq._SCRATCH.pairs) <= sq.PLAIN_PAIRS


def test_a_pose_of_any_array_type_gives_the_answer_of_its_plain_copy():
    """Pair keeps the kernel's machine code for its own argument types and calls it without numba's
    type dispatch (spq.query._machine_code), which does not check them: every other kind of pose
    (transposed or sliced views, read-only, float32, Fortran order, lists) must reach it as a plain
    C float64 copy. The oracle: the same pose as a fresh C float64 array, on a new Pair, and the exact
    reference's distance within the bounds."""
    a, b = hull(21), hull(22)
    pb = pose(rot=Rotation.from_rotvec([0.4, -0.3, 0.2]).as_matrix(), t=(0.45, 0.1, -0.05))
    readonly = pb.copy()
    readonly.flags.writeable = False
    big = np.zeros((8, 8))
    big[::2, ::2] = pb
    variants = [pb.T.copy().T, np.asfortranarray(pb), readonly, pb.astype(np.float32), pb.tolist(), big[::2, ::2],
                np.broadcast_to(pb, (4, 4))]
    exact = reference_distance(a, b, np.eye(4), pb).signed_distance  # independent of spq's kernels
    for signed in (False, True):
        want = spq.Pair(a, b, signed=signed).distance(np.eye(4), np.array(pb, dtype=np.float64, order="C"))
        assert want.lower_bound - 1e-9 <= (exact if signed else max(exact, 0.0)) <= want.upper_bound + 1e-9
        f32 = spq.Pair(a, b, signed=signed).distance(np.eye(4), np.array(pb.astype(np.float32), dtype=np.float64))
        pair = spq.Pair(a, b, signed=signed)
        pair.cold_distance(np.eye(4), pb)  # the machine code is taken here, for plain arrays
        for k, v in enumerate(variants):
            expect = f32 if k == 3 else want
            got = pair.cold_distance(np.eye(4), v)
            assert np.array_equal(got._out, expect._out, equal_nan=True), k
            plain = spq.distance(a, b, v, np.eye(4), signed=signed)  # and as A's pose, on the plain call
            copy = spq.Pair(a, b, signed=signed).distance(np.array(v, dtype=np.float64, order="C"), np.eye(4))
            assert np.array_equal(plain._out, copy._out, equal_nan=True), k


def test_results_kept_across_calls_and_threads_keep_their_own_values():
    """Results kept over many per-call queries, made on two threads at once (each with its own
    scratch, spq.query._SCRATCH), must each hold their own query's answer: no per-call path may hand
    out a buffer that a later call writes over. The oracles: the batched call's fields, and the exact
    reference's distance within each result's bounds."""
    from concurrent.futures import ThreadPoolExecutor

    a, b = hull(31), hull(32)
    rng = np.random.default_rng(5)
    pa = np.stack([random_pose(rng, 0.0) for _ in range(24)])
    pb = np.stack([random_pose(rng, 0.5) for _ in range(24)])
    exact = [reference_distance(a, b, pa[i], pb[i]).signed_distance for i in range(len(pa))]

    def kept(signed):
        pair, path = spq.Pair(a, b, signed=signed), spq.Pair(a, b, signed=signed)
        return ([spq.distance(a, b, x, y, signed=signed) for x, y in zip(pa, pb)],
                [pair.cold_distance(x, y) for x, y in zip(pa, pb)],
                [path.distance(x, y) for x, y in zip(pa, pb)])

    with ThreadPoolExecutor(2) as pool:
        runs = {signed: pool.submit(kept, signed) for signed in (False, True)}
        runs = {signed: run.result() for signed, run in runs.items()}
    for signed, (plain, cold, path) in runs.items():
        batch = spq.distances(a, b, pa, pb, signed=signed)
        along = spq.Pair(a, b, signed=signed).distances(pa, pb, coherent=True)
        for ref, results in ((batch, plain), (batch, cold), (along, path)):
            for i, r in enumerate(results):
                assert r.status == ref.status[i] and r.iterations == ref.iterations[i], (signed, i)
                for field in ("distance", "point_a", "point_b", "normal", "lower_bound", "upper_bound"):
                    assert np.array_equal(getattr(r, field), getattr(ref, field)[i], equal_nan=True), (signed, i, field)
                value = exact[i] if signed else max(exact[i], 0.0)
                assert r.lower_bound - 1e-9 <= value <= r.upper_bound + 1e-9, (signed, i)
        assert len({r.distance for r in plain}) == len(plain) or not signed  # distinct poses, distinct answers
    assert 0 < sum(d < 0 for d in exact) < len(exact)  # both overlaps and separated poses


def test_the_plain_call_takes_another_pair_when_an_option_changes():
    """spq.distance reuses the last pair only for the very same shapes and option objects: a new
    tolerance, mode or shape gets its own packing (the answers are a new Pair's, bit for bit)."""
    a, b = hull(23), hull(24)
    pb = pose(rot=Rotation.from_rotvec([0.1, 0.2, 0.3]).as_matrix(), t=(0.2, 0.05, 0.0))
    exact = reference_distance(a, b, np.eye(4), pb).signed_distance  # independent of spq's kernels
    for kwargs in ({}, {"tol": 1e-3}, {"signed": True}, {"rel_tol": 1e-2, "max_iter": 3}, {}):
        got = spq.distance(a, b, np.eye(4), pb, **kwargs)
        new = spq.Pair(a, b, **kwargs).distance(np.eye(4), pb)
        assert np.array_equal(got._out, new._out, equal_nan=True), kwargs
        # bounds hold the exact value whatever the options (max_iter=3 may stop early, with looser bounds)
        value = exact if kwargs.get("signed") else max(exact, 0.0)
        assert got.lower_bound - 1e-9 <= value <= got.upper_bound + 1e-9, kwargs
    with pytest.raises(ValueError, match="signed must be True or False"):
        spq.distance(a, b, np.eye(4), pb, signed=1)  # equal to True, but not a bool: the check still runs


def test_per_call_and_batched_agree_bit_for_bit_on_every_kind():
    """The per-call kernel reads each shape from its packed array (KernelData.packed, spq.kernels.
    kinds.pack_shape) and the Pair's state from one array; the batched kernel reads the shapes' fdata
    and idata. Every kind against every kind, unsigned and signed, cold and along a path: the same
    answers, bit for bit, and the exact reference's distance within the bounds on the polytopes."""
    rng = np.random.default_rng(11)
    pts = rng.normal(size=(25, 3)) * 0.15
    shapes = {"box": spq.Box(0.05, 0.1, 0.15), "sphere": spq.Sphere(0.1), "capsule": spq.Capsule(0.05, 0.15),
              "pch": spq.Polyhedron.from_points(pts), "stp": spq.STPBV.from_points(pts, 0.02, 1.0),
              "cse": spq.Superellipsoid(0.1, 0.08, 0.05, 0.5, 0.7)}
    pa = np.stack([random_pose(rng, 0.0) for _ in range(6)])
    pb = np.stack([random_pose(rng, 0.25) for _ in range(6)])
    for a_name, A in shapes.items():
        for b_name, B in shapes.items():
            for signed in (False, True):
                cold = spq.distances(A, B, pa, pb, signed=signed)
                path = spq.Pair(A, B, signed=signed).distances(pa, pb, coherent=True)
                pair = spq.Pair(A, B, signed=signed)
                for i in range(len(pa)):
                    one = spq.distance(A, B, pa[i], pb[i], signed=signed)
                    step = pair.distance(pa[i], pb[i])
                    where = (a_name, b_name, signed, i)
                    assert one.distance == cold.distance[i] and np.array_equal(one.point_a, cold.point_a[i],
                                                                               equal_nan=True), where
                    assert step.distance == path.distance[i] and step.iterations == path.iterations[i], where
                    assert np.array_equal(step.normal, path.normal[i], equal_nan=True), where
                    if a_name == b_name == "pch":
                        exact = reference_distance(A, B, pa[i], pb[i]).signed_distance
                        value = exact if signed else max(exact, 0.0)
                        assert one.lower_bound - 1e-9 <= value <= one.upper_bound + 1e-9, where


def test_the_reported_bounds_hold_the_distance_on_every_kind():
    """lower_bound <= distance == upper_bound on every answer that did not fail, every kind against
    every kind, unsigned and signed, batched, per Pair and by the plain call. A descent's lower bound
    and the gap between its witness points are different sums, which rounding crossed by an ulp or two
    on 7% to 49% of the separated queries between polytopes, primitives and smooth bodies (by kind)
    before the entry points took the lesser. Between the polytopes, the exact reference (independent of
    spq's kernels) lies in each interval."""
    rng = np.random.default_rng(5)
    pts = rng.normal(size=(40, 3)) * (0.12, 0.08, 0.05)
    shapes = {"box": spq.Box(0.05, 0.08, 0.1), "sphere": spq.Sphere(0.06), "capsule": spq.Capsule(0.04, 0.1),
              "ellipsoid": spq.Ellipsoid(0.05, 0.07, 0.09), "pch": spq.Polyhedron.from_points(pts),
              "stp": spq.STPBV.from_points(pts, 0.005, 1.0), "cse": spq.Superellipsoid(0.05, 0.07, 0.09, 0.3, 0.5)}
    pa = np.stack([random_pose(rng, 0.0) for _ in range(2000)])
    pb = np.stack([random_pose(rng, 0.3) for _ in range(2000)])
    names = list(shapes)
    for i, a_name in enumerate(names):
        for b_name in names[i:]:
            A, B = shapes[a_name], shapes[b_name]
            for signed in (False, True):
                r = spq.distances(A, B, pa, pb, signed=signed)
                ok = r.status != "failed"
                where = (a_name, b_name, signed)
                assert ok.sum() == len(pa) and (r.status == "separated").sum() > 1000, where
                assert (r.lower_bound[ok] <= r.distance[ok]).all(), (where, np.max(r.lower_bound - r.distance))
                assert (r.distance[ok] == r.upper_bound[ok]).all(), where
                pair = spq.Pair(A, B, signed=signed)
                for k in range(0, len(pa), 97):
                    for q in (pair.distance(pa[k], pb[k]), spq.distance(A, B, pa[k], pb[k], signed=signed)):
                        assert q.lower_bound <= q.distance == q.upper_bound, (where, k)
                    if a_name == b_name == "pch":  # the interval, clamped, still holds the exact value
                        exact = reference_distance(A, B, pa[k], pb[k]).signed_distance
                        value = exact if signed else max(exact, 0.0)
                        assert r.lower_bound[k] - 1e-12 <= value <= r.upper_bound[k] + 1e-12, (where, k, value)


def test_a_shapes_arrays_are_views_of_its_packed_array():
    """A shape's fdata and idata are views of its packed array, which the per-call kernel reads: a
    change to one (an STP-BV's support method, set in idata) reaches a Pair made before it, whose
    answers then equal a new Pair's and the brute-force STP oracle's; and a packed array holds what
    was given, whatever its length."""
    from harness.references.stp_oracle import brute_force_support
    from spq.kernels.kinds import pack_shape
    for nf, ni in ((0, 0), (1, 1), (5, 2), (4, 7)):
        f, i = np.arange(nf) * 0.5, np.arange(ni, dtype=np.int32) - 3
        packed, fv, iv = pack_shape(f, i)
        assert np.array_equal(fv, f) and np.array_equal(iv, i) and iv.dtype == np.int32
        assert (nf == 0 or np.shares_memory(packed, fv)) and (ni == 0 or np.shares_memory(packed, iv))
    pts = np.random.default_rng(5).normal(size=(40, 3)) * 0.1
    stp = spq.STPBV.from_points(pts, 0.01, 1.0)
    kd = stp.kernel_data()
    assert np.shares_memory(kd.packed, kd.fdata) and np.shares_memory(kd.packed, kd.idata)
    pb = pose(rot=Rotation.from_rotvec([0.3, 0.1, -0.2]).as_matrix(), t=(0.6, 0.05, 0.1))
    old = spq.Pair(stp, stp)
    for method in ("naive", "march", "hull"):
        stp.method = method
        got = old.cold_distance(np.eye(4), pb)
        new = spq.Pair(stp, stp).cold_distance(np.eye(4), pb)
        assert np.array_equal(got._out, new._out, equal_nan=True), method
        # the oracle: the gap between the bodies along the returned normal, from brute-force supports
        # of the generating points (no topology, no kernel), is the distance
        n = got.normal
        h_a = n @ brute_force_support(pts, 0.01, 1.0, n)
        h_b = -n @ (pb[:3, :3] @ brute_force_support(pts, 0.01, 1.0, pb[:3, :3].T @ -n) + pb[:3, 3])
        assert got.status == "separated" and abs((-h_b - h_a) - got.distance) <= 1e-9, method
