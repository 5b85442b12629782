"""Scenes with exact primitives (Scene.from_urdf(primitives="exact"), from_model, with_policy, the
hull cache): distances against closed forms (ball-ball, ball-box, ball-capsule), the hulls
circumscribing their primitives, policies derived without rebuilding."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from spq.kinematics import PrimitiveGeometry
from spq.scene import Scene
from spq.shapes.primitives import Box, Capsule, Sphere

URDF = """<?xml version="1.0"?>
<robot name="prims">
  <link name="base"><collision><geometry><box size="0.2 0.1 0.06"/></geometry></collision></link>
  <link name="l1"><collision><origin xyz="0.3 0 0"/><geometry><sphere radius="0.05"/></geometry></collision></link>
  <link name="l2"><collision><origin xyz="0.3 0 0"/><geometry><cylinder radius="0.03" length="0.1"/></geometry></collision></link>
  <link name="l3"><collision><origin xyz="0.2 0 0"/><geometry><sphere radius="0.04"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.3 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0.3 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3"/></joint>
</robot>
"""


@pytest.fixture
def urdf(tmp_path):
    path = tmp_path / "prims.urdf"
    path.write_text(URDF)
    return path


def ball_box_distance(centre_in_box: np.ndarray, half: np.ndarray, radius: float) -> float:
    """Closed form: distance from a point to an axis-aligned box, minus the ball's radius."""
    return float(np.linalg.norm(np.maximum(np.abs(centre_in_box) - half, 0.0))) - radius


def test_exact_primitives_answer_the_closed_forms(urdf):
    scene = Scene.from_urdf(urdf, policy="pch", primitives="exact")
    kinds = [type(b.shape).__name__ if b.shape is not None else "hull" for b in scene.bodies]
    assert kinds == ["Box", "Sphere", "hull", "Sphere"]  # the cylinder keeps its circumscribing prism
    names = scene.pair_names
    rng = np.random.default_rng(4)
    checked = 0
    for q in scene.model.random_configuration(rng, 40):
        res = scene.distances(q, coherent=False)
        poses = scene.body_poses(q)
        for k, (a, b) in enumerate(names):
            ia, ib = scene.body_names.index(a), scene.body_names.index(b)
            sa, sb = scene.bodies[ia].shape, scene.bodies[ib].shape
            if isinstance(sa, Box) and isinstance(sb, Sphere):
                local = np.linalg.solve(poses[ia], poses[ib][:, 3])[:3]
                expected = ball_box_distance(local, sa.half_extents, sb.radius)
            elif isinstance(sa, Sphere) and isinstance(sb, Sphere):
                expected = np.linalg.norm(poses[ia][:3, 3] - poses[ib][:3, 3]) - sa.radius - sb.radius
            else:
                continue
            if expected > 1e-9:
                assert res.status[k] == "separated" and abs(res.distance[k] - expected) < 1e-9, (a, b)
                checked += 1
            elif expected < -1e-9:
                assert res.status[k] == "overlapping", (a, b)
    assert checked > 20


def test_hull_mode_stays_the_default_and_circumscribes(urdf):
    hulls = Scene.from_urdf(urdf, policy="pch")
    exact = Scene.from_urdf(urdf, policy="pch", primitives="exact")
    assert all(b.shape is None for b in hulls.bodies)
    for h, e in zip(hulls.bodies, exact.bodies):
        if isinstance(e.shape, Sphere):  # every hull face at least the radius from the centre
            assert h.hull.face_offsets.min() >= e.shape.radius - 1e-12
    q = np.full(3, 0.7)
    d_hull, d_exact = hulls.distances(q).distance, exact.distances(q).distance
    assert np.all(d_hull <= d_exact + 1e-12)  # circumscribing covers are never farther apart
    with pytest.raises(ValueError, match="unknown primitives mode 'mesh'"):
        Scene.from_urdf(urdf, primitives="mesh")


