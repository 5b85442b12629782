"""Between another library's robot configuration and velocity and an spq scene's q and Jacobian columns.

pinocchio (pink) and MuJoCo (mink) order a robot's joints their own way and store some of them
differently; spq's scene has one entry of q per movable joint that mimics no other
(``RobotModel.joint_names``) and, for a floating-base scene, 6 base columns before the joints. A
:class:`JointMap` matches the joints by name and converts both ways:

- ``to_spq_q(q_other)``: the scene's q (ndof,) from the other model's configuration;
- ``columns(G, q_other)``: rows written in the scene's velocity columns (k, nv_spq), such as
  :class:`~spq.control.damper.DamperRows` or ``SceneDistances.jacobian``, in the other model's
  velocity columns (k, nv_other), so that ``G_other @ v_other == G @ v_spq`` for the same motion.

How each joint is stored:

- pinocchio: a revolute or prismatic joint has one q and one v entry; a continuous joint
  (JointModelRUBX/Y/Z) has two q entries (cos θ, sin θ) and one v entry; a free-flyer root has
  q = (x, y, z, qx, qy, qz, qw) and v = (linear, angular) velocity of the base frame, both in the
  BASE (local) frame. pinocchio 4.1's URDF parser (``mimic=False``, its default) reads a
  ``<mimic>`` joint as an independent joint; with ``mimic=True`` it is a JointModelMimic with no q
  or v entry of its own, and nothing to map.
- MuJoCo: hinge and slide joints have one qpos and one qvel entry (a URDF continuous joint is an
  unlimited hinge; its angle is wrapped to [-π, π] here, spq's range for it); a free joint has
  qpos = (x, y, z, qw, qx, qy, qz) and qvel = linear velocity in the WORLD frame, angular velocity
  in the BODY frame. MuJoCo's URDF import ignores ``<mimic>``. Ball joints are refused.

Mimic joints: spq moves a mimicking joint with its master (``q_multiplier``, ``q_offset``), so the
master's column of a scene Jacobian already holds the whole chain's effect; the mimicking joint's
own column in the other model gets 0, and ``from_spq_q`` sets its value from the master. A
controller must keep the other model's mimic joints following their masters (an equality task)
for the scene to describe its robot.

Floating base: with a floating-base scene (``scene.floating_base``) the base pose is read from the
other model's root joint and set on the scene (``scene.set_base``) by :meth:`JointMap.update_scene`,
and the scene's base columns (world-frame twist of the base origin) are rotated into the other
model's convention. With a fixed-base scene and a floating other model, the base does not move the
scene's bodies relative to each other: its columns are 0, which is exact for self-collision and
refused when the scene has static obstacles (link -1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spq.kinematics import CONTINUOUS

BASE_COLUMNS = 6  # a floating base's twist: linear then angular velocity
LIMIT_TOLERANCE = 1e-6  # rad or m: a joint this far past a limit (a QP's rounding) is put back on it, as pink's
#                         check_limits tolerates; farther, the scene refuses the configuration (ValueError)


def _pinocchio():
    try:
        import pinocchio
    except ImportError as exc:
        raise ImportError(f"this needs pinocchio (pip install pin): {exc}") from None
    return pinocchio


def _mujoco():
    try:
        import mujoco
    except ImportError as exc:
        raise ImportError(f"this needs MuJoCo (pip install mujoco): {exc}") from None
    return mujoco


def scene_is_floating(scene) -> bool:
    """Whether the scene's Jacobians carry the 6 base columns before the joints."""
    return bool(getattr(scene, "floating_base", False))


def _has_obstacles(scene) -> bool:
    return any(b.link < 0 for b in scene.bodies)


