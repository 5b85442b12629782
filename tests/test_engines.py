"""External-engine adapters (harness.engines) against boxes whose distances and witness faces are
known in closed form, and against each other on a random hull.

Box scene (oracle: the geometry below). A is a box with half extents (0.5, 0.3, 0.2) m; B is the same
box rotated 90 deg about z, so its half extent along world x is 0.3 m. B sits beside A along +x:
  gap 0.3 m  -> A's +x face at x = 0.5, B's -x face at x = 0.8 (in A's frame);
  overlap 0.1 m along x (the smallest penetration direction).
The whole scene is also moved rigidly by an arbitrary pose, which changes no distance: witness
points returned in a body-local frame instead of the world frame would then miss the faces.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import spq
from harness.engines import (
    STATUSES,
    BatchResult,
    available_engines,
    engine_names,
    register_engine,
)
from harness.engines.base import EngineResult, status_of
from spq.shapes.polyhedron import Polyhedron

pytestmark = pytest.mark.engines

ENGINES = ["fcl", "coal", "bullet", "bullet-margin", "mujoco"]
HALF = np.array([0.5, 0.3, 0.2])  # m, half extents of both boxes
GAP = 0.3  # m
DEPTH = 0.1  # m
BULLET_DEFAULT_MARGIN = 1e-3  # m per body, pybullet's default for convex hulls

# Accuracy each engine is held to on the boxes (absolute m, or relative for "bullet").
DIST_ABS_TOL = {"fcl": 1e-6, "coal": 1e-6, "mujoco": 1e-6, "bullet": 1e-4 * GAP, "bullet-margin": 3e-3}
# Where each engine's witness points may sit off the true faces (m): bullet-margin's lie on the
# margin-inflated surface, 1 mm outside.
POINT_TOL = {"fcl": 1e-6, "coal": 1e-6, "mujoco": 1e-6, "bullet": 1e-4 * GAP, "bullet-margin": 1.5e-3}


def box(half: np.ndarray) -> Polyhedron:
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    return Polyhedron.from_points(corners * half)


def pose(rotation: np.ndarray, translation) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = rotation
    out[:3, 3] = translation
    return out


RZ90 = Rotation.from_euler("z", 90, degrees=True).as_matrix()
SCENE_MOVES = {  # rigid motions applied to the whole scene
    "identity": np.eye(4),
    "moved": pose(Rotation.from_rotvec([0.4, -1.1, 0.7]).as_matrix(), [3.0, -7.0, 11.0]),
}


def box_scene(offset_x: float, move: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Poses of A and B with B's centre ``offset_x`` m from A's along A's x axis, then moved."""
    pose_a = pose(np.eye(3), [0.1, -0.2, 0.3])
    pose_b = pose(RZ90, pose_a[:3, 3] + [offset_x, 0.05, 0.02])
    return move @ pose_a, move @ pose_b


def to_frame(pose_: np.ndarray, world_point: np.ndarray) -> np.ndarray:
    """World point expressed in the frame of ``pose_``."""
    return pose_[:3, :3].T @ (world_point - pose_[:3, 3])


@pytest.fixture(scope="module")
def engines():
    built = available_engines(include=ENGINES)
    yield built
    for engine in built.values():
        engine.close()


@pytest.fixture(scope="module")
def boxes():
    return box(HALF), box(HALF)