def test_a_capsule_geometry_is_an_exact_capsule_inside_its_hull(urdf):
    from spq.io.urdf import read_urdf

    model = read_urdf(urdf)
    ball = model.link_geometry[1][0]
    geometry = list(model.link_geometry)
    geometry[1] = (PrimitiveGeometry("capsule", np.array([0.05, 0.1]), ball.origin),)
    scene = Scene.from_model(dataclasses.replace(model, link_geometry=tuple(geometry)), policy="pch",
                             primitives="exact")
    body = scene.bodies[1]
    assert isinstance(body.shape, Capsule) and body.shape.radius == 0.05 and body.shape.half_length == 0.05
    # the hull circumscribes: each face plane lies beyond the capsule's support in its normal
    support = np.abs(body.hull.face_normals[:, 2]) * 0.05 + 0.05
    assert np.all(body.hull.face_offsets >= support - 1e-12)
    # the capsule (l1) against the ball of l3: closed form, the ball's centre to the segment
    k = scene.pair_names.index(("l1", "l3"))
    checked = 0
    for q in scene.model.random_configuration(np.random.default_rng(5), 30):
        res = scene.distances(q, coherent=False)
        poses = scene.body_poses(q)
        centre = np.linalg.solve(poses[1], poses[3][:, 3])[:3]  # in the capsule's frame
        nearest = np.array([0.0, 0.0, np.clip(centre[2], -0.05, 0.05)])
        expected = np.linalg.norm(centre - nearest) - 0.05 - 0.04
        if expected > 1e-9:
            assert res.status[k] == "separated" and abs(res.distance[k] - expected) < 1e-9
            checked += 1
    assert checked > 10


def test_with_policy_shares_bodies_and_keeps_the_pairs(urdf):
    cache = {}
    pch = Scene.from_urdf(urdf, policy="pch", primitives="exact", hull_cache=cache)
    again = Scene.from_urdf(urdf, policy="pch", primitives="exact", hull_cache=cache)
    assert all(a.hull is b.hull for a, b in zip(pch.bodies, again.bodies))
    auto = pch.with_policy("auto")
    direct = Scene.from_urdf(urdf, policy="auto", primitives="exact")
    assert np.array_equal(auto.pairs, pch.pairs) and auto.pair_kinds == direct.pair_kinds
    assert all(a.hull is b.hull and a.shape is b.shape for a, b in zip(auto.bodies, pch.bodies))
    # spheres are strictly convex already: no STP-BV, the sphere stands on the STP side
    assert [b.stp is None for b in auto.bodies] == [False, True, False, True]
    qs = pch.model.random_configuration(np.random.default_rng(6), 20)
    assert np.array_equal(auto.distances_many(qs), direct.distances_many(qs))
    assert auto.with_policy("pch").pair_kinds == pch.pair_kinds


def test_an_stp_bv_takes_the_same_hull_in_another_vertex_order():
    import spq
    from spq.shapes.polyhedron import Polyhedron
    from spq.shapes.stpbv import STPBV

    rng = np.random.default_rng(8)
    points = rng.normal(size=(60, 3)) * [0.05, 0.03, 0.08]
    own, swapped = STPBV.from_points(points, 0.005, 2.0), STPBV.from_points(points, 0.005, 2.0)
    other = Polyhedron.from_points(swapped.hull.vertices[::-1])
    assert not np.array_equal(other.vertices, swapped.hull.vertices)
    assert swapped.use_hull(other) and swapped.hull is other
    assert not own.use_hull(Polyhedron.from_points(points * 1.01))  # another polytope: kept its own
    box = spq.Box(0.02, 0.03, 0.04)
    for _ in range(20):
        pose = np.eye(4)
        pose[:3, 3] = rng.normal(size=3) * 0.2
        a, b = spq.distance(own, box, np.eye(4), pose), spq.distance(swapped, box, np.eye(4), pose)
        assert a.status == b.status and abs(a.distance - b.distance) <= 1e-12
