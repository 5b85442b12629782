"""Robot kinematics: URDF reading (spq.io.urdf), RobotModel checks, compiled forward kinematics.

Oracles: pybullet's link frames for JVRC-1, the KUKA iiwa and the Franka Panda; hand-composed
transforms for a small URDF with continuous, prismatic and mimic joints; the URDF files themselves
(counts, the JVRC-1 hull files named after the link meshes).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from datasets.paths import pybullet_data_dir
from datasets.robots import ROBOTS, link_shape_file, robot_files, robot_urdf
from harness.references.pybullet_kinematics import PybulletRobot, quaternion_matrix
from spq.io.urdf import read_urdf
from spq.kernels.kinematics import within_limits
from spq.kinematics import (CONTINUOUS, FIXED, LIMIT_SLACK, PRISMATIC, REVOLUTE, MeshGeometry, PrimitiveGeometry,
                           RobotModel)

FK_TOL = 1e-9  # m for positions, dimensionless for rotation-matrix entries
N_CONFIGURATIONS = 20
PYBULLET_URDFS = {"kuka_iiwa": "kuka_iiwa/model.urdf", "panda": "franka_panda/panda.urdf"}
JVRC1_URDF = "jvrc1/urdf/jvrc1.urdf"


def _urdf_path(robot: str, request) -> Path:
    if robot == "jvrc1":
        return request.getfixturevalue("shared_datasets") / JVRC1_URDF
    return pybullet_data_dir() / PYBULLET_URDFS[robot]


# ---------------------------------------------------------------- JVRC-1 as described by its URDF


def test_jvrc1_has_60_links_44_revolute_joints_and_34_dofs_with_mimic(shared_datasets):
    model = read_urdf(shared_datasets / JVRC1_URDF)
    assert model.name == "jvrc1" and model.nlinks == 60 and model.link_names[0] == "base_link"
    assert (model.joint_type == REVOLUTE).sum() == 44
    assert (model.joint_type == FIXED).sum() == 16  # 15 fixed joints and the root
    # the 10 finger joints mimic R_UTHUMB / L_UTHUMB: they share its entry of q
    assert model.ndof == 34 and set(model.q_multiplier[model.joint_type != FIXED]) == {1.0, -1.0, 3.0, -3.0}
    thumb = model.joint_names.index("R_UTHUMB")
    followers = {model.link_joint_names[i] for i in np.flatnonzero(model.q_index == thumb)}
    assert followers == {"R_UTHUMB", "R_LTHUMB", "R_UINDEX", "R_LINDEX", "R_ULITTLE", "R_LLITTLE"}
    independent = read_urdf(shared_datasets / JVRC1_URDF, follow_mimic=False)
    assert independent.ndof == 44 and (independent.q_multiplier == 1.0).all()


def test_jvrc1_35_link_meshes_each_have_a_convex_hull_file(shared_datasets):
    model = read_urdf(shared_datasets / JVRC1_URDF)
    meshes = {}
    for name, geometry in zip(model.link_names, model.link_geometry):
        assert all(isinstance(g, MeshGeometry) for g in geometry)
        if geometry:
            assert len(geometry) == 1
            meshes[name] = geometry[0].filename
    assert len(meshes) == 35
    convex = shared_datasets / "jvrc1" / "convex"
    for link, filename in meshes.items():
        base = Path(filename).name
        assert base.endswith(".dae")
        assert (convex / f"{base[: -len('.dae')]}-ch.txt").is_file(), (link, filename)
    assert {Path(f).stem for f in meshes.values()} == {p.name[: -len("-ch.txt")] for p in convex.glob("*-ch.txt")}


# ---------------------------------------------------------------- forward kinematics against pybullet


@pytest.mark.engines
@pytest.mark.parametrize("robot", ["jvrc1", "kuka_iiwa", "panda"])
def test_link_poses_match_pybullet_link_frames(robot, request):
    path = _urdf_path(robot, request)
    model = read_urdf(path)
    with PybulletRobot(path, model, strip_geometry=robot == "jvrc1") as bullet:
        assert len(bullet.joint_info) == model.nlinks - 1
        assert [model.link_joint_names[i] for i in bullet.links] == [row[1].decode() for row in bullet.joint_info]
        assert bullet.fixed_joints_agree()
        # the root's link frame is the world frame in pybullet as in our model
        np.testing.assert_allclose(bullet.base_frame(), np.eye(4), rtol=0, atol=FK_TOL)
        rng = np.random.default_rng(20240606)
        for _ in range(N_CONFIGURATIONS):
            q = model.random_configuration(rng)
            poses = model.link_poses(q)
            expected = bullet.link_frames(q)
            np.testing.assert_allclose(poses, expected, rtol=0, atol=FK_TOL)
            # pybullet's single-precision link frame (getLinkState 4, 5): same frame, coarser digits
            for state, i in zip(bullet.link_states(), bullet.links):
                assert np.abs(poses[i, :3, 3] - state[4]).max() < 1e-6
                assert np.abs(poses[i, :3, :3] - quaternion_matrix(state[5])).max() < 1e-6


# ---------------------------------------------------------------- a small URDF with every joint type

TOY_URDF = """<?xml version="1.0"?>
<robot name="toy">
  <link name="slider">
    <collision><geometry><sphere radius="0.02"/></geometry></collision>
    <collision><origin xyz="0 0 0.01"/>
      <geometry><mesh filename="package://toy/meshes/tip.stl" scale="0.001 0.001 0.001"/></geometry></collision>
  </link>
  <link name="base">
    <collision><origin xyz="0 0 0.1"/><geometry><box size="0.2 0.3 0.4"/></geometry></collision>
  </link>
  <link name="arm">
    <visual><geometry><cylinder radius="0.05" length="0.5"/></geometry></visual>
  </link>
  <link name="follower"/>
  <joint name="spin" type="continuous">
    <parent link="base"/><child link="arm"/><origin xyz="1 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="arm"/><child link="slider"/><origin xyz="0 0.5 0"/><axis xyz="0 0 2"/>
    <limit lower="-0.1" upper="0.2" effort="1" velocity="1"/>
  </joint>
  <joint name="follow" type="revolute">
    <parent link="arm"/><child link="follower"/><origin rpy="0 0 1.5707963267948966"/><axis xyz="1 0 0"/>
    <limit lower="-4" upper="4" effort="1" velocity="1"/>
    <mimic joint="spin" multiplier="2" offset="0.1"/>
  </joint>
