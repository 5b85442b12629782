"""spq.control: the velocity damper's rows, the joint maps to pinocchio and MuJoCo, pink's barrier and
the pink / mink limits, each against an independent oracle: spq's per-pair gradient
(Scene.distance_gradient, Python), central finite differences of the scene's distances along the
other library's own integration (pinocchio.integrate, mujoco.mj_integratePos), the brute-force list
of close pairs, and pink's own SelfCollisionBarrier on pinocchio + coal hulls of the same vertices."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from spq.control import DamperLimit, DamperRows, VelocityDamper
from spq.control.joint_map import mujoco_joint_map, pinocchio_joint_map
from spq.kernels.gjk import FAILED
from spq.scene import Obstacle, Scene
from spq.shapes.primitives import Box

# A planar arm that folds back on itself, with a continuous wrist roll and a two-finger gripper whose
# second finger mimics the first (pinocchio and MuJoCo read it as an independent joint).
CLAW_URDF = """<robot name="claw">
  <link name="base">{inertial}<collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <link name="arm">{inertial}<collision><origin xyz="0 0 0.25"/>
    <geometry><box size="0.05 0.05 0.4"/></geometry></collision></link>
  <link name="forearm">{inertial}<collision><origin xyz="0 0 0.15"/>
    <geometry><box size="0.04 0.04 0.3"/></geometry></collision></link>
  <link name="wrist">{inertial}<collision><origin xyz="0 0 0.04"/>
    <geometry><box size="0.04 0.07 0.08"/></geometry></collision></link>
  <link name="finger_l">{inertial}<collision><origin xyz="0 0 0.04"/>
    <geometry><box size="0.01 0.02 0.08"/></geometry></collision></link>
  <link name="finger_r">{inertial}<collision><origin xyz="0 0 0.04"/>
    <geometry><box size="0.01 0.02 0.08"/></geometry></collision></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.05"/>
    <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" effort="1" velocity="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="arm"/><child link="forearm"/><origin xyz="0 0 0.45"/>
    <axis xyz="0 1 0"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="roll" type="continuous"><parent link="forearm"/><child link="wrist"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 0 1"/><limit effort="1" velocity="1"/></joint>
  <joint name="grip" type="prismatic"><parent link="wrist"/><child link="finger_l"/>
    <origin xyz="0.02 0 0.08"/><axis xyz="1 0 0"/><limit lower="-0.012" upper="0.015" effort="1" velocity="1"/></joint>
  <joint name="grip_mimic" type="prismatic"><parent link="wrist"/><child link="finger_r"/>
    <origin xyz="-0.02 0 0.08"/><axis xyz="1 0 0"/><limit lower="-0.015" upper="0.012" effort="1" velocity="1"/>
    <mimic joint="grip" multiplier="-1"/></joint>
</robot>
"""
INERTIAL = '<inertial><mass value="0.5"/><inertia ixx="1e-3" iyy="1e-3" izz="1e-3" ixy="0" ixz="0" iyz="0"/></inertial>'
DI, DS, XI = 0.05, 0.01, 0.5
FD_STEP = 1e-6  # rad or m: central differences' step
FD_TOL = 1e-6  # m per unit: central differences of polytope distances at unique closest features (O(step^2) + GJK)
TABLE = Obstacle("table", Box.from_size(0.3, 0.3, 0.02), np.array(
    [[1.0, 0, 0, 0.32], [0, 1.0, 0, 0.0], [0, 0, 1.0, 0.3], [0, 0, 0, 1.0]]))


@pytest.fixture(scope="module")
def claw_urdf(tmp_path_factory):
    path = tmp_path_factory.mktemp("claw") / "claw.urdf"
    path.write_text(CLAW_URDF.format(inertial=INERTIAL))
    return path


@pytest.fixture(scope="module")
def claw(claw_urdf):
    return Scene.from_urdf(claw_urdf, policy="pch")


@pytest.fixture(scope="module")
def floating_claw(claw_urdf):
    return Scene.from_urdf(claw_urdf, policy="pch", floating_base=True, obstacles=[TABLE])


# folded so that the wrist and fingers come near the arm, the table near the forearm
FOLDED = np.array([0.3, 2.8, 0.3, 0.004])


def close_configurations(scene, n, seed):
    """Configurations (of n drawn) with at least one pair closer than DI and none closer than DS."""
    rng = np.random.default_rng(seed)
    out = [FOLDED]
    while len(out) < n:
        q = scene.random_configuration(rng)
        d = scene.distances(q, coherent=False, signed=True).distance
        if DS < d.min() < DI:
            out.append(q)
    return out


def fd_gradient(distance_at, q, pair, step=FD_STEP):
    """Central differences of pair ``pair``'s distance along each coordinate of q."""
    grad = np.empty(len(q))
    for j in range(len(q)):
        e = np.zeros(len(q))
        e[j] = step
        grad[j] = (distance_at(q + e)[pair] - distance_at(q - e)[pair]) / (2 * step)
    return grad


