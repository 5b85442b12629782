"""Signed distance (penetration depth) of spq: ``signed=True`` in distance, distances, Pair and Scene.

Oracles (never spq itself):

- harness.references.minkowski.MinkowskiReference: the exact signed distance of two polytopes from the hull of
  their Minkowski difference (scipy's Qhull), with its own witness points and normal;
- closed forms for primitives (spheres, capsules, axis-aligned boxes, containment);
- the hulls' own plane equations for "on the surface" checks;
- central finite differences of the reference's signed distance for gradients of overlaps.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import spq
from datasets import load_object
from harness.references.minkowski import MinkowskiReference, reference_distance
from harness.workloads.poses import bucket_suite, pose_matrix
from spq.kernels.gjk import OUT_DISTANCE, OUT_LOWER
from spq.scene import Scene

OVERLAP_BUCKETS = ["overlap-1e-4", "overlap-1e-3", "overlap-1e-2", "overlap-1e-1"]
DEPTH_TOL = 1e-9  # m: spq's depth against the exact reference (acceptance 1)
SURFACE_TOL = 1e-9  # m: witness points on their bodies' surfaces
RELATION_TOL = 1e-12  # m: point_b - point_a = distance * normal
PER_BUCKET = 40


def off_surface(poly: spq.Polyhedron, poses: np.ndarray, points: np.ndarray) -> np.ndarray:
    """|signed distance| of world points to the boundary of poly at each pose, from its planes."""
    local = np.einsum("nji,nj->ni", poses[:, :3, :3], points - poses[:, :3, 3])
    return np.abs(poly.signed_distance_to_surface(local))


@pytest.fixture(scope="module")
def links():
    return load_object("kuka_link_4"), load_object("kuka_link_2")


@pytest.fixture(scope="module")
def overlap_suite(links):
    a, b = links
    return bucket_suite(a, b, PER_BUCKET, seed=2611, buckets=OVERLAP_BUCKETS + ["touching", "close-1e-3"])


# ---------------------------------------------------------------- polytopes against the exact reference


def test_pch_depth_matches_the_exact_reference_in_every_overlap_bucket(links, overlap_suite):
    a, b = links
    s = overlap_suite
    r = spq.distances(a, b, s.pose_a, s.pose_b, signed=True)
    assert not (r.status == "failed").any()
    for bucket in OVERLAP_BUCKETS:
        m = s.bucket == bucket
        assert m.sum() == PER_BUCKET and (s.ref_signed[m] < 0).all()
        err = np.abs(r.distance[m] - s.ref_signed[m])
        assert err.max() <= DEPTH_TOL, (bucket, err.max())
        assert (r.status[m] == "overlapping").all()
    # the certificate holds on every pose, both signs
    assert (r.lower_bound <= s.ref_signed + 1e-15).all()
    assert (s.ref_signed <= r.upper_bound + 1e-15).all()
    assert (r.lower_bound <= r.distance).all() and (r.distance <= r.upper_bound).all()


def test_pch_witness_points_lie_on_the_surfaces_and_span_the_signed_distance(links, overlap_suite):
    a, b = links
    s = overlap_suite
    r = spq.distances(a, b, s.pose_a, s.pose_b, signed=True)
    assert off_surface(a, s.pose_a, r.point_a).max() <= SURFACE_TOL
    assert off_surface(b, s.pose_b, r.point_b).max() <= SURFACE_TOL
    gap = r.point_b - r.point_a - r.distance[:, None] * r.normal
    assert np.abs(gap).max() <= RELATION_TOL
    np.testing.assert_allclose(np.linalg.norm(r.normal, axis=1), 1.0, atol=1e-12)
    # the normal is the reference's direction of least penetration (unique on these random poses)
    deep = s.ref_signed < -1e-6
    cos = np.einsum("ij,ij->i", r.normal[deep], s.ref_normal[deep])
    assert cos.min() >= 1 - 1e-9


def test_single_queries_and_pairs_equal_the_batched_ones(links, overlap_suite):
    a, b = links
    s = overlap_suite
    batch = spq.distances(a, b, s.pose_a[:30], s.pose_b[:30], signed=True)
    pair = spq.Pair(a, b, signed=True)
    for i in range(30):
        one = spq.distance(a, b, s.pose_a[i], s.pose_b[i], signed=True)
        warm = pair.distance(s.pose_a[i], s.pose_b[i])
        assert abs(one.distance - batch.distance[i]) <= 1e-15
        assert abs(warm.distance - s.ref_signed[i]) <= DEPTH_TOL
        assert warm.lower_bound <= s.ref_signed[i] + 1e-15 <= warm.upper_bound + 2e-15


def test_unsigned_results_are_unchanged(links, overlap_suite):
    a, b = links
    s = overlap_suite
    plain = spq.distances(a, b, s.pose_a, s.pose_b)
    explicit = spq.distances(a, b, s.pose_a, s.pose_b, signed=False)
    for field in ("distance", "lower_bound", "point_a", "point_b", "normal", "iterations"):
        np.testing.assert_array_equal(getattr(plain, field), getattr(explicit, field))
    over = s.ref_signed < -1e-9
    assert (plain.status[over] == "overlapping").all() and (plain.distance[over] == 0).all()
    assert np.isnan(plain.point_a[over]).all()
    signed = spq.distances(a, b, s.pose_a, s.pose_b, signed=True)
    apart = s.ref_signed > 1e-9
    np.testing.assert_array_equal(signed.distance[apart], plain.distance[apart])


def test_random_poses_agree_with_the_reference_for_both_signs(links):
    a, b = links
    rng = np.random.default_rng(5)
    n = 300
    pa = np.stack([pose_matrix(R, rng.uniform(-0.05, 0.05, 3)) for R in Rotation.random(n, random_state=1).as_matrix()])
    pb = np.stack([pose_matrix(R, rng.uniform(-0.15, 0.15, 3)) for R in Rotation.random(n, random_state=2).as_matrix()])
    truth = np.array([reference_distance(a, b, pa[i], pb[i]).signed_distance for i in range(n)])
    assert (truth < 0).sum() > 100  # most of these overlap, many deeply
    r = spq.distances(a, b, pa, pb, signed=True)
    assert np.abs(r.distance - truth).max() <= DEPTH_TOL
    assert ((r.lower_bound <= truth + 1e-15) & (truth <= r.upper_bound + 1e-15)).all()


# ---------------------------------------------------------------- primitives: closed forms


def translate(x, y=0.0, z=0.0) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = x, y, z
    return pose


def rotated(pose, rotvec) -> np.ndarray:
    out = pose.copy()
    out[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    return out


def check_result(res, expected, tol=1e-9):
    assert res.status == ("overlapping" if expected < -1e-12 else res.status)
    assert abs(res.distance - expected) <= tol, (res.distance, expected)
    assert res.lower_bound <= expected + tol and expected <= res.upper_bound + tol
    assert np.abs(res.point_b - res.point_a - res.distance * res.normal).max() <= RELATION_TOL


@pytest.mark.parametrize("gap", [0.3, 1e-3, 1e-9, 0.0, -1e-9, -1e-3, -0.3, -1.1])
def test_spheres(gap):
    A, B = spq.Sphere(0.5), spq.Sphere(0.7)
    res = spq.distance(A, B, np.eye(4), translate(1.2 + gap, 0.0, 0.0), signed=True)
    check_result(res, gap, tol=1e-12)
    np.testing.assert_allclose(res.normal, [1, 0, 0], atol=1e-9)
    np.testing.assert_allclose(res.point_a, [0.5, 0, 0], atol=1e-9)


def test_coincident_spheres_give_the_sum_of_radii_along_some_unit_normal():
    res = spq.distance(spq.Sphere(0.5), spq.Sphere(0.25), np.eye(4), np.eye(4), signed=True)
    check_result(res, -0.75, tol=1e-12)
    assert abs(np.linalg.norm(res.normal) - 1) <= 1e-12
    assert abs(np.linalg.norm(res.point_a) - 0.5) <= 1e-12


@pytest.mark.parametrize("depth", [1e-12, 1e-9, 1e-6, 1e-3, 0.05])
@pytest.mark.parametrize("shift", [0.0, 0.013])
def test_boxes_face_to_face(depth, shift):
    # axis-aligned boxes: GJK ends with the origin on a face or an edge of a box-like simplex
    A, B = spq.Box(0.5, 0.3, 0.2), spq.Box(0.4, 0.25, 0.1)
    res = spq.distance(A, B, np.eye(4), translate(shift, 0.0, 0.3 - depth), signed=True)
    check_result(res, -depth, tol=1e-12)
    np.testing.assert_allclose(res.normal, [0, 0, 1], atol=1e-9)
    assert abs(res.point_a[2] - 0.2) <= 1e-12 and abs(res.point_b[2] - (0.2 - depth)) <= 1e-12


def test_a_box_inside_a_box_gets_the_least_way_out():
    A, B = spq.Box(1.0, 0.8, 0.6), spq.Box(0.1, 0.1, 0.1)
    # B's centre at (0.2, -0.5, 0.05): ways out along +x 0.9, -y 0.4, +z 0.65 (plus B's half size)
    res = spq.distance(A, B, np.eye(4), translate(0.2, -0.5, 0.05), signed=True)
    check_result(res, -(0.8 - 0.5 + 0.1), tol=1e-12)
    np.testing.assert_allclose(res.normal, [0, -1, 0], atol=1e-9)


def test_a_rotated_box_edge_into_a_face():
    A, B = spq.Box(0.5, 0.5, 0.5), spq.Box(0.2, 0.2, 0.2)
    depth = 0.01
    # B turned 45 deg about x: its lowest edge is 0.2*sqrt(2) below its centre
    pose_b = rotated(translate(0.1, 0.0, 0.5 + 0.2 * np.sqrt(2) - depth), [np.pi / 4, 0, 0])
    res = spq.distance(A, B, np.eye(4), pose_b, signed=True)
    check_result(res, -depth, tol=1e-12)
    np.testing.assert_allclose(res.normal, [0, 0, 1], atol=1e-9)


@pytest.mark.parametrize("gap", [0.2, -1e-6, -0.05])
def test_crossing_capsules(gap):
    A, B = spq.Capsule(0.1, 1.0), spq.Capsule(0.05, 0.7)
    # A along z, B along x (both capsules lie along their local z): axes cross at distance 0.15 + gap
    pose_b = rotated(translate(0.0, 0.15 + gap, 0.3), [0, np.pi / 2, 0])
    res = spq.distance(A, B, np.eye(4), pose_b, signed=True)
    check_result(res, gap, tol=1e-12)
    np.testing.assert_allclose(res.normal, [0, 1, 0], atol=1e-9)


def test_sphere_in_a_box_and_box_in_a_sphere():
    box, ball = spq.Box(0.5, 0.4, 0.3), spq.Sphere(0.1)
    res = spq.distance(box, ball, np.eye(4), translate(0.0, 0.0, 0.25), signed=True)
    check_result(res, -(0.05 + 0.1), tol=1e-12)
    np.testing.assert_allclose(res.normal, [0, 0, 1], atol=1e-9)
    # swapped: now the box is B, and it must move down for the ball to leave through its top
    res = spq.distance(ball, box, translate(0.0, 0.0, 0.25), np.eye(4), signed=True)
    check_result(res, -(0.05 + 0.1), tol=1e-12)
    np.testing.assert_allclose(res.normal, [0, 0, -1], atol=1e-9)


# ---------------------------------------------------------------- status, bounds and bad input


def test_an_iteration_cap_gives_failed_with_valid_bounds():
    """Deep overlaps of two superellipsoids (round: the EPA converges only linearly) with the least
    budget, max_iter=1 (32 EPA expansions): queries decline, and their bounds still hold the depth
    oracle's answer; the default budget meets it."""
    from harness.references.depth_oracle import body_of
    from harness.references.depth_oracle import signed_distance as oracle_sd

    a = spq.Superellipsoid(0.3, 0.2, 0.15, 0.8, 0.9)
    b = spq.Superellipsoid(0.25, 0.2, 0.1, 1.0, 0.7)
    rng = np.random.default_rng(3)
    n = 24
    poses_a = np.repeat(np.eye(4)[None], n, axis=0)
    poses_b = pose_matrix(Rotation.random(n, random_state=rng).as_matrix(), rng.uniform(-0.05, 0.05, (n, 3)))
    r = spq.distances(a, b, poses_a, poses_b, signed=True, max_iter=1)
    failed = r.status == "failed"
    assert failed.any()
    A, B = body_of("CSE", a), body_of("CSE", b)
    truth = np.array([oracle_sd(A, poses_a[i], B, poses_b[i]).signed_distance for i in range(n)])
    assert (truth < -0.05).all()
    assert (r.lower_bound <= r.upper_bound).all()
    # the oracle's value is a lower bound of sd (its best normal's separation), within its polish
    assert (truth <= r.upper_bound + 1e-9).all()
    ok = ~failed
    assert (np.abs(r.distance[ok] - truth[ok]) <= 1e-7).all()
    full = spq.distances(a, b, poses_a, poses_b, signed=True)  # the default budget closes them all
    assert (full.status == "overlapping").all()
    assert (np.abs(full.distance - truth) <= 1e-7).all()


