"""The common face of every distance engine the harness measures.

An :class:`Engine` turns two convex polyhedra into a :class:`PreparedPair` once (building the
engine's own geometry objects), and the pair then answers distance queries at any pair of poses.
Poses are 4x4 homogeneous rigid transforms (rotation block + translation, metres) from each body's
local frame to the world frame. Every result is reported in the world frame.

A query never raises because of the engine: whatever the engine throws (or a non-finite distance it
returns) comes back as status ``"failed"`` with NaN distance and points, so that one bad query cannot
end a benchmark run. Malformed input from the caller (a pose that is not 4x4) still raises ValueError.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

STATUSES = ("separated", "touching", "overlapping", "failed")
TOUCHING_TOL = 1e-9  # m: a non-negative distance up to this is reported as touching
_STATUS_DTYPE = "<U11"  # fits the longest status, "overlapping"
_NAN_POINT = (np.nan, np.nan, np.nan)


@dataclass
class EngineResult:
    """One distance query as an engine answered it.

    distance : float
        Metres, >= 0: the engine's distance, with a negative (penetration) value mapped to 0.
        NaN when the query failed.
    point_a, point_b : (3,) float64
        Witness points in the world frame, on body A and on body B (NaN when failed).
    status : str
        One of :data:`STATUSES`.
    raw_distance : float
        What the engine returned before mapping (negative = penetration depth, if it gives one).
    message : str
        Why the query failed; empty otherwise.
    """

    distance: float
    point_a: np.ndarray
    point_b: np.ndarray
    status: str
    raw_distance: float
    message: str = ""


@dataclass
class BatchResult:
    """N queries: ``distance`` (N,), ``point_a`` (N, 3), ``point_b`` (N, 3), ``status`` (N,) str,
    ``raw_distance`` (N,); the same meaning per row as :class:`EngineResult`."""

    distance: np.ndarray
    point_a: np.ndarray
    point_b: np.ndarray
    status: np.ndarray
    raw_distance: np.ndarray

    def __len__(self) -> int:
        return len(self.distance)

    @classmethod
    def empty(cls, n: int) -> "BatchResult":
        """A batch of ``n`` rows, all NaN / "failed"."""
        return cls(
            distance=np.full(n, np.nan),
            point_a=np.full((n, 3), np.nan),
            point_b=np.full((n, 3), np.nan),
            status=np.full(n, "failed", dtype=_STATUS_DTYPE),
            raw_distance=np.full(n, np.nan),
        )

    @classmethod
    def from_results(cls, results: list[EngineResult]) -> "BatchResult":
        """Stack single results into a batch (cheaper than filling arrays row by row)."""
        if not results:
            return cls.empty(0)
        return cls(
            distance=np.array([r.distance for r in results], dtype=np.float64),
            point_a=np.array([r.point_a for r in results], dtype=np.float64),
            point_b=np.array([r.point_b for r in results], dtype=np.float64),
            status=np.array([r.status for r in results], dtype=_STATUS_DTYPE),
            raw_distance=np.array([r.raw_distance for r in results], dtype=np.float64),
        )


def status_of(raw_distance: float, colliding: bool = False) -> str:
    """Status from an engine's raw signed distance (m) and, if it reports one, its collision flag."""
    if not math.isfinite(raw_distance):
        return "failed"
    if colliding or raw_distance < 0.0:
        return "overlapping"
    if raw_distance <= TOUCHING_TOL:
        return "touching"
    return "separated"


def failed_result(message: str, raw_distance: float = np.nan) -> EngineResult:
    """The result of a query that did not produce a usable answer."""
    return EngineResult(np.nan, np.array(_NAN_POINT), np.array(_NAN_POINT), "failed", raw_distance, message)


