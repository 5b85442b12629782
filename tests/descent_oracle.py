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
    return st, np.sqrt(vv) - ka.margin - kb_.margin, lower - ka.margin - kb_.margin
