"""The robots of example-robot-data: the catalogue, the loader's bodies and pairs against the URDF
read independently (ElementTree), exact primitives, the failures' reasons, and spq's distances on
loaded robots against coal's (and the bodies' poses against pinocchio's kinematics)."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import pytest

from datasets import example_robots as er

try:
    ROOT = er.package_root()
except ValueError as exc:  # the pip package is missing: its message says how to install it
    pytest.skip(str(exc), allow_module_level=True)

from spq.kinematics import MeshGeometry  # noqa: E402
from spq.shapes.primitives import Box, Capsule, Sphere  # noqa: E402


def urdf_tree(name: str):
    """({link: [(geometry tag, its attributes)] of its collision elements, else its visual ones},
    {link: parent link}) read straight from the URDF file."""
    root = ElementTree.parse(er.robot_urdf(name)).getroot()
    geoms = {}
    for link in root.findall("link"):
        elements = link.findall("collision") or link.findall("visual")
        geoms[link.get("name")] = [(g.tag, g.attrib) for g in (next(iter(e.find("geometry"))) for e in elements)]
    # top-level joints only: a <transmission> names joints too
    parent = {j.find("child").get("link"): j.find("parent").get("link") for j in root.findall("joint")}
    return geoms, parent


def expected_pairs(name: str) -> tuple[int, int]:
    """(bodies, pairs) by the rule the module states: every body pair except those on one link or on a
    link and its nearest ancestor that has a body. Computed from the raw URDF, not spq's reader."""
    geoms, parent = urdf_tree(name)
    bodies = [link for link, g in geoms.items() for _ in g]

    def nearest_with_body(link):
        up = parent.get(link)
        while up is not None and not geoms.get(up):
            up = parent.get(up)
        return up

    pairs = 0
    for i in range(len(bodies)):
        for j in range(i + 1, len(bodies)):
            a, b = bodies[i], bodies[j]
            if a == b or nearest_with_body(a) == b or nearest_with_body(b) == a:
                continue
            pairs += 1
    return len(bodies), pairs


def test_every_urdf_of_the_package_is_one_robot():
    files = sorted(ROOT.joinpath("robots").rglob("*.urdf"))
    names = er.robot_names()
    assert len(names) == len(files) >= 60 and len(set(names)) == len(names)
    assert sorted(er.robot_urdf(n) for n in names) == files
    assert {"anymal_b_simple_description/anymal", "anymal_c_simple_description/anymal"} <= set(names)  # same stem


def test_an_unknown_robot_is_a_clear_value_error():
    for call in (er.robot_urdf, er.load_model, er.load_scene):
        with pytest.raises(ValueError, match="unknown robot 'no_such_robot'.*known: .*ur5_robot"):
            call("no_such_robot")


def test_a_missing_package_is_a_clear_value_error(monkeypatch):
    from importlib import metadata

    def missing(name):
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(metadata, "distribution", missing)
    with pytest.raises(ValueError, match="pip install example-robot-data"):
        er.package_root()


@pytest.mark.parametrize("name", ["ur5_robot", "panda", "a1", "solo12", "b1", "talos_left_arm"])
def test_bodies_and_pairs_match_the_urdf_and_every_mesh_is_found(name):
    model = er.load_model(name)
    meshes = [g for geoms in model.link_geometry for g in geoms if isinstance(g, MeshGeometry)]
    assert bool(meshes) == (name not in ("a1", "b1"))  # these two collide with boxes, spheres, cylinders only
    assert all(Path(g.filename).is_file() and Path(g.filename).is_relative_to(ROOT.resolve()) for g in meshes)
    scene = er.load_scene(name)
    bodies, pairs = expected_pairs(name)
    assert (len(scene.bodies), len(scene.pairs)) == (bodies, pairs)
    assert 0 < pairs < bodies * (bodies - 1) // 2
    for b in scene.bodies:  # robot-sized hulls, each holding its exact primitive
        assert 1e-4 < b.hull.bounding_radius() < 2.0, b.name  # a1 has a 1 mm dummy box
        if b.shape is not None:
            assert b.shape.bounding_radius() <= b.hull.bounding_radius() * (1 + 1e-12) + 1e-12, b.name


def test_every_form_of_mesh_filename_resolves_inside_the_package():
    urdf = er.robot_urdf("talos_full_v2")
    inner = "robots/talos_data/meshes/torso/torso_2_collision.STL"
    expected = (ROOT / inner).resolve()
    for filename in (f"package://example-robot-data/{inner}", f"package:///example-robot-data/{inner}",
                     f"file://{ROOT / inner}", f"../../../{inner}"):
        assert er.resolve_mesh(filename, urdf) == expected, filename
    assert er.resolve_mesh("package://b1_description/meshes/trunk.dae", er.robot_urdf("b1")) == (
        ROOT / "robots/b1_description/meshes/trunk.dae").resolve()
    with pytest.raises(ValueError, match="mesh 'package://nowhere/x.stl' not found"):
        er.resolve_mesh("package://nowhere/x.stl", urdf)


