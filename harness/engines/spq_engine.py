"""spq adapter: the library under test behind the same interface as the external engines.

``query`` goes through ``spq.Pair`` (per call, warm start kept); ``query_many`` through the batched
``spq.distances`` (one compiled loop, each query cold), which is what a user calls for many poses.
With ``signed`` (the registered "spq" engine) the queries are signed: an overlap's raw_distance is
minus its penetration depth, with witness points on both surfaces; distance stays max(0, sd).
"""

from __future__ import annotations

import numpy as np

import spq
from harness.engines.base import BatchResult, Engine, EngineResult, PreparedPair


class SpqPair(PreparedPair):
    def __init__(self, a, b, tol: float, rel_tol: float, signed: bool = False):
        self._pair = spq.Pair(a, b, tol=tol, rel_tol=rel_tol, signed=signed)
        self._a, self._b, self._tol, self._rel_tol, self._signed = a, b, tol, rel_tol, signed

    def _query(self, pose_a: np.ndarray, pose_b: np.ndarray) -> EngineResult:
        r = self._pair.distance(pose_a, pose_b)
        return EngineResult(max(r.distance, 0.0), r.point_a, r.point_b, r.status, r.distance)

    def distance_loop(self, poses_a: np.ndarray, poses_b: np.ndarray) -> np.ndarray:
        query = self._pair.distance
        return np.array([query(pa, pb).distance for pa, pb in zip(poses_a, poses_b)])

    def distance_batch(self, poses_a: np.ndarray, poses_b: np.ndarray) -> np.ndarray:
        """Distances (N,) from one batched compiled call (cold starts)."""
        return spq.distances(self._a, self._b, poses_a, poses_b, tol=self._tol, rel_tol=self._rel_tol).distance

    def query_many(self, poses_a, poses_b) -> BatchResult:
        poses_a, poses_b = self._check_batches(poses_a, poses_b)
        r = spq.distances(self._a, self._b, poses_a, poses_b, tol=self._tol, rel_tol=self._rel_tol,
                          signed=self._signed)
        self.last_bounds = (r.lower_bound, r.upper_bound)  # spq's certificate, for the depth scores
        return BatchResult(np.maximum(r.distance, 0.0), r.point_a, r.point_b, r.status.astype("<U11"),
                           r.distance.copy())


class SpqEngine(Engine):
    """spq's GJK at absolute tolerance ``tol`` (m) and relative tolerance ``rel_tol``; ``signed``:
    overlaps get their penetration depth (EPA)."""

    def __init__(self, tol: float = spq.DEFAULT_TOL_ABS, rel_tol: float = spq.DEFAULT_TOL_REL, name: str = "spq",
                 signed: bool = False):
        self.name = name
        self.tolerance = float(tol)
        self.rel_tol = float(rel_tol)
        self.signed = self.gives_depth = bool(signed)

    def prepare(self, a, b) -> SpqPair:
        return SpqPair(a, b, self.tolerance, self.rel_tol, self.signed)

    def warm_up(self) -> None:
        """One per-call and one batched query, unsigned and signed, between two boxes 1 m apart: numba
        compiles spq's kernels (or loads them from its cache) here, minutes on a cold cache, rather than
        in the first query an isolated child is timed on (the kernels take shapes as arrays, so two
        boxes serve every shape)."""
        box = spq.Box(0.1, 0.1, 0.1)
        pa, pb = np.eye(4), np.eye(4)
        pb[0, 3] = 1.0
        for signed in (False, True):
            spq.Pair(box, box, tol=self.tolerance, rel_tol=self.rel_tol, signed=signed).distance(pa, pb)
            spq.distances(box, box, pa[None], pb[None], tol=self.tolerance, rel_tol=self.rel_tol, signed=signed)

    def version(self) -> str:
        import numba

        return f"spq {spq.__version__} (numba {numba.__version__})"