@dataclass(frozen=True, eq=False)
class JointMap:
    """A correspondence between another model's (q, v) and a scene's q and velocity columns.

    Build one with :func:`pinocchio_joint_map` or :func:`mujoco_joint_map`. Per spq degree of
    freedom j (in ``scene.model.joint_names`` order): ``q_address[j]`` its first entry in the
    other model's q, ``v_address[j]`` its entry in v, ``cos_sin[j]`` whether q stores (cos, sin),
    ``wrap[j]`` whether the angle is wrapped to [-π, π]. ``mimic``: (q_address, v_address,
    master dof, multiplier, offset, cos_sin) of the other model's joints that spq moves with a
    master. ``base``: None, 'pinocchio' or 'mujoco', the other model's root free joint, at
    q entries ``base_q`` .. +7 and v entries ``base_v`` .. +6."""

    joint_names: tuple
    nq: int
    nv: int
    q_address: np.ndarray
    v_address: np.ndarray
    cos_sin: np.ndarray
    wrap: np.ndarray
    mimic: tuple
    base: str | None
    base_q: int
    base_v: int
    scene_floating: bool
    lower: np.ndarray
    upper: np.ndarray

    @property
    def scene_nv(self) -> int:
        """Velocity columns of the scene's Jacobians (``scene.nv``): 6 + ndof floating, ndof fixed."""
        return len(self.joint_names) + (BASE_COLUMNS if self.scene_floating else 0)

    def _check(self, values, size: int, what: str) -> np.ndarray:
        arr = np.asarray(values, dtype=np.float64)
        if arr.shape != (size,):
            raise ValueError(f"{what} must have shape ({size},); got {arr.shape}")
        if not np.isfinite(arr).all():
            raise ValueError(f"{what} must be finite")
        return arr

    def to_spq_q(self, q_other) -> np.ndarray:
        """The scene's joint values (ndof,) in radians / metres from the other model's q (nq,); a
        value past the scene's joint limits by at most LIMIT_TOLERANCE is put on the limit."""
        q_other = self._check(q_other, self.nq, "the other model's configuration")
        a = self.q_address
        out = q_other[a].copy()
        cs = self.cos_sin
        out[cs] = np.arctan2(q_other[a[cs] + 1], q_other[a[cs]])
        out[self.wrap] = np.mod(out[self.wrap] + np.pi, 2.0 * np.pi) - np.pi
        near = (out >= self.lower - LIMIT_TOLERANCE) & (out <= self.upper + LIMIT_TOLERANCE)
        out[near] = np.clip(out[near], self.lower[near], self.upper[near])
        return out

    def base_pose(self, q_other) -> np.ndarray | None:
        """World pose (4, 4) of the base frame read from the other model's root free joint, or None."""
        if self.base is None:
            return None
        q_other = self._check(q_other, self.nq, "the other model's configuration")
        x = q_other[self.base_q:self.base_q + 7]
        pose = np.eye(4)
        pose[:3, 3] = x[:3]
        pose[:3, :3] = self._rotation(x[3:7])
        return pose

    def _rotation(self, quaternion: np.ndarray) -> np.ndarray:
        if self.base == "pinocchio":
            pin = _pinocchio()
            return pin.Quaternion(quaternion[3], quaternion[0], quaternion[1], quaternion[2]).normalized().matrix()
        mujoco = _mujoco()
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, quaternion / np.linalg.norm(quaternion))
        return rot.reshape(3, 3)

    def update_scene(self, scene, q_other) -> np.ndarray:
        """The scene's q for the other model's q; a floating-base scene's base is set from the other
        model's root joint first (``scene.set_base``)."""
        q = self.to_spq_q(q_other)
        if self.scene_floating and self.base is not None:
            scene.set_base(self.base_pose(q_other))
        return q

    def from_spq_q(self, q_spq, q_other=None, base=None) -> np.ndarray:
        """The other model's q (nq,) for the scene's q (ndof,): every mapped joint set, mimicking joints
        from their masters, a continuous joint as (cos, sin); the base (if the other model has one)
        from ``base`` (4, 4) or else kept. Entries not mapped are taken from ``q_other`` (default:
        zeros, with a unit quaternion and cos = 1 where needed)."""
        q_spq = self._check(q_spq, len(self.joint_names), "the scene's configuration")
        out = self._neutral() if q_other is None else self._check(q_other, self.nq, "q_other").copy()
        self._write(out, self.q_address, self.cos_sin, q_spq)
        for qa, _, master, mult, off, cs in self.mimic:
            self._write(out, np.array([qa]), np.array([cs]), np.array([mult * q_spq[master] + off]))
        if base is not None and self.base is not None:
            pose = np.asarray(base, dtype=np.float64)
            out[self.base_q:self.base_q + 7] = self._base_q(pose)
        return out

    @staticmethod
    def _write(out, address, cos_sin, values):
        out[address[~cos_sin]] = values[~cos_sin]
        out[address[cos_sin]] = np.cos(values[cos_sin])
        out[address[cos_sin] + 1] = np.sin(values[cos_sin])

    def _neutral(self) -> np.ndarray:
        out = np.zeros(self.nq)
        out[self.q_address[self.cos_sin]] = 1.0
        for qa, _, _, _, _, cs in self.mimic:
            if cs:
                out[qa] = 1.0
        if self.base == "pinocchio":
            out[self.base_q + 6] = 1.0
        elif self.base == "mujoco":
            out[self.base_q + 3] = 1.0
        return out

    def _base_q(self, pose: np.ndarray) -> np.ndarray:
        if self.base == "pinocchio":
            pin = _pinocchio()
            return np.asarray(pin.SE3ToXYZQUAT(pin.SE3(pose[:3, :3].copy(), pose[:3, 3].copy())), dtype=np.float64)
        mujoco = _mujoco()
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(pose[:3, :3]).ravel())
        return np.concatenate([pose[:3, 3], quat])

    def velocity_matrix(self, q_other) -> np.ndarray:
        """M (scene_nv, nv): the scene's velocity columns as functions of the other model's v,
        v_spq = M v_other, so that rows G (k, scene_nv) become G @ M (k, nv)."""
        m = np.zeros((self.scene_nv, self.nv))
        off = BASE_COLUMNS if self.scene_floating else 0
        m[off + np.arange(len(self.joint_names)), self.v_address] = 1.0
        if self.scene_floating and self.base is not None:
            rot = self.base_pose(q_other)[:3, :3]
            b = self.base_v
            # spq: world-frame linear velocity of the base origin and world-frame angular velocity
            m[0:3, b:b + 3] = rot if self.base == "pinocchio" else np.eye(3)  # pinocchio's linear part is local
            m[3:6, b + 3:b + 6] = rot  # both store the angular velocity in the base frame
        return m

    def columns(self, rows, q_other) -> np.ndarray:
        """Rows (k, scene_nv) in the scene's velocity columns as rows (k, nv) in the other model's."""
        rows = np.asarray(rows, dtype=np.float64)
        if rows.ndim != 2 or rows.shape[1] != self.scene_nv:
            raise ValueError(f"rows must have shape (k, {self.scene_nv}) (the scene's velocity columns); "
                             f"got {rows.shape}")
        return rows @ self.velocity_matrix(q_other)


