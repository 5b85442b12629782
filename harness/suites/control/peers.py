"""The peers in their own controllers, on the same robot, hulls, pairs, tasks and damper law.

- **pink** (pip ``pin-pink``): ``pink.solve_ik`` with a ``FrameTask`` per hand, a ``PostureTask``, its
  ``ConfigurationLimit`` and ``VelocityLimit``, and ``pink.barriers.SelfCollisionBarrier`` over every pair,
  on a pinocchio model (its own URDF parser, the frozen joints locked by ``buildReducedModel``) whose
  GeometryModel holds the scene's bodies as coal shapes (harness/pinocchio_peer.coal_geometry: the PCH
  hull as coal.Convex, exact primitives as coal's) on the same links, with the same pairs; obstacles on
  the universe joint.
- **mink** (pip ``mink``): ``mink.solve_ik`` with a ``FrameTask`` per hand (a site), a ``PostureTask``,
  ``ConfigurationLimit``, ``VelocityLimit`` and ``mink.CollisionAvoidanceLimit`` over the same pairs, on a
  MuJoCo model written from spq's RobotModel (one body per link, frozen joints welded at q0) with the
  same hulls as mesh geoms (vertices inline; MuJoCo hulls them) and primitives as MuJoCo's.

The damper law is made the same: pink's barrier row ``−J q̇ ≤ γ (d − d_min)`` with γ = ξ/(d_i − d_s) and
d_min = d_s (pink keeps every pair's row, loose beyond d_i); mink's row ``−J Δq ≤ g (d − d_min)/dt``
(its own scaling, Δq = q̇ dt) with g = ξ dt²/(d_i − d_s), d_min = d_s, detection distance d_i. Joint
limits: ``Δq ≤ g (q_max − q)`` in both, with g = v_max dt/(s_i − s_s) and the limits pulled in by s_s,
the slope of spq's joint damper. Tasks: both peers' tasks have no feed-forward term; their gain is K dt
(the same feedback K; one gain for position and orientation), their costs the square roots of spq's
weights (pink and mink square a task's cost in the objective), and each step's target is put where their
feedback K (target − x) equals spq's demand v_ref + K clip(x_ref − x) (the reference's velocity fed
forward through the target, the error clipped as spq clips it). Solvers: pink with
proxqp warm-started; mink with daqp (MINK_SOLVER: proxqp reported NoSolutionFound on most of mink's
steps once pairs were active, warm-started or not).

For the common metrics each peer's trajectory is mapped to spq's q by joint name, and its rows (pairs
with d < d_i, by the peer's own distances and Jacobians) are logged with the witness points in spq's
body frames.
"""

from __future__ import annotations

import time

import numpy as np

from harness.suites.control.controller import STATUS_FAILED, STATUS_SOLVED, RunLog, StepRows, body_frame_points, \
    clipped_error, joint_bounds, urdf_velocity_limits

PEERS = ("pink", "mink")
MINK_SOLVER = "daqp"  # proxqp (cold) reports NoSolutionFound on most of mink's steps once pairs are active; daqp solves them all
MINK_OPTIONS: dict = {}
MINK_WARM = True


def _need(module: str, pip: str):
    from importlib import import_module

    try:
        return import_module(module)
    except ImportError as exc:
        raise ImportError(f"the {module} peer needs pip install {pip}: {exc}") from None


