"""SRDF collision pairs: the reader and writer (ElementTree read back independently), skip_pairs
against pinocchio's removeCollisionPairs on example-robot-data's shipped SRDFs, MoveIt's adjacency
rule on hand-made trees, and the SRDF sampled for JVRC-1 (adjacent pairs from the URDF's joints read
with ElementTree; fewer random configurations in collision once pruned)."""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree

import numpy as np
import pytest

from spq.collision_pairs import ADJACENT, REASONS, adjacent_links, default_configuration, skip_pairs
from spq.io.srdf import read_srdf, write_srdf
from tests.conftest import require_shared_datasets


def test_round_trip_keeps_every_pair_and_reason(tmp_path):
    pairs = [("base", "arm", "Adjacent"), ("arm", "hand", "Never"), ("base", "hand", "")]
    path = write_srdf(tmp_path / "r.srdf", "toy", pairs, comment="made -- by a test")
    assert read_srdf(path) == pairs
    root = ElementTree.parse(path).getroot()  # the file as any SRDF reader sees it
    assert root.tag == "robot" and root.get("name") == "toy"
    assert [(e.get("link1"), e.get("link2"), e.get("reason")) for e in root.iter("disable_collisions")] == pairs


def test_reader_keeps_a_pair_once_in_either_order(tmp_path):
    path = tmp_path / "d.srdf"
    path.write_text('<robot name="r"><group name="g"/><disable_collisions link1="a" link2="b" reason="Never"/>'
                    '<disable_collisions link1="b" link2="a" reason="Default"/>'
                    '<disable_collisions link1="a" link2="c"/></robot>')
    assert read_srdf(path) == [("a", "b", "Never"), ("a", "c", "")]


@pytest.mark.parametrize("text, match", [
    ("<robot name='r'><disable_collisions link1='a'", "well-formed"),
    ("<model name='r'/>", "root element"),
    ("<robot name='r'><disable_collisions link1='a' reason='Never'/></robot>", "link2"),
    ("<robot name='r'><disable_collisions link1='' link2='b'/></robot>", "link1"),
    ("<robot name='r'><enable_collisions link1='a' link2='b'/></robot>", "enable_collisions"),
])
def test_bad_srdf_raises_value_error(tmp_path, text, match):
    path = tmp_path / "bad.srdf"
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        read_srdf(path)


def test_missing_file_and_bad_pairs_raise_value_error(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        read_srdf(tmp_path / "absent.srdf")
    with pytest.raises(ValueError, match="pairs\\[0\\]"):
        write_srdf(tmp_path / "w.srdf", "r", [("a",)])
    with pytest.raises(ValueError, match="robot_name"):
        write_srdf(tmp_path / "w.srdf", "", [])
    bodies = [("a", "A"), ("b", "B")]
    with pytest.raises(ValueError, match="unknown link"):
        skip_pairs(bodies, [("A", "NOPE", "Never")], link_names=["A", "B"])
    assert skip_pairs(bodies, [("A", "NOPE", "Never")], link_names=["A", "B"], unknown="ignore") == []


def test_skip_pairs_expands_links_to_their_bodies():
    bodies = [("A#0", "A"), ("A#1", "A"), ("B", "B"), ("D", "D")]  # link C has no body
    got = skip_pairs(bodies, [("A", "B", "Never"), ("B", "A"), ("C", "D", "Adjacent"), ("A", "A")],
                     link_names=["A", "B", "C", "D"])
    assert got == [("A#0", "B"), ("A#1", "B")]


def test_adjacency_passes_through_links_without_geometry():
    # 0 - 1 - 2 - 3 and 1 - 4, 4 - 5 - 6; links 1 and 5 have no geometry. By hand (MoveIt's rule):
    # 0, 2, 4 meet through 1; 2 - 3 share a joint; 4 - 6 meet through 5.
    parent = [-1, 0, 1, 2, 1, 4, 5]
    assert adjacent_links(parent, {0, 2, 3, 4, 6}) == {(0, 2), (0, 4), (2, 4), (2, 3), (4, 6)}
    assert adjacent_links(parent, {0, 3}) == {(0, 3)}  # a whole chain without geometry in between


def test_default_configuration_is_zero_or_the_middle_of_the_limits():
    class Limits:
        lower, upper = np.array([-1.0, 0.2, -3.0]), np.array([1.0, 0.6, -1.0])

    assert np.array_equal(default_configuration(Limits), [0.0, 0.4, -2.0])


def _pinocchio_link_pairs(model, geom):
    frames = model.frames
    return {frozenset((frames[geom.geometryObjects[p.first].parentFrame].name,
                       frames[geom.geometryObjects[p.second].parentFrame].name)) for p in geom.collisionPairs}


@pytest.mark.parametrize("robot", ["panda", "talos_reduced", "ur5_gripper"])
def test_skip_pairs_remove_what_pinocchio_removes(robot):
    """pinocchio's removeCollisionPairs on the shipped SRDF (its own URDF and SRDF parsers) removes
    the same link pairs as skip_pairs, over the pairs pinocchio has (it never pairs geometries that
    share a joint)."""
    pin = pytest.importorskip("pinocchio")
    from datasets import example_robots as er

    urdf, srdf = er.robot_urdf(robot), er.robot_srdf(robot)
    assert srdf is not None
    model = pin.buildModelFromUrdf(str(urdf))
    geom = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION,
                                package_dirs=[str(er.package_root().parent)])
    geom.addAllCollisionPairs()
    before = _pinocchio_link_pairs(model, geom)
    pin.removeCollisionPairs(model, geom, str(srdf), False)
    removed = before - _pinocchio_link_pairs(model, geom)

    spq_model = er.load_model(robot)
    bodies = [(link + (f"#{k}" if len(geoms) > 1 else ""), link)
              for link, geoms in zip(spq_model.link_names, spq_model.link_geometry) for k in range(len(geoms))]
    link_of = dict(bodies)
    skipped = skip_pairs(bodies, read_srdf(srdf), link_names=spq_model.link_names, unknown="ignore")
    mine = {frozenset((link_of[a], link_of[b])) for a, b in skipped}
    assert len(removed) > 10
    assert mine & before == removed


