"""Gradient of the separation distance with respect to rigid motions of either body.

Frame convention (world frame throughout, metres and radians):

* A pose is a 4x4 homogeneous matrix T = [[R, t], [0, 1]] mapping the body's local frame to the world.
* A body's motion is a 6-vector xi = (dt, omega), both expressed in the **world** frame:
  ``dt`` is a world-frame translation of the body, ``omega`` a small world-frame rotation vector applied
  **about the body's own origin** (the pose translation t), i.e. the perturbed pose is

      R <- expm([omega]x) @ R,   t <- t + dt,

  so that a body point p moves to  t + dt + expm([omega]x) (p - t)  (to first order p + dt + omega x (p - t)).
  This is a left (world-frame) perturbation of the rotation with the pivot at t, not at the world origin.

With n the unit normal from A to B and p_A, p_B the witness points (p_B - p_A = d n, d the signed
distance, negative when a signed query found the bodies overlapping):

    dd/dt_B = n,        dd/domega_B =  (p_B - t_B) x n,
    dd/dt_A = -n,       dd/domega_A = -(p_A - t_A) x n.

The formula is exact wherever the distance is differentiable: the witness points may move, but to first
order they slide within their surfaces orthogonally to n (envelope theorem). It holds for any convex pair,
separated or (signed queries) overlapping, since both signs are d = -min over unit n of
h_A(n) + h_B(-n) with h the support functions, and the minimiser n is the normal; for two polyhedra the
translational part is continuous, but the rotational
part jumps where the witness point jumps (e.g. two faces rotating through parallel). With an STP-BV or a
superellipsoid on the side(s) that rotate, the witness point moves continuously and the gradient is C0.

Failed results, results at distance exactly 0, and overlaps from unsigned queries (distance 0, no
normal) have no gradient here: every entry is NaN. Overlaps from ``signed=True`` queries have one, and it
is continuous through contact wherever the normal is.
"""

from __future__ import annotations

import numpy as np

__all__ = ["distance_gradient", "distance_gradients"]

_NO_GRADIENT = ("failed",)


def _translation(pose) -> np.ndarray:
    pose = np.asarray(pose, dtype=np.float64)
    if pose.shape[-2:] != (4, 4):
        raise ValueError(f"a pose must be a 4x4 homogeneous matrix (or N x 4 x 4); got shape {pose.shape}")
    return pose[..., :3, 3]


def distance_gradient(result, pose_a, pose_b) -> tuple[np.ndarray, np.ndarray]:
    """(grad_a, grad_b), each (6,) = (dd/dt, dd/domega) of body A and of body B.

    result: a :class:`spq.DistanceResult` of ``spq.distance(A, B, pose_a, pose_b)`` (or of a Pair).
    pose_a, pose_b: the 4x4 world poses used for that query (only their translations enter: the
    rotation pivot). See the module docstring for the frame convention: world-frame translation t
    and world-frame small rotation omega about the body's origin, R <- expm([omega]x) R.

    Valid for both signs: a ``signed=True`` overlap (negative distance) has a gradient too. Returns
    NaN vectors when the result failed, when its distance is exactly 0 (the normal is then
    undefined), or for an unsigned overlap (distance 0, NaN normal).
    """
    t_a, t_b = _translation(pose_a), _translation(pose_b)
    n = np.asarray(result.normal, dtype=np.float64)
    p_a = np.asarray(result.point_a, dtype=np.float64)
    p_b = np.asarray(result.point_b, dtype=np.float64)
    d = float(result.distance)
    if result.status in _NO_GRADIENT or d == 0.0 or not np.isfinite(d) or not np.all(np.isfinite(n)):
        nan = np.full(6, np.nan)
        return nan, nan.copy()
    grad_b = np.concatenate([n, np.cross(p_b - t_b, n)])
    grad_a = np.concatenate([-n, -np.cross(p_a - t_a, n)])
    return grad_a, grad_b


def distance_gradients(batch, poses_a, poses_b) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised :func:`distance_gradient` for a :class:`spq.BatchDistances`.

    poses_a, poses_b: (N, 4, 4) or a single (4, 4) (broadcast), the poses of the batched query.
    Returns (grad_a, grad_b), each (N, 6); rows of failed or zero-distance results (which include
    unsigned overlaps) are NaN.
    """
    n = np.asarray(batch.normal, dtype=np.float64)
    count = len(n)
    t_a = np.broadcast_to(_translation(poses_a), (count, 3))
    t_b = np.broadcast_to(_translation(poses_b), (count, 3))
    p_a = np.asarray(batch.point_a, dtype=np.float64)
    p_b = np.asarray(batch.point_b, dtype=np.float64)
    grad_b = np.concatenate([n, np.cross(p_b - t_b, n)], axis=1)
    grad_a = np.concatenate([-n, -np.cross(p_a - t_a, n)], axis=1)
    status = np.asarray(batch.status)
    d = np.asarray(batch.distance, dtype=np.float64)
    bad = np.isin(status, _NO_GRADIENT) | ~np.isfinite(d) | (d == 0.0) | ~np.all(np.isfinite(n), axis=1)
    grad_a[bad] = np.nan
    grad_b[bad] = np.nan
    return grad_a, grad_b