# --- pinocchio / pink -----------------------------------------------------------------------------
class PinModel:
    """A pinocchio model + GeometryModel of an spq scene, frozen joints locked at q0, hand frames added."""

    def __init__(self, scene, urdf, q0, frozen, hands):
        pin = _need("pinocchio", "pin")
        from harness.engines.pinocchio_peer import coal_geometry

        model = pin.buildModelFromUrdf(str(urdf))
        geometry = pin.GeometryModel()
        m = scene.model
        for body in scene.bodies:
            if body.link < 0:  # an obstacle: on the universe joint, at its world pose
                placement = pin.SE3(body.offset[:3, :3].copy(), body.offset[:3, 3].copy())
                geometry.addGeometryObject(pin.GeometryObject(body.name, 0, 0, placement, coal_geometry(body)))
                continue
            fid = model.getFrameId(m.link_names[body.link], pin.FrameType.BODY)
            frame = model.frames[fid]
            placement = frame.placement * pin.SE3(body.offset[:3, :3].copy(), body.offset[:3, 3].copy())
            geometry.addGeometryObject(pin.GeometryObject(body.name, frame.parentJoint, fid, placement,
                                                          coal_geometry(body)))
        for i, (link, point) in enumerate(hands):
            fid = model.getFrameId(m.link_names[link], pin.FrameType.BODY)
            frame = model.frames[fid]
            model.addFrame(pin.Frame(f"hand{i}", frame.parentJoint, fid,
                                     frame.placement * pin.SE3(np.eye(3), np.asarray(point, float)), pin.FrameType.OP_FRAME))
        q0_full = self._full_configuration(pin, model, m, q0)
        active = {m.joint_names[j] for j in np.flatnonzero(~np.asarray(frozen, bool))}
        # every joint but the active ones is locked at q0 (mimic joints at their master's value)
        lock = [jid for jid in range(1, model.njoints) if model.names[jid] not in active]
        self.model, self.geometry = pin.buildReducedModel(model, geometry, lock, q0_full)
        self.geometry.removeAllCollisionPairs()
        for a, b in np.asarray(scene.pairs).tolist():
            self.geometry.addCollisionPair(pin.CollisionPair(int(a), int(b)))
        self.data = self.model.createData()
        self.gdata = pin.GeometryData(self.geometry)
        # spq q index of each reduced-model joint (1-dof joints only; continuous: cos/sin)
        self.idx_q, self.idx_v, self.src, self.cont = [], [], [], []
        for jid in range(1, self.model.njoints):
            name = self.model.names[jid]
            joint = self.model.joints[jid]
            if name not in m.joint_names:
                raise ValueError(f"pinocchio joint {name!r} is not one of spq's joints")
            self.idx_q.append(joint.idx_q)
            self.idx_v.append(joint.idx_v)
            self.src.append(m.joint_names.index(name))
            self.cont.append(joint.nq == 2)
        self.idx_q, self.idx_v, self.src, self.cont = (np.array(a) for a in (self.idx_q, self.idx_v, self.src, self.cont))
        self.q_template = np.array(q0, float)

    @staticmethod
    def _full_configuration(pin, model, m, q):
        out = pin.neutral(model)
        for link in range(m.nlinks):
            if m.q_index[link] < 0:
                continue
            name = m.link_joint_names[link]
            value = m.q_multiplier[link] * q[m.q_index[link]] + m.q_offset[link]
            if model.existJointName(name):
                joint = model.joints[model.getJointId(name)]
                if joint.nq == 2:
                    out[joint.idx_q], out[joint.idx_q + 1] = np.cos(value), np.sin(value)
                else:
                    out[joint.idx_q] = value
        return out

    def to_pin(self, q):
        pin = _need("pinocchio", "pin")
        out = pin.neutral(self.model)
        v = np.asarray(q)[self.src]
        plain = ~self.cont
        out[self.idx_q[plain]] = v[plain]
        out[self.idx_q[self.cont]] = np.cos(v[self.cont])
        out[self.idx_q[self.cont] + 1] = np.sin(v[self.cont])
        return out

    def to_spq_velocity(self, v, n):
        out = np.zeros(n)
        out[self.src] = np.asarray(v)[self.idx_v]
        return out

    def from_spq_vector(self, x):
        """A per-joint spq vector (n,) -> the reduced model's v order."""
        out = np.zeros(self.model.nv)
        out[self.idx_v] = np.asarray(x)[self.src]
        return out


def _pink_barrier_class():
    from pink.barriers import SelfCollisionBarrier

    class TimedSelfCollisionBarrier(SelfCollisionBarrier):
        """pink's barrier, unchanged, with the time of its distances' use and rows recorded."""

        seconds = 0.0
        last_jacobian = None

        def compute_barrier(self, configuration):
            start = time.perf_counter()
            out = super().compute_barrier(configuration)
            self.seconds += time.perf_counter() - start
            return out

        def compute_jacobian(self, configuration):
            start = time.perf_counter()
            out = super().compute_jacobian(configuration)
            self.seconds += time.perf_counter() - start
            self.last_jacobian = out
            return out

    return TimedSelfCollisionBarrier