@pytest.mark.parametrize("bad", ["yes", 1, None, np.array([True])])
def test_signed_must_be_a_bool(links, bad):
    a, b = links
    with pytest.raises(ValueError, match="signed"):
        spq.distance(a, b, np.eye(4), np.eye(4), signed=bad)
    with pytest.raises(ValueError, match="signed"):
        spq.distances(a, b, np.eye(4)[None], np.eye(4)[None], signed=bad)
    with pytest.raises(ValueError, match="signed"):
        spq.Pair(a, b, signed=bad)


# ---------------------------------------------------------------- gradient and continuity through contact


def test_gradient_of_an_overlap_matches_finite_differences_of_the_reference(links, overlap_suite):
    a, b = links
    s = overlap_suite
    h = 1e-7
    idx = np.flatnonzero(s.bucket == "overlap-1e-2")[:8]
    for i in idx:
        res = spq.distance(a, b, s.pose_a[i], s.pose_b[i], signed=True)
        ga, gb = spq.distance_gradient(res, s.pose_a[i], s.pose_b[i])
        assert np.isfinite(ga).all() and np.isfinite(gb).all()
        ref = MinkowskiReference(a, b, s.pose_a[i], s.pose_b[i])
        for k in range(3):  # translations of B: the exact signed distance is piecewise linear there
            step = np.zeros(3)
            step[k] = h
            fd = (ref.query(step).signed_distance - ref.query(-step).signed_distance) / (2 * h)
            assert abs(fd - gb[k]) <= 1e-6, (i, k, fd, gb[k])
        np.testing.assert_allclose(ga[:3], -gb[:3])
    # unsigned overlaps still have none
    res = spq.distance(a, b, s.pose_a[idx[0]], s.pose_b[idx[0]])
    assert np.isnan(spq.distance_gradient(res, s.pose_a[idx[0]], s.pose_b[idx[0]])[1]).all()