# ---------------------------------------------------------------- 1. the damper's rows
def test_damper_rows_are_minus_each_close_pairs_gradient_and_h_is_the_damper_rate(claw):
    damper = VelocityDamper(claw, di=DI, ds=DS, xi=XI)
    for q in close_configurations(claw, 4, 1):
        rows = damper.rows(q)
        assert isinstance(rows, DamperRows) and len(rows) >= 1 and rows.n_failed == 0
        full = claw.distances(q, coherent=False, signed=True)  # every pair, unpruned: the brute-force list
        assert sorted(rows.pairs.tolist()) == np.flatnonzero(full.distance < DI).tolist()
        assert np.all(np.diff(rows.distance) >= 0)
        np.testing.assert_allclose(rows.distance, full.distance[rows.pairs], atol=1e-9)
        np.testing.assert_allclose(rows.h, XI * (full.distance[rows.pairs] - DS) / (DI - DS), atol=1e-9)
        for G, pair in zip(rows.G, rows.pairs):
            np.testing.assert_allclose(-G, claw.distance_gradient(q, full, pair), atol=1e-9)
        np.testing.assert_array_equal(rows.jacobian, -rows.G)


def test_damper_rows_equal_central_differences(claw):
    damper = VelocityDamper(claw, di=DI, ds=DS, xi=XI)

    def distance_at(q):
        return claw.distances(q, coherent=False, signed=True).distance

    for q in close_configurations(claw, 3, 2):
        rows = damper.rows(q)
        for G, pair in zip(rows.G, rows.pairs):
            np.testing.assert_allclose(-G, fd_gradient(distance_at, q, pair), atol=FD_TOL)


def test_damper_rejects_bad_parameters(claw):
    for kwargs, message in [
        (dict(di=0.01, ds=0.01), r"0 <= ds < di"),
        (dict(di=0.05, ds=-0.01), r"0 <= ds < di"),
        (dict(xi=0.0), r"xi must be > 0"),
        (dict(di=np.nan), "di must be a finite number"),
        (dict(xi="fast"), "xi must be a finite number"),
    ]:
        with pytest.raises(ValueError, match=message):
            VelocityDamper(claw, **kwargs)
    with pytest.raises(ValueError, match="outside its limits"):
        VelocityDamper(claw).rows([0.0, 3.2, 0.0, 0.0])


def test_a_failed_query_gives_no_row_and_is_counted(claw):
    from spq.control.damper import damper_rows
    from spq.kernels.gjk import OUT_STATUS

    result = claw.distances(FOLDED, coherent=False, signed=True, jacobian=True)
    close = np.flatnonzero(result.distance < DI)
    assert len(close) >= 3
    result._rows[close[:2], OUT_STATUS] = FAILED  # as the sweep writes a query that did not converge
    assert (result.status[close[:2]] == "failed").all()
    result.jacobian[close[0]] = np.nan  # close[1]'s row stays finite: its status alone must leave it out
    rows = damper_rows(result, DI, DS, XI)
    assert rows.failed.tolist() == close[:2].tolist() and rows.n_failed == 2
    assert sorted(rows.pairs.tolist()) == close[2:].tolist()
    with pytest.raises(ValueError, match=r"jacobian=True"):
        damper_rows(claw.distances(FOLDED), DI, DS, XI)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 40), st.integers(1, 8), st.integers(0, 2**32 - 1))