@pytest.mark.parametrize("move", SCENE_MOVES, ids=list(SCENE_MOVES))
@pytest.mark.parametrize("name", ENGINES)
def test_separated_boxes_give_gap_and_world_witness_points_on_facing_faces(engines, boxes, name, move):
    pose_a, pose_b = box_scene(HALF[0] + GAP + HALF[1], SCENE_MOVES[move])
    result = engines[name].prepare(*boxes).query(pose_a, pose_b)

    assert result.status == "separated"
    expected = GAP - 2 * BULLET_DEFAULT_MARGIN if name == "bullet-margin" else GAP
    assert abs(result.distance - expected) <= (1e-5 if name == "bullet-margin" else DIST_ABS_TOL[name])
    assert abs(result.distance - GAP) <= DIST_ABS_TOL[name]
    assert result.raw_distance == result.distance
    # Witness points, taken back into A's frame: A's on its +x face, B's on B's -x face (x = 0.8).
    local_a = to_frame(SCENE_MOVES[move] @ pose(np.eye(3), [0.1, -0.2, 0.3]), result.point_a)
    local_b = to_frame(SCENE_MOVES[move] @ pose(np.eye(3), [0.1, -0.2, 0.3]), result.point_b)
    tol = POINT_TOL[name]
    assert local_a[0] == pytest.approx(HALF[0], abs=tol)
    assert local_b[0] == pytest.approx(HALF[0] + GAP, abs=tol)
    # ... inside the region where the two faces face each other (y in [-0.3, 0.3], z in [-0.18, 0.2]).
    for local in (local_a, local_b):
        assert -HALF[1] - tol <= local[1] <= HALF[1] + tol
        assert -HALF[2] + 0.02 - tol <= local[2] <= HALF[2] + tol
    assert np.linalg.norm(result.point_b - result.point_a) == pytest.approx(result.distance, abs=tol)


@pytest.mark.parametrize("name", ["bullet-margin"])
def test_bullet_default_margin_shortens_the_distance_by_about_two_millimetres(engines, boxes, name):
    pose_a, pose_b = box_scene(HALF[0] + GAP + HALF[1], np.eye(4))
    pair = engines[name].prepare(*boxes)
    shortfall = GAP - pair.query(pose_a, pose_b).distance
    assert pair.margins == pytest.approx((BULLET_DEFAULT_MARGIN, BULLET_DEFAULT_MARGIN))
    assert 1.5e-3 <= shortfall <= 3e-3


@pytest.mark.parametrize("move", SCENE_MOVES, ids=list(SCENE_MOVES))
@pytest.mark.parametrize("name", ENGINES)
def test_overlapping_boxes_are_reported_overlapping_with_zero_distance(engines, boxes, name, move):
    pose_a, pose_b = box_scene(HALF[0] + HALF[1] - DEPTH, SCENE_MOVES[move])
    result = engines[name].prepare(*boxes).query(pose_a, pose_b)

    assert result.status == "overlapping"
    assert result.distance == 0.0
    assert result.raw_distance < 0.0
    # Raw value is minus the penetration depth (plus both margins for bullet-margin).
    assert -result.raw_distance == pytest.approx(DEPTH, abs=3e-3 if name == "bullet-margin" else 1e-4)
    assert np.isfinite(result.point_a).all() and np.isfinite(result.point_b).all()


@pytest.mark.parametrize("name", ENGINES)
def test_query_many_matches_query_row_by_row(engines, boxes, name):
    offsets = [HALF[0] + HALF[1] - DEPTH, HALF[0] + GAP + HALF[1], HALF[0] + 2.0 + HALF[1]]
    scenes = [box_scene(dx, SCENE_MOVES["moved"]) for dx in offsets]
    poses_a = np.stack([s[0] for s in scenes])
    poses_b = np.stack([s[1] for s in scenes])
    pair = engines[name].prepare(*boxes)
    batch = pair.query_many(poses_a, poses_b)

    assert isinstance(batch, BatchResult) and len(batch) == 3
    assert batch.point_a.shape == (3, 3) and batch.point_b.shape == (3, 3)
    assert list(batch.status) == ["overlapping", "separated", "separated"]
    for i in range(3):
        single = pair.query(poses_a[i], poses_b[i])
        assert batch.distance[i] == pytest.approx(single.distance, abs=1e-12)
        assert batch.raw_distance[i] == pytest.approx(single.raw_distance, abs=1e-9)
        np.testing.assert_allclose(batch.point_a[i], single.point_a, atol=1e-9)
    # A far query after near ones still reports its own distance and points (no stale reused result).
    assert batch.distance[2] - batch.distance[1] == pytest.approx(2.0 - GAP, abs=DIST_ABS_TOL[name])
    empty = pair.query_many(np.zeros((0, 4, 4)), np.zeros((0, 4, 4)))
    assert len(empty) == 0