def test_signed_distance_is_continuous_through_contact(links):
    # B slides along a line through A and out again: the exact signed distance is 1-Lipschitz in the
    # translation, so no two steps may differ by more than the step length
    a, b = links
    rng = np.random.default_rng(9)
    for trial in range(3):
        R = Rotation.random(random_state=trial).as_matrix()
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        ts = np.linspace(-0.4, 0.4, 401)
        pb = np.stack([pose_matrix(R, t * u) for t in ts])
        pa = np.broadcast_to(np.eye(4), pb.shape).copy()
        r = spq.distances(a, b, pa, pb, signed=True)
        assert (r.distance < 0).any() and (r.distance > 0).any()
        step = ts[1] - ts[0]
        assert np.abs(np.diff(r.distance)).max() <= step * (1 + 1e-9)
        truth = np.array([reference_distance(a, b, pa[i], pb[i]).signed_distance for i in range(0, len(ts), 10)])
        assert np.abs(r.distance[::10] - truth).max() <= DEPTH_TOL


# ---------------------------------------------------------------- robot scenes


def test_scene_signed_distances_match_the_reference_per_pair():
    from datasets.robots import ROBOTS

    files = ROBOTS["panda"]
    scene = Scene.from_urdf(files.urdf, mesh_root=files.mesh_root, policy="pch")
    rng = np.random.default_rng(3)
    qs = rng.uniform(scene.model.lower, scene.model.upper, (300, len(scene.model.lower)))
    # keep configurations where some pair overlaps (about one in seven); spq only picks them, the
    # reference judges every pair of them
    chosen = [q for q in qs if (scene.distances(q, signed=True).distance < -1e-6).any()][:5]
    assert len(chosen) == 5
    overlaps = 0
    for q in chosen:
        signed = scene.distances(q, signed=True)
        plain = scene.distances(q)
        poses = scene.body_poses(q)
        for k, (i, j) in enumerate(signed.pairs):
            ref = reference_distance(scene.bodies[i].hull, scene.bodies[j].hull, poses[i], poses[j])
            assert abs(signed.distance[k] - ref.signed_distance) <= DEPTH_TOL
            assert signed.lower_bound[k] <= ref.signed_distance + 1e-15 <= signed.upper_bound[k] + 2e-15
            if ref.signed_distance > 1e-9:
                assert signed.distance[k] == plain.distance[k]
            overlaps += ref.signed_distance < -1e-9
    assert overlaps >= 5