def test_damper_rows_agree_with_a_plain_python_filter_and_sort(n, nv, seed):
    """The compiled rows against the definition, in plain Python: pairs with d < di whose status is not
    FAILED and whose row is finite, by increasing distance (ties in pair order); failed: the FAILED
    pairs and the close ones with a non-finite row, in pair order. Distances drawn with ties, inf
    (pruned), NaN and overlaps; rows with NaN and inf entries."""
    from spq.control.damper import damper_rows
    from spq.kernels.gjk import OUT_DISTANCE, OUT_SIZE, OUT_STATUS
    from spq.scene import SceneDistances

    rng = np.random.default_rng(seed)
    distance = rng.choice([-0.004, 0.0, 0.01, 0.02, 0.02, 0.049, 0.05, 0.3, np.inf, np.nan], size=n)
    distance = np.where(rng.random(n) < 0.5, distance, rng.uniform(-0.01, 0.1, n))
    status = rng.choice(np.array([0, 1, 2, FAILED, -1], dtype=np.int8), size=n)
    jac = rng.normal(size=(n, nv))
    bad = rng.random(n) < 0.2
    jac[bad, rng.integers(0, nv, n)[bad]] = rng.choice([np.nan, np.inf, -np.inf], size=int(bad.sum()))
    out = rng.normal(size=(n, OUT_SIZE))  # the sweep's rows: only the distance and status columns count
    out[:, OUT_DISTANCE], out[:, OUT_STATUS] = distance, status
    result = SceneDistances(np.zeros((n, 2), np.int64), out)
    result.jacobian = jac
    rows = damper_rows(result, DI, DS, XI)
    finite = [all(np.isfinite(jac[p])) for p in range(n)]
    keep = [p for p in range(n) if status[p] != FAILED and distance[p] < DI and finite[p]]
    keep.sort(key=lambda p: (distance[p], p))
    failed = [p for p in range(n) if status[p] == FAILED or (distance[p] < DI and not finite[p])]
    assert rows.pairs.tolist() == keep and rows.failed.tolist() == failed
    assert rows.pairs.dtype == rows.failed.dtype == np.int64
    assert rows.distance.tolist() == [distance[p] for p in keep]
    assert rows.h.tolist() == [XI * (distance[p] - DS) / (DI - DS) for p in keep]
    assert rows.jacobian.shape == rows.G.shape == (len(keep), nv)
    assert np.array_equal(rows.jacobian, jac[keep]) and np.array_equal(rows.G, -jac[keep])


def test_an_unsigned_overlap_gives_no_row_and_is_counted(claw):
    q = np.array([0.3, 3.0, 0.3, 0.004])  # folded into the arm and the base
    signed = claw.distances(q, coherent=False, signed=True)
    overlapping = np.flatnonzero(signed.distance < 0)
    assert overlapping.size
    rows = VelocityDamper(claw, signed=False).rows(q)
    assert set(overlapping) <= set(rows.failed.tolist()) and not set(overlapping) & set(rows.pairs.tolist())
    rows = VelocityDamper(claw, signed=True).rows(q)
    assert set(overlapping) <= set(rows.pairs.tolist()) and rows.n_failed == 0
    assert np.all(rows.h[np.isin(rows.pairs, overlapping)] < 0)  # an overlap's row pushes the pair apart


# ---------------------------------------------------------------- 2. joint maps
@pytest.fixture(scope="module")
def pin_claw(claw_urdf):
    pin = pytest.importorskip("pinocchio", reason="pin not installed (pip install pin)")
    return pin.buildModelFromUrdf(str(claw_urdf))


@pytest.fixture(scope="module")
def pin_floating_claw(claw_urdf):
    pin = pytest.importorskip("pinocchio", reason="pin not installed (pip install pin)")
    return pin.buildModelFromUrdf(str(claw_urdf), pin.JointModelFreeFlyer())


