"""Pose suites hit their distance buckets, are seeded, and use proper rotations."""

from __future__ import annotations

import numpy as np
import pytest

from datasets import load_object
from harness.references.minkowski import reference_distance
from harness.workloads.poses import BUCKETS, PoseSuite, body_size, bucket_suite, pose_matrix, random_poses

# Separated buckets must equal their target to 1e-12 relative; at the closest bucket (1e-4 L, ~2e-5 m
# for a robot link) that is below the rounding of coordinates of size L (1 ulp of 0.2 m = 2.8e-17 m
# = 1.4e-12 of the target), so a few ulps of L are allowed on top.
REL_TOL = 1e-12
ULPS_OF_L = 4e-15


def assert_rigid(poses):
    poses = np.asarray(poses)
    rot = poses[:, :3, :3]
    np.testing.assert_allclose(np.einsum("nji,njk->nik", rot, rot), np.broadcast_to(np.eye(3), rot.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-12)
    np.testing.assert_array_equal(poses[:, 3], np.broadcast_to([0.0, 0.0, 0.0, 1.0], (len(poses), 4)))


@pytest.fixture(scope="module")
def suite():
    a, b = load_object("random_hull_50"), load_object("random_hull_200")
    return bucket_suite(a, b, 4, seed=3)


@pytest.fixture(scope="module")
def link_suite():
    link = load_object("kuka_link_4")
    return bucket_suite(link, link, 2, seed=0)


def check_buckets(s: PoseSuite):
    L = s.scale
    assert len(s) % len(BUCKETS) == 0
    for name, rel in BUCKETS.items():
        sel = s.bucket == name
        assert sel.any()
        target = s.target[sel]
        np.testing.assert_array_equal(target, rel * L)
        signed = s.ref_signed[sel]
        if rel > 0:
            assert (s.ref_status[sel] == "separated").all(), name
            assert np.all(np.abs(signed - target) <= REL_TOL * target + ULPS_OF_L * L), (name, signed - target)
            np.testing.assert_array_equal(s.ref_distance[sel], signed)
        elif rel == 0:
            assert (s.ref_status[sel] == "touching").all()
            assert np.all(np.abs(signed) <= 1e-12)
        else:
            assert (s.ref_status[sel] == "overlapping").all(), name
            assert np.all(signed < 0) and np.all(s.ref_distance[sel] == 0)
            # pushed |target| past contact along the normal: the true depth is at most that
            assert np.all(-signed <= -target * (1 + 1e-9) + ULPS_OF_L * L)
            assert np.all(-signed >= 0.05 * -target)
    gap = np.linalg.norm(s.ref_point_b - s.ref_point_a, axis=1)
    np.testing.assert_allclose(gap, np.abs(s.ref_signed), atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(s.ref_normal, axis=1), 1.0, atol=1e-12)
    assert_rigid(s.pose_a)
    assert_rigid(s.pose_b)


def test_buckets_hit_targets(suite):
    check_buckets(suite)
    assert suite.scale == pytest.approx(body_size(load_object("random_hull_50"), load_object("random_hull_200")))
    assert suite.pair_name == "random_hull_50|random_hull_200"


def test_buckets_hit_targets_robot_link(link_suite):
    check_buckets(link_suite)


def test_stored_reference_matches_final_poses(suite):
    a, b = load_object("random_hull_50"), load_object("random_hull_200")
    for k in range(0, len(suite), 5):
        res = reference_distance(a, b, suite.pose_a[k], suite.pose_b[k])
        assert res.signed_distance == pytest.approx(suite.ref_signed[k], abs=1e-15)
        assert res.status == suite.ref_status[k] or abs(res.signed_distance) <= 1e-12


def test_seeded_determinism():
    a = load_object("random_hull_50")
    s1 = bucket_suite(a, a, 1, seed=7, buckets=["close-1e-2", "overlap-1e-2"])
    s2 = bucket_suite(a, a, 1, seed=7, buckets=["close-1e-2", "overlap-1e-2"])
    s3 = bucket_suite(a, a, 1, seed=8, buckets=["close-1e-2", "overlap-1e-2"])
    for f in ("pose_a", "pose_b", "ref_signed", "ref_point_a", "bucket", "ref_status"):
        np.testing.assert_array_equal(getattr(s1, f), getattr(s2, f))
    assert not np.array_equal(s1.pose_a, s3.pose_a)
    pa1, pb1 = random_poses(5, seed=1)
    pa2, pb2 = random_poses(5, seed=1)
    np.testing.assert_array_equal(pa1, pa2)
    np.testing.assert_array_equal(pb1, pb2)
    assert not np.array_equal(pa1, random_poses(5, seed=2)[0])


def test_random_poses_are_uniform_rigid_transforms():
    pa, pb = random_poses(3000, seed=0, translation_range=0.25)
    assert pa.shape == pb.shape == (3000, 4, 4)
    assert_rigid(pa)
    assert_rigid(pb)
    t = np.concatenate([pa[:, :3, 3], pb[:, :3, 3]])
    assert np.abs(t).max() <= 0.25 and np.abs(t).max() > 0.24
    # uniform on SO(3): E[R] = 0 and the angle density (1 - cos w) / pi gives E[cos w] = -1/2
    rot = np.concatenate([pa[:, :3, :3], pb[:, :3, :3]])
    assert np.abs(rot.mean(axis=0)).max() < 0.05
    cos_w = (np.trace(rot, axis1=1, axis2=2) - 1) / 2
    assert cos_w.mean() == pytest.approx(-0.5, abs=0.03)


def test_bucket_selection_and_roundtrip(tmp_path, suite):
    a = load_object("random_hull_50")
    s = bucket_suite(a, a, 2, seed=1, buckets={"custom": 0.3, "deep": -0.05})
    assert list(s.bucket) == ["custom", "custom", "deep", "deep"]
    assert (s.ref_status == np.array(["separated", "separated", "overlapping", "overlapping"])).all()
    empty = bucket_suite(a, a, 0, seed=1)
    assert len(empty) == 0 and empty.pose_a.shape == (0, 4, 4)
    sub = suite.bucket_of("touching")
    assert len(sub) == 4 and (sub.bucket == "touching").all()
    path = tmp_path / "suite.npz"
    suite.save(path)
    back = PoseSuite.load(path)
    for f in ("bucket", "pose_a", "pose_b", "target", "ref_signed", "ref_point_b", "ref_status", "ref_normal"):
        np.testing.assert_array_equal(getattr(back, f), getattr(suite, f))
    assert back.seed == suite.seed and back.pair_name == suite.pair_name and back.scale == suite.scale


def test_bad_input():
    a = load_object("random_hull_50")
    with pytest.raises(ValueError, match="unknown bucket"):
        bucket_suite(a, a, 1, seed=0, buckets=["nope"])
    with pytest.raises(ValueError, match="n_per_bucket"):
        bucket_suite(a, a, -1, seed=0)
    with pytest.raises(ValueError, match="Polyhedron"):
        bucket_suite(a.vertices, a, 1, seed=0)
    with pytest.raises(ValueError, match="translation_range"):
        random_poses(3, seed=0, translation_range=-1.0)
    with pytest.raises(ValueError):
        pose_matrix(np.eye(3), np.zeros(2))
