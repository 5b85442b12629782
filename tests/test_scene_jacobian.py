"""All-pairs distance Jacobians of a robot scene (Scene.distances(..., jacobian=True)) against two
independent oracles: central finite differences of the scene's distances over the joints (where the
distance is C1: STP-BV and superellipsoid pairs), and pinocchio's frame Jacobians at the same witness
points (its own URDF kinematics). Also a floating base, static obstacles and link_jacobian."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from datasets.robots import robot_files
from spq.scene import WORLD, Obstacle, Scene
from spq.shapes.polyhedron import Polyhedron
from spq.shapes.primitives import Box
from tests.conftest import require_shared_datasets

TIGHT = dict(tol=1e-13, rel_tol=1e-13)  # m, m/m: solver noise ~1e-13 / H stays far below AGREE
H = 1e-6  # rad: central-difference step; truncation ~H^2 d''' on a C1, piecewise-C2 distance
AGREE = 1e-6  # relative: |J - J_fd| <= AGREE * max(1, |J|) per row (the acceptance figure)
CLEAR = 1e-3  # m: pairs at least this far apart (a touching pair's distance is not differentiable)


def jvrc1(policy: str) -> Scene:
    require_shared_datasets()
    files = robot_files("jvrc1")
    return Scene.from_urdf(files.urdf, convex_dir=files.convex_dir, policy=policy, **TIGHT)


def inner_configurations(model, n: int, seed: int) -> np.ndarray:
    """n configurations drawn uniformly inside the limits, H away from them (for central differences)."""
    rng = np.random.default_rng(seed)
    lo, hi = model.lower + 2 * H, model.upper - 2 * H
    return lo + (hi - lo) * rng.random((n, model.ndof))


def fd_rows(scene: Scene, q: np.ndarray) -> np.ndarray:
    """(npairs, ndof) central differences of every pair's distance over each joint."""
    n = scene.model.ndof
    qs = np.repeat(q[None], 2 * n, axis=0)
    qs[np.arange(n), np.arange(n)] += H
    qs[n + np.arange(n), np.arange(n)] -= H
    out = scene.distances_many(qs, coherent=False)
    d = out[:, :, 0]
    return ((d[:n] - d[n:]) / (2 * H)).T


def smooth_samples(scene: Scene, configurations: int, seed: int) -> tuple[int, float]:
    """(samples checked, worst relative error) of the Jacobian rows against central differences over
    the separated pairs at random configurations."""
    checked, worst = 0, 0.0
    for q in inner_configurations(scene.model, configurations, seed):
        res = scene.distances(q, coherent=False, jacobian=True)
        fd = fd_rows(scene, q)
        ok = (res.status == "separated") & (res.distance > CLEAR)
        err = np.abs(res.jacobian[ok] - fd[ok]).max(axis=1) / np.maximum(1.0, np.abs(res.jacobian[ok]).max(axis=1))
        checked += int(ok.sum())
        worst = max(worst, float(err.max(initial=0.0)))
    return checked, worst


@pytest.mark.parametrize("policy", ["stp-both", "auto", "cse"])
def test_jacobian_rows_equal_central_differences_where_the_distance_is_c1(policy):
    scene = jvrc1(policy)
    checked, worst = smooth_samples(scene, 4, seed={"stp-both": 1, "auto": 2, "cse": 3}[policy])
    assert checked >= 1000, checked
    assert worst <= AGREE, (policy, worst)


def pinocchio_rows(scene: Scene, q: np.ndarray, res) -> np.ndarray:
    """Each pair's row from pinocchio: its BODY frames' Jacobians (LOCAL_WORLD_ALIGNED) carried to the
    witness points, nᵀ(J_B(p_B) − J_A(p_A)), columns mapped back onto spq's q (mimic joints summed
    into their master with their multiplier)."""
    pin = pytest.importorskip("pinocchio")
    from harness.engines import pinocchio_peer

    peer = pinocchio_peer.build(scene, robot_files("jvrc1").urdf)
    model, data = peer.model, peer.data
    pin.computeJointJacobians(model, data, peer.configuration(q))
    pin.updateFramePlacements(model, data)
    rm = scene.model
    to_spq = np.zeros((model.nv, rm.ndof))
    for li in range(rm.nlinks):
        if rm.q_index[li] >= 0:
            joint = model.joints[model.getJointId(rm.link_joint_names[li])]
            to_spq[joint.idx_v, rm.q_index[li]] += rm.q_multiplier[li]

    def point_jacobian(body: int, p: np.ndarray) -> np.ndarray:
        fid = model.getFrameId(rm.link_names[scene.bodies[body].link], pin.FrameType.BODY)
        J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        r = p - data.oMf[fid].translation  # v_p = v_frame + ω × r
        return J[:3] + np.cross(J[3:].T, r).T

    rows = np.full((len(scene.pairs), rm.ndof), np.nan)
    for k, (a, b) in enumerate(scene.pairs):
        if res.status[k] != "separated":
            continue
        rows[k] = res.normal[k] @ (point_jacobian(b, res.point_b[k]) - point_jacobian(a, res.point_a[k])) @ to_spq
    return rows