def test_pinocchio_map_reads_continuous_and_mimic_joints(claw, pin_claw):
    jmap = pinocchio_joint_map(claw, pin_claw)
    assert pin_claw.nq == 6 and pin_claw.nv == 5  # roll is (cos, sin); grip_mimic is a joint of its own
    q = np.array([0.3, -1.2, -2.9, 0.01])
    q_pin = jmap.from_spq_q(q)
    np.testing.assert_allclose(jmap.to_spq_q(q_pin), q, atol=1e-15)
    mimic = pin_claw.joints[pin_claw.getJointId("grip_mimic")]
    assert q_pin[mimic.idx_q] == -0.01  # set from its master
    M = jmap.velocity_matrix(q_pin)
    assert M[:, mimic.idx_v].tolist() == [0.0] * 4  # the master's column carries the chain
    roll = pin_claw.joints[pin_claw.getJointId("roll")]
    np.testing.assert_allclose(q_pin[roll.idx_q:roll.idx_q + 2], [np.cos(-2.9), np.sin(-2.9)])


def pinocchio_fd_rows(pin, model, jmap, scene, q_pin, pairs, step=FD_STEP):
    """Central differences of the pairs' distances along each of pinocchio's velocity directions
    (pinocchio.integrate), the scene fed through the map."""
    out = np.empty((len(pairs), model.nv))
    for k in range(model.nv):
        v = np.zeros(model.nv)
        v[k] = step
        d = []
        for sign in (1, -1):
            qk = pin.integrate(model, q_pin, sign * v)
            d.append(scene.distances(jmap.update_scene(scene, qk), coherent=False, signed=True).distance[pairs])
        out[:, k] = (d[0] - d[1]) / (2 * step)
    return out


@pytest.mark.parametrize("mimic", [False, True])
def test_rows_in_pinocchio_columns_equal_differences_along_pinocchio_integrate(claw, claw_urdf, mimic):
    pin = pytest.importorskip("pinocchio")
    # mimic=True: pinocchio's JointModelMimic, with no q or v entry of its own
    model = pin.buildModelFromUrdf(str(claw_urdf), mimic=mimic)
    assert model.nv == (4 if mimic else 5)
    jmap = pinocchio_joint_map(claw, model)
    damper = VelocityDamper(claw, di=DI, ds=DS, xi=XI)
    for q in close_configurations(claw, 2, 3):
        q_pin = jmap.from_spq_q(q)
        rows = damper.rows(jmap.update_scene(claw, q_pin))
        G_pin = jmap.columns(rows.G, q_pin)
        np.testing.assert_allclose(-G_pin, pinocchio_fd_rows(pin, model, jmap, claw, q_pin, rows.pairs),
                                   atol=FD_TOL)


def test_floating_base_columns_equal_differences_along_pinocchio_integrate(floating_claw, pin_floating_claw):
    pin = pytest.importorskip("pinocchio")
    model = pin_floating_claw
    jmap = pinocchio_joint_map(floating_claw, model)
    assert jmap.base == "pinocchio" and jmap.scene_nv == 6 + 4 and model.nv == 6 + 5
    base = np.eye(4)
    base[:3, :3] = pin.rpy.rpyToMatrix(0.2, -0.3, 0.4)
    base[:3, 3] = [0.05, -0.02, 0.01]
    q_pin = jmap.from_spq_q(FOLDED, base=base)
    q = jmap.update_scene(floating_claw, q_pin)
    np.testing.assert_allclose(floating_claw.base, base, atol=1e-12)
    result = floating_claw.distances(q, coherent=False, signed=True, jacobian=True)
    table = floating_claw.body_names.index("table")
    with_table = [p for p, (a, b) in enumerate(floating_claw.pairs) if table in (a, b)]
    G_pin = jmap.columns(result.jacobian[with_table], q_pin)
    assert np.abs(G_pin[:, :6]).max() > 0.1  # the base moves the robot relative to the table
    np.testing.assert_allclose(G_pin, pinocchio_fd_rows(pin, model, jmap, floating_claw, q_pin, with_table),
                               atol=FD_TOL)


