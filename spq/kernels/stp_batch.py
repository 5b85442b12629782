"""Batched STP-BV support queries and region checks (for tests, benchmarks and users)."""

from __future__ import annotations

import math

import numpy as np

from spq.kernels.jit import kernel
from spq.kernels.stp_support import (IDX_E, IDX_F, IDX_H, IDX_V, _offsets, find_patch, hull_vertex_step, in_region,
                                     patch_support, small_sphere_owns)


@kernel(allocates=True)
def support_batch(f, ix, method, directions, coherent):
    """Support points (m, 3), owning patches (m,) and search steps (m,) for (m, 3) directions.

    coherent: each search starts from the previous direction's patch."""
    m = directions.shape[0]
    points = np.empty((m, 3))
    patches = np.empty(m, dtype=np.int64)
    steps = np.empty(m, dtype=np.int64)
    start = -1
    for k in range(m):
        d0, d1, d2 = directions[k, 0], directions[k, 1], directions[k, 2]
        n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if n == 0.0:
            d0, n = 1.0, 1.0
        u0, u1, u2 = d0 / n, d1 / n, d2 / n
        p, s = find_patch(f, ix, method, start if coherent else -1, u0, u1, u2)
        patch_support(f, ix, p, u0, u1, u2, points[k])
        patches[k] = p
        steps[k] = s
        start = p
    return points, patches, steps


@kernel(allocates=True)
def owner_counts(f, ix, directions):
    """Number of patches whose region holds each direction (m,)."""
    P = ix[IDX_V] + ix[IDX_F] + ix[IDX_E]
    o_faces, o_tori, o_planes, o_hull = _offsets(ix)
    m = directions.shape[0]
    counts = np.zeros(m, dtype=np.int64)
    for k in range(m):
        d0, d1, d2 = directions[k, 0], directions[k, 1], directions[k, 2]
        n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        for p in range(P):
            if in_region(f, ix, o_planes, p, d0 / n, d1 / n, d2 / n):
                counts[k] += 1
    return counts


@kernel(allocates=True)
def hull_vertex_table_answers(f, ix, directions):
    """For each direction (m rows, any length) and underlying-hull vertex h (H), what the hull-vertex
    table says: whether h's small sphere owns it (m, H) and the patch its march step goes to (m, H;
    -1 where it owns it)."""
    m, H = directions.shape[0], ix[IDX_H]
    owns = np.zeros((m, H), dtype=np.bool_)
    steps = np.empty((m, H), dtype=np.int64)
    for k in range(m):
        d0, d1, d2 = directions[k, 0], directions[k, 1], directions[k, 2]
        n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        for h in range(H):
            owns[k, h] = small_sphere_owns(f, ix, h, d0 / n, d1 / n, d2 / n)
            steps[k, h] = hull_vertex_step(f, ix, h, d0 / n, d1 / n, d2 / n)
    return owns, steps