def _scene_joints(scene):
    """(dof by joint name, {mimicking joint name: (master dof, multiplier, offset)}) of a scene's model."""
    m = scene.model
    dof = {name: j for j, name in enumerate(m.joint_names)}
    mimic = {}
    for link in range(m.nlinks):
        name = m.link_joint_names[link]
        if m.q_index[link] >= 0 and name not in dof:
            mimic[name] = (int(m.q_index[link]), float(m.q_multiplier[link]), float(m.q_offset[link]))
    return dof, mimic


def _check_base(scene, base, what: str) -> None:
    if scene_is_floating(scene) and base is None:
        raise ValueError(f"the scene has a floating base but {what} has no free root joint")
    if base is not None and not scene_is_floating(scene) and _has_obstacles(scene):
        raise ValueError(f"{what} has a floating base but the scene is fixed-base and has static obstacles: "
                         f"build the scene with floating_base=True")


def _finish(scene, found, unknown, mimic_rows, nq, nv, base, base_q, base_v, what):
    names = scene.model.joint_names
    missing = [n for n in names if n not in found]
    if missing or unknown:
        raise ValueError(f"{what} and the scene are not the same robot: {what} has no joint named {missing} and "
                         f"joints the scene does not know: {unknown} (the scene's joints: {list(names)})")
    _check_base(scene, base, what)
    qa, va, cs, wrap = (np.array([found[n][k] for n in names]) for k in range(4))
    return JointMap(tuple(names), int(nq), int(nv), qa.astype(np.int64).reshape(-1), va.astype(np.int64).reshape(-1),
                    cs.astype(bool).reshape(-1), wrap.astype(bool).reshape(-1), tuple(mimic_rows), base,
                    int(base_q), int(base_v), scene_is_floating(scene), scene.model.lower, scene.model.upper)


