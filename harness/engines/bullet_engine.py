"""pybullet adapter: ``getClosestPoints`` between two static convex-hull bodies.

Each engine owns one DIRECT physics client; each prepared pair owns two bodies in it (mass 0, one
``GEOM_MESH`` convex hull each). Bullet inflates every convex shape by a collision margin (1 mm by
default for these hulls), so distances come out short by the sum of both margins. The margin is a
per-body dynamics property: ``changeDynamics(body, -1, collisionMargin=m)`` sets it (and
``getDynamicsInfo(body, -1)[11]`` reads it back); ``createCollisionShape`` has no margin argument.
"bullet" sets it to 0, "bullet-margin" keeps the default so its bias shows.

Bullet exposes no tolerance. Witness points (positionOnA/B) and contactDistance (negative when
penetrating) come back in the world frame. Quaternions are x, y, z, w.
"""

from __future__ import annotations

import math
from importlib import metadata

import numpy as np
import pybullet as p
from scipy.spatial.transform import Rotation

from harness.engines.base import (
    BatchResult,
    Engine,
    EngineResult,
    PreparedPair,
    failed_result,
    mesh_arrays,
    result_from_raw,
)

DEFAULT_MAX_DISTANCE = 1e3  # m: getClosestPoints reports nothing farther apart than this
_DYNAMICS_MARGIN = 11  # index of the collision margin in getDynamicsInfo's tuple
_BODY_A, _POSITION_ON_A, _POSITION_ON_B, _CONTACT_DISTANCE = 1, 5, 6, 8  # fields of a contact point