def test_robot_srdf_finds_shipped_files():
    from datasets import example_robots as er

    assert er.robot_srdf("panda").name == "panda.srdf"
    assert er.robot_srdf("talos_left_arm").name == "talos.srdf"
    assert er.robot_srdf("tiago") is None
    with pytest.raises(ValueError, match="unknown robot"):
        er.robot_srdf("no_such_robot")


def _joined_links_from_urdf(urdf) -> set[frozenset]:
    """Link pairs joined by one joint, both links with geometry, read straight from the URDF."""
    root = ElementTree.parse(urdf).getroot()
    geometric = {link.get("name") for link in root.findall("link") if link.find("collision") is not None
                 or link.find("visual") is not None}
    out = set()
    for joint in root.findall("joint"):
        a, b = joint.find("parent").get("link"), joint.find("child").get("link")
        if a in geometric and b in geometric:
            out.add(frozenset((a, b)))
    return out


def test_jvrc1_srdf_disables_adjacent_pairs_and_the_pair_always_in_collision():
    """The committed JVRC-1 SRDF (sampled on the PCH scene) lists every pair of links joined by a
    joint as Adjacent. With its pairs skipped, no pair is in collision at nearly every random
    configuration any more (PELVIS_S - WAIST_R_S is, in the scene that skips only adjacent bodies), and
    fewer configurations and fewer pairs per configuration are in collision. (Pairs in collision at a
    third of the configurations, such as PELVIS_S - R_HIP_Y_S, stay: MoveIt's rules keep them.)"""
    require_shared_datasets()
    from datasets.robots import robot_files
    from datasets.srdf import generated_srdf
    from spq.kernels.gjk import OUT_STATUS, OVERLAPPING, TOUCHING
    from spq.scene import Scene

    srdf = generated_srdf("jvrc1")
    assert srdf is not None, "datasets/srdf/jvrc1.srdf is missing"
    pairs = read_srdf(srdf)
    assert {r for _, _, r in pairs} <= set(REASONS)
    adjacent = {frozenset((a, b)) for a, b, r in pairs if r == ADJACENT}
    files = robot_files("jvrc1")
    assert _joined_links_from_urdf(files.urdf) <= adjacent

    plain = Scene.from_urdf(files.urdf, convex_dir=files.convex_dir, policy="pch")
    skip = skip_pairs(plain.bodies, pairs, link_names=plain.model.link_names)
    pruned = Scene(plain.model, plain.bodies, policy="pch", skip=skip)
    assert len(pruned.pairs) < len(plain.pairs)
    qs = plain.model.random_configuration(np.random.default_rng(123), 200)

    def collisions(scene):
        status = scene.distances_many(qs, prune=1e-9)[:, :, OUT_STATUS]
        return (status == OVERLAPPING) | (status == TOUCHING)  # (configurations, pairs)

    before, after = collisions(plain), collisions(pruned)
    assert before.mean(axis=0).max() > 0.95 and after.mean(axis=0).max() < 0.95
    assert after.any(axis=1).mean() < before.any(axis=1).mean() - 0.1
    assert after.sum(axis=1).mean() < before.sum(axis=1).mean() - 0.5