def pinocchio_joint_map(scene, model) -> JointMap:
    """The map between a pinocchio Model (pink's ``configuration.model``) and an spq Scene of the same
    robot, joints matched by name. ValueError if a scene joint is missing from the model, if the
    model has a joint the scene does not know (other than a free-flyer root), or for joint types
    other than revolute, continuous, prismatic and a free-flyer root."""
    dof, mimic = _scene_joints(scene)
    found, mimic_rows, unknown = {}, [], []
    base, base_q, base_v = None, -1, -1
    for jid in range(1, model.njoints):
        joint, name = model.joints[jid], model.names[jid]
        kind = joint.shortname()
        if "Mimic" in kind or joint.nv == 0:
            continue  # a pinocchio mimic joint has no entries of its own
        if "FreeFlyer" in kind and model.parents[jid] == 0 and name not in dof:
            base, base_q, base_v = "pinocchio", joint.idx_q, joint.idx_v
            continue
        if joint.nv != 1 or joint.nq not in (1, 2):
            raise ValueError(f"pinocchio joint {name!r} of type {kind} is not supported (revolute, continuous, "
                             f"prismatic, or a free-flyer root)")
        cos_sin = joint.nq == 2
        if name in dof:
            found[name] = (joint.idx_q, joint.idx_v, cos_sin, False)
        elif name in mimic:
            mimic_rows.append((joint.idx_q, joint.idx_v) + mimic[name] + (cos_sin,))
        else:
            unknown.append(name)
    return _finish(scene, found, unknown, mimic_rows, model.nq, model.nv, base, base_q, base_v, "the pinocchio model")


def mujoco_joint_map(scene, model) -> JointMap:
    """The map between a MuJoCo MjModel (mink's ``configuration.model``) and an spq Scene of the same
    robot, joints matched by name; hinge and slide joints, and a free joint on a body of the world.
    ValueError as for :func:`pinocchio_joint_map`."""
    mujoco = _mujoco()
    dof, mimic = _scene_joints(scene)
    m = scene.model
    continuous = {m.link_joint_names[k] for k in range(m.nlinks) if m.joint_type[k] == CONTINUOUS}
    found, mimic_rows, unknown = {}, [], []
    base, base_q, base_v = None, -1, -1
    free, ball = int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL)
    hinge = int(mujoco.mjtJoint.mjJNT_HINGE)
    for jid in range(model.njnt):
        name = model.joint(jid).name
        kind = int(model.jnt_type[jid])
        qa, va = int(model.jnt_qposadr[jid]), int(model.jnt_dofadr[jid])
        if kind == free and model.body_parentid[model.jnt_bodyid[jid]] == 0 and name not in dof:
            base, base_q, base_v = "mujoco", qa, va
            continue
        if kind in (free, ball):
            raise ValueError(f"MuJoCo joint {name!r} is a {'free' if kind == free else 'ball'} joint; supported: "
                             f"hinge, slide, and a free joint on a body of the world")
        # a URDF continuous joint (an unlimited hinge in MuJoCo) is wrapped to spq's [-pi, pi]
        wrap = kind == hinge and name in continuous
        if name in dof:
            found[name] = (qa, va, False, wrap)
        elif name in mimic:
            mimic_rows.append((qa, va) + mimic[name] + (False,))
        else:
            unknown.append(name)
    return _finish(scene, found, unknown, mimic_rows, model.nq, model.nv, base, base_q, base_v, "the MuJoCo model")