def run_pink(task, scene, urdf, params, steps: int, frozen) -> RunLog:
    """``task`` with pink (see the module docstring); a pink failure is a stated status per step."""
    pin = _need("pinocchio", "pin")
    pink = _need("pink", "pin-pink")
    from pink.limits import ConfigurationLimit, VelocityLimit
    from pink.tasks import FrameTask, PostureTask

    m = scene.model
    n = m.ndof
    pm = PinModel(scene, urdf, task.q0, frozen, task.hands)
    model = pm.model
    vmax_spq = urdf_velocity_limits(m, params.velocity_limit)
    vmax = pm.from_spq_vector(vmax_spq)
    # pull the limits in by s_s so that pink's Δq <= g (q_max - q) slows the joint to a stop s_s short
    span = params.joint_di - params.joint_ds
    model.lowerPositionLimit = model.lowerPositionLimit + params.joint_ds
    model.upperPositionLimit = model.upperPositionLimit - params.joint_ds
    gain_limit = float(min(1.0, np.max(vmax) * params.dt / span))
    q_pin = pm.to_pin(task.q0)
    config = pink.Configuration(model, pm.data, q_pin, collision_model=pm.geometry, collision_data=pm.gdata)
    hands = [FrameTask(f"hand{i}", position_cost=np.sqrt(params.position_weight),  # pink squares its costs
                       orientation_cost=np.sqrt(params.orientation_weight), gain=params.position_gain * params.dt)
             for i in range(len(task.hands))]
    posture = PostureTask(cost=np.sqrt(params.posture_weight), gain=params.posture_gain * params.dt)
    posture.set_target(q_pin.copy())
    R_start = {h.frame: config.get_transform_frame_to_world(h.frame).rotation.copy() for h in hands}
    limits = [ConfigurationLimit(model, config_limit_gain=gain_limit), VelocityLimit(model, vmax)]
    npairs = len(scene.pairs)
    barrier = _pink_barrier_class()(npairs, gain=params.xi / (params.di - params.ds), d_min=params.ds)
    start_points = task.hand_points(scene, task.q0)
    log = _log("pink", task, steps, n)
    q = np.array(task.q0, float)
    v_prev = np.zeros(model.nv)
    for k in range(steps):
        t0 = time.perf_counter()
        config.update(q_pin)
        t_update = time.perf_counter() - t0
        refs, vels = task.reference(k * params.dt, start_points)
        for h, ref, vel in zip(hands, refs, vels):  # spq's demand v_ref + K clip(x_ref - x) through the target
            current = config.get_transform_frame_to_world(h.frame)
            goal = (current.translation + clipped_error(np.asarray(ref, float) - current.translation, params)
                    + np.asarray(vel, float) / params.position_gain)
            h.set_target(pin.SE3(R_start[h.frame], goal))
        barrier.seconds = 0.0
        barrier.last_jacobian = None
        t1 = time.perf_counter()
        try:
            v = pink.solve_ik(config, [*hands, posture], params.dt, solver="proxqp", damping=params.damping,
                              limits=limits, barriers=[barrier], safety_break=False,
                              initvals=v_prev * params.dt)
            status = STATUS_SOLVED
        except Exception as exc:  # noqa: BLE001  pink's NoSolutionFound and solver errors: a stated status
            v, status = np.zeros(model.nv), f"{STATUS_FAILED}: {type(exc).__name__}"
        t_solve = time.perf_counter() - t1
        qdot = pm.to_spq_velocity(v, n)
        rows = _pink_rows(scene, q, pm, barrier, params, n)
        lb, ub, damped = joint_bounds(q, m.lower, m.upper, vmax_spq, params, frozen)
        _put(log, k, rows, qdot, status, t_update + barrier.seconds, t_solve - barrier.seconds, damped, lb, ub)
        q_pin = pin.integrate(model, q_pin, v * params.dt)
        v_prev = v
        q = q + params.dt * qdot
        q, log.clipped = _clip(q, m, log.clipped)
        _track(log, k, task, scene, q, start_points, params)
    log.note = f"pink {_version('pin-pink')}: {npairs} pairs in SelfCollisionBarrier; joint-limit gain {gain_limit:.3g}"
    return log