</robot>
"""


def _rot(axis: str, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    R = {"x": [[1, 0, 0], [0, c, -s], [0, s, c]], "z": [[c, -s, 0], [s, c, 0], [0, 0, 1]]}[axis]
    T = np.eye(4)
    T[:3, :3] = R
    return T


def _trans(x, y, z) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


@pytest.fixture
def toy(tmp_path) -> RobotModel:
    path = tmp_path / "toy.urdf"
    path.write_text(TOY_URDF)
    return read_urdf(path)


def test_toy_links_come_in_tree_order_with_typed_joints_and_limits(toy):
    assert toy.link_names == ("base", "arm", "slider", "follower")
    assert toy.parent.tolist() == [-1, 0, 1, 1]
    assert toy.joint_type.tolist() == [FIXED, CONTINUOUS, PRISMATIC, REVOLUTE]
    assert toy.link_joint_names == ("", "spin", "slide", "follow")
    assert toy.joint_names == ("spin", "slide") and toy.q_index.tolist() == [-1, 0, 1, 0]
    np.testing.assert_array_equal(toy.lower, [-np.pi, -0.1])
    np.testing.assert_array_equal(toy.upper, [np.pi, 0.2])
    np.testing.assert_allclose(toy.joint_axis[2], [0, 0, 1])  # normalised from (0, 0, 2)
    (box,), (cylinder,), (sphere, tip), () = toy.link_geometry  # arm has only a visual: used
    assert isinstance(box, PrimitiveGeometry) and box.kind == "box"
    np.testing.assert_array_equal(box.size, [0.2, 0.3, 0.4])
    np.testing.assert_array_equal(box.origin, _trans(0, 0, 0.1))
    assert cylinder.kind == "cylinder" and cylinder.size.tolist() == [0.05, 0.5]
    assert sphere.kind == "sphere" and sphere.size.tolist() == [0.02]
    assert isinstance(tip, MeshGeometry) and tip.filename == "package://toy/meshes/tip.stl"
    np.testing.assert_array_equal(tip.scale, [0.001] * 3)
    independent = read_urdf(toy.source, follow_mimic=False)
    assert independent.joint_names == ("spin", "slide", "follow") and independent.upper[2] == 4.0


def test_toy_link_poses_equal_hand_composed_transforms(toy):
    q = np.array([0.7, 0.15])
    base = _trans(0.3, -0.2, 1.0) @ _rot("z", -0.4) @ _rot("x", 0.25)
    arm = _trans(1, 0, 0) @ _rot("z", 0.7)
    expected = np.array([
        np.eye(4),
        arm,
        arm @ _trans(0, 0.5, 0) @ _trans(0, 0, 0.15),
        arm @ _rot("z", math.pi / 2) @ _rot("x", 2 * 0.7 + 0.1),  # mimic: 2 * spin + 0.1
    ])
    np.testing.assert_allclose(toy.link_poses(q), expected, rtol=0, atol=1e-15)
    np.testing.assert_allclose(toy.link_poses(q, base=base), base @ expected, rtol=0, atol=1e-15)
    np.testing.assert_allclose(toy.joint_values(q), [0.0, 0.7, 0.15, 1.5], rtol=0, atol=1e-15)


MIMIC_CHAIN = """<robot name="chain"><link name="a"/><link name="b"/><link name="c"/><link name="d"/>
  <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><limit lower="-1" upper="1"/></joint>
  <joint name="j2" type="revolute"><parent link="b"/><child link="c"/><limit lower="-5" upper="5"/>
    <mimic joint="j1" multiplier="2" offset="0.5"/></joint>
  <joint name="j3" type="prismatic"><parent link="c"/><child link="d"/><limit lower="-5" upper="5"/>
    <mimic joint="j2" multiplier="-3" offset="0.25"/></joint>