def test_srdf_reasons_honours_only_the_named_reasons():
    """Scene.from_urdf(srdf=, srdf_reasons=): with ('Adjacent', 'Default') the 'Never' pairs stay in the
    scene (a controller must watch them); the pair counts follow the file as ElementTree reads it."""
    require_shared_datasets()
    from datasets.robots import robot_files
    from datasets.srdf import generated_srdf
    from spq.scene import Scene

    files, srdf = robot_files("jvrc1"), generated_srdf("jvrc1")
    root = ElementTree.parse(srdf).getroot()
    never = {frozenset((e.get("link1"), e.get("link2"))) for e in root.iter("disable_collisions")
             if e.get("reason") == "Never"}
    every = Scene.from_urdf(files.urdf, convex_dir=files.convex_dir, policy="pch", srdf=srdf)
    kept = Scene.from_urdf(files.urdf, convex_dir=files.convex_dir, policy="pch", srdf=srdf,
                           srdf_reasons=("Adjacent", "Default", "Always"))
    links = kept.model.link_names

    def link_pairs(scene):
        return {frozenset((links[scene.bodies[a].link], links[scene.bodies[b].link])) for a, b in scene.pairs}

    assert never and never <= link_pairs(kept) and not never & link_pairs(every)
    assert link_pairs(kept) - link_pairs(every) == never  # JVRC-1: one body per link
    with pytest.raises(ValueError, match="collection of reasons"):
        Scene.from_urdf(files.urdf, convex_dir=files.convex_dir, srdf=srdf, srdf_reasons="Never")


def test_sampling_agrees_with_coal_on_the_same_hulls():
    """disabled_pairs_by_sampling on JVRC-1's PCH scene against pinocchio's kinematics and coal's
    distances on the same hulls (harness.engines.pinocchio_peer) at other random configurations: no pair that
    coal finds in collision in 2% of them or more is 'Never' (2200 samples would all miss a pair in
    collision 1% of the time with probability 2e-10); the pairs coal finds overlapping at the default
    configuration are Adjacent or Default, and every Default pair is in collision there for coal."""
    require_shared_datasets()
    from datasets.robots import robot_files
    from harness.engines import pinocchio_peer
    from spq.collision_pairs import DEFAULT, NEVER, disabled_pairs_by_sampling
    from spq.scene import Scene

    files = robot_files("jvrc1")
    scene = Scene.from_urdf(files.urdf, convex_dir=files.convex_dir, policy="pch", skip_adjacent=False)
    reason = {frozenset((a, b)): r for a, b, r in disabled_pairs_by_sampling(scene, samples=2000, seed=5)}
    links = scene.model.link_names
    pair_links = [frozenset((links[scene.bodies[a].link], links[scene.bodies[b].link])) for a, b in scene.pairs]
    peer = pinocchio_peer.build(scene, files.urdf)
    qs = scene.model.random_configuration(np.random.default_rng(99), 300)
    coal_d = np.array([peer.distances(peer.configuration(q)) for q in qs])  # (configurations, pairs)
    share = (coal_d <= 1e-6).mean(axis=0)
    often = {pair_links[p] for p in np.flatnonzero(share >= 0.02)}
    assert len(often) >= 5
    assert not [sorted(k) for k in often if reason.get(k) == NEVER]
    at_default = peer.distances(peer.configuration(default_configuration(scene.model)))
    overlapping = {pair_links[p] for p in np.flatnonzero(at_default < -1e-6)}
    assert all(reason.get(k) in (ADJACENT, DEFAULT) for k in overlapping)
    touching = {pair_links[p] for p in np.flatnonzero(at_default <= 1e-6)}
    assert {k for k, r in reason.items() if r == DEFAULT} <= touching


def test_spq_srdf_command_writes_a_sampled_srdf(tmp_path):
    """`spq srdf` on the KUKA iiwa (pybullet_data): the file reads back, names only the URDF's links,
    and lists each pair of links joined by a joint (read with ElementTree) as Adjacent."""
    from datasets.robots import robot_files
    from harness.cli import main

    urdf = robot_files("kuka_iiwa").urdf
    if not urdf.is_file():
        pytest.skip(f"pybullet_data's KUKA iiwa not found at {urdf}")
    out = tmp_path / "kuka.srdf"
    assert main(["srdf", "kuka_iiwa", "--out", str(out), "--samples", "300", "--seed", "1"]) == 0
    pairs = read_srdf(out)
    links = {link.get("name") for link in ElementTree.parse(urdf).getroot().findall("link")}
    assert {n for a, b, _ in pairs for n in (a, b)} <= links
    assert {r for _, _, r in pairs} <= set(REASONS)
    assert _joined_links_from_urdf(urdf) <= {frozenset((a, b)) for a, b, r in pairs if r == ADJACENT}
    assert "300 random configurations" in out.read_text()
