"""The control benchmark's robot scenes: one robot read once, then one scene per bounding-volume policy
sharing its bodies (hulls, STP-BVs, fits) and its pruned pair set, plus the robot's static obstacles.

Pairs: the SRDF-pruned set (``Scene.from_model(..., srdf=...)``: JVRC-1's sampled SRDF in datasets/srdf/,
example-robot-data's shipped ones) less its 'Never' entries (:data:`CONTROL_SRDF_REASONS`), else adjacent
links skipped; every method and peer uses the same pairs,
those of :func:`robot_scene`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

SPQ_POLICIES = ("pch", "stp", "cse", "auto")
# SRDF reasons a controller honours: MoveIt's 'Never' means never in collision over the setup assistant's
# random configurations, not along a controller's motion (JVRC-1: 93 of its 218 are arm-arm pairs such as
# L_ELBOW_P_S - R_WRIST_Y_S, which the crossing tasks bring together), so those pairs keep their rows.
CONTROL_SRDF_REASONS = ("Adjacent", "Default", "Always", "User", "")


@dataclass
class RobotScenes:
    """A robot's scenes: ``base`` (pch, obstacles included), ``by_policy`` {policy: Scene}, the URDF
    path (for the peers), how the pairs were pruned, and the obstacles [(name, half extents, pose)]."""

    robot: str
    urdf: str
    base: object
    by_policy: dict
    pairs_note: str
    obstacles: list


def _srdf_path(robot: str):
    """The robot's SRDF: generated here (datasets/srdf/, JVRC-1) or shipped with example-robot-data; or None."""
    from datasets.srdf import generated_srdf

    path = generated_srdf(robot)
    if path is not None:
        return path
    from datasets.example_robots import robot_names, robot_srdf

    return robot_srdf(robot) if robot in robot_names() else None


def _read(robot: str, srdf):
    """(model, urdf path, mesh folder options) of robot."""
    if robot == "jvrc1":
        from datasets.robots import robot_files
        from spq.io.urdf import read_urdf

        files = robot_files(robot)
        return read_urdf(files.urdf), files.urdf, {"convex_dir": files.convex_dir, "mesh_root": files.mesh_root,
                                                     "urdf_dir": files.urdf.parent}
    from datasets.example_robots import load_model, robot_urdf

    urdf = robot_urdf(robot)
    return load_model(robot), urdf, {"urdf_dir": urdf.parent, "primitives": "exact"}


def _from_model(model, policy, srdf, options, obstacles=()):
    from spq.scene import Scene

    if srdf is not None:
        return (Scene.from_model(model, policy=policy, srdf=srdf, srdf_reasons=CONTROL_SRDF_REASONS,
                                 obstacles=obstacles, **options),
                f"SRDF {Path(srdf).name} (its 'Never' pairs kept)")
    return Scene.from_model(model, policy=policy, obstacles=obstacles, **options), "adjacent links skipped"


def obstacle_objects(specs):
    """spq Obstacles from [(name, half extents, pose)]."""
    from spq.scene import Obstacle
    from spq.shapes.primitives import Box

    return [Obstacle(name, Box(*half), pose) for name, half, pose in specs]


def with_policy(base, policy: str):
    """``base`` under scene policy ``policy``: its bodies (volumes shared), pairs and obstacles."""
    return base.with_policy(policy)


def moving_joints(model, link: int, frozen: np.ndarray) -> frozenset:
    """The active joints (q indices) between ``link`` and the root: what moves the link (WORLD: none)."""
    out = set()
    while link >= 0:
        j = model.q_index[link]
        if j >= 0 and not frozen[j]:
            out.add(int(j))
        link = model.parent[link]
    return frozenset(out)


def rigid_pairs(scene, frozen: np.ndarray) -> list[tuple[str, str]]:
    """Pairs of the scene whose two bodies the active joints move together (or not at all): their
    distance cannot change, so no controller can act on them (a pair of the frozen legs, two gripper
    fingers, the base and an obstacle). They are left out for every method."""
    moving = [moving_joints(scene.model, b.link, frozen) for b in scene.bodies]
    return [(scene.bodies[a].name, scene.bodies[b].name) for a, b in np.asarray(scene.pairs).tolist()
            if moving[a] == moving[b]]


