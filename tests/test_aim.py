"""A cold query's first direction: the line from A's aim point to B's."""

import numpy as np
from scipy.spatial.transform import Rotation

import spq
from spq.kernels import batch as kb
from spq.shapes.polyhedron import Polyhedron
from spq.shapes.primitives import Capsule, Sphere


def _random_poses(rng, n, reach):
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    poses[:, :3, :3] = Rotation.random(n, random_state=rng).as_matrix()
    poses[:, :3, 3] = rng.uniform(-reach, reach, (n, 3))
    return poses


def _bar(rng, offset):
    """A hull of points about a bar 0.5 m long along x, its middle at offset from its frame's origin."""
    pts = rng.normal(size=(300, 3)) * [0.15, 0.03, 0.03]
    return Polyhedron.from_points(pts + offset)


def test_hulls_and_stp_bvs_aim_from_the_middle_of_their_box():
    rng = np.random.default_rng(2)
    hull = _bar(rng, [0.4, -0.1, 0.2])
    stp = spq.STPBV.from_points(hull.vertices, 0.005, 2.0)
    for shape, points in ((hull, hull.vertices), (stp, stp.topology.vertices)):
        assert np.allclose(shape.aim_point(), 0.5 * (points.min(axis=0) + points.max(axis=0)))
    assert np.array_equal(Sphere(0.2).aim_point(), np.zeros(3))
    assert np.array_equal(Capsule(0.1, 0.3).aim_point(), np.zeros(3))
    for A, B in ((hull, stp), (stp, Capsule(0.1, 0.4)), (Sphere(0.2), hull)):
        floats = spq.Pair(A, B)._floats
        assert np.array_equal(floats[kb.F_CENTRES:kb.F_CENTRES + 3], A.aim_point())
        assert np.array_equal(floats[kb.F_CENTRES + 3:kb.F_DIR], B.aim_point())


def test_a_hull_far_from_its_origin_takes_no_more_steps_than_one_about_it():
    """The same geometric problems, once with the hulls about their frames' origins and once 1 m off:
    with the aim at their middles the GJK's steps are those of the centred hulls (from the origin
    they were 9% more), and the distances agree within the tolerance."""
    rng = np.random.default_rng(4)
    centred = _bar(rng, [0.0, 0.0, 0.0])
    moved = Polyhedron.from_points(centred.vertices + [1.0, 0.0, 0.0])
    poses_a, poses_b = _random_poses(rng, 4000, 0.4), _random_poses(rng, 4000, 0.4)
    back = np.eye(4)
    back[0, 3] = -1.0  # the moved hull's frame placed so that its points land where the centred ones do
    near = spq.Pair(centred, centred).distances(poses_a, poses_b)
    far = spq.Pair(moved, moved).distances(poses_a @ back, poses_b @ back)
    from_origin = spq.Pair(moved, moved)
    from_origin._floats[kb.F_CENTRES:kb.F_DIR] = 0.0
    old = from_origin.distances(poses_a @ back, poses_b @ back)
    assert np.mean(far.iterations) <= 1.02 * np.mean(near.iterations)
    assert np.mean(old.iterations) >= 1.05 * np.mean(far.iterations)
    assert np.allclose(far.distance, near.distance, rtol=0.0, atol=1e-9)
