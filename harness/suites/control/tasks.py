"""Seeded tasks that drive a robot's bodies near each other (or near static obstacles).

A :class:`Task` moves one or two hand points (a point fixed to a link) from where they are at the start
posture q0 through waypoints, each segment on a minimum-jerk profile (zero velocity and acceleration at
every waypoint), so the reference itself is smooth and any jump in the commands comes from the geometry.

Robots (:data:`ROBOTS`), each with its active joints (the rest held still), hands and start posture:

- humanoids (JVRC-1 from the shared data, talos_reduced from example-robot-data): waist/torso and both
  arms active. Tasks alternate *cross* (both hands cross in front of the torso, to each other's side)
  and *behind* (one hand reaches behind the other arm's elbow, the other hand holds still), mirrored
  left/right.
- arms (panda and ur5_robot from example-robot-data) with two static obstacles placed relative to the
  hand's start: a shelf board ahead and below the hand, and a wall to the side. Tasks alternate *shelf*
  (reach forward under the board) and *wall* (go round the wall's end to its far side).

Every target is jittered by the task's own seed (uniform, ±JITTER_M per axis) and every segment's
duration too, so that no two tasks are alike.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from harness.suites.control.controller import min_jerk

JITTER_M = 0.04  # m: uniform jitter of every target, per axis
SEGMENT_S = (1.0, 1.4)  # s: range of each waypoint segment's duration (uniform)
HUMANOIDS = ("jvrc1", "talos_reduced")
ARMS = ("panda", "ur5_robot")


@dataclass(frozen=True)
class RobotSetup:
    """How a robot is driven: active joints (all others frozen at q0), hands (link, point in the link
    frame, m), the start posture as {joint: value} (the rest 0, clipped into the limits)."""

    name: str
    kind: str  # 'humanoid' or 'arm'
    active: tuple  # joint names, or prefixes ending in '*'
    hands: tuple  # ((link name, (x, y, z)), ...): humanoids right hand first
    posture: dict = field(default_factory=dict)


ROBOTS = {
    "jvrc1": RobotSetup(
        "jvrc1", "humanoid",
        ("WAIST_*", "R_SHOULDER_*", "R_ELBOW_*", "R_WRIST_*", "L_SHOULDER_*", "L_ELBOW_*", "L_WRIST_*"),
        (("R_WRIST_Y_S", (0.0, 0.0, -0.08)), ("L_WRIST_Y_S", (0.0, 0.0, -0.08))),
        {"R_SHOULDER_P": -0.4, "L_SHOULDER_P": -0.4, "R_SHOULDER_R": -0.25, "L_SHOULDER_R": 0.25,
         "R_ELBOW_P": -1.3, "L_ELBOW_P": -1.3}),
    "talos_reduced": RobotSetup(
        "talos_reduced", "humanoid",
        ("torso_*", "arm_right_*", "arm_left_*"),
        (("arm_right_7_link", (0.0, 0.0, -0.1)), ("arm_left_7_link", (0.0, 0.0, -0.1))),
        {"arm_right_1_joint": -0.3, "arm_left_1_joint": 0.3, "arm_right_2_joint": -0.3, "arm_left_2_joint": 0.3,
         "arm_right_4_joint": -1.4, "arm_left_4_joint": -1.4}),
    "panda": RobotSetup(
        "panda", "arm", ("panda_joint*",), (("panda_hand_tcp", (0.0, 0.0, 0.0)),),
        {"panda_joint2": -0.6, "panda_joint4": -2.2, "panda_joint6": 1.6, "panda_joint7": 0.785,
         "panda_finger_joint1": 0.02}),
    "ur5_robot": RobotSetup(
        "ur5_robot", "arm", ("shoulder_*", "elbow_*", "wrist_*"), (("tool0", (0.0, 0.0, 0.0)),),
        {"shoulder_lift_joint": -1.3, "elbow_joint": 1.7, "wrist_1_joint": -1.9, "wrist_2_joint": -1.57}),
}


def setup(robot: str) -> RobotSetup:
    if robot not in ROBOTS:
        raise ValueError(f"unknown control robot {robot!r}; choose from {sorted(ROBOTS)}")
    return ROBOTS[robot]


def _matches(name: str, patterns) -> bool:
    return any(name.startswith(p[:-1]) if p.endswith("*") else name == p for p in patterns)


def frozen_mask(model, robot_setup: RobotSetup) -> np.ndarray:
    """(ndof,) bool: the joints the controller holds still."""
    return np.array([not _matches(n, robot_setup.active) for n in model.joint_names])


def start_posture(model, robot_setup: RobotSetup) -> np.ndarray:
    """q0 (ndof,): the setup's posture, 0 elsewhere, clipped 0.05 inside the limits."""
    q = np.zeros(model.ndof)
    for name, value in robot_setup.posture.items():
        if name in model.joint_names:
            q[model.joint_names.index(name)] = value
    margin = np.minimum(0.05, 0.25 * (model.upper - model.lower))
    return np.clip(q, model.lower + margin, model.upper - margin)


