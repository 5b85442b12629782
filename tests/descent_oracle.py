"""The plain GJK descent on two shapes' own supports, as a test oracle: no hulls, no patches, no
warm start, only the support functions and the descent's certified bounds."""

from __future__ import annotations

import numpy as np

from spq.kernels import batch as kb
from spq.kernels import gjk


def plain_descent(a, b, pose_a, pose_b, tol=1e-12):
    """Distance by the plain GJK descent on the shapes' own supports (no hulls, no patches)."""
    ka, kb_ = a.kernel_data(), b.kernel_data()
    R, t = np.empty((3, 3)), np.empty(3)
    kb.relative_pose(pose_a, pose_b, R, t)
    work = np.empty((gjk.WORK_ROWS, 4))
    warm = np.zeros(gjk.WARM_SIZE, dtype=np.int64)
    pair = (ka.kind, ka.margin, ka.fdata, ka.idata, kb_.kind, kb_.margin, kb_.fdata, kb_.idata, R, t)
    st, k, v0, v1, v2, vv, lower, it = gjk.descend(pair, (tol, tol, 2000), np.zeros(3), warm, work)
    # the upper bound from the simplex's witness points, each its first point plus the weighted steps to
    # the others: on a needle simplex the weights miss a sum of 1 by up to 1e-11, and |sum lam_i w_i|
    # (the descent's |v|) then falls short of every distance of the two bodies (by 1.3e-12 m at
    # kuka_link_4's STP-PCH pose 2790 of random_poses(5000, 0, 0.3))
    lam = work[12, :k]
    pa = work[4, :3] + lam[1:] @ (work[5:4 + k, :3] - work[4, :3])
    pb = work[8, :3] + lam[1:] @ (work[9:8 + k, :3] - work[8, :3])
    return st, float(np.linalg.norm(pb - pa)) - ka.margin - kb_.margin, lower - ka.margin - kb_.margin
