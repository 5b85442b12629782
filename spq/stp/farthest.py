"""The farthest point of a cloud from each of many centres, compiled: the STP-BV construction's ball checks.

Each candidate face of an STP-BV is a ball of radius rho that must hold every hull point, so the
construction asks, for thousands of ball centres, how far the farthest of thousands of points lies.
As numpy blocks (|x|^2 - 2 x.c + |c|^2 through a matrix product) that took a fifth of a robot's
load: the blocks' temporaries, not the arithmetic, set the pace. Here it is one pass over the
points per centre, with the difference taken before it is squared, which also rounds less than the
expanded form (a centre rho away no longer costs a few eps rho).
"""

from __future__ import annotations

import math

import numpy as np

from spq.kernels.jit import kernel


@kernel(nogil=True)
def _farthest_into(x0, x1, x2, centres, out):
    for k in range(centres.shape[0]):
        c0, c1, c2 = centres[k, 0], centres[k, 1], centres[k, 2]
        best = 0.0
        for i in range(x0.shape[0]):
            d0, d1, d2 = x0[i] - c0, x1[i] - c1, x2[i] - c2
            best = max(best, d0 * d0 + d1 * d1 + d2 * d2)
        out[k] = math.sqrt(best)


def farthest_distances(x: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """max_i |x_i - c_k| for each centre: (k,) float64, from points x (n, 3) and centres (k, 3), one
    unit for both; 0 for every centre when there are no points."""
    x = np.asarray(x, dtype=np.float64).reshape(-1, 3)
    c = np.ascontiguousarray(centres, dtype=np.float64).reshape(-1, 3)
    out = np.empty(len(c))
    # coordinates as three contiguous arrays: the inner loop then streams through each
    _farthest_into(np.ascontiguousarray(x[:, 0]), np.ascontiguousarray(x[:, 1]), np.ascontiguousarray(x[:, 2]), c, out)
    return out