def _pink_rows(scene, q, pm, barrier, params, n) -> StepRows:
    """The barrier's rows of the pairs with d < di (pink's own distances and Jacobians), spq's columns."""
    results = pm.gdata.distanceResults
    d = np.array([r.min_distance for r in results])
    close = np.flatnonzero(d < params.di)
    if barrier.last_jacobian is None or not len(close):
        return StepRows.empty(n)
    order = np.argpartition(-d, -barrier.dim)[-barrier.dim:]  # pink's own row order
    row_of = {int(p): i for i, p in enumerate(order)}
    J = np.array([pm.to_spq_velocity(barrier.last_jacobian[row_of[int(p)]], n) for p in close])
    wa = np.array([np.array(results[int(p)].getNearestPoint1()) for p in close])
    wb = np.array([np.array(results[int(p)].getNearestPoint2()) for p in close])
    la, lb = body_frame_points(scene, q, close, wa, wb)
    return StepRows(close.astype(np.int64), d[close], J, la, lb)


# --- MuJoCo / mink --------------------------------------------------------------------------------
def _quat(R) -> str:
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=np.float64).ravel())
    return " ".join(repr(float(x)) for x in q)


def _pose_attrs(T) -> str:
    return f'pos="{" ".join(repr(float(x)) for x in T[:3, 3])}" quat="{_quat(T[:3, :3])}"'


def _geom_xml(body, index: int, meshes: list) -> str:
    from spq.shapes.primitives import Box, Capsule, Sphere

    s = body.shape
    name = f'name="g{index}"'
    where = _pose_attrs(body.offset if body.link >= 0 else body.offset)
    if isinstance(s, Box):
        return f'<geom {name} type="box" size="{" ".join(map(repr, map(float, s.half_extents)))}" {where}/>'
    if isinstance(s, Sphere):
        return f'<geom {name} type="sphere" size="{float(s.radius)!r}" {where}/>'
    if isinstance(s, Capsule):
        return f'<geom {name} type="capsule" size="{float(s.radius)!r} {float(s.half_length)!r}" {where}/>'
    v = np.asarray(body.hull.vertices, dtype=np.float64)
    meshes.append(f'<mesh name="m{index}" vertex="{" ".join(map(repr, v.ravel().tolist()))}"/>')
    return f'<geom {name} type="mesh" mesh="m{index}" {where}/>'


def _motion(m, link, value) -> np.ndarray:
    """The joint's motion (4x4) at joint value ``value``."""
    from spq.kinematics import PRISMATIC

    T = np.eye(4)
    axis = m.joint_axis[link]
    if m.joint_type[link] == PRISMATIC:
        T[:3, 3] = axis * value
    elif m.q_index[link] >= 0:
        from scipy.spatial.transform import Rotation

        T[:3, :3] = Rotation.from_rotvec(axis * value).as_matrix()
    return T


def mjcf(scene, q0, frozen, hands) -> str:
    """An MJCF of the scene: a body per link (frozen joints welded at q0), the bodies' geoms, the
    obstacles in the world body, a site per hand point (hand0, hand1...)."""
    from spq.kinematics import PRISMATIC

    m = scene.model
    meshes: list[str] = []
    geoms_of = {}
    for i, b in enumerate(scene.bodies):
        geoms_of.setdefault(b.link, []).append(_geom_xml(b, i, meshes))
    sites = {}
    for i, (link, point) in enumerate(hands):
        sites.setdefault(link, []).append(f'<site name="hand{i}" pos="{" ".join(map(repr, map(float, point)))}"/>')
    children = {}
    for link in range(m.nlinks):
        children.setdefault(int(m.parent[link]), []).append(link)

    def body(link: int) -> str:
        j = m.q_index[link]
        moving = j >= 0 and not frozen[j]
        value = m.q_multiplier[link] * q0[j] + m.q_offset[link] if j >= 0 else 0.0
        if m.parent[link] < 0:
            pose = scene.base @ m.joint_origin[link]
        else:
            pose = m.joint_origin[link] @ (np.eye(4) if moving else _motion(m, link, value))
        joint = ""
        if moving:
            if m.q_multiplier[link] != 1.0 or m.q_offset[link] != 0.0:
                raise ValueError(f"{m.link_joint_names[link]}: a mimic joint cannot be active in the MuJoCo peer")
            kind = "slide" if m.joint_type[link] == PRISMATIC else "hinge"
            joint = (f'<joint name="{m.link_joint_names[link]}" type="{kind}" axis="{" ".join(map(repr, map(float, m.joint_axis[link])))}" '
                     f'range="{float(m.lower[j])!r} {float(m.upper[j])!r}" limited="true"/>')
        inner = "".join(geoms_of.get(link, [])) + "".join(sites.get(link, []))
        kids = "".join(body(c) for c in children.get(link, []))
        inertial = '<inertial pos="0 0 0" mass="0.1" diaginertia="1e-4 1e-4 1e-4"/>'  # kinematics only: any mass
        return f'<body name="link_{m.link_names[link]}" {_pose_attrs(pose)}>{inertial}{joint}{inner}{kids}</body>'  # 'world' is MuJoCo's

    tree = "".join(body(r) for r in children.get(-1, []))
    world = "".join(geoms_of.get(-1, []))
    return (f'<mujoco model="{m.name}"><compiler angle="radian"/><asset>{"".join(meshes)}</asset>'
            f"<worldbody>{world}{tree}</worldbody></mujoco>")