def result_from_raw(raw_distance, point_a, point_b, colliding: bool = False) -> EngineResult:
    """Build a result from what an engine returned: raw signed distance (m) and world witness points.

    The points are taken without a copy when they already are float64 arrays, so an adapter must pass
    arrays the engine will not overwrite later (all three engines return fresh ones per call).
    """
    raw = float(raw_distance)
    status = status_of(raw, colliding)
    if status == "failed":
        return failed_result(f"engine returned a non-finite distance ({raw})", raw)
    pa = np.asarray(point_a, dtype=np.float64)
    pb = np.asarray(point_b, dtype=np.float64)
    if pa.shape != (3,) or pb.shape != (3,):
        return failed_result(f"engine returned witness points of shape {pa.shape} and {pb.shape}", raw)
    return EngineResult(0.0 if status == "overlapping" else raw, pa, pb, status, raw)


def check_pose(pose, name: str) -> np.ndarray:
    """``pose`` as a float64 array, after checking it is 4x4 (cheap: run once per query).

    Rigidity is not checked here, to keep per-query overhead low; :meth:`PreparedPair.query_many`
    checks whole batches with :func:`spq.validation.as_poses`.
    """
    arr = np.asarray(pose, dtype=np.float64)
    if arr.shape != (4, 4):
        raise ValueError(f"{name} must be a 4x4 homogeneous matrix; got shape {arr.shape}")
    return arr


def check_pose_batch(poses, name: str) -> np.ndarray:
    """``poses`` as a validated (N, 4, 4) float64 array of rigid transforms (raises ValueError)."""
    from spq.validation import as_poses

    arr = np.asarray(poses, dtype=np.float64)
    if arr.ndim != 3:
        raise ValueError(f"{name} must be an N x 4 x 4 batch; got shape {arr.shape}")
    if len(arr) == 0:
        return arr.reshape(0, 4, 4)
    return as_poses(arr, name)


@dataclass(frozen=True)
class Mesh:
    """A polyhedron as the native engines read it (see :func:`mesh_arrays`): what crosses the pipe
    to an engine's child process, which then need not import spq to unpickle the shape."""

    vertices: np.ndarray
    faces: np.ndarray


def as_mesh(shape):
    """``shape``'s arrays (:func:`mesh_arrays`) as a :class:`Mesh`, or ``shape`` itself if the
    engines cannot take it (the engine given it then raises its own error, in its own words)."""
    try:
        return Mesh(*mesh_arrays(shape))
    except (TypeError, ValueError):
        return shape