def test_maps_refuse_models_of_another_robot(claw, pin_claw, floating_claw, claw_urdf, tmp_path):
    pin = pytest.importorskip("pinocchio")
    other = tmp_path / "other.urdf"
    other.write_text(CLAW_URDF.format(inertial=INERTIAL).replace('"elbow"', '"knee"'))
    with pytest.raises(ValueError, match=r"no joint named \['elbow'\] and joints the scene does not know: \['knee'\]"):
        pinocchio_joint_map(claw, pin.buildModelFromUrdf(str(other)))
    with pytest.raises(ValueError, match="floating base but the pinocchio model has no free root joint"):
        pinocchio_joint_map(floating_claw, pin_claw)
    jmap = pinocchio_joint_map(claw, pin_claw)
    with pytest.raises(ValueError, match=r"shape \(6,\)"):
        jmap.to_spq_q(np.zeros(4))
    # a QP's rounding past a limit is put back on it; a real excursion is refused by the scene
    q_pin = jmap.from_spq_q(np.array([1.5 + 1e-9, 0.0, 0.0, 0.0]))
    assert jmap.to_spq_q(q_pin)[0] == 1.5
    q_pin = jmap.from_spq_q(np.array([1.5 + 1e-3, 0.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="'shoulder' is outside its limits"):
        VelocityDamper(claw).rows(jmap.to_spq_q(q_pin))
    # a free-flyer model on a fixed-base scene: exact for self-collision (the base moves every body
    # alike, its columns are 0), refused when the scene has obstacles
    pin_floating = pin.buildModelFromUrdf(str(claw_urdf), pin.JointModelFreeFlyer())
    jmap = pinocchio_joint_map(claw, pin_floating)
    assert not jmap.velocity_matrix(pin.neutral(pin_floating))[:, :6].any()
    with_table = Scene.from_urdf(claw_urdf, policy="pch", obstacles=[TABLE])
    with pytest.raises(ValueError, match="build the scene with floating_base=True"):
        pinocchio_joint_map(with_table, pin_floating)


# ---------------------------------------------------------------- 3. MuJoCo
@pytest.fixture(scope="module")
def mj_claw(claw_urdf):
    mujoco = pytest.importorskip("mujoco", reason="mujoco not installed (pip install mujoco)")
    return mujoco.MjModel.from_xml_path(str(claw_urdf))


def mujoco_fd_rows(mujoco, model, jmap, scene, qpos, pairs, step=FD_STEP):
    out = np.empty((len(pairs), model.nv))
    for k in range(model.nv):
        d = []
        for sign in (1, -1):
            qk = qpos.copy()
            v = np.zeros(model.nv)
            v[k] = sign
            mujoco.mj_integratePos(model, qk, v, step)
            d.append(scene.distances(jmap.update_scene(scene, qk), coherent=False, signed=True).distance[pairs])
        out[:, k] = (d[0] - d[1]) / (2 * step)
    return out


def test_rows_in_mujoco_columns_equal_differences_along_mj_integrate_pos(claw, mj_claw):
    mujoco = pytest.importorskip("mujoco")
    jmap = mujoco_joint_map(claw, mj_claw)
    damper = VelocityDamper(claw, di=DI, ds=DS, xi=XI)
    q = FOLDED.copy()
    q[2] = -3.0
    qpos = jmap.from_spq_q(q)
    qpos[jmap.q_address[2]] += 2 * np.pi  # an unlimited hinge wraps onto spq's [-pi, pi]
    np.testing.assert_allclose(jmap.to_spq_q(qpos), q, atol=1e-12)
    rows = damper.rows(jmap.update_scene(claw, qpos))
    G = jmap.columns(rows.G, qpos)
    np.testing.assert_allclose(-G, mujoco_fd_rows(mujoco, mj_claw, jmap, claw, qpos, rows.pairs), atol=FD_TOL)


def test_mujoco_free_joint_columns_equal_differences_along_mj_integrate_pos(floating_claw, claw_urdf):
    mujoco = pytest.importorskip("mujoco")
    spec = mujoco.MjSpec.from_file(str(claw_urdf))
    spec.body("base").add_freejoint()
    model = spec.compile()
    jmap = mujoco_joint_map(floating_claw, model)
    assert jmap.base == "mujoco"
    base = np.eye(4)
    base[:3, :3] = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[np.cos(0.3), 0.0, np.sin(0.3)], [0.0, 1.0, 0.0], [-np.sin(0.3), 0.0, np.cos(0.3)]])
    base[:3, 3] = [0.02, 0.05, -0.01]
    qpos = jmap.from_spq_q(FOLDED, base=base)
    q = jmap.update_scene(floating_claw, qpos)
    np.testing.assert_allclose(floating_claw.base, base, atol=1e-12)
    result = floating_claw.distances(q, coherent=False, signed=True, jacobian=True)
    table = floating_claw.body_names.index("table")
    with_table = [p for p, (a, b) in enumerate(floating_claw.pairs) if table in (a, b)]
    G = jmap.columns(result.jacobian[with_table], qpos)
    np.testing.assert_allclose(G, mujoco_fd_rows(mujoco, model, jmap, floating_claw, qpos, with_table),
                               atol=FD_TOL)


