"""Engine plugins for the tests of ``spq check``: an example adapter and planted bugs.

Each is a class taking no arguments, as ``spq check --engine package.module:Class`` and the entry-point
group "spq.engines" expect. The mutants wrap spq's signed engine and break one thing each.
"""

from __future__ import annotations

import numpy as np

from harness.engines.base import (
    BatchResult,
    Engine,
    EngineResult,
    PreparedPair,
    result_from_raw,
)
from harness.engines.spq_engine import SpqEngine, SpqPair


class ExamplePair(PreparedPair):
    """The example plugin's pair: one spq.Pair call per query, turned into the protocol's result
    (world-frame witness points, metres, the status from the raw signed distance)."""

    def __init__(self, a, b):
        import spq

        self._pair = spq.Pair(a, b, signed=True)

    def _query(self, pose_a, pose_b) -> EngineResult:
        r = self._pair.distance(pose_a, pose_b)
        return result_from_raw(r.distance, r.point_a, r.point_b, colliding=r.distance < 0)


class ExampleEngine(Engine):
    """A minimal third-party adapter, as a user would write one for the engine under test."""

    name = "example"
    tolerance = 1e-10
    gives_depth = True

    def prepare(self, a, b) -> PreparedPair:
        return ExamplePair(a, b)

    def version(self) -> str:
        return "example 1.0 (tests/check_plugins.py)"


class _MutantPair(SpqPair):
    def mutate(self, r: BatchResult) -> BatchResult:
        return r

    def mutate_bounds(self, lower, upper):
        """The certified bounds the mutant reports beside its answers (spq's own by default)."""
        return lower, upper

    def query_many(self, poses_a, poses_b) -> BatchResult:
        r = self.mutate(super().query_many(poses_a, poses_b))
        self.last_bounds = self.mutate_bounds(*self.last_bounds)
        return r

    def _query(self, pose_a, pose_b) -> EngineResult:
        one = self.mutate(BatchResult(*(np.array([x]) for x in _fields(super()._query(pose_a, pose_b)))))
        return EngineResult(float(one.distance[0]), one.point_a[0], one.point_b[0], str(one.status[0]),
                            float(one.raw_distance[0]))


def _fields(r: EngineResult):
    return r.distance, r.point_a, r.point_b, r.status, r.raw_distance


class _Mutant(SpqEngine):
    pair_class = _MutantPair

    def __init__(self):
        super().__init__(signed=True)

    def prepare(self, a, b):
        return self.pair_class(a, b, self.tolerance, self.rel_tol, self.signed)


class _OffPair(_MutantPair):
    def mutate(self, r):
        r.distance = np.where(r.distance > 0, r.distance + 1e-6, r.distance)
        r.raw_distance = r.raw_distance + 1e-6
        return r

    def mutate_bounds(self, lower, upper):
        return lower + 1e-6, upper + 1e-6


class OffByMicron(_Mutant):
    """Every distance (and signed distance) 1e-6 m too large."""
    pair_class = _OffPair


class _MissPair(_MutantPair):
    def mutate(self, r):
        over = r.status == "overlapping"
        r.status = np.where(over, "separated", r.status)
        r.distance = np.where(over, 1e-3, r.distance)
        r.raw_distance = np.where(over, 1e-3, r.raw_distance)
        return r


class MissesOverlaps(_Mutant):
    """Reports every overlap as separated by 1 mm."""
    pair_class = _MissPair


class _SlowPair(SpqPair):
    def distance_loop(self, poses_a, poses_b):
        for _ in range(2):
            super().distance_loop(poses_a, poses_b)
        return super().distance_loop(poses_a, poses_b)


class ThreeTimesSlower(_Mutant):
    """Right answers, but its per-call loop does the work three times."""
    pair_class = _SlowPair


class _AbortPair(SpqPair):
    def _query(self, pose_a, pose_b):
        r = super()._query(pose_a, pose_b)
        if r.status == "overlapping":
            import os

            os.abort()  # as a native engine's uncaught C++ exception does
        return r

    def query_many(self, poses_a, poses_b):
        return PreparedPair.query_many(self, poses_a, poses_b)


class AbortsOnOverlap(_Mutant):
    """Ends its process on every overlapping pose (a stand-in for python-fcl's rare C++ aborts)."""
    pair_class = _AbortPair


class _HangPair(SpqPair):
    def _query(self, pose_a, pose_b):
        r = super()._query(pose_a, pose_b)
        if r.status == "overlapping":
            import time

            time.sleep(3600)  # as python-fcl looping on one pose
        return r

    def query_many(self, poses_a, poses_b):
        return PreparedPair.query_many(self, poses_a, poses_b)


class HangsOnOverlap(_Mutant):
    """Never answers on an overlapping pose (a stand-in for python-fcl's rare endless loops)."""
    pair_class = _HangPair


class _FirstQuerySlow:
    """Stands in for a JIT's first query (numba compiling spq's kernels on a cold cache, minutes):
    the first query of the process sleeps COMPILE_S, unless warm_up ran it first."""

    COMPILE_S = 2.0
    compiled = False

    @classmethod
    def compile(cls) -> None:
        if not cls.compiled:
            import time

            time.sleep(cls.COMPILE_S)
            cls.compiled = True


class _SlowFirstPair(SpqPair):
    def _query(self, pose_a, pose_b):
        _FirstQuerySlow.compile()
        return super()._query(pose_a, pose_b)

    def query_many(self, poses_a, poses_b):
        _FirstQuerySlow.compile()
        return super().query_many(poses_a, poses_b)


class SlowFirstQuery(_Mutant):
    """Right answers, but the first query of its process is slow, unless it is warmed up."""

    pair_class = _SlowFirstPair

    def warm_up(self) -> None:
        super().warm_up()  # spq's own kernels
        _FirstQuerySlow.compile()
