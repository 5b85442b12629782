"""A differential-IK controller as a QP at a fixed step, with velocity dampers on the pairs near contact.

At every step (``dt``, 5 ms by default) the controller solves, for the joint velocities q̇ (spq's q order,
rad/s or m/s)::

    minimise   ½ Σ_hands w_p ‖J_p q̇ − (ẋ_ref + K_p (x_ref − x))‖²          hand points (m/s)
             + ½ Σ_hands w_o ‖J_ω q̇ − K_o e_o‖²                            hand orientations (optional)
             + ½ w_post ‖q̇ − K_post (q_0 − q)‖²  + ½ λ ‖q̇‖²                posture, damping
    subject to −∂d/∂q q̇ ≤ ξ (d − d_s)/(d_i − d_s)     every pair with d < d_i (the velocity damper)
               lb ≤ q̇ ≤ ub                               joint velocity limits and joint-limit dampers

The joint-limit damper (mc_rtc's idea, in a continuous form): for a joint at s from a limit,
|q̇ toward it| ≤ v_max (s − s_s)/(s_i − s_s) once s < s_i, which equals v_max at s = s_i, so the bound
turns on without a jump and the joint slows to a stop at s_s instead of hitting the limit in one step.

The QP goes to proxsuite's proxqp through qpsolvers, warm-started with the previous step's q̇; where proxqp
finds no solution, daqp tries (counted apart). A failed solve is a stated status (counted; q̇ = 0 that
step), never an exception. The damper rows come from a
*distance source* (:class:`SpqSource` for an spq Scene; harness.suites.control.peers has pinocchio's and
MuJoCo's), so one QP serves every geometry.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from xml.etree import ElementTree

import numpy as np

QP_SOLVER = "proxqp"  # qpsolvers' name for proxsuite's dense proxqp
QP_EPS_ABS = 1e-9  # proxqp's absolute tolerance on the constraints and the optimality (rad/s, m/s)
STATUS_SOLVED = "solved"
STATUS_FAILED = "failed"  # the solver found no solution (infeasible or not converged): q̇ = 0 held
STATUS_FALLBACK = "solved by daqp"  # proxqp found none, its fallback did (counted apart, not a failure)
QP_FALLBACK = "daqp"


@dataclass(frozen=True)
class ControlParams:
    """Every parameter of the controller (SI units), stated with each result.

    dt: step (s). di, ds: the velocity damper's interaction and safety distances (m); xi: its gain (m/s:
    the approach speed it allows at d = di). position_gain, orientation_gain (1/s), position_weight,
    orientation_weight (0: position only): the hand tasks. posture_gain (1/s), posture_weight: a weak pull
    to the start posture that resolves the redundancy. damping: Tikhonov weight on q̇.
    joint_di, joint_ds: the joint-limit damper's interaction and safety gaps (rad, or m for a prismatic
    joint). velocity_limit: cap on every joint's speed (rad/s; the URDF's limit where lower).
    task_speed_limit: the position feedback K_p (x_ref − x) is clipped to this speed (m/s), so that a hand
    held back by a damper does not push ever harder as its error grows.
    xi_auto: mc_rtc's automatic damper gain: a pair's row turning on at distance d with the pair already
    approaching at -ḋ > xi (d - ds)/(di - ds) gets its own gain ξ_p = -ḋ (di - ds)/(d - ds) (kept while it stays
    within di), so that the row turns on without forcing a jump; otherwise ξ_p = xi.
    """

    dt: float = 0.005
    di: float = 0.05
    ds: float = 0.01
    xi: float = 0.5
    position_gain: float = 10.0
    orientation_gain: float = 5.0
    position_weight: float = 1.0
    orientation_weight: float = 0.1
    posture_gain: float = 1.0
    posture_weight: float = 1e-2
    damping: float = 1e-4
    joint_di: float = 0.15
    joint_ds: float = 0.02
    velocity_limit: float = 2.0
    task_speed_limit: float = 0.5
    xi_auto: bool = True

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool):
                continue
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"control parameter {f.name} must be a finite number >= 0; got {v}")
        if self.dt <= 0 or self.xi <= 0 or self.velocity_limit <= 0 or self.task_speed_limit <= 0:
            raise ValueError(f"dt, xi and velocity_limit must be > 0; got {self.dt}, {self.xi}, {self.velocity_limit}")
        if not self.ds < self.di:
            raise ValueError(f"the damper needs 0 <= ds < di (m); got ds={self.ds}, di={self.di}")
        if not self.joint_ds < self.joint_di:
            raise ValueError(f"the joint-limit damper needs 0 <= joint_ds < joint_di; got {self.joint_ds}, "
                             f"{self.joint_di}")

    def describe(self) -> dict:
        return dataclasses.asdict(self)


@dataclass
class StepRows:
    """A distance source's answer at one configuration, for the pairs with d < di (k of them).

    pairs (k,) indices into scene.pairs; distance (k,) m; jacobian (k, n) ∂d/∂q in spq's q order;
    witness_a, witness_b (k, 3): the witness points in their own body's frame (m), to see the closest
    features switch; failed: pairs whose query gave no usable row."""

    pairs: np.ndarray
    distance: np.ndarray
    jacobian: np.ndarray
    witness_a: np.ndarray
    witness_b: np.ndarray
    failed: int = 0
    h: np.ndarray | None = None  # (k,) the damper bounds the QP got (m/s), set by the Controller

    @classmethod
    def empty(cls, n: int) -> "StepRows":
        return cls(np.zeros(0, np.int64), np.zeros(0), np.zeros((0, n)), np.zeros((0, 3)), np.zeros((0, 3)))


def body_frame_points(scene, q, pairs: np.ndarray, world_a: np.ndarray, world_b: np.ndarray):
    """Witness points (k, 3) world -> each pair's body frames, at q (spq's body poses)."""
    links = scene.link_poses(q)
    out = []
    for side, world in ((0, world_a), (1, world_b)):
        local = np.empty((len(pairs), 3))
        for i, p in enumerate(pairs):
            body = scene.bodies[scene.pairs[p, side]]
            pose = body.offset if body.link < 0 else links[body.link] @ body.offset
            local[i] = pose[:3, :3].T @ (world[i] - pose[:3, 3])
        out.append(local)
    return out


class SpqSource:
    """Damper rows from an spq Scene: ``spq.control.VelocityDamper`` (one compiled call for the
    distances and every row ∂d/∂q of the pairs within di, coherent along the run)."""

    def __init__(self, scene, params: ControlParams, name: str | None = None):
        from spq.control import VelocityDamper

        self.scene = scene
        self.name = name or f"spq-{scene.policy}"
        self.damper = VelocityDamper(scene, di=params.di, ds=params.ds, xi=params.xi, signed=True)

    def reset(self) -> None:
        self.scene.reset()

    def rows(self, q) -> tuple[StepRows, float]:
        """(rows, seconds spent on distances and Jacobians)."""
        start = time.perf_counter()
        damper = self.damper.rows(q)
        seconds = time.perf_counter() - start
        result = self.damper.last_result
        p = damper.pairs
        wa, wb = body_frame_points(self.scene, q, p, result.point_a[p], result.point_b[p])
        return StepRows(p, damper.distance, damper.jacobian, wa, wb, damper.n_failed), seconds


def clipped_error(error: np.ndarray, params: ControlParams) -> np.ndarray:
    """The position error (3,) m, shortened to task_speed_limit / position_gain when longer."""
    cap = params.task_speed_limit / params.position_gain if params.position_gain > 0 else np.inf
    norm = float(np.linalg.norm(error))
    return error if norm <= cap else error * (cap / norm)


def rotation_error(R_target: np.ndarray, R: np.ndarray) -> np.ndarray:
    """(3,) world-frame rotation vector taking R to R_target (rad): the log map of R_target Rᵀ, in closed
    form (scipy's Rotation.from_matrix validated and orthogonalised its input, a third of a step's time)."""
    E = R_target @ R.T
    vee = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])  # sin θ · axis
    s = float(np.linalg.norm(vee))
    angle = float(np.arctan2(s, 0.5 * (E[0, 0] + E[1, 1] + E[2, 2] - 1.0)))
    if s < 1e-12:  # no rotation (a half turn cannot occur: the hands start at their target orientation)
        return vee
    return vee * (angle / s)


def urdf_velocity_limits(model, cap: float) -> np.ndarray:
    """(ndof,) speed limit per joint: the URDF's ``<limit velocity>`` (by joint name) where below
    ``cap``, else ``cap`` (rad/s or m/s)."""
    out = np.full(model.ndof, float(cap))
    if not model.source:
        return out
    try:
        root = ElementTree.parse(model.source).getroot()
    except (OSError, ElementTree.ParseError):
        return out
    index = {n: i for i, n in enumerate(model.joint_names)}
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        name = joint.get("name")
        if limit is None or name not in index or limit.get("velocity") is None:
            continue
        v = float(limit.get("velocity"))
        if v > 0:
            out[index[name]] = min(out[index[name]], v)
    return out


def joint_bounds(q, lower, upper, vmax, params: ControlParams, frozen: np.ndarray):
    """(lb, ub, damped) on q̇: velocity limits and the continuous joint-limit damper (module docstring);
    damped (n,) bool: a joint within joint_di of a limit. A frozen joint gets 0 both sides."""
    span = params.joint_di - params.joint_ds
    up = upper - q
    down = q - lower
    ub = vmax * np.clip((up - params.joint_ds) / span, None, 1.0)
    lb = -vmax * np.clip((down - params.joint_ds) / span, None, 1.0)
    damped = (up < params.joint_di) | (down < params.joint_di)
    lb = np.minimum(lb, ub)  # a joint pushed past both safety gaps (a tiny range): keep the box non-empty
    lb[frozen] = 0.0
    ub[frozen] = 0.0
    return lb, ub, damped


def min_jerk(tau):
    """Minimum-jerk profile s(τ) and ds/dτ for τ in [0, 1] (clipped): 10τ³ − 15τ⁴ + 6τ⁵."""
    t = np.clip(tau, 0.0, 1.0)
    return 10 * t**3 - 15 * t**4 + 6 * t**5, (30 * t**2 - 60 * t**3 + 30 * t**4) * (0.0 <= tau <= 1.0)


@dataclass
class RunLog:
    """One run of one task with one method. Arrays over the T steps (q has T + 1 rows)."""

    method: str
    task: str
    robot: str
    q: np.ndarray  # (T + 1, n) spq's q order
    qdot: np.ndarray  # (T, n)
    status: list  # (T,) QP status per step
    seconds_distance: np.ndarray  # (T,) distances and their Jacobians
    seconds_qp: np.ndarray  # (T,) task Jacobians, QP build and solve
    rows: list  # (T,) StepRows
    joint_damped: np.ndarray  # (T, n) bool
    joint_binding: np.ndarray  # (T, n) bool: q̇ at a damped joint bound
    speed_binding: np.ndarray  # (T, n) bool: q̇ at its velocity limit (joint not damped)
    task_error: np.ndarray  # (T,) m: largest hand distance to its final target
    reference_error: np.ndarray  # (T,) m: largest hand distance to its moving reference
    clipped: int = 0  # steps where q had to be clipped back into the limits (should stay 0)
    note: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def failures(self) -> int:
        return sum(s not in (STATUS_SOLVED, STATUS_FALLBACK) for s in self.status)

    @property
    def fallbacks(self) -> int:
        return sum(s == STATUS_FALLBACK for s in self.status)


def solve_qp(P, c, G, h, lb, ub, init):
    """(q̇, status) from proxqp through qpsolvers, warm-started; where proxqp finds no solution, daqp (an
    active-set method) is tried before the step counts as failed (seen: proxqp reporting no solution on a
    feasible JVRC-1 QP with duplicate damper rows at h = 0, which daqp solves). A solver exception or
    no solution from either gives (None, status)."""
    import qpsolvers

    try:
        problem = qpsolvers.Problem(P, c, G if len(h) else None, h if len(h) else None, lb=lb, ub=ub)
        result = qpsolvers.solve_problem(problem, solver=QP_SOLVER, initvals=init, eps_abs=QP_EPS_ABS,
                                         eps_rel=0.0)
        if not _found(result):
            result = qpsolvers.solve_problem(problem, solver=QP_FALLBACK)
            if _found(result):
                return result.x, STATUS_FALLBACK
    except Exception as exc:  # a solver error is a stated status, not a crash  # noqa: BLE001
        return None, f"{STATUS_FAILED}: {type(exc).__name__}"
    if not _found(result):
        return None, STATUS_FAILED
    return result.x, STATUS_SOLVED


def _found(result) -> bool:
    return bool(result.found) and result.x is not None and bool(np.isfinite(result.x).all())


class Controller:
    """The QP of the module docstring for one robot scene (the task Jacobians come from ``scene``,
    the damper rows from ``source``). frozen: (n,) bool, joints held still (q̇ = 0)."""

    def __init__(self, scene, source, params: ControlParams, frozen=None):
        self.scene, self.source, self.params = scene, source, params
        m = scene.model
        self.n = m.ndof
        self.frozen = np.zeros(self.n, bool) if frozen is None else np.asarray(frozen, bool)
        self.active = np.flatnonzero(~self.frozen)
        self.vmax = urdf_velocity_limits(m, params.velocity_limit)
        self.lower, self.upper = m.lower.copy(), m.upper.copy()

    def objective(self, q, hands, refs, ref_vels, q0, R_ref=None):
        """(P, c) of the QP at q: hands [(link, point in the link frame)], refs / ref_vels (h, 3);
        R_ref: (h, 3, 3) the hands' target orientations (their start), or None."""
        p = self.params
        P = (p.damping + p.posture_weight) * np.eye(self.n)
        c = -p.posture_weight * p.posture_gain * (q0 - q)
        points, rotations, jacobians = self.scene.frame_jacobians(q, hands)  # one kinematics pass
        jacobians[:, :, self.frozen] = 0.0
        for k, (x, J, x_ref, v_ref) in enumerate(zip(points, jacobians, refs, ref_vels)):
            v = v_ref + p.position_gain * clipped_error(x_ref - x, p)
            P += p.position_weight * J[:3].T @ J[:3]
            c -= p.position_weight * J[:3].T @ v
            if p.orientation_weight > 0 and R_ref is not None:  # back to the hand's start orientation
                w = p.orientation_gain * rotation_error(R_ref[k], rotations[k])
                P += p.orientation_weight * J[3:].T @ J[3:]
                c -= p.orientation_weight * J[3:].T @ w
        return P, c

    def solve(self, P, c, G, h, lb, ub, init) -> tuple[np.ndarray, str]:
        """(q̇ (n,), status) of the QP over the active joints only: a frozen joint's q̇ is 0, so its
        variable, its rows of P and its columns of G drop out (the same minimiser, a smaller QP for
        proxqp: JVRC-1's 17 active joints of 34). A failure gives q̇ = 0 and its status."""
        a = self.active
        x, status = solve_qp(P[np.ix_(a, a)], c[a], G[:, a], h, lb[a], ub[a], init[a])
        qdot = np.zeros(self.n)
        if x is not None:
            qdot[a] = x
        return qdot, status

    def run(self, task, steps: int) -> RunLog:
        """Run ``task`` (harness.suites.control.tasks.Task) for ``steps`` steps from rest at task.q0."""
        p = self.params
        q = np.array(task.q0, dtype=np.float64)
        q0 = q.copy()
        qdot = np.zeros(self.n)
        hands = task.hands
        start_points = task.hand_points(self.scene, q)
        links0 = self.scene.link_poses(q)
        R_ref = np.array([links0[link][:3, :3] for link, _ in hands])
        self.source.reset()
        gains: dict = {}  # pair -> its damper gain while it stays within di (xi_auto)
        log = _empty_log(self.source.name, task, steps, self.n, q)
        for k in range(steps):
            rows, t_dist = self.source.rows(q)
            t0 = time.perf_counter()
            refs, vels = task.reference(k * p.dt, start_points)
            P, c = self.objective(q, hands, refs, vels, q0, R_ref)
            lb, ub, damped = joint_bounds(q, self.lower, self.upper, self.vmax, p, self.frozen)
            h = damper_bounds(rows, qdot, gains, p)
            rows.h = h
            qdot, status = self.solve(P, c, -rows.jacobian, h, lb, ub, qdot)
            t_qp = time.perf_counter() - t0
            _record(log, k, rows, qdot, status, t_dist, t_qp, damped, lb, ub)
            q = q + p.dt * qdot
            q, log.clipped = _clip(q, self.lower, self.upper, log.clipped)
            log.q[k + 1] = q
            x_now = task.hand_points(self.scene, q)
            log.task_error[k] = np.linalg.norm(x_now - task.final_targets(start_points), axis=1).max()
            refs_next, _ = task.reference((k + 1) * p.dt, start_points)
            log.reference_error[k] = np.linalg.norm(x_now - refs_next, axis=1).max()
        return log