# ---------------------------------------------------------------- 4. pink
@pytest.fixture(scope="module")
def kuka_pink():
    pytest.importorskip("pink", reason="pink not installed (pip install pin-pink)")
    from datasets.robots import robot_files
    from harness.engines import pinocchio_peer

    files = robot_files("kuka_iiwa")
    scene = Scene.from_urdf(files.urdf, mesh_root=files.mesh_root, policy="pch")
    peer = pinocchio_peer.build(scene, files.urdf, tolerance=1e-9)
    return scene, peer


def test_scene_barrier_equals_pinks_self_collision_barrier_on_the_same_hulls(kuka_pink):
    import pink

    from spq.control import SceneBarrier

    scene, peer = kuka_pink
    n = 6
    theirs = pink.barriers.SelfCollisionBarrier(n_collision_pairs=n, d_min=0.02)
    mine = SceneBarrier(scene, n_collision_pairs=n, d_min=0.02)
    rng = np.random.default_rng(4)
    compared = 0
    for q in scene.model.random_configuration(rng, 6):
        q_pin = peer.configuration(q)
        with_coal = pink.Configuration(peer.model, peer.model.createData(), q_pin, collision_model=peer.geometry,
                                       collision_data=peer.geometry_data)
        plain = pink.Configuration(peer.model, peer.model.createData(), q_pin)  # SceneBarrier needs no collision model
        h_theirs, J_theirs = theirs.compute_barrier(with_coal), theirs.compute_jacobian(with_coal)
        h_mine, J_mine = mine.compute_barrier(plain), mine.compute_jacobian(plain)
        if np.any(h_mine + 0.02 <= 1e-3):  # touching or overlapping: pink's Jacobian is zero there
            continue
        # which pair each of pink's rows is: its barrier and its Jacobian pick the n closest pairs of
        # coal's distances with np.argpartition, each in its own order
        coal_d = np.array([r.min_distance for r in with_coal.collision_data.distanceResults])
        rows_h = np.argpartition(-(coal_d - 0.02), -n)[-n:]
        rows_J = np.argpartition(-coal_d, -n)[-n:]
        assert sorted(mine.pairs.tolist()) == sorted(rows_h.tolist()) == sorted(rows_J.tolist())
        for row, pair in enumerate(mine.pairs):
            assert abs(h_mine[row] - h_theirs[rows_h == pair][0]) < 1e-7  # both GJKs to 1e-9 m, unique features
            np.testing.assert_allclose(J_mine[row], J_theirs[rows_J == pair][0], atol=1e-6)
        compared += 1
    assert compared >= 3


def test_pink_solve_ik_step_keeps_the_barrier_and_the_damper(claw, pin_claw):
    pink = pytest.importorskip("pink", reason="pink not installed (pip install pin-pink)")
    pin = pytest.importorskip("pinocchio")
    from spq.control import SceneBarrier

    jmap = pinocchio_joint_map(claw, pin_claw)
    q_pin = jmap.from_spq_q(FOLDED)
    configuration = pink.Configuration(pin_claw, pin_claw.createData(), q_pin)
    task = pink.tasks.FrameTask("wrist", position_cost=1.0, orientation_cost=0.0)
    target = configuration.get_transform_frame_to_world("wrist").copy()
    arm = configuration.get_transform_frame_to_world("arm")
    target.translation = arm.translation + 0.3 * (arm.rotation @ np.array([0.0, 0.0, 1.0]))  # into the arm
    task.set_target(target)
    dt = 0.01
    barrier = SceneBarrier(claw, n_collision_pairs=3, gain=1.0, d_min=0.02)
    limit = DamperLimit(claw, di=DI, ds=DS, xi=XI)
    assert isinstance(limit, pink.limits.Limit) and isinstance(limit, DamperLimit)
    v = pink.solve_ik(configuration, [task], dt, solver="daqp", barriers=[barrier], limits=[limit])
    assert v.shape == (pin_claw.nv,) and np.linalg.norm(v) > 0
    G, h = limit.compute_qp_inequalities(configuration, dt)
    assert len(h) >= 1 and np.all(G @ (v * dt) <= h + 1e-9)
    J, hb = barrier.compute_jacobian(configuration), barrier.compute_barrier(configuration)
    assert np.all(J @ v + barrier.gain * hb >= -1e-9)
    # the step goes where the rows allow: the close pairs do not approach faster than promised
    q_next = pin.integrate(pin_claw, q_pin, v * dt)
    d_next = claw.distances(jmap.to_spq_q(q_next), coherent=False, signed=True).distance
    rows = limit.last_rows
    assert np.all(d_next[rows.pairs] - rows.distance >= -dt * rows.h - 1e-4)