STATIC_SAMPLES = 64  # random configurations of the active joints on which a pair's distance is sampled
STATIC_RANGE_M = 0.002  # m: a pair whose distance varies less than this over them is static


def static_pairs(scene, q0, frozen: np.ndarray, seed: int = 0) -> list[tuple[str, str]]:
    """Pairs whose distance hardly depends on the active joints (it varies by under STATIC_RANGE_M over
    STATIC_SAMPLES configurations drawn within the limits of the active joints, the others at q0): a
    tiny frame box on a wrist's axis, say. A damper row on such a pair has no authority: below d_s it
    makes the QP infeasible at every step. They are left out for every method, as MoveIt's setup
    assistant leaves out pairs 'always' or 'never' in collision."""
    from spq.kernels.gjk import OUT_DISTANCE

    rng = np.random.default_rng(seed)
    m = scene.model
    qs = np.tile(np.asarray(q0, float), (STATIC_SAMPLES, 1))
    active = np.flatnonzero(~frozen)
    qs[:, active] = rng.uniform(m.lower[active], m.upper[active], (STATIC_SAMPLES, len(active)))
    d = scene.distances_many(qs, signed=True)[:, :, OUT_DISTANCE]
    spread = np.nanmax(d, axis=0) - np.nanmin(d, axis=0)
    return [scene.pair_names[p] for p in np.flatnonzero(spread < STATIC_RANGE_M)]


START_DS_M = 0.01  # m: the damper's d_s; a pair closer at the start posture (under any volume) is left out


def start_pairs(scene, q0, policies) -> list[tuple[str, str]]:
    """Pairs closer than START_DS_M at the start posture q0 under any of the policies' volumes (MoveIt's
    setup assistant's 'default' rule: pairs in contact at the default posture are disabled): a
    controller started there would begin inside the damper's safety distance."""
    out = set()
    for policy in dict.fromkeys(["pch", *policies]):
        sc = scene if policy == "pch" else scene.with_policy(policy)
        r = sc.distances(q0, coherent=False, signed=True)
        out |= {sc.pair_names[p] for p in np.flatnonzero(r.distance < START_DS_M)}
    return sorted(out)


def robot_scenes(robot: str, policies=SPQ_POLICIES) -> RobotScenes:
    """Read ``robot``, place its obstacles (arms), build one scene per policy; the pairs: the SRDF's (or
    adjacent links skipped) less the rigid pairs (:func:`rigid_pairs`) under the robot's frozen joints."""
    from harness.suites.control.tasks import arm_obstacles, frozen_mask, setup

    s = setup(robot)
    srdf = _srdf_path(robot)
    model, urdf, options = _read(robot, srdf)
    options["hull_cache"] = {}
    scene, note = _from_model(model, "pch", srdf, options)
    obstacles = arm_obstacles(scene, s) if s.kind == "arm" else []
    frozen = frozen_mask(model, s)
    with_obstacles, _ = _from_model(model, "pch", srdf, options, obstacle_objects(obstacles))
    from harness.suites.control.tasks import start_posture

    q0 = start_posture(model, s)
    rigid = rigid_pairs(with_obstacles, frozen)
    static = [p for p in static_pairs(with_obstacles, q0, frozen) if p not in set(rigid)]
    start = [p for p in start_pairs(with_obstacles, q0, policies) if p not in set(rigid) | set(static)]
    scene, _ = _from_model(model, "pch", srdf, {**options, "skip": rigid + static + start}, obstacle_objects(obstacles))
    note += (f"; {len(rigid)} rigid pairs left out (no active joint between the bodies), {len(static)} static "
             f"(distance within {STATIC_RANGE_M * 1e3:g} mm over {STATIC_SAMPLES} random configurations), "
             f"{len(start)} within d_s = {START_DS_M:g} m at the start posture under some volume")
    by_policy = {p: (scene if p == "pch" else with_policy(scene, p)) for p in policies}
    return RobotScenes(robot, str(urdf), scene, by_policy, note, obstacles)


def check_start(scene, q0, ds: float) -> float:
    """Smallest signed distance (m) at q0 over the scene's pairs."""
    r = scene.distances(q0, coherent=False, signed=True)
    return float(np.nanmin(r.distance))