def damper_bounds(rows: StepRows, qdot_prev: np.ndarray, gains: dict, params: ControlParams) -> np.ndarray:
    """h (k,) of the damper rows −J q̇ ≤ h = ξ_p (d − d_s)/(d_i − d_s). With xi_auto a pair turning on
    while approaching faster than xi (d − d_s)/(d_i − d_s) keeps the gain that allows its current rate
    (ḋ from the previous command and the new row); ``gains`` carries the pairs' gains between steps and
    forgets the pairs that left."""
    p = params
    scale = (rows.distance - p.ds) / (p.di - p.ds)
    if not p.xi_auto:
        return p.xi * scale
    out = np.empty(len(rows.pairs))
    kept = {}
    for i, pair in enumerate(rows.pairs.tolist()):
        xi = gains.get(pair)
        if xi is None:
            rate = float(rows.jacobian[i] @ qdot_prev)  # ḋ if the command did not change
            xi = p.xi if scale[i] <= 0 else max(p.xi, -rate / scale[i])
        kept[pair] = xi
        out[i] = xi * scale[i]
    gains.clear()
    gains.update(kept)
    return out


def _empty_log(method, task, steps, n, q) -> RunLog:
    log = RunLog(method, task.name, task.robot, np.zeros((steps + 1, n)), np.zeros((steps, n)), [None] * steps,
                 np.zeros(steps), np.zeros(steps), [None] * steps, np.zeros((steps, n), bool),
                 np.zeros((steps, n), bool), np.zeros((steps, n), bool), np.zeros(steps), np.zeros(steps))
    log.q[0] = q
    return log


BINDING_TOL = 1e-6  # rad/s: q̇ this close to a damped joint's bound counts as held by it


def _record(log, k, rows, qdot, status, t_dist, t_qp, damped, lb, ub) -> None:
    log.rows[k] = rows
    log.qdot[k] = qdot
    log.status[k] = status
    log.seconds_distance[k] = t_dist
    log.seconds_qp[k] = t_qp
    log.joint_damped[k] = damped
    at_bound = (np.abs(qdot - ub) < BINDING_TOL) | (np.abs(qdot - lb) < BINDING_TOL)
    log.joint_binding[k] = damped & at_bound
    log.speed_binding[k] = ~damped & at_bound & (np.abs(qdot) > BINDING_TOL)


def _clip(q, lower, upper, clipped):
    """q back within the limits (the dampers should make this a no-op; counted when it is not)."""
    out = np.clip(q, lower, upper)
    return out, clipped + int(not np.array_equal(out, q))