class MjModel:
    """A MuJoCo model of the scene (see :func:`mjcf`) and its joint map to spq's q."""

    def __init__(self, scene, q0, frozen, hands):
        mujoco = _need("mujoco", "mujoco")
        xml = mjcf(scene, np.asarray(q0, float), np.asarray(frozen, bool), hands)
        try:
            self.model = mujoco.MjModel.from_xml_string(xml)
        except ValueError as exc:  # a flat hull has no volume for MuJoCo's inertia: take it from the surface
            if "volume" not in str(exc).lower() and "inertia" not in str(exc).lower():
                raise
            self.model = mujoco.MjModel.from_xml_string(xml.replace("<mesh ", '<mesh inertia="shell" '))
        # geom ids follow the MJCF tree's order, not spq's bodies': geom_of[body index] -> geom id
        self.geom_of = np.array([self.model.geom(f"g{i}").id for i in range(len(scene.bodies))], dtype=np.int64)
        names = scene.model.joint_names
        self.qadr, self.vadr, self.src = [], [], []
        for jid in range(self.model.njnt):
            self.qadr.append(self.model.jnt_qposadr[jid])
            self.vadr.append(self.model.jnt_dofadr[jid])
            self.src.append(names.index(self.model.joint(jid).name))
        self.qadr, self.vadr, self.src = (np.array(a, dtype=np.int64) for a in (self.qadr, self.vadr, self.src))

    def to_mj(self, q):
        out = np.zeros(self.model.nq)
        out[self.qadr] = np.asarray(q)[self.src]
        return out

    def to_spq_velocity(self, v, n):
        out = np.zeros(n)
        out[self.src] = np.asarray(v)[self.vadr]
        return out