def test_a_scene_switching_signed_on_and_off_answers_as_fresh_scenes():
    """Scene._run writes the pairs' signed flag only when a call asks otherwise than the last, and
    reset() rebuilds the pairs' state unsigned: in any order of signed calls, unsigned calls and
    resets, each answer is a fresh scene's, bit for bit (overlaps negative only when signed)."""
    from datasets.robots import ROBOTS

    files = ROBOTS["panda"]
    make = lambda: Scene.from_urdf(files.urdf, mesh_root=files.mesh_root, policy="pch")  # noqa: E731
    scene = make()
    rng = np.random.default_rng(3)
    qs = rng.uniform(scene.model.lower, scene.model.upper, (60, len(scene.model.lower)))
    fresh = {signed: make().distances_many(qs, signed=signed)[:, :, [OUT_DISTANCE, OUT_LOWER]] for signed in (False, True)}
    assert (fresh[True][:, :, 0] < -1e-6).any() and (fresh[False][:, :, 0] >= 0.0).all()
    for step in (True, "reset", True, False, "reset", False, True, True, "reset", True, False):
        if step == "reset":
            scene.reset()
            continue
        got = scene.distances_many(qs, signed=step)[:, :, [OUT_DISTANCE, OUT_LOWER]]
        assert np.array_equal(got, fresh[step]), f"signed={step}"
        one = scene.distances(qs[7], coherent=False, signed=step)
        assert np.array_equal(one.distance, fresh[step][7, :, 0]) and np.array_equal(one.lower_bound, fresh[step][7, :, 1])


