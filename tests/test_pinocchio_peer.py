"""The pinocchio peer: pinocchio's own URDF kinematics and coal distances on spq's scene, checked
against spq's kinematics and spq's distances (two independent implementations)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pinocchio", reason="pin not installed (pip install pin)")

from datasets.robots import robot_files  # noqa: E402
from harness.engines import pinocchio_peer as pp  # noqa: E402
from harness.suites.robot.robot_bench import RobotBenchConfig, load_scene  # noqa: E402
from harness.workloads.robot_poses import random_configurations  # noqa: E402

pytestmark = pytest.mark.engines


@pytest.fixture(scope="module")
def kuka():
    scene = load_scene(RobotBenchConfig(robot="kuka_iiwa"), "pch")
    return scene, pp.build(scene, robot_files("kuka_iiwa").urdf)


def test_pinocchio_places_every_body_where_spq_does(kuka):
    import pinocchio as pin

    scene, peer = kuka
    for q in random_configurations(scene.model, 5, 1):
        pin.computeDistances(peer.model, peer.data, peer.geometry, peer.geometry_data, peer.configuration(q))
        for b, pose in enumerate(scene.body_poses(q)):
            placed = peer.geometry_data.oMg[b].homogeneous
            assert np.allclose(placed, pose, atol=1e-9), scene.bodies[b].name


def test_pinocchio_distances_agree_with_spq(kuka):
    scene, peer = kuka
    qs = random_configurations(scene.model, 20, 2)
    for q in qs:
        mine = scene.distances(q, coherent=False)
        theirs = peer.distances(peer.configuration(q))
        separated = mine.status == "separated"
        assert np.abs(theirs[separated] - mine.distance[separated]).max() < 1e-5
        assert np.all(theirs[mine.status == "overlapping"] <= 1e-6)


def test_pinocchio_on_auto_volumes_brackets_spq_auto_from_above_by_the_meshes_error():
    """pinocchio (coal) on each pair's STP side as the STP-BV's certified mesh, which lies inside the
    STP-BV within its error: an external oracle for spq's auto distances, at or above them by at most
    the mesh's error (beside coal's 1e-6 m GJK tolerance)."""
    scene = load_scene(RobotBenchConfig(robot="kuka_iiwa"), "auto")
    shapes, errors = pp.stp_mesh_shapes(scene, 1e-3)
    stp_sides = {i for pair, sides in zip(scene.pairs.tolist(), scene.pair_kinds) for i, s in zip(pair, sides)
                 if s == "stp"}
    assert stp_sides and set(shapes) == set(errors) == {i for i in stp_sides if scene.bodies[i].stp is not None}
    peer = pp.build(scene, robot_files("kuka_iiwa").urdf, stp_shapes=shapes)
    assert len(peer.geometry.geometryObjects) == len(scene.bodies) + len(shapes)
    for q in random_configurations(scene.model, 20, 3):
        mine = scene.distances(q, coherent=False)
        theirs = peer.distances(peer.configuration(q))
        separated = mine.status == "separated"
        diff = theirs[separated] - mine.distance[separated]
        assert diff.min() >= -1e-6 and diff.max() <= max(errors.values()) + 1e-6
        assert np.all(theirs[mine.status == "overlapping"] <= max(errors.values()) + 1e-6)


def test_unknown_variant_is_refused(kuka):
    scene, _ = kuka
    with pytest.raises(ValueError, match="variant"):
        pp.build(scene, robot_files("kuka_iiwa").urdf, "fastest")


def test_without_pin_the_robot_bench_says_why_pinocchio_did_not_run(kuka, monkeypatch):
    import sys

    from harness.suites.robot.robot_bench import pinocchio_table

    monkeypatch.setitem(sys.modules, "pinocchio", None)
    scene, _ = kuka
    table = pinocchio_table(RobotBenchConfig(robot="kuka_iiwa"), {"pch": scene}, None, None)
    assert len(table) == 1 and table.status[0].startswith("not run:") and "pip install pin" in table.status[0]