REACH_INTO_BASE = np.array([0.12, 0.0, 0.05])  # m: a wrist target beside the base, reached only through it


def pink_run(claw, model, limits, barriers, steps=150, dt=0.01):
    """Smallest distance of each pair over a pink loop driving the wrist to REACH_INTO_BASE from FOLDED."""
    import pink

    jmap = pinocchio_joint_map(claw, model)
    configuration = pink.Configuration(model, model.createData(), jmap.from_spq_q(FOLDED))
    task = pink.tasks.FrameTask("wrist", position_cost=1.0, orientation_cost=0.0)
    target = configuration.get_transform_frame_to_world("wrist").copy()
    target.translation = REACH_INTO_BASE
    task.set_target(target)
    smallest = np.full(len(claw.pairs), np.inf)
    for _ in range(steps):
        v = pink.solve_ik(configuration, [task], dt, solver="daqp", barriers=barriers,
                          limits=limits + [model.configuration_limit, model.velocity_limit])
        configuration.integrate_inplace(v, dt)
        d = claw.distances(jmap.to_spq_q(configuration.q), coherent=False, signed=True).distance
        smallest = np.minimum(smallest, d)
    return smallest


def test_in_a_pink_loop_the_damper_and_the_barrier_keep_the_bodies_apart(claw, pin_claw):
    pytest.importorskip("pink", reason="pink not installed (pip install pin-pink)")
    from spq.control import SceneBarrier

    assert pink_run(claw, pin_claw, [], None).min() < -0.05  # unconstrained, the hand goes through the base
    # first-order rows at 1 rad/s and 10 ms steps: the corners of boxes overshoot by under a millimetre
    assert pink_run(claw, pin_claw, [DamperLimit(claw, di=DI, ds=DS, xi=XI)], None).min() > DS - 1e-3
    barrier = SceneBarrier(claw, n_collision_pairs=3, d_min=0.02)
    assert pink_run(claw, pin_claw, [], [barrier]).min() > 0.02 - 1e-3


def test_scene_barrier_beyond_the_detection_distance_has_inactive_rows(claw, pin_claw):
    pink = pytest.importorskip("pink", reason="pink not installed (pip install pin-pink)")
    from spq.control import SceneBarrier
    from spq.control.pink_barrier import INACTIVE_VALUE

    jmap = pinocchio_joint_map(claw, pin_claw)
    n = len(claw.pairs)
    barrier = SceneBarrier(claw, n_collision_pairs=n, d_min=0.005, detection_distance=DI)
    for q, dt in ((FOLDED, 0.01), (np.zeros(4), 0.01)):  # some pairs close; every pair far
        configuration = pink.Configuration(pin_claw, pin_claw.createData(), jmap.from_spq_q(q))
        h, J = barrier.compute_barrier(configuration), barrier.compute_jacobian(configuration)
        full = claw.distances(q, coherent=False, signed=True).distance
        close = np.sort(full[full < DI])  # a pair closer than DI always has its bounding spheres within DI
        active = barrier.pairs >= 0
        assert len(close) <= active.sum() < n  # pairs whose spheres are farther than DI apart give no row
        np.testing.assert_allclose(h[:len(close)], close - 0.005, atol=1e-9)
        assert np.all(h[~active] == INACTIVE_VALUE) and not J[~active].any()
        H, c = barrier.compute_qp_objective(configuration)
        assert np.isfinite(H).all() and np.isfinite(c).all()
        task = pink.tasks.FrameTask("wrist", position_cost=1.0, orientation_cost=0.0)
        task.set_target_from_configuration(configuration)
        v = pink.solve_ik(configuration, [task], dt, solver="daqp", barriers=[barrier])
        assert np.isfinite(v).all()