def test_patch_rounds_skipped_where_the_hulls_overlap_could_not_have_closed():
    """signed_from_hulls skips the small-ball certificate (query._certify_overlap) where the hulls
    overlap by more than its tolerance (query._small_balls_reach). On JVRC-1's overlapping STP-PCH
    pairs that certificate must then fail even at the bodies' own optimal normal (the hulls' signed
    distance from the PCH scene, an independent query); where it is not skipped and the overlap is
    shallow, it closes there, so the check can tell."""
    from tests.conftest import require_shared_datasets

    require_shared_datasets()
    from harness.suites.robot.robot_bench import RobotBenchConfig, load_scene
    from harness.workloads.robot_poses import random_configurations
    from spq.kernels.batch import F_MARGIN_A, F_MARGIN_B, I_KIND_A, I_KIND_B
    from spq.kernels.gjk import (OUT_DISTANCE, OUT_NORMAL, OUT_SIZE, OUT_STATUS, OVERLAPPING, PROBE_END, PROBE_ROW,
                                 WARM_SIZE)
    from spq.kernels.kinds import STP
    from spq.kernels.query import _certify_overlap, _small_balls_reach

    config = RobotBenchConfig()
    auto, pch = load_scene(config, "auto"), load_scene(config, "pch")
    qs = random_configurations(auto.model, 25, 7)
    signed_auto = auto.distances_many(qs, signed=True)
    hulls = pch.distances_many(qs, signed=True)[:, :, OUT_DISTANCE]
    work = np.zeros((PROBE_END, 4))
    skipped = closed_shallow = 0
    for i, q in enumerate(qs):
        poses = auto.body_poses(q)
        for p in np.flatnonzero(signed_auto[i, :, OUT_STATUS] == OVERLAPPING):
            ints, floats = auto._pair_ints[p], auto._pair_floats[p]
            if (ints[I_KIND_A] == STP) == (ints[I_KIND_B] == STP):
                continue
            sa, sb = auto._pair_slots[p]
            fa, fb, ia, ib = auto._slot_frange[sa], auto._slot_frange[sb], auto._slot_irange[sa], auto._slot_irange[sb]
            fA, iA = auto._fpool[fa[0]:fa[1]], auto._ipool[ia[0]:ia[1]]
            fB, iB = auto._fpool[fb[0]:fb[1]], auto._ipool[ib[0]:ib[1]]
            a, b = auto.pairs[p]
            TA, TB = poses[a], poses[b]
            R, t = TA[:3, :3].T @ TB[:3, :3], TA[:3, :3].T @ (TB[:3, 3] - TA[:3, 3])
            m = TA[:3, :3].T @ signed_auto[i, p, OUT_NORMAL:OUT_NORMAL + 3]
            r = (fA if ints[I_KIND_A] == STP else fB)[0]
            reach = _small_balls_reach(hulls[i, p], r + floats[F_MARGIN_A] + floats[F_MARGIN_B], 1e-10, 1e-10)
            verdict = _certify_overlap((ints[I_KIND_A], floats[F_MARGIN_A], fA, iA, ints[I_KIND_B], floats[F_MARGIN_B],
                                        fB, iB, R, t), m[0], m[1], m[2], 1e-10, 1e-10,
                                       np.zeros(WARM_SIZE, dtype=np.int64), work[PROBE_ROW:PROBE_END],
                                       np.zeros(WARM_SIZE, dtype=np.int64), np.zeros(OUT_SIZE))
            if not reach:
                assert verdict != 1, (i, p)
                skipped += 1
            elif verdict == 1 and signed_auto[i, p, OUT_DISTANCE] > -0.5 * r:
                closed_shallow += 1
    assert skipped >= 20 and closed_shallow >= 20