def hand_links(model, robot_setup: RobotSetup):
    """[(link index, point (3,))] of the setup's hands."""
    out = []
    for name, point in robot_setup.hands:
        if name not in model.link_names:
            raise ValueError(f"{robot_setup.name}: no link {name!r}")
        out.append((model.link_names.index(name), np.asarray(point, dtype=np.float64)))
    return out


@dataclass
class Task:
    """One task: hands moved from their start through ``waypoints`` (m, h, 3) world points (m) in
    ``durations`` (m,) seconds each, on minimum-jerk segments."""

    name: str
    robot: str
    kind: str
    seed: int
    q0: np.ndarray
    hands: list
    waypoints: np.ndarray
    durations: np.ndarray
    obstacles: list = field(default_factory=list)

    @property
    def duration(self) -> float:
        return float(self.durations.sum())

    def hand_points(self, scene, q) -> np.ndarray:
        """(h, 3) world positions of the hand points at q."""
        links = scene.link_poses(q)
        return np.array([links[link][:3, :3] @ p + links[link][:3, 3] for link, p in self.hands])

    def final_targets(self, start) -> np.ndarray:
        return self.waypoints[-1]

    def reference(self, t: float, start) -> tuple[np.ndarray, np.ndarray]:
        """(positions (h, 3) m, velocities (h, 3) m/s) of the reference at time t (s)."""
        points = np.concatenate([np.asarray(start)[None], self.waypoints])
        t0 = 0.0
        for i, d in enumerate(self.durations):
            if t < t0 + d:
                s, ds = min_jerk((t - t0) / d)
                delta = points[i + 1] - points[i]
                return points[i] + s * delta, (ds / d) * delta
            t0 += d
        return points[-1].copy(), np.zeros_like(points[-1])


def _jitter(rng, shape=(3,)):
    return rng.uniform(-JITTER_M, JITTER_M, shape)


def _durations(rng, m):
    return rng.uniform(*SEGMENT_S, m)