# ---------------------------------------------------------------- 5. mink
def test_mink_solve_ik_keeps_the_damper_step_by_step(claw, mj_claw):
    mink = pytest.importorskip("mink", reason="mink not installed (pip install mink)")
    jmap = mujoco_joint_map(claw, mj_claw)
    configuration = mink.Configuration(mj_claw)
    configuration.update(jmap.from_spq_q(FOLDED))
    task = mink.FrameTask("wrist", "body", position_cost=1.0, orientation_cost=0.0)
    wrist = configuration.get_transform_frame_to_world("wrist", "body")
    task.set_target(mink.SE3.from_rotation_and_translation(wrist.rotation(), REACH_INTO_BASE))
    limit = DamperLimit(claw, di=DI, ds=DS, xi=XI, backend="mink")
    assert isinstance(limit, mink.limits.Limit) and isinstance(limit, DamperLimit)
    speed = mink.VelocityLimit(mj_claw, {name: 1.0 for name in ("shoulder", "elbow", "roll", "grip", "grip_mimic")})
    dt, active, smallest = 0.01, 0, np.inf
    for _ in range(150):
        v = mink.solve_ik(configuration, [task], dt, "daqp", limits=[limit, mink.ConfigurationLimit(mj_claw), speed])
        constraint = limit.compute_qp_inequalities(configuration, dt)
        if not constraint.inactive:
            active += 1
            assert np.all(constraint.G @ (v * dt) <= constraint.h + 1e-9)
        configuration.integrate_inplace(v, dt)
        q = jmap.to_spq_q(configuration.q)
        smallest = min(smallest, claw.distances(q, coherent=False, signed=True).min_distance)
    assert active >= 100 and smallest > DS - 1e-3


# ---------------------------------------------------------------- 6. optional dependencies
def test_without_pink_or_mink_the_adapters_say_what_to_install(claw, monkeypatch):
    import spq.control.limits as limits

    monkeypatch.setitem(sys.modules, "pink", None)
    monkeypatch.setitem(sys.modules, "pink.barriers", None)
    monkeypatch.setitem(sys.modules, "pink.limits", None)
    monkeypatch.setitem(sys.modules, "mink", None)
    monkeypatch.setitem(sys.modules, "mink.limits", None)
    monkeypatch.delitem(sys.modules, "spq.control.pink_barrier", raising=False)
    monkeypatch.setattr(limits, "_CLASSES", {})
    import spq.control

    with pytest.raises(ImportError, match="pip install pin-pink"):
        spq.control.SceneBarrier
    with pytest.raises(ImportError, match="pip install pin-pink"):
        DamperLimit(claw)
    with pytest.raises(ImportError, match="pip install mink"):
        DamperLimit(claw, backend="mink")
    with pytest.raises(ValueError, match=r"unknown DamperLimit backend 'drake'; choose one of \['pink', 'mink'\]"):
        DamperLimit(claw, backend="drake")
    VelocityDamper(claw).rows(FOLDED)  # the damper itself needs neither


def test_scene_barrier_rejects_bad_parameters(claw):
    pytest.importorskip("pink", reason="pink not installed (pip install pin-pink)")
    from spq.control import SceneBarrier

    npairs = len(claw.pairs)
    for kwargs, message in [
        (dict(n_collision_pairs=0), rf"integer in 1..{npairs}"),
        (dict(n_collision_pairs=npairs + 1), rf"integer in 1..{npairs}"),
        (dict(n_collision_pairs=1, d_min=-0.1), "d_min must be a finite distance >= 0"),
        (dict(n_collision_pairs=1, gain=0.0), "gain must be a finite number > 0"),
        (dict(n_collision_pairs=1, detection_distance=0.01), "detection_distance must be None or"),
    ]:
        with pytest.raises(ValueError, match=message):
            SceneBarrier(claw, **kwargs)