def mesh_arrays(shape) -> tuple[np.ndarray, np.ndarray]:
    """Vertices ((n, 3) float64, local frame, m) and triangles ((m, 3) int64) of a polyhedron.

    Accepts any object with ``vertices`` and ``faces`` arrays (a :class:`spq.shapes.Polyhedron`);
    raises TypeError for shapes the external engines cannot take (STP-BV, superellipsoid, ...).
    """
    vertices = getattr(shape, "vertices", None)
    faces = getattr(shape, "faces", None)
    if vertices is None or faces is None:
        raise TypeError(
            f"external engines take convex polyhedra (with .vertices and .faces); got {type(shape).__name__}"
        )
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 4:
        raise ValueError(f"polyhedron vertices must have shape (n >= 4, 3); got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) < 4:
        raise ValueError(f"polyhedron faces must be (m >= 4, 3) triangles; got {f.shape}")
    if f.min() < 0 or f.max() >= len(v):
        raise ValueError(f"polyhedron faces index vertices outside 0..{len(v) - 1}")
    return v, f


def split_frames(poses_a: np.ndarray, poses_b: np.ndarray) -> tuple[np.ndarray, ...]:
    """Rotations ((N, 3, 3)) and translations ((N, 3)) of two (N, 4, 4) pose batches, each a contiguous
    array: (rotations_a, translations_a, rotations_b, translations_b). The leanest per-query loops of
    engines that take a rotation and a translation (coal, python-fcl) iterate over these, made in the
    timed call."""
    return (np.ascontiguousarray(poses_a[:, :3, :3]), np.ascontiguousarray(poses_a[:, :3, 3]),
            np.ascontiguousarray(poses_b[:, :3, :3]), np.ascontiguousarray(poses_b[:, :3, 3]))


class PreparedPair(ABC):
    """Two bodies loaded into an engine, ready to be queried at any poses."""

    def query(self, pose_a, pose_b) -> EngineResult:
        """Distance between body A at ``pose_a`` and body B at ``pose_b`` (4x4 world poses)."""
        pose_a = check_pose(pose_a, "pose_a")
        pose_b = check_pose(pose_b, "pose_b")
        try:
            return self._query(pose_a, pose_b)
        except Exception as exc:  # an engine error must never end a run: report it per query
            return failed_result(f"{type(exc).__name__}: {exc}")

    @abstractmethod
    def _query(self, pose_a: np.ndarray, pose_b: np.ndarray) -> EngineResult:
        """Engine-specific query on checked 4x4 float64 poses; may raise (caught by :meth:`query`)."""

    def query_many(self, poses_a, poses_b) -> BatchResult:
        """One query per row of ``poses_a`` and ``poses_b`` (each N x 4 x 4, validated as rigid
        transforms); loops over the rows in Python, with :meth:`query`'s contract per row."""
        poses_a, poses_b = self._check_batches(poses_a, poses_b)
        return self.query_checked(poses_a, poses_b)

    def query_checked(self, poses_a: np.ndarray, poses_b: np.ndarray) -> BatchResult:
        """:meth:`query_many` on batches checked already (float64 N x 4 x 4 rigid transforms of
        equal length), as by the process that sent them to an engine's child."""
        query = self._query  # skip query()'s per-pose check
        results = []
        for pose_a, pose_b in zip(poses_a, poses_b):
            try:
                results.append(query(pose_a, pose_b))
            except Exception as exc:  # as in query(): report, do not raise
                results.append(failed_result(f"{type(exc).__name__}: {exc}"))
        return BatchResult.from_results(results)

    def distance_loop(self, poses_a: np.ndarray, poses_b: np.ndarray) -> np.ndarray:
        """Distances (N,) from the leanest per-query Python loop a user of this engine would write.

        For throughput measurement: no result objects, no per-query checks. ``poses_a``/``poses_b``
        are validated (N, 4, 4) float64 arrays. Engines override this with their raw calls.
        """
        query = self._query
        return np.array([query(pa, pb).distance for pa, pb in zip(poses_a, poses_b)])

    @staticmethod
    def _check_batches(poses_a, poses_b) -> tuple[np.ndarray, np.ndarray]:
        poses_a = check_pose_batch(poses_a, "poses_a")
        poses_b = check_pose_batch(poses_b, "poses_b")
        if len(poses_a) != len(poses_b):
            raise ValueError(f"poses_a and poses_b must have the same length; got {len(poses_a)} and {len(poses_b)}")
        return poses_a, poses_b

    def close(self) -> None:
        """Release what the pair holds inside the engine (no-op unless the engine keeps a world)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class Engine(ABC):
    """An external distance engine. ``name`` identifies it in reports; ``tolerance`` is the
    convergence tolerance it runs at (None if the engine does not expose one). ``gives_depth``: an
    overlap's raw_distance is minus the penetration depth (the length of the shortest translation
    that separates the bodies); where it is False the depth scores list the engine as giving none."""

    name: str
    tolerance: float | None = None
    gives_depth: bool = True

    @abstractmethod
    def prepare(self, a, b) -> PreparedPair:
        """Load polyhedra ``a`` and ``b`` (local frames, m) into the engine."""

    @abstractmethod
    def version(self) -> str:
        """Package name(s) and version(s), for reports."""

    def warm_up(self) -> None:
        """Compile or load whatever the first query would (a JIT's code); an isolated child runs it
        before its time limits apply. Nothing by default."""

    def close(self) -> None:
        """Release engine-wide resources (a physics client, ...)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, tolerance={self.tolerance!r})"
