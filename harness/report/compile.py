"""Compile spq's kernels ahead of the report's suites, in parts that a pool runs side by side.

On a fresh install numba's cache is empty, and every process that first meets a kernel compiles it.
The report's pool runs two suites at once, which then compiled the same kernels twice at the same time
(several minutes each). Here the kernels fall into parts with few shared callees (the robot scene's
all-pairs loop, which inlines the query, and the per-call and batched queries); each part is one task
whose calls reach its kernels with the argument types the suites use, so that the suites, on any
process, then load them from the cache. Nothing here is timed or written into the report.
"""

from __future__ import annotations

import time

import numpy as np

PARTS = ("scene", "queries")


def _shapes() -> dict:
    import spq

    rng = np.random.default_rng(0)
    pts = rng.normal(size=(25, 3)) * 0.15
    return {"box": spq.Box(0.05, 0.1, 0.15), "sphere": spq.Sphere(0.1), "capsule": spq.Capsule(0.05, 0.15),
            "pch": spq.Polyhedron.from_points(pts), "stp": spq.STPBV.from_points(pts, 0.02, 1.0),
            "cse": spq.Superellipsoid(0.1, 0.08, 0.05, 0.5, 0.7)}


def _queries() -> None:
    """Every kind against every kind: the plain call, a Pair along a path and the batched call,
    unsigned and signed."""
    import spq

    rng = np.random.default_rng(1)
    poses = np.tile(np.eye(4), (4, 1, 1))
    poses[:, :3, 3] = rng.normal(size=(4, 3)) * 0.2
    eye = np.tile(np.eye(4), (4, 1, 1))
    shapes = _shapes()
    for a in shapes.values():
        for b in shapes.values():
            for signed in (False, True):
                spq.distances(a, b, eye, poses, signed=signed)
                pair = spq.Pair(a, b, signed=signed)
                pair.distances(eye, poses, coherent=True)
                for i in range(2):
                    spq.distance(a, b, eye[i], poses[i], signed=signed)
                    pair.distance(eye[i], poses[i])


def _scene() -> None:
    """The KUKA iiwa of pybullet_data under each volume policy: every pair cold and coherent, signed,
    and with the rows ∂d/∂q (a controller's call)."""
    import pybullet_data

    import spq

    urdf = f"{pybullet_data.getDataPath()}/kuka_iiwa/model.urdf"
    for policy in ("auto", "pch"):
        scene = spq.Scene.from_urdf(urdf, policy=policy)
        qs = np.stack([scene.random_configuration(np.random.default_rng(k)) for k in range(3)])
        for signed in (False, True):
            scene.distances_many(qs, coherent=False, signed=signed)
            scene.distances_many(qs, coherent=True, signed=signed)
            scene.distances(qs[0], signed=signed)
            scene.distances(qs[0], signed=signed, jacobian=True)
            scene.distances_many(qs, signed=signed, jacobian=True)


def compile_part(part: str) -> tuple[str, float]:
    """Compile (or load from the cache) one part's kernels in this process: (part, seconds)."""
    if part not in PARTS:
        raise ValueError(f"unknown compile part {part!r}; expected one of {', '.join(PARTS)}")
    start = time.perf_counter()
    {"scene": _scene, "queries": _queries}[part]()
    return part, round(time.perf_counter() - start, 1)