@pytest.mark.parametrize("name", ENGINES)
def test_the_timing_loop_gives_each_querys_raw_distance(engines, name):
    """distance_loop (what the benchmarks time, laid out in each engine's leanest form) returns, pose
    for pose, the raw distance of query (held to closed form on the boxes above), on a random hull
    at random poses: separated, overlapping and far, world frames moved arbitrarily."""
    rng = np.random.default_rng(3)
    hull = Polyhedron.from_points(rng.normal(size=(60, 3)) * [0.3, 0.2, 0.1])
    n = 40
    poses_a = np.stack([pose(r, t) for r, t in zip(Rotation.random(n, random_state=4).as_matrix(),
                                                     rng.uniform(-2.0, 2.0, (n, 3)))])
    offsets = rng.normal(size=(n, 3)) * rng.uniform(0.0, 1.5, (n, 1))
    poses_b = np.stack([pose(r, a[:3, 3] + o) for r, a, o in zip(Rotation.random(n, random_state=5).as_matrix(),
                                                                 poses_a, offsets)])
    pair = engines[name].prepare(hull, hull)
    loop = pair.distance_loop(poses_a, poses_b)
    single = np.array([pair.query(a, b).raw_distance for a, b in zip(poses_a, poses_b)])
    assert loop.shape == (n,) and loop.dtype == np.float64
    assert np.any(single < 0.0) or name.startswith("bullet") or name == "fcl"  # coal and MuJoCo sign overlaps
    assert np.any(single > 0.0)
    np.testing.assert_allclose(loop, single, rtol=0.0, atol=1e-12)
    assert len(pair.distance_loop(np.zeros((0, 4, 4)), np.zeros((0, 4, 4)))) == 0
    # and against an independent engine: spq's certified distance (signed, for the engines that sign)
    exact = spq.distances(hull, hull, poses_a, poses_b, signed=True).distance
    apart = exact > 1e-3
    hull_tol = {"bullet": 1e-3}.get(name, DIST_ABS_TOL[name])  # bullet: as test_engines_agree_on_a_random_hull
    np.testing.assert_allclose(loop[apart], exact[apart], rtol=0.0, atol=hull_tol)
    if name in ("coal", "mujoco"):
        np.testing.assert_allclose(loop[~apart], exact[~apart], rtol=0.0, atol=1e-5)


@pytest.mark.parametrize("name", ENGINES)
def test_a_result_is_not_overwritten_by_the_next_query(engines, boxes, name):
    pair = engines[name].prepare(*boxes)
    first = pair.query(*box_scene(HALF[0] + GAP + HALF[1], np.eye(4)))
    kept = (first.distance, first.point_a.copy(), first.point_b.copy())
    pair.query(*box_scene(HALF[0] + 2.0 + HALF[1], SCENE_MOVES["moved"]))
    assert first.distance == kept[0]
    np.testing.assert_array_equal(first.point_a, kept[1])
    np.testing.assert_array_equal(first.point_b, kept[2])


@pytest.mark.parametrize("name", ENGINES)
def test_query_many_rejects_malformed_or_mismatched_batches(engines, boxes, name):
    pair = engines[name].prepare(*boxes)
    with pytest.raises(ValueError):
        pair.query_many(np.tile(np.eye(4), (2, 1, 1)), np.tile(np.eye(4), (3, 1, 1)))
    with pytest.raises(ValueError):
        pair.query_many(np.tile(2 * np.eye(4), (2, 1, 1)), np.tile(np.eye(4), (2, 1, 1)))
    with pytest.raises(ValueError):
        pair.query(np.eye(3), np.eye(4))


def _raise(*args, **kwargs):
    raise RuntimeError("injected engine failure")