def run_mink(task, scene, urdf, params, steps: int, frozen) -> RunLog:
    """``task`` with mink (see the module docstring); a mink failure is a stated status per step."""
    mujoco = _need("mujoco", "mujoco")
    mink = _need("mink", "mink")
    from mink.limits.collision_avoidance_limit import compute_contact_normal_jacobian

    m = scene.model
    n = m.ndof
    mm = MjModel(scene, task.q0, frozen, task.hands)
    model = mm.model
    vmax_spq = urdf_velocity_limits(m, params.velocity_limit)
    span = params.joint_di - params.joint_ds
    gain_limit = float(min(1.0, np.max(vmax_spq) * params.dt / span))
    config = mink.Configuration(model)
    config.update(mm.to_mj(task.q0))
    hands = [mink.FrameTask(f"hand{i}", "site", position_cost=np.sqrt(params.position_weight),  # squared by mink
                            orientation_cost=np.sqrt(params.orientation_weight), gain=params.position_gain * params.dt)
             for i in range(len(task.hands))]
    posture = mink.PostureTask(model, cost=np.sqrt(params.posture_weight), gain=params.posture_gain * params.dt)
    posture.set_target(mm.to_mj(task.q0))
    R_start = {h.frame_name: config.get_transform_frame_to_world(h.frame_name, "site").rotation() for h in hands}
    geom_pairs = [([f"g{a}"], [f"g{b}"]) for a, b in np.asarray(scene.pairs).tolist()]
    collision = mink.CollisionAvoidanceLimit(model, geom_pairs, gain=params.xi * params.dt**2 / (params.di - params.ds),
                                             minimum_distance_from_collisions=params.ds,
                                             collision_detection_distance=params.di)
    ours = [(min(a, b), max(a, b)) for a, b in mm.geom_of[np.asarray(scene.pairs)].tolist()]
    dropped = len(ours) - len(collision.geom_id_pairs)
    if set(collision.geom_id_pairs) != set(ours):  # mink drops welded / parent-child bodies: keep spq's pairs
        collision.geom_id_pairs = ours
        collision.max_num_contacts = len(ours)
        collision._init_broadphase(model)
    limits = [mink.ConfigurationLimit(model, gain=gain_limit, min_distance_from_limits=params.joint_ds),
              mink.VelocityLimit(model, {model.joint(j).name: float(vmax_spq[mm.src[j]]) for j in range(model.njnt)}),
              collision]
    start_points = task.hand_points(scene, task.q0)
    log = _log("mink", task, steps, n)
    q = np.array(task.q0, float)
    v_prev = np.zeros(model.nv)
    fromto, normal = np.zeros(6), np.zeros(3)
    jac1, jac2 = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    for k in range(steps):
        t0 = time.perf_counter()
        config.update(mm.to_mj(q))
        t_update = time.perf_counter() - t0
        refs, vels = task.reference(k * params.dt, start_points)
        for h, ref, vel in zip(hands, refs, vels):  # spq's demand v_ref + K clip(x_ref - x) through the target
            now = config.get_transform_frame_to_world(h.frame_name, "site").translation()
            goal = now + clipped_error(np.asarray(ref, float) - now, params) + np.asarray(vel, float) / params.position_gain
            h.set_target(mink.SE3.from_rotation_and_translation(R_start[h.frame_name], goal))
        t1 = time.perf_counter()
        collision.compute_qp_inequalities(config, params.dt)  # timed alone: mink's distances and rows
        t_rows = time.perf_counter() - t1
        t2 = time.perf_counter()
        try:
            v = mink.solve_ik(config, [*hands, posture], params.dt, solver=MINK_SOLVER, damping=params.damping,
                              limits=limits, **({"initvals": v_prev * params.dt} if MINK_WARM else {}), **MINK_OPTIONS)
            status = STATUS_SOLVED
        except Exception as exc:  # noqa: BLE001  mink's NoSolutionFound and solver errors: a stated status
            v, status = np.zeros(model.nv), f"{STATUS_FAILED}: {type(exc).__name__}"
        t_solve = time.perf_counter() - t2  # includes mink's own call of the collision limit: subtracted
        qdot = mm.to_spq_velocity(v, n)
        rows = _mink_rows(scene, q, mm, config, params, n, fromto, normal, jac1, jac2, mujoco,
                          compute_contact_normal_jacobian)
        lb, ub, damped = joint_bounds(q, m.lower, m.upper, vmax_spq, params, frozen)
        _put(log, k, rows, qdot, status, t_update + t_rows, max(t_solve - t_rows, 0.0), damped, lb, ub)
        v_prev = v
        q = q + params.dt * qdot
        q, log.clipped = _clip(q, m, log.clipped)
        _track(log, k, task, scene, q, start_points, params)
    log.note = (f"mink {_version('mink')}: {len(ours)} pairs in CollisionAvoidanceLimit"
                + (f" (mink's own filter would drop {dropped}: spq's pair set kept)" if dropped else "")
                + f"; joint-limit gain {gain_limit:.3g}")
    return log


def _mink_rows(scene, q, mm, config, params, n, fromto, normal, jac1, jac2, mujoco, row_of) -> StepRows:
    """Rows of the pairs with d < di from MuJoCo's distances (mj_geomDistance) and mj_jac, spq's columns."""
    model, data = mm.model, config.data
    pairs, dist, rows, wa, wb = [], [], [], [], []
    for p, (a, b) in enumerate(mm.geom_of[np.asarray(scene.pairs)].tolist()):
        d = mujoco.mj_geomDistance(model, data, a, b, params.di, fromto)
        if d >= params.di:
            continue
        row = row_of(model, data, a, b, fromto, normal, jac1, jac2)
        sign = 1.0 if d >= 0 else -1.0
        pairs.append(p)
        dist.append(d)
        rows.append(mm.to_spq_velocity(sign * row, n))
        wa.append(fromto[:3].copy())
        wb.append(fromto[3:].copy())
    if not pairs:
        return StepRows.empty(n)
    pairs = np.array(pairs, dtype=np.int64)
    la, lb = body_frame_points(scene, q, pairs, np.array(wa), np.array(wb))
    return StepRows(pairs, np.array(dist), np.array(rows), la, lb)