def test_jacobian_rows_equal_pinocchio_frame_jacobians_at_the_witness_points():
    scene = jvrc1("auto")
    for q in inner_configurations(scene.model, 3, 7):
        res = scene.distances(q, coherent=False, jacobian=True)
        theirs = pinocchio_rows(scene, q, res)
        ok = res.status == "separated"
        assert ok.sum() > 100
        assert np.abs(res.jacobian[ok] - theirs[ok]).max() <= 1e-9


def kuka(policy: str = "stp", **options) -> Scene:
    files = robot_files("kuka_iiwa")
    return Scene.from_urdf(files.urdf, mesh_root=files.mesh_root, policy=policy, **TIGHT, **options)


def test_pruned_rows_are_zero_and_unsigned_overlaps_are_nan():
    scene = kuka("pch")
    q = np.zeros(scene.model.ndof)
    res = scene.distances(q, coherent=False, prune=0.05, jacobian=True)
    assert res.pruned.any()
    assert (res.jacobian[res.pruned] == 0.0).all()
    assert np.isfinite(res.jacobian[~res.pruned & (res.status == "separated")]).all()
    unsigned_overlap = res.status == "overlapping"
    assert np.isnan(res.jacobian[unsigned_overlap]).all()
    assert scene.distances(q, jacobian=False).jacobian is None


def test_floating_base_columns_equal_differences_of_the_base_pose():
    scene = kuka("stp", floating_base=True)
    assert scene.nv == 6 + scene.model.ndof
    base = np.eye(4)
    base[:3, :3] = Rotation.from_rotvec([0.2, -0.1, 0.3]).as_matrix()
    base[:3, 3] = [0.3, -0.2, 0.1]
    q = inner_configurations(scene.model, 1, 4)[0]
    scene.set_base(base)
    res = scene.distances(q, coherent=False, jacobian=True)
    ok = (res.status == "separated") & (res.distance > CLEAR)
    assert ok.any()
    for k in range(6):
        plus, minus = base.copy(), base.copy()
        if k < 3:  # the base origin's velocity, world frame
            plus[k, 3] += H
            minus[k, 3] -= H
        else:  # the base's angular velocity, world frame, about its own origin
            w = np.zeros(3)
            w[k - 3] = H
            plus[:3, :3] = Rotation.from_rotvec(w).as_matrix() @ base[:3, :3]
            minus[:3, :3] = Rotation.from_rotvec(-w).as_matrix() @ base[:3, :3]
        scene.set_base(plus)
        dp = scene.distances(q, coherent=False).distance
        scene.set_base(minus)
        dm = scene.distances(q, coherent=False).distance
        fd = (dp - dm) / (2 * H)
        assert np.abs(res.jacobian[ok, k] - fd[ok]).max() <= AGREE
    scene.set_base(base)
    joints = scene.distances(q, coherent=False, jacobian=True).jacobian[:, 6:]
    fixed = kuka("stp", base=base)
    assert np.allclose(joints[ok], fixed.distances(q, coherent=False, jacobian=True).jacobian[ok], atol=1e-12)