# How to make each engine's own call raise inside a query.
def _break_fcl(monkeypatch, pair):
    from harness.engines import fcl_engine

    monkeypatch.setattr(fcl_engine.fcl, "distance", _raise)


def _break_coal(monkeypatch, pair):
    monkeypatch.setattr(pair, "_compute", _raise)


def _break_bullet(monkeypatch, pair):
    from harness.engines import bullet_engine

    monkeypatch.setattr(bullet_engine.p, "getClosestPoints", _raise)


def _break_mujoco(monkeypatch, pair):
    monkeypatch.setattr(pair, "_distance", _raise)


BREAKERS = {"fcl": _break_fcl, "coal": _break_coal, "bullet": _break_bullet, "bullet-margin": _break_bullet,
            "mujoco": _break_mujoco}


@pytest.mark.parametrize("name", ENGINES)
def test_an_engine_exception_becomes_a_failed_result(engines, boxes, name, monkeypatch):
    pose_a, pose_b = box_scene(HALF[0] + GAP + HALF[1], np.eye(4))
    pair = engines[name].prepare(*boxes)
    BREAKERS[name](monkeypatch, pair)

    result = pair.query(pose_a, pose_b)
    assert result.status == "failed"
    assert np.isnan(result.distance) and np.isnan(result.point_a).all() and np.isnan(result.point_b).all()
    assert "injected engine failure" in result.message
    batch = pair.query_many(pose_a[None], pose_b[None])
    assert list(batch.status) == ["failed"] and np.isnan(batch.distance).all()


def test_bullet_reports_failed_when_no_point_lies_within_its_threshold(boxes):
    from harness.engines.bullet_engine import BulletEngine

    with BulletEngine(margin=0.0, max_distance=0.1) as engine:
        result = engine.prepare(*boxes).query(*box_scene(HALF[0] + GAP + HALF[1], np.eye(4)))
    assert result.status == "failed" and np.isnan(result.distance)


def test_a_closed_bullet_pair_or_engine_reports_failed_queries(boxes):
    from harness.engines.bullet_engine import BulletEngine

    scene = box_scene(HALF[0] + GAP + HALF[1], np.eye(4))
    engine = BulletEngine(margin=0.0)
    pair, other = engine.prepare(*boxes), engine.prepare(*boxes)
    pair.close()
    engine.prepare(*boxes)  # may reuse the closed pair's body ids
    assert pair.query(*scene).status == "failed"
    assert other.query(*scene).status == "separated"
    engine.close()
    assert not engine.connected and other.query(*scene).status == "failed"
    with pytest.raises(RuntimeError, match="closed"):
        engine.prepare(*boxes)


def test_status_rule_overlapping_touching_separated_failed():
    assert status_of(-1e-12) == "overlapping"
    assert status_of(0.5, colliding=True) == "overlapping"
    assert status_of(0.0) == "touching" and status_of(1e-9) == "touching"
    assert status_of(2e-9) == "separated"
    assert status_of(float("nan")) == "failed" and status_of(float("inf")) == "failed"
    assert set(STATUSES) == {"separated", "touching", "overlapping", "failed"}


def test_bullet_quaternion_matches_scipy_including_half_turns():
    from harness.engines.bullet_engine import quat_xyzw

    rotations = Rotation.random(200, random_state=3)
    axes = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [1.0, 1.0, 0]])
    half_turns = Rotation.from_rotvec(np.pi * axes / np.linalg.norm(axes, axis=1)[:, None])  # trace -1
    for rot in list(rotations) + list(half_turns):
        q = np.array(quat_xyzw(rot.as_matrix()))
        expected = rot.as_quat()
        assert min(np.abs(q - expected).max(), np.abs(q + expected).max()) < 1e-12