# --- shared bookkeeping ---------------------------------------------------------------------------
def _version(dist: str) -> str:
    from importlib import metadata

    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def _log(method, task, steps, n) -> RunLog:
    from harness.suites.control.controller import _empty_log

    return _empty_log(method, task, steps, n, np.array(task.q0, float))


def _put(log, k, rows, qdot, status, t_dist, t_qp, damped, lb, ub):
    from harness.suites.control.controller import _record

    _record(log, k, rows, qdot, status, t_dist, t_qp, damped, lb, ub)


def _clip(q, m, clipped):
    from harness.suites.control.controller import _clip as clip

    return clip(q, m.lower, m.upper, clipped)


def _track(log, k, task, scene, q, start_points, params):
    log.q[k + 1] = q
    x = task.hand_points(scene, q)
    log.task_error[k] = np.linalg.norm(x - task.final_targets(start_points), axis=1).max()
    refs, _ = task.reference((k + 1) * params.dt, start_points)
    log.reference_error[k] = np.linalg.norm(x - refs, axis=1).max()


def run_peer(name: str, task, scene, urdf, params, steps, frozen) -> RunLog:
    if name == "pink":
        return run_pink(task, scene, urdf, params, steps, frozen)
    if name == "mink":
        return run_mink(task, scene, urdf, params, steps, frozen)
    raise ValueError(f"unknown peer {name!r}; choose from {list(PEERS)}")


# --- the same damper QP fed by a peer's distances and Jacobians -----------------------------------
DAMPER_PEERS = ("pin-damper", "mujoco-damper")


def _point_jacobian_from_joint(J6: np.ndarray, origin: np.ndarray, point: np.ndarray) -> np.ndarray:
    """(3, nv) linear Jacobian of ``point`` from a joint's LOCAL_WORLD_ALIGNED Jacobian (6, nv) at its
    origin: v_p = v_o + ω × (p − o)."""
    r = point - origin
    skew = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    return J6[:3] - skew @ J6[3:]


class PinocchioSource:
    """Damper rows from pinocchio + coal: ``computeDistances`` (forward kinematics, placements and every
    pair's coal distance in one call), then for each pair within d_i ``computeJointJacobians`` /
    ``getJointJacobian`` shifted to the two witness points and projected on the normal."""

    name = "pin-damper"

    def __init__(self, scene, urdf, q0, frozen, hands, params):
        self.pin = _need("pinocchio", "pin")
        self.scene, self.params = scene, params
        self.pm = PinModel(scene, urdf, q0, frozen, hands)
        self.n = scene.model.ndof
        geometry = self.pm.geometry
        self.joints = [(geometry.geometryObjects[int(a)].parentJoint, geometry.geometryObjects[int(b)].parentJoint)
                       for a, b in np.asarray(scene.pairs).tolist()]

    def reset(self) -> None:
        pass

    def rows(self, q) -> tuple[StepRows, float]:
        pin, pm, params = self.pin, self.pm, self.params
        start = time.perf_counter()
        q_pin = pm.to_pin(q)
        pin.computeDistances(pm.model, pm.data, pm.geometry, pm.gdata, q_pin)
        results = pm.gdata.distanceResults
        d = np.fromiter((r.min_distance for r in results), float, len(results))
        close = np.flatnonzero(d < params.di)
        rows = np.zeros((len(close), pm.model.nv))
        wa, wb = np.zeros((len(close), 3)), np.zeros((len(close), 3))
        if len(close):
            pin.computeJointJacobians(pm.model, pm.data, q_pin)
            frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
            for i, p in enumerate(close):
                r = results[int(p)]
                pa, pb = np.array(r.getNearestPoint1()), np.array(r.getNearestPoint2())
                n = (pb - pa) / d[p] if d[p] > 1e-9 else np.array(r.normal)
                row = np.zeros(pm.model.nv)
                for joint, point, sign in ((self.joints[p][1], pb, 1.0), (self.joints[p][0], pa, -1.0)):
                    if joint > 0:
                        J6 = pin.getJointJacobian(pm.model, pm.data, joint, frame)
                        row += sign * (n @ _point_jacobian_from_joint(J6, pm.data.oMi[joint].translation, point))
                rows[i], wa[i], wb[i] = row, pa, pb
        seconds = time.perf_counter() - start
        J = np.array([pm.to_spq_velocity(r, self.n) for r in rows]).reshape(len(close), self.n)
        la, lb = body_frame_points(self.scene, q, close, wa, wb)
        return StepRows(close.astype(np.int64), d[close], J, la, lb), seconds


