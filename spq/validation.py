"""Input checks shared by every public entry point.

Each check returns a clean, C-contiguous float64 array or raises a ``ValueError`` that names the
problem and the admissible range, so that bad input never reaches a compiled kernel.
"""

from __future__ import annotations

import numpy as np

ROTATION_TOL = 1e-6  # max |R^T R - I| entry and |det R - 1| accepted for a rotation (dimensionless)


def as_points(points, name: str = "points", min_count: int = 1) -> np.ndarray:
    """Return ``points`` as a C-contiguous (n, 3) float64 array of finite values.

    Raises ValueError for a wrong shape, fewer than ``min_count`` rows, or NaN/inf entries.
    """
    try:
        arr = np.array(points, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an (n, 3) array of numbers: {exc}") from None
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (n, 3); got {arr.shape}")
    if arr.shape[0] < min_count:
        raise ValueError(f"{name} needs at least {min_count} points; got {arr.shape[0]}")
    bad = ~np.isfinite(arr)
    if bad.any():
        row = int(np.argwhere(bad)[0, 0])
        raise ValueError(f"{name} contains NaN or inf (first at row {row}); all coordinates must be finite")
    return np.ascontiguousarray(arr)


def as_positive(value, name: str) -> float:
    """Return ``value`` as a finite float > 0, or raise ValueError."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number > 0; got {value!r}") from None
    if not np.isfinite(x) or x <= 0.0:
        raise ValueError(f"{name} must be finite and > 0; got {x}")
    return x


def as_poses(poses, name: str = "pose") -> np.ndarray:
    """Return ``poses`` as a C-contiguous (N, 4, 4) float64 array of rigid transforms.

    Accepts one 4x4 matrix (returned as N = 1) or an N x 4 x 4 batch. Each must be finite, have the
    bottom row (0, 0, 0, 1), and a rotation block R with |R^T R - I| <= ROTATION_TOL and det R > 0.
    """
    try:
        arr = np.array(poses, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a 4x4 homogeneous matrix or an N x 4 x 4 batch: {exc}") from None
    if arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[1:] != (4, 4):
        raise ValueError(f"{name} must have shape (4, 4) or (N, 4, 4); got {arr.shape}")
    if not np.isfinite(arr).all():
        idx = int(np.argwhere(~np.isfinite(arr))[0, 0])
        raise ValueError(f"{name} contains NaN or inf (pose {idx}); poses must be finite")
    bottom_err = np.abs(arr[:, 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1)
    if (bottom_err > 0.0).any():
        idx = int(np.argmax(bottom_err))
        raise ValueError(f"{name} {idx} has bottom row {arr[idx, 3]}; a homogeneous pose needs (0, 0, 0, 1)")
    rot = arr[:, :3, :3]
    ortho_err = np.abs(np.einsum("nji,njk->nik", rot, rot) - np.eye(3)).max(axis=(1, 2))
    det = np.linalg.det(rot)
    bad = (ortho_err > ROTATION_TOL) | (np.abs(det - 1.0) > ROTATION_TOL)
    if bad.any():
        idx = int(np.argmax(bad))
        raise ValueError(
            f"{name} {idx} has a rotation block that is not a rotation "
            f"(|R^T R - I| = {ortho_err[idx]:.3g}, det = {det[idx]:.6g}); "
            f"need an orthonormal matrix with det +1 within {ROTATION_TOL}"
        )
    return np.ascontiguousarray(arr)


def as_pose(pose, name: str = "pose") -> np.ndarray:
    """Return one validated 4x4 rigid transform (see :func:`as_poses`)."""
    arr = np.asarray(pose)
    if arr.shape != (4, 4):
        raise ValueError(f"{name} must have shape (4, 4); got {arr.shape}")
    return as_poses(arr, name)[0]