</robot>"""


def test_a_mimic_of_a_mimic_composes_the_affine_maps_and_a_cycle_is_refused(tmp_path):
    path = tmp_path / "chain.urdf"
    path.write_text(MIMIC_CHAIN)
    model = read_urdf(path)
    assert model.joint_names == ("j1",) and model.q_index.tolist() == [-1, 0, 0, 0]
    # j2 = 2 j1 + 0.5; j3 = -3 j2 + 0.25 = -6 j1 - 1.25
    np.testing.assert_allclose(model.joint_values([0.2]), [0.0, 0.2, 0.9, -2.45], rtol=0, atol=1e-15)
    path.write_text(MIMIC_CHAIN.replace('upper="1"/>', 'upper="1"/><mimic joint="j3"/>'))
    with pytest.raises(ValueError, match="mimic joints form a cycle"):
        read_urdf(path)


def test_batched_link_poses_equal_one_at_a_time(toy, request):
    for model in (toy, read_urdf(_urdf_path("panda", request))):
        qs = model.random_configuration(np.random.default_rng(3), n=50)
        bases = np.array([_trans(k * 0.1, 0, 0) @ _rot("z", k * 0.3) for k in range(50)])
        many = model.link_poses_many(qs)
        np.testing.assert_array_equal(many, np.array([model.link_poses(q) for q in qs]))
        one_base = np.array([model.link_poses(q, bases[7]) for q in qs])
        np.testing.assert_array_equal(model.link_poses_many(qs, base=bases[7]), one_base)
        each_base = np.array([model.link_poses(q, b) for q, b in zip(qs, bases)])
        np.testing.assert_array_equal(model.link_poses_many(qs, base=bases), each_base)
        assert model.link_poses_many(np.empty((0, model.ndof))).shape == (0, model.nlinks, 4, 4)


def test_random_configurations_are_seeded_and_within_limits(toy, request):
    for model in (toy, read_urdf(_urdf_path("kuka_iiwa", request))):
        qs = model.random_configuration(np.random.default_rng(5), n=2000)
        assert qs.shape == (2000, model.ndof)
        assert (qs >= model.lower).all() and (qs <= model.upper).all()
        again = model.random_configuration(np.random.default_rng(5), n=2000)
        np.testing.assert_array_equal(qs, again)
        model.check_configurations(qs)
    with pytest.raises(ValueError, match="Generator"):
        toy.random_configuration(5)


# ---------------------------------------------------------------- bad input


def test_bad_configurations_raise_naming_the_joint(toy):
    ok = np.array([0.1, 0.0])
    toy.check_configuration([np.pi + 1e-13, 0.2 + 1e-13])  # limits are met to 1e-12 (rounding)
    for bad, message in [
        ([0.1], r"shape \(2,\)"),
        ([0.1, 0.0, 0.0], r"shape \(2,\)"),
        ([[0.1, 0.0]], r"shape \(2,\)"),
        ([np.nan, 0.0], "'spin'.*finite"),
        ([0.1, np.inf], "'slide'.*finite"),
        ([0.1, 0.25], r"0\.25 of joint 'slide' is outside its limits \[-0\.1, 0\.2\]"),
        ([-3.2, 0.0], "'spin' is outside"),
        (["a", 0.0], "numbers"),
    ]:
        with pytest.raises(ValueError, match=message):
            toy.link_poses(bad)
    with pytest.raises(ValueError, match="configurations 1: value 0.3 of joint 'slide'"):
        toy.link_poses_many([ok, [0.1, 0.3]])
    with pytest.raises(ValueError, match=r"shape \(N, 2\)"):
        toy.link_poses_many(ok)
    with pytest.raises(ValueError, match="base"):
        toy.link_poses(ok, base=np.diag([2.0, 1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="one per configuration"):
        toy.link_poses_many([ok, ok, ok], base=np.array([np.eye(4), np.eye(4)]))


def test_model_arrays_are_read_only(toy):
    with pytest.raises(ValueError):
        toy.joint_origin[1, 0, 3] = 5.0
    with pytest.raises(ValueError):
        toy.link_geometry[0][0].size[0] = 5.0
    with pytest.raises(AttributeError):
        toy.lower = np.zeros(2)  # frozen dataclass: FrozenInstanceError is an AttributeError


def _two_links(joint_type: str, inside: str = "") -> str:
    """A URDF with links a, b and a joint j of ``joint_type`` holding ``inside``."""
    joint = f'<joint name="j" type="{joint_type}"><parent link="a"/><child link="b"/>{inside}</joint>'
    return f'<robot name="x"><link name="a"/><link name="b"/>{joint}</robot>'


LIMIT = '<limit lower="-1" upper="1" effort="1" velocity="1"/>'
CAPSULE = '<visual><geometry><capsule radius="1" length="2"/></geometry></visual>'


@pytest.mark.parametrize(
    "text, message",
    [
        ("hello, not xml\n", "not a readable URDF"),
        ("", "not a readable URDF"),
        ('<mesh name="x"/>', "no <robot> with <link>"),
        (_two_links("floating"), "'floating'; supported"),
        (_two_links("planar"), "'planar'; supported"),
        (_two_links("revolute"), "no <limit>"),
        (_two_links("revolute", '<limit lower="1" upper="-1"/>'), "lower <= upper"),
        (_two_links("revolute", LIMIT + '<axis xyz="0 0 0"/>'), "nonzero direction"),
        (_two_links("revolute", LIMIT + '<mimic joint="nope"/>'), "mimics 'nope'"),
        ('<robot name="x"><link name="a"/><link name="b"/></robot>', "one root"),
        (_two_links("fixed").replace('<link name="b"/>', ""), "'b', which is not defined"),
        (f'<robot name="x"><link name="a">{CAPSULE}</link></robot>', "capsule"),  # yourdfpy refuses it
    ],
)
def test_bad_urdf_files_raise_naming_the_file(tmp_path, text, message):
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(ValueError, match=message) as err:
        read_urdf(path)
    assert str(path) in str(err.value)


def test_missing_urdf_file_raises(tmp_path):
    with pytest.raises(ValueError, match="no such file"):
        read_urdf(tmp_path / "absent.urdf")
    with pytest.raises(ValueError, match="no such file"):
        read_urdf(tmp_path)  # a folder is not a file


# ---------------------------------------------------------------- datasets.robots


def test_robot_files_resolve_every_collision_mesh():
    assert set(ROBOTS) == {"jvrc1", "kuka_iiwa", "panda"}
    for name in ("kuka_iiwa", "panda"):
        model = read_urdf(robot_urdf(name))
        files = [link_shape_file(name, g.filename) for geometry in model.link_geometry for g in geometry]
        assert len(files) == {"kuka_iiwa": 8, "panda": 11}[name]  # panda_link8 and panda_grasptarget have none
        assert all(f.is_file() and f.suffix in {".stl", ".obj"} for f in files)
    with pytest.raises(ValueError, match="known: \\['jvrc1', 'kuka_iiwa', 'panda'\\]"):
        robot_urdf("atlas")
    with pytest.raises(FileNotFoundError):
        link_shape_file("panda", "package://meshes/collision/nothing.obj")


def test_jvrc1_robot_files_give_the_hull_of_each_link_mesh(shared_datasets):
    assert robot_files("jvrc1").urdf == shared_datasets / JVRC1_URDF
    model = read_urdf(robot_urdf("jvrc1"))
    hulls = {link_shape_file("jvrc1", g.filename) for geometry in model.link_geometry for g in geometry}
    assert len(hulls) == 35 and all(p.name.endswith("-ch.txt") for p in hulls)


# ---------------------------------------------------------------- the compiled limits check


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from([0.0, -0.1, 0.2, 0.2 + 5e-13, 0.2 + 2e-12, -0.1 - 2e-12, -2.0, 3.0, math.nan,
                                 math.inf, -math.inf, -1e300]), min_size=2, max_size=12))
def test_within_limits_agrees_with_numpy_on_every_value(values):
    """spq.kernels.kinematics.within_limits, which RobotModel's checks run first, against numpy's
    isfinite and comparisons with the same slack (values at, just inside and just outside the
    slack, NaN and infinities, on a joint with an infinite limit too)."""
    qs = np.array(values[: len(values) // 2 * 2]).reshape(-1, 2)
    lower, upper = np.array([-0.1, -np.inf]), np.array([0.2, np.inf])
    expected = bool(np.isfinite(qs).all() and not ((qs < lower - LIMIT_SLACK) | (qs > upper + LIMIT_SLACK)).any())
    assert within_limits(qs, lower, upper, LIMIT_SLACK) is expected