def quat_xyzw(rotation: np.ndarray) -> list[float]:
    """Unit quaternion (x, y, z, w) of a 3x3 rotation matrix, in plain Python floats.

    Same rotation as ``scipy.spatial.transform.Rotation.from_matrix(R).as_quat()`` (up to sign),
    without scipy's per-call overhead (tens of microseconds, more than the pybullet query itself).
    Shepperd's method: divide by the largest of 4w^2, 4x^2, 4y^2, 4z^2 for accuracy.
    """
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rotation.tolist()
    trace = r00 + r11 + r22
    if trace > 0.0:
        s = 2.0 * math.sqrt(1.0 + trace)  # 4w
        x, y, z, w = (r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s, 0.25 * s
    elif r00 >= r11 and r00 >= r22:
        s = 2.0 * math.sqrt(max(1.0 + r00 - r11 - r22, 0.0))  # 4x
        x, y, z, w = 0.25 * s, (r01 + r10) / s, (r02 + r20) / s, (r21 - r12) / s
    elif r11 >= r22:
        s = 2.0 * math.sqrt(max(1.0 + r11 - r00 - r22, 0.0))  # 4y
        x, y, z, w = (r01 + r10) / s, 0.25 * s, (r12 + r21) / s, (r02 - r20) / s
    else:
        s = 2.0 * math.sqrt(max(1.0 + r22 - r00 - r11, 0.0))  # 4z
        x, y, z, w = (r02 + r20) / s, (r12 + r21) / s, 0.25 * s, (r10 - r01) / s
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    return [x / norm, y / norm, z / norm, w / norm]


class BulletPair(PreparedPair):
    """Two bodies in the engine's client; each query moves them and asks for the closest points."""

    def __init__(self, engine: "BulletEngine", bodies: tuple[int, int], shapes: tuple[int, int]):
        self._engine = engine  # keeps the client connected while the pair lives
        self._client = engine.client_id
        self._body_a, self._body_b = bodies
        self._shapes = shapes
        self._max_distance = engine.max_distance
        self.margins = tuple(
            p.getDynamicsInfo(body, -1, physicsClientId=self._client)[_DYNAMICS_MARGIN] for body in bodies
        )  # m, as Bullet reports them

    def _query(self, pose_a: np.ndarray, pose_b: np.ndarray) -> EngineResult:
        return self._query_placed(
            pose_a[:3, 3].tolist(), quat_xyzw(pose_a[:3, :3]), pose_b[:3, 3].tolist(), quat_xyzw(pose_b[:3, :3])
        )

    def _query_placed(self, position_a, quat_a, position_b, quat_b) -> EngineResult:
        if self._shapes is None:  # pybullet may hand the removed bodies' ids to new bodies
            raise RuntimeError("this pair is closed")
        client, body_a = self._client, self._body_a
        p.resetBasePositionAndOrientation(body_a, position_a, quat_a, physicsClientId=client)
        p.resetBasePositionAndOrientation(self._body_b, position_b, quat_b, physicsClientId=client)
        contacts = p.getClosestPoints(body_a, self._body_b, self._max_distance, physicsClientId=client)
        if not contacts:
            return failed_result(f"getClosestPoints found no point within {self._max_distance} m")
        best = min(contacts, key=lambda c: c[_CONTACT_DISTANCE])
        if best[_BODY_A] == body_a:
            return result_from_raw(best[_CONTACT_DISTANCE], best[_POSITION_ON_A], best[_POSITION_ON_B])
        return result_from_raw(best[_CONTACT_DISTANCE], best[_POSITION_ON_B], best[_POSITION_ON_A])

    def distance_loop(self, poses_a: np.ndarray, poses_b: np.ndarray) -> np.ndarray:
        """pybullet's leanest loop: positions and quaternions as lists (in the timed call), the client
        passed positionally to resetBasePositionAndOrientation (its fourth parameter; getClosestPoints's
        fourth is a link index), the functions bound once. As before stop 66 (keyword client, the module's
        attributes per query) it took 15.1-16.3 us a query against 14.4-14.8 (1.04x-1.10x in three same-process
        runs, kuka_link_4, 5,000 poses, same distances): getClosestPoints itself takes most of it."""
        quats_a = Rotation.from_matrix(poses_a[:, :3, :3]).as_quat().tolist()
        quats_b = Rotation.from_matrix(poses_b[:, :3, :3]).as_quat().tolist()
        client, body_a, body_b, reach = self._client, self._body_a, self._body_b, self._max_distance
        reset, closest = p.resetBasePositionAndOrientation, p.getClosestPoints
        out = []
        append = out.append
        for ta, qa, tb, qb in zip(poses_a[:, :3, 3].tolist(), quats_a, poses_b[:, :3, 3].tolist(), quats_b):
            reset(body_a, ta, qa, client)
            reset(body_b, tb, qb, client)
            contacts = closest(body_a, body_b, reach, physicsClientId=client)
            append(min([c[_CONTACT_DISTANCE] for c in contacts]) if contacts else np.nan)
        return np.array(out, dtype=float)

    def query_checked(self, poses_a, poses_b) -> BatchResult:
        """As :meth:`PreparedPair.query_checked`, converting all rotations to quaternions in one scipy call."""
        if len(poses_a) == 0:
            return BatchResult.empty(0)
        quats_a = Rotation.from_matrix(poses_a[:, :3, :3]).as_quat().tolist()
        quats_b = Rotation.from_matrix(poses_b[:, :3, :3]).as_quat().tolist()
        positions_a = poses_a[:, :3, 3].tolist()
        positions_b = poses_b[:, :3, 3].tolist()
        results = []
        for placement in zip(positions_a, quats_a, positions_b, quats_b):
            try:
                results.append(self._query_placed(*placement))
            except Exception as exc:  # same contract as query(): report, do not raise
                results.append(failed_result(f"{type(exc).__name__}: {exc}"))
        return BatchResult.from_results(results)

    def close(self) -> None:
        """Remove both bodies from the engine's world; later queries report "failed".

        The collision shapes stay until the engine closes: pybullet refuses to remove a shape a
        (removed) body used, and prints a warning when asked to.
        """
        if self._shapes is not None and self._engine.connected:
            for body in (self._body_a, self._body_b):
                p.removeBody(body, physicsClientId=self._client)
        self._shapes = None


class BulletEngine(Engine):
    """pybullet in DIRECT mode.

    margin : float or None
        Collision margin (m) set on every body; None keeps pybullet's default (1 mm for these hulls).
    max_distance : float
        getClosestPoints threshold (m); it must exceed every distance queried, or the query fails.
    """

    tolerance = None

    def __init__(self, margin: float | None = 0.0, max_distance: float = DEFAULT_MAX_DISTANCE, name: str | None = None):
        if margin is not None and not (0.0 <= float(margin) < float("inf")):
            raise ValueError(f"margin must be None or a finite value >= 0 (m); got {margin}")
        if not (0.0 < float(max_distance) < float("inf")):
            raise ValueError(f"max_distance must be finite and > 0 (m); got {max_distance}")
        self.margin = None if margin is None else float(margin)
        self.max_distance = float(max_distance)
        if name is None:
            name = "bullet-margin" if margin is None else ("bullet" if margin == 0.0 else f"bullet-margin-{margin:g}")
        self.name = name
        self.client_id = p.connect(p.DIRECT)
        if self.client_id < 0:
            raise RuntimeError("pybullet could not open a DIRECT physics client")

    @property
    def connected(self) -> bool:
        client = getattr(self, "client_id", -1)
        return client >= 0 and bool(p.getConnectionInfo(physicsClientId=client)["isConnected"])

    def _add_body(self, shape) -> tuple[int, int]:
        vertices, _ = mesh_arrays(shape)  # Bullet builds its own hull from the points
        cid = self.client_id
        shape_id = p.createCollisionShape(p.GEOM_MESH, vertices=vertices.tolist(), physicsClientId=cid)
        if shape_id < 0:
            raise RuntimeError(f"pybullet could not create a convex hull from {len(vertices)} vertices")
        body = p.createMultiBody(baseMass=0, baseCollisionShapeIndex=shape_id, physicsClientId=cid)
        if body < 0:
            raise RuntimeError("pybullet could not create a body")
        if self.margin is not None:
            p.changeDynamics(body, -1, collisionMargin=self.margin, physicsClientId=cid)
        return body, shape_id

    def prepare(self, a, b) -> BulletPair:
        if not self.connected:
            raise RuntimeError(f"engine {self.name!r} is closed")
        body_a, shape_a = self._add_body(a)
        body_b, shape_b = self._add_body(b)
        return BulletPair(self, (body_a, body_b), (shape_a, shape_b))

    def version(self) -> str:
        return f"pybullet {metadata.version('pybullet')} (API {p.getAPIVersion()})"

    def close(self) -> None:
        if self.connected:
            p.disconnect(physicsClientId=self.client_id)
        self.client_id = -1

    def __del__(self):
        try:
            self.close()
        except Exception:  # interpreter shutdown: pybullet may already be gone
            pass