def humanoid_task(scene, robot_setup: RobotSetup, index: int, seed: int) -> Task:
    """Task ``index``: even cross, odd behind; every other pair mirrored (left hand leads)."""
    model = scene.model
    rng = np.random.default_rng([seed, index])
    q0 = start_posture(model, robot_setup)
    hands = hand_links(model, robot_setup)
    links = scene.link_poses(q0)
    start = np.array([links[l][:3, :3] @ p + links[l][:3, 3] for l, p in hands])
    mirror = (index // 2) % 2 == 1
    lead, other = (1, 0) if mirror else (0, 1)
    forward = np.array([1.0, 0.0, 0.0])
    if index % 2 == 0:  # cross: each hand to the other's side, in front of the torso
        mid = start.mean(axis=0)
        w1 = np.array([start[i] + 0.6 * (mid - start[i]) + 0.12 * forward + _jitter(rng) for i in range(2)])
        w2 = np.array([start[1 - i] + 0.12 * forward + _jitter(rng) for i in range(2)])
        w2[other, 2] -= 0.08  # one hand passes under the other
        waypoints = np.stack([w1, w2])
        kind = "cross"
    else:  # behind: the lead hand behind the other arm's elbow, the other hand still
        elbow_link = model.parent[hands[other][0]]
        while elbow_link >= 0 and "ELBOW" not in model.link_names[elbow_link].upper() and \
                "_4_" not in model.link_names[elbow_link]:
            elbow_link = model.parent[elbow_link]
        elbow = links[elbow_link][:3, 3] if elbow_link >= 0 else start[other]
        front = start[lead] + 0.5 * (elbow - start[lead]) + 0.15 * forward
        behind = elbow - 0.1 * forward + 0.04 * np.sign(elbow[1] - start[lead][1]) * np.array([0.0, 1.0, 0.0])
        w1 = start.copy()
        w1[lead] = front + _jitter(rng)
        w2 = start.copy()
        w2[lead] = behind + _jitter(rng)
        waypoints = np.stack([w1, w2])
        kind = "behind"
    side = "left" if mirror else "right"
    return Task(f"{robot_setup.name}-{kind}-{side}-{index:02d}", robot_setup.name, kind, seed, q0, hands,
                waypoints, _durations(rng, len(waypoints)))


def arm_layout(scene, robot_setup: RobotSetup):
    """(hand start (3,), forward (3,), left (3,)) at q0: forward is the horizontal direction from the
    base to the hand."""
    model = scene.model
    q0 = start_posture(model, robot_setup)
    hands = hand_links(model, robot_setup)
    links = scene.link_poses(q0)
    link, p = hands[0]
    x0 = links[link][:3, :3] @ p + links[link][:3, 3]
    fwd = np.array([x0[0] - scene.base[0, 3], x0[1] - scene.base[1, 3], 0.0])
    fwd = fwd / np.linalg.norm(fwd) if np.linalg.norm(fwd) > 1e-6 else np.array([1.0, 0.0, 0.0])
    left = np.array([-fwd[1], fwd[0], 0.0])
    return x0, fwd, left


def arm_obstacles(scene, robot_setup: RobotSetup):
    """[(name, half extents (3,), pose 4x4)]: the shelf board ahead of and below the hand's start, and a
    wall to its left (boxes, m)."""
    x0, fwd, left = arm_layout(scene, robot_setup)
    rot = np.column_stack([fwd, left, [0.0, 0.0, 1.0]])

    def pose(centre):
        T = np.eye(4)
        T[:3, :3] = rot
        T[:3, 3] = centre
        return T

    shelf = ("shelf", np.array([0.15, 0.25, 0.01]), pose(x0 + 0.22 * fwd - 0.12 * np.array([0, 0, 1.0])))
    wall = ("wall", np.array([0.12, 0.01, 0.3]), pose(x0 + 0.02 * fwd + 0.25 * left))
    return [shelf, wall]


def arm_task(scene, robot_setup: RobotSetup, index: int, seed: int) -> Task:
    """Task ``index``: even under the shelf, odd round the wall."""
    model = scene.model
    rng = np.random.default_rng([seed, index])
    q0 = start_posture(model, robot_setup)
    hands = hand_links(model, robot_setup)
    x0, fwd, left = arm_layout(scene, robot_setup)
    up = np.array([0.0, 0.0, 1.0])
    if index % 2 == 0:  # shelf: down in front of the board, then forward under it
        w1 = x0 - 0.25 * up + 0.02 * fwd + _jitter(rng)
        w2 = x0 - 0.25 * up + 0.25 * fwd + _jitter(rng)
        kind = "shelf"
    else:  # wall: forward past the wall's end, then to its far side and back along it
        w1 = x0 + 0.3 * fwd + 0.15 * left + _jitter(rng)
        w2 = x0 + 0.05 * fwd + 0.35 * left + _jitter(rng)
        kind = "wall"
    waypoints = np.stack([w1[None], w2[None]])
    return Task(f"{robot_setup.name}-{kind}-{index:02d}", robot_setup.name, kind, seed, q0, hands, waypoints,
                _durations(rng, 2))


def make_tasks(scene, robot: str, count: int, seed: int) -> list[Task]:
    """``count`` seeded tasks for ``robot`` on its scene (ValueError for count < 1)."""
    if count < 1:
        raise ValueError(f"tasks must be >= 1; got {count}")
    s = setup(robot)
    make = humanoid_task if s.kind == "humanoid" else arm_task
    return [make(scene, s, i, seed) for i in range(count)]