def test_primitives_become_spq_shapes_and_cylinders_circumscribing_prisms():
    scene = er.load_scene("a1")
    sizes, _ = urdf_tree("a1")
    seen = set()
    for b in scene.bodies:
        link = scene.model.link_names[b.link]
        k = int(b.name.split("#")[1]) if "#" in b.name else 0
        tag, attrib = sizes[link][k]
        seen.add(tag)
        if tag == "box":
            assert isinstance(b.shape, Box)
            assert np.allclose(2 * b.shape.half_extents, [float(v) for v in attrib["size"].split()])
        elif tag == "sphere":
            assert isinstance(b.shape, Sphere) and b.shape.radius == float(attrib["radius"])
        elif tag == "cylinder":
            radius, length = float(attrib["radius"]), float(attrib["length"])
            v = b.hull.vertices
            rho = np.hypot(v[:, 0], v[:, 1])
            assert b.shape is None
            assert np.isclose(np.ptp(v[:, 2]), length)
            # a 64-gon around the circle: corners at r / cos(pi/64), every face at distance r
            assert np.isclose(rho.max(), radius / math.cos(math.pi / 64))
            assert np.isclose(np.abs(b.hull.face_offsets[np.abs(b.hull.face_normals[:, 2]) < 1e-9]).min(), radius)
    assert seen == {"box", "sphere", "cylinder"}


def test_pinocchio_collision_capsule_becomes_a_capsule():
    scene = er.load_scene("simple_humanoid")
    caps = [b for b in scene.bodies if isinstance(b.shape, Capsule)]
    # <cylinder radius="1" length="1"/> named "test", listed under <collision_checking><capsule name="test"/>
    assert len(caps) == 1 and caps[0].shape.radius == 1.0 and caps[0].shape.half_length == 0.5
    assert len(scene.pairs) == 0  # both bodies sit on the pelvis


@pytest.mark.parametrize("name, reason", [
    ("romeo_laas_small", "link 'body'.*TrunkYaw.mesh' not found"),
    ("ur3", "not a readable URDF"),
    ("alex_psyonic_hands", "mimics 'index_q1', which is not a movable joint"),
    ("simple_humanoid_classical", "at least one body"),
])
def test_a_robot_that_cannot_load_says_why(name, reason):
    with pytest.raises(ValueError, match=reason):
        er.load_scene(name)


def test_robots_sharing_meshes_share_hulls():
    cache = {}
    a = er.load_scene("ur5_robot", hull_cache=cache)
    b = er.load_scene("ur5_joint_limited_robot", hull_cache=cache)
    assert [x.hull for x in a.bodies] == [y.hull for y in b.bodies]
    assert all(x.hull is y.hull for x, y in zip(a.bodies, b.bodies))


@pytest.mark.parametrize("name", ["a1", "panda", "ur5_gripper"])
def test_spq_distances_agree_with_coal_on_loaded_robots(name):
    """Oracle: coal (another GJK/EPA, its own Sphere/Box and Convex) at the same body poses."""
    coal = pytest.importorskip("coal")
    from harness.engines.coal_engine import CoalPair
    from harness.engines.pinocchio_peer import coal_geometry
    from harness.workloads.robot_poses import random_configurations

    pch = er.load_scene(name)
    auto = pch.with_policy("auto")
    request = coal.DistanceRequest()
    request.gjk_tolerance = 1e-9
    geometry = [coal_geometry(b) for b in pch.bodies]
    for q in random_configurations(pch.model, 4, 7):
        mine = pch.distances(q, coherent=False)
        poses = pch.body_poses(q)
        theirs = np.array([CoalPair(geometry[a], geometry[b], request).query(poses[a], poses[b]).raw_distance
                           for a, b in pch.pairs])
        separated = mine.status == "separated"
        assert separated.any()
        assert np.abs(theirs[separated] - mine.distance[separated]).max() < 1e-7
        assert np.all(theirs[mine.status == "overlapping"] <= 1e-7)
        # auto swaps one side for its STP-BV, which holds the hull: never farther apart than the PCHs
        rounded = auto.distances(q, coherent=False)
        both = separated & (rounded.status == "separated")
        assert np.all(rounded.distance[both] <= mine.distance[both] + 1e-9)


def test_pinocchio_places_the_loaded_bodies_where_spq_does():
    pytest.importorskip("pinocchio")
    from harness.engines import pinocchio_peer as pp
    from harness.workloads.robot_poses import random_configurations

    scene = er.load_scene("a1")
    peer = pp.build(scene, er.robot_urdf("a1"))
    import pinocchio as pin

    for q in random_configurations(scene.model, 3, 3):
        pin.computeDistances(peer.model, peer.data, peer.geometry, peer.geometry_data, peer.configuration(q))
        for k, pose in enumerate(scene.body_poses(q)):
            assert np.allclose(peer.geometry_data.oMg[k].homogeneous, pose, atol=1e-9), scene.bodies[k].name
