"""Support function of a convex polytope: brute force, or hill climbing from a cube-map start.

A support function takes a direction (d0, d1, d2) in the shape's local frame (any length, not
necessarily unit) and returns the farthest vertex along it.
"""

from __future__ import annotations

import numpy as np
from spq.kernels.jit import kernel

from spq.kernels.kinds import BRUTE_FORCE_MAX_VERTICES


@kernel(inline="always")
def _vertex_dot(f, i, d0, d1, d2):
    return f[3 * i] * d0 + f[3 * i + 1] * d1 + f[3 * i + 2] * d2


@kernel(inline="always")
def polytope_support_brute(f, n, d0, d1, d2):
    """Index of the vertex maximising d.x, by a linear scan over n vertices."""
    best = 0
    best_val = _vertex_dot(f, 0, d0, d1, d2)
    for i in range(1, n):
        val = _vertex_dot(f, i, d0, d1, d2)
        if val > best_val:
            best_val = val
            best = i
    return best


@kernel(inline="always")
def cube_cell(d0, d1, d2, G):
    """Index of the cube-map cell holding direction d: face (2 * axis + negative), then G x G cells."""
    a0, a1, a2 = abs(d0), abs(d1), abs(d2)
    if a0 >= a1 and a0 >= a2:
        axis, m, u, v, neg = 0, a0, d1, d2, d0 < 0.0
    elif a1 >= a2:
        axis, m, u, v, neg = 1, a1, d2, d0, d1 < 0.0
    else:
        axis, m, u, v, neg = 2, a2, d0, d1, d2 < 0.0
    if m == 0.0:
        return 0
    iu = int((u / m + 1.0) * 0.5 * G)
    iv = int((v / m + 1.0) * 0.5 * G)
    iu = min(max(iu, 0), G - 1)
    iv = min(max(iv, 0), G - 1)
    return ((2 * axis + (1 if neg else 0)) * G + iu) * G + iv


def cube_cell_corners(G: int) -> np.ndarray:
    """(6 G^2, 4, 3) corner directions of the cube-map cells, in cube_cell's order."""
    e = -1.0 + np.arange(G + 1) * 2.0 / G
    out = np.empty((6, G, G, 4, 3))
    for axis in range(3):
        for neg in (0, 1):
            for corner, (du, dv) in enumerate(((0, 0), (1, 0), (0, 1), (1, 1))):
                face = out[2 * axis + neg, :, :, corner]
                face[..., axis] = -1.0 if neg else 1.0
                face[..., (axis + 1) % 3] = e[du:du + G][:, None]
                face[..., (axis + 2) % 3] = e[dv:dv + G][None, :]
    return out.reshape(-1, 4, 3)


EXACT_CELL_MARGIN = 1e-9  # support lead, relative to the largest vertex norm, a cell's corners need to be exact


def cube_map_table(vertices: np.ndarray, G: int) -> np.ndarray:
    """(6 G^2,) int64 cube map of a polytope: each cell's start vertex v, or -(v + 1) where v is the
    support vertex of every direction in the cell.

    A cell's directions are the non-negative combinations of its four corner directions (the cell is
    a flat quadrilateral on the cube), so a vertex that is the unique maximiser at all four corners
    maximises d.x over the whole cell. Its lead over the runner-up at each corner must exceed
    EXACT_CELL_MARGIN times the largest vertex norm, so that neither the rounding of the dot
    products nor a direction that cube_cell's rounding puts just outside the cell can change the
    answer (both are some 1e-16 relative)."""
    V = np.asarray(vertices, dtype=np.float64)
    table = np.argmax(cube_cell_centres(G) @ V.T, axis=1)
    if len(V) < 2:
        return table.astype(np.int64)
    vals = cube_cell_corners(G) @ V.T  # (cells, 4, n)
    best = vals.argmax(axis=2)
    top2 = np.partition(vals, -2, axis=2)[:, :, -2:]
    lead = (top2[:, :, 1] - top2[:, :, 0]).min(axis=1)
    exact = (best == best[:, :1]).all(axis=1) & (lead > EXACT_CELL_MARGIN * np.linalg.norm(V, axis=1).max())
    return np.where(exact, -(best[:, 0] + 1), table).astype(np.int64)


def cube_cell_centres(G: int) -> np.ndarray:
    """(6 G^2, 3) centre directions of the cube-map cells, in cube_cell's order."""
    c = -1.0 + (np.arange(G) + 0.5) * 2.0 / G
    out = np.empty((6, G, G, 3))
    for axis in range(3):
        for neg in (0, 1):
            face = np.empty((G, G, 3))
            face[..., axis] = -1.0 if neg else 1.0
            face[..., (axis + 1) % 3] = c[:, None]
            face[..., (axis + 2) % 3] = c[None, :]
            out[2 * axis + neg] = face
    return out.reshape(-1, 3)


@kernel(inline="always")
def polytope_support_climb(f, ix, d0, d1, d2, start):
    """Index of the vertex maximising d.x, by steepest-ascent hill climbing over the hull graph.

    A cell the cube map marks exact (all its directions share one support vertex) gives that vertex
    at once. Otherwise the climb starts from the better of ``start`` (the warm start) and the cube-map
    vertex of d's cell. On a convex polytope a vertex with no strictly better neighbour is a global maximiser:
    the polytope lies in the cone its edges span at that vertex. A flat region (equal values)
    therefore ends the climb at an optimal vertex, and because every step strictly increases d.x
    the climb cannot loop. The step cap (n) and the brute-force fallback guard a corrupted graph.
    """
    n = ix[0]
    G = ix[1]
    cur = ix[ix[2] + cube_cell(d0, d1, d2, G)]
    if cur < 0:  # a cell inside one vertex's normal cone: that vertex, with no climb (cube_map_table)
        return -cur - 1
    cur_val = _vertex_dot(f, cur, d0, d1, d2)
    if 0 <= start < n and start != cur:
        val = _vertex_dot(f, start, d0, d1, d2)
        if val > cur_val:
            cur, cur_val = start, val
    nb = n + 4
    for _ in range(n):
        nxt = -1
        nxt_val = cur_val
        for k in range(ix[3 + cur], ix[4 + cur]):
            j = ix[nb + k]
            val = _vertex_dot(f, j, d0, d1, d2)
            if val > nxt_val:
                nxt_val = val
                nxt = j
        if nxt < 0:
            return cur
        cur = nxt
        cur_val = nxt_val
    return polytope_support_brute(f, n, d0, d1, d2)


@kernel(inline="always")
def polytope_support_index(f, ix, d0, d1, d2, start):
    """Support vertex index: brute force below BRUTE_FORCE_MAX_VERTICES, hill climbing above."""
    n = ix[0]
    if n <= BRUTE_FORCE_MAX_VERTICES:
        return polytope_support_brute(f, n, d0, d1, d2)
    return polytope_support_climb(f, ix, d0, d1, d2, start)