class MujocoSource:
    """Damper rows from MuJoCo: ``mj_kinematics`` + ``mj_comPos``, a bounding-sphere broadphase (as mink's),
    ``mj_geomDistance`` per pair (distmax d_i) and ``mj_jac`` at the two witness points."""

    name = "mujoco-damper"

    def __init__(self, scene, q0, frozen, hands, params):
        self.mujoco = _need("mujoco", "mujoco")
        self.scene, self.params = scene, params
        self.mm = MjModel(scene, q0, frozen, hands)
        self.data = self.mujoco.MjData(self.mm.model)
        self.n = scene.model.ndof
        self.pairs = self.mm.geom_of[np.asarray(scene.pairs, dtype=np.int64)]
        self.rsum = self.mm.model.geom_rbound[self.pairs[:, 0]] + self.mm.model.geom_rbound[self.pairs[:, 1]]
        nv = self.mm.model.nv
        self._fromto, self._jac = np.zeros(6), (np.zeros((3, nv)), np.zeros((3, nv)))

    def reset(self) -> None:
        pass

    def rows(self, q) -> tuple[StepRows, float]:
        mujoco, model, data, params = self.mujoco, self.mm.model, self.data, self.params
        start = time.perf_counter()
        data.qpos[:] = self.mm.to_mj(q)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        gap = np.linalg.norm(data.geom_xpos[self.pairs[:, 0]] - data.geom_xpos[self.pairs[:, 1]], axis=1) - self.rsum
        pairs, dist, rows, wa, wb = [], [], [], [], []
        fromto, (ja, jb) = self._fromto, self._jac
        for p in np.flatnonzero(gap < params.di):
            a, b = int(self.pairs[p, 0]), int(self.pairs[p, 1])
            d = mujoco.mj_geomDistance(model, data, a, b, params.di, fromto)
            if d >= params.di:
                continue
            n = fromto[3:] - fromto[:3]
            norm = np.linalg.norm(n)
            n = n / norm if norm > 1e-12 else n
            mujoco.mj_jac(model, data, ja, None, fromto[:3], model.geom_bodyid[a])
            mujoco.mj_jac(model, data, jb, None, fromto[3:], model.geom_bodyid[b])
            row = (1.0 if d >= 0 else -1.0) * (n @ (jb - ja))  # mink's convention: fromto points along -n inside
            pairs.append(p)
            dist.append(d)
            rows.append(row)
            wa.append(fromto[:3].copy())
            wb.append(fromto[3:].copy())
        seconds = time.perf_counter() - start
        if not pairs:
            return StepRows.empty(self.n), seconds
        pairs = np.array(pairs, dtype=np.int64)
        J = np.array([self.mm.to_spq_velocity(r, self.n) for r in rows])
        la, lb = body_frame_points(self.scene, q, pairs, np.array(wa), np.array(wb))
        return StepRows(pairs, np.array(dist), J, la, lb), seconds


def damper_source(name: str, task, scene, urdf, params, frozen):
    """The distance source of a damper peer (DAMPER_PEERS) for ``task`` on ``scene``."""
    if name == "pin-damper":
        return PinocchioSource(scene, urdf, task.q0, frozen, task.hands, params)
    if name == "mujoco-damper":
        return MujocoSource(scene, task.q0, frozen, task.hands, params)
    raise ValueError(f"unknown damper peer {name!r}; choose from {list(DAMPER_PEERS)}")