def test_engines_agree_on_a_random_hull(engines):
    """fcl and coal against each other to 1e-6 m (no closed form here); bullet (margin 0) to 1 mm."""
    rng = np.random.default_rng(0)
    hull = Polyhedron.from_points(rng.normal(size=(200, 3)))
    pairs = {name: engines[name].prepare(hull, hull) for name in ("fcl", "coal", "bullet")}
    rotations = Rotation.random(20, random_state=1).as_matrix()
    directions = rng.normal(size=(20, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    radius = hull.bounding_radius()
    for rot, direction, scale in zip(rotations, directions, rng.uniform(1.2, 3.0, size=20)):
        pose_b = pose(rot, direction * radius * scale)
        results = {name: pair.query(np.eye(4), pose_b) for name, pair in pairs.items()}
        assert results["fcl"].distance == pytest.approx(results["coal"].distance, abs=1e-6)
        assert results["bullet"].distance == pytest.approx(results["coal"].distance, abs=1e-3)
        assert len({r.status for r in results.values()}) == 1


def test_registry_builds_named_engines_and_accepts_new_ones():
    names = engine_names()
    assert [n for n in names if n in ENGINES] == ENGINES and "spq" in names
    with pytest.raises(ValueError, match="unknown engine"):
        available_engines(include=["nope"])
    built = available_engines(include="coal")
    assert list(built) == ["coal"] and built["coal"].tolerance == 1e-8
    with pytest.raises(ValueError, match="already registered"):
        register_engine("coal", lambda: None)


def test_coal_tolerance_is_a_constructor_argument_and_reaches_the_request():
    from harness.engines.coal_engine import CoalEngine

    engine = CoalEngine(tolerance=1e-6)
    assert engine.tolerance == 1e-6 and engine._request.gjk_tolerance == 1e-6
    with pytest.raises(ValueError):
        CoalEngine(tolerance=0.0)


def test_engines_reject_shapes_that_are_not_polyhedra(engines):
    with pytest.raises(TypeError):
        engines["coal"].prepare(object(), object())


def test_results_are_engine_results_with_world_points_as_float_arrays(engines, boxes):
    result = engines["fcl"].prepare(*boxes).query(*box_scene(HALF[0] + GAP + HALF[1], np.eye(4)))
    assert isinstance(result, EngineResult)
    assert result.point_a.dtype == np.float64 and result.point_a.shape == (3,)


def test_isolated_engine_survives_native_crashes():
    """A query that kills the engine's process comes back 'failed'; the others keep the engine's answers."""
    from datasets import load_object
    from harness.engines.isolated import CRASHED, IsolatedEngine
    from harness.workloads.poses import random_poses

    a, b = load_object("kuka_link_4"), load_object("panda_link_2")
    pa, pb = random_poses(8, 6, 0.12)  # one overlapping pose of eight
    truth = spq.distances(a, b, pa, pb, signed=True)
    over = truth.status == "overlapping"
    assert 0 < over.sum() < len(over)
    engine = IsolatedEngine("aborts", plugin="tests.check_plugins:AbortsOnOverlap")
    try:
        pair = engine.prepare(a, b)
        got = pair.query_many(pa, pb)
        one = pair.query(pa[np.argmax(over)], pb[np.argmax(over)])
    finally:
        engine.close()
    assert (got.status[over] == "failed").all()
    np.testing.assert_array_equal(got.distance[~over], truth.distance[~over])
    assert one.status == "failed" and one.message == CRASHED


def test_isolated_engine_survives_a_hang(monkeypatch):
    """A query on which the engine never answers is killed after the time limit and comes back 'failed';
    the others keep the engine's answers."""
    from datasets import load_object
    from harness.engines import isolated as iso
    from harness.workloads.poses import random_poses

    monkeypatch.setattr(iso, "HANG_BASE_S", 1.0)
    a, b = load_object("kuka_link_4"), load_object("panda_link_2")
    pa, pb = random_poses(8, 6, 0.12)  # one overlapping pose of eight
    truth = spq.distances(a, b, pa, pb, signed=True)
    over = truth.status == "overlapping"
    engine = iso.IsolatedEngine("hangs", plugin="tests.check_plugins:HangsOnOverlap")
    try:
        got = engine.prepare(a, b).query_many(pa, pb)
    finally:
        engine.close()
    assert (got.status[over] == "failed").all()
    np.testing.assert_array_equal(got.distance[~over], truth.distance[~over])



def test_an_isolated_engine_is_timed_on_its_queries_not_on_its_warm_up(monkeypatch):
    """A child's first query would compile a JIT's code (spq's kernels: minutes on a cold cache, as on a
    fresh CI machine with the tests on two processes); the engine's warm_up runs before the time
    limit applies, so that query is not taken for a hang. The plugin's first query sleeps 2 s unless
    warmed up; the limit here is 0.5 s. Oracle: spq's own answers in this process."""
    from harness.engines import isolated as iso

    monkeypatch.setattr(iso, "HANG_BASE_S", 0.5)
    a, b = spq.Box(0.1, 0.2, 0.3), spq.Sphere(0.2)
    pa = np.repeat(np.eye(4)[None], 3, axis=0)
    pb = pa.copy()
    pb[:, 0, 3] = [1.0, 1.5, 2.0]
    truth = spq.distances(a, b, pa, pb, signed=True)
    engine = iso.IsolatedEngine("slow-first", plugin="tests.check_plugins:SlowFirstQuery")
    try:
        got = engine.prepare(a, b).query_many(pa, pb)
    finally:
        engine.close()
    assert (got.status == "separated").all()
    np.testing.assert_array_equal(got.distance, truth.distance)

@pytest.mark.engines
def test_isolated_engine_gives_the_engines_own_answers():
    """Served from a child process, coal answers bit for bit as in-process (results cross the pipe as
    they are)."""
    from datasets import load_object
    from harness.engines.isolated import IsolatedEngine
    from harness.workloads.poses import random_poses

    a, b = load_object("kuka_link_4"), load_object("panda_link_2")
    pa, pb = random_poses(50, 1, 0.12)
    direct = available_engines(["coal"])["coal"]
    isolated = IsolatedEngine("coal")
    try:
        want = direct.prepare(a, b).query_many(pa, pb)
        got = isolated.prepare(a, b).query_many(pa, pb)
    finally:
        isolated.close()
        direct.close()
    for field in ("distance", "point_a", "point_b", "status", "raw_distance"):
        np.testing.assert_array_equal(getattr(got, field), getattr(want, field))
    assert isolated.tolerance == direct.tolerance and isolated.gives_depth == direct.gives_depth


def test_mujoco_reports_its_pipeline_and_a_distance_beyond_distmax_as_failed(boxes):
    from harness.engines.mujoco_engine import MujocoEngine

    native, libccd = MujocoEngine(), MujocoEngine(nativeccd=False, distmax=0.1)
    assert native.settings()["pipeline"] == "native GJK/EPA" and libccd.settings()["pipeline"] == "libccd"
    assert "native ccd" in native.version() and "libccd" in libccd.version()
    pose_a, pose_b = box_scene(HALF[0] + GAP + HALF[1], np.eye(4))
    assert abs(libccd.prepare(*boxes).query(*box_scene(HALF[0] + 0.05 + HALF[1], np.eye(4))).distance - 0.05) < 1e-6
    far = libccd.prepare(*boxes).query(pose_a, pose_b)  # 0.3 m apart, beyond distmax
    assert far.status == "failed" and "distmax" in far.message
    with pytest.raises(ValueError, match="distmax"):
        MujocoEngine(distmax=0.0)


def test_a_missing_optional_engine_package_is_named_and_skipped(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "mujoco", None)  # as if not installed: import raises ImportError
    from harness.engines.mujoco_engine import MujocoEngine

    with pytest.raises(ImportError, match="pip install mujoco"):
        MujocoEngine()
    with pytest.warns(RuntimeWarning, match="mujoco"):
        engines = available_engines()
    assert "mujoco" not in engines and "coal" in engines
    for engine in engines.values():
        engine.close()
    with pytest.raises(ImportError, match="pip install mujoco"):
        available_engines(["mujoco"])  # asked for by name: an error, not a skip