def test_obstacles_pair_with_every_robot_body_and_their_rows_equal_differences():
    wall = np.eye(4)
    wall[:3, 3] = [0.45, 0.0, 0.6]
    shelf = np.eye(4)
    shelf[:3, 3] = [0.0, 0.5, 0.4]
    board = Polyhedron.from_points(np.array([[x, y, z] for x in (-0.2, 0.2) for y in (-0.1, 0.1) for z in (0, 0.02)]))
    obstacles = [Obstacle("wall", Box(0.02, 0.5, 0.5), wall), Obstacle("shelf", board, shelf)]
    scene = kuka("stp", obstacles=obstacles)
    robot = [i for i, b in enumerate(scene.bodies) if b.link != WORLD]
    world = [i for i, b in enumerate(scene.bodies) if b.link == WORLD]
    assert len(world) == 2
    pairs = {tuple(p) for p in scene.pairs.tolist()}
    assert all((min(r, w), max(r, w)) in pairs for r in robot for w in world)
    assert (world[0], world[1]) not in pairs
    q = inner_configurations(scene.model, 1, 5)[0]
    res = scene.distances(q, coherent=False, jacobian=True)
    fd = fd_rows(scene, q)
    on_world = np.isin(scene.pairs, world).any(axis=1) & (res.status == "separated") & (res.distance > CLEAR)
    assert on_world.sum() >= 10
    assert np.abs(res.jacobian[on_world] - fd[on_world]).max() <= AGREE
    poses = scene.body_poses(q)
    assert np.allclose(poses[world[0]], wall) and np.allclose(poses[world[1]], shelf)


def test_link_jacobian_equals_differences_of_the_link_pose():
    scene = kuka("pch", floating_base=True)
    q = inner_configurations(scene.model, 1, 6)[0]
    link = scene.model.nlinks - 1
    local = np.array([0.01, 0.02, 0.05])
    pose = scene.link_poses(q)[link]
    J = scene.link_jacobian(q, link, pose[:3, :3] @ local + pose[:3, 3])
    assert J.shape == (6, 6 + scene.model.ndof)
    for j in range(scene.model.ndof):
        dq = np.zeros(scene.model.ndof)
        dq[j] = H
        Tp, Tm = scene.link_poses(q + dq)[link], scene.link_poses(q - dq)[link]
        v = ((Tp[:3, :3] @ local + Tp[:3, 3]) - (Tm[:3, :3] @ local + Tm[:3, 3])) / (2 * H)
        w = Rotation.from_matrix(Tp[:3, :3] @ Tm[:3, :3].T).as_rotvec() / (2 * H)
        assert np.allclose(J[:3, 6 + j], v, atol=1e-8) and np.allclose(J[3:, 6 + j], w, atol=1e-8)
    assert np.allclose(J[:3, :3], np.eye(3)) and np.allclose(J[3:, 3:6], np.eye(3))
    points, rotations, jacobians = scene.frame_jacobians(q, [(link, local), (2, np.zeros(3))])
    assert np.allclose(points[0], pose[:3, :3] @ local + pose[:3, 3], atol=1e-15)
    assert np.allclose(rotations[0], pose[:3, :3], atol=1e-15) and np.array_equal(jacobians[0], J)
    assert np.array_equal(jacobians[1], scene.link_jacobian(q, 2, scene.link_poses(q)[2][:3, 3]))


def test_bad_input_is_a_clear_value_error():
    scene = kuka("pch")
    q = np.zeros(scene.model.ndof)
    with pytest.raises(ValueError, match="link"):
        scene.link_jacobian(q, 99, np.zeros(3))
    with pytest.raises(ValueError, match="point"):
        scene.link_jacobian(q, 1, [0.0, np.nan, 0.0])
    with pytest.raises(ValueError, match="Obstacle"):
        kuka("pch", obstacles=[Box(0.1, 0.1, 0.1)])
    with pytest.raises(ValueError, match="shape"):
        kuka("pch", obstacles=[Obstacle("cone", object(), np.eye(4))])
    with pytest.raises(ValueError, match="jac_out"):
        scene.distances_many(q[None], jacobian=True, jac_out=np.empty((1, 1, 1)))


def test_rows_on_threads_equal_one_threads_bit_for_bit():
    scene = kuka("auto")
    qs = inner_configurations(scene.model, 64, 8)
    out1, jac1 = scene.distances_many(qs, jacobian=True, signed=True)
    out2, jac2 = scene.distances_many(qs, jacobian=True, signed=True, workers=2)
    assert np.array_equal(out1, out2, equal_nan=True) and np.array_equal(jac1, jac2, equal_nan=True)
    assert np.array_equal(out1, scene.distances_many(qs, signed=True), equal_nan=True)  # rows change no result
    single = scene.distances(qs[3], coherent=False, signed=True, jacobian=True)
    assert np.array_equal(single.jacobian, jac1[3], equal_nan=True)