@settings(max_examples=200, deadline=None)
@given(st.integers(4, 40), st.integers(0, 2**32 - 1), st.booleans())
def test_tied_vertices_are_the_two_farthest_along_a_direction(n, seed, plant_tie):
    """epa._tied_vertices (the polytope side's two farthest vertices along e, and whether they tie) against
    a sort of every vertex's value; a planted tie (a vertex copied and moved across e) is found."""
    from spq.kernels.epa import TIE_REL, _tied_vertices

    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3))
    e = rng.normal(size=3)
    e /= np.linalg.norm(e)
    if plant_tie:
        best = int(np.argmax(pts @ e))
        across = np.cross(e, rng.normal(size=3))
        pts[(best + 1) % n] = pts[best] + 0.1 * across / np.linalg.norm(across)
    i1, i2, tied = _tied_vertices(pts.ravel(), e[0], e[1], e[2], TIE_REL)
    values = pts @ e  # (numpy's rounding, not the kernel's: a planted tie may swap within an ulp)
    top = np.sort(values)[::-1]
    assert i1 != i2 and abs(values[i1] - top[0]) <= 1e-14 and abs(values[i2] - top[1]) <= 1e-14
    gap, line = top[0] - top[1], TIE_REL * np.abs(pts).max()
    if abs(gap - line) > 1e-14:
        assert tied == (gap <= line)
    if plant_tie:
        assert tied
