"""Support function of a convex polytope: a scan of the few candidates of the direction's cube-map cell.

A support function takes a direction (d0, d1, d2) in the shape's local frame (any length, not
necessarily unit) and returns the farthest vertex along it.

The directions are binned into cells on the faces of a cube (cube_cell). For each cell the polytope
stores every vertex that can be the support of some direction in the cell (a small superset, about
2.5 vertices per cell on robot link hulls), so the support is the best of those: no graph walk,
no data-dependent loop length beyond the cell's list, and exact by construction (cell_candidates).

Each cell has CELL_SLOTS slots at a place computed from its index, holding its candidates (the last
one repeated to fill them), or, for the few cells with more, where their list lies further on. A
support is then two dependent memory reads, the cell's slots and the candidate vertices, instead
of three through a table of list offsets: in an all-pairs loop that sweeps a robot's hulls in a
random order those reads are cache misses, and they held most of the descent's time.
"""

from __future__ import annotations

import numpy as np

from spq.kernels.indexing import at
from spq.kernels.jit import kernel

CELL_SLOTS = 4  # candidates stored in a cell's own slots (94% of the cells of JVRC-1's link hulls have at most 4)


@kernel(inline="always")
def _vertex_dot(f, i, d0, d1, d2):
    return f[at(3 * i)] * d0 + f[at(3 * i + 1)] * d1 + f[at(3 * i + 2)] * d2


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


CANDIDATE_MARGIN = 1e-12  # lead, relative to the largest vertex norm, by which a vertex must lose to be dropped
CELL_GROWTH = 1e-7  # relative growth of each cell about its centre, so that cube_cell's rounding stays inside
# A cell overlaps the normal cones of about 2 + 3 / (cells per vertex) vertices (measured on random
# and robot hulls: 4.9 at one cell per vertex, 2.6 at six).
CELLS_PER_VERTEX = 2.0


def cube_map_size(n_vertices: int, minimum: int) -> int:
    """Cells per cube face edge for a polytope of n_vertices: at least ``minimum``, and at least
    CELLS_PER_VERTEX cells per vertex, so that large hulls keep short candidate lists."""
    return max(minimum, int(np.ceil(np.sqrt(n_vertices * CELLS_PER_VERTEX / 6.0))))


def cell_candidates(vertices: np.ndarray, G: int, chunk: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Each cube-map cell's support candidates as CSR: (offsets (6 G^2 + 1,), vertex ids), int64.

    A direction d of a cell is a non-negative combination of the cell's four corner directions q_k
    (the cell is a flat quadrilateral on the cube). If vertex w beats vertex v at all four corners,
    q_k.w > q_k.v, it beats it at every d of the cell, so v is never the cell's support and is
    dropped; the kept vertices (those no single vertex beats at all four corners) therefore include
    the support of every direction of the cell. Cells are grown by CELL_GROWTH and a vertex must lose
    by CANDIDATE_MARGIN times the largest vertex norm, so that neither the rounding of the dot
    products nor a direction that cube_cell's rounding puts just outside the cell can miss its
    support (both are some 1e-16 relative)."""
    V = np.asarray(vertices, dtype=np.float64)
    corners = cube_cell_corners(G)
    centre = corners.mean(axis=1, keepdims=True)
    corners = centre + (corners - centre) * (1.0 + CELL_GROWTH)
    eps = CANDIDATE_MARGIN * max(float(np.linalg.norm(V, axis=1).max()), np.finfo(float).tiny)
    centres = cube_cell_centres(G)
    kept = []
    survivors = np.empty(len(V), dtype=np.int64)
    ids = np.empty((chunk, len(V)), dtype=np.int64)
    counts = np.empty(chunk, dtype=np.int64)
    for c0 in range(0, len(corners), chunk):
        M = np.ascontiguousarray(corners[c0:c0 + chunk] @ V.T)  # (cells, 4, n): each vertex's value at each corner
        # first against the supports of the corners and the centre, which beat most vertices
        # (per chunk: all cells' centres at once are a (6 G^2, n) matrix, 6.5 GB for 20,000 vertices)
        centre_support = (centres[c0:c0 + chunk] @ V.T).argmax(axis=1)
        probes = np.concatenate([M.argmax(axis=2), centre_support[:, None]], axis=1)  # (cells, 5)
        probes = np.ascontiguousarray(probes, dtype=np.int64)
        _cell_survivors(M, probes, eps, survivors, ids, counts)
        kept += [ids[c, :counts[c]].copy() for c in range(len(M))]
    offsets = np.concatenate([[0], np.cumsum([len(k) for k in kept])]).astype(np.int64)
    return offsets, np.concatenate(kept).astype(np.int64)


@kernel(inline="always")
def _beats(M, c, w, v, eps):
    """Whether vertex w beats vertex v by more than eps at all four corners of cell c."""
    return (M[c, 0, w] > M[c, 0, v] + eps and M[c, 1, w] > M[c, 1, v] + eps
            and M[c, 2, w] > M[c, 2, v] + eps and M[c, 3, w] > M[c, 3, v] + eps)


@kernel
def _cell_survivors(M, probes, eps, survivors, ids, counts):
    """Per cell c of M (cells, 4, n), its candidates in ids[c, :counts[c]], ascending: the vertices
    that no probe (probes[c], 5 vertices) beats at all four corners, then those of them that no other
    survivor beats (cell_candidates); survivors (n,) is scratch. A loop here: the numpy form took
    seconds on hulls of thousands of vertices, in Python's per-cell overhead and in its (survivors x
    survivors) temporaries."""
    n = M.shape[2]
    for c in range(M.shape[0]):
        k = 0
        for v in range(n):
            beaten = False
            for p in range(probes.shape[1]):
                if _beats(M, c, probes[c, p], v, eps):
                    beaten = True
                    break
            if not beaten:
                survivors[k] = v
                k += 1
        kept = 0
        for j in range(k):
            lost = False
            for i in range(k):
                if _beats(M, c, survivors[i], survivors[j], eps):
                    lost = True
                    break
            if not lost:
                ids[c, kept] = survivors[j]
                kept += 1
        counts[c] = kept


def cube_map_idata(n_vertices: int, G: int, offsets: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """POLYTOPE idata (layout in kinds) from cell_candidates' CSR lists: each cell's CELL_SLOTS
    slots hold its candidates, in order, the last repeated (which cannot change the best of them);
    a cell with more holds (-1 - position of its list, its length) and the list follows the slots."""
    cells_start = 3
    ncells = len(offsets) - 1
    counts = np.diff(offsets)
    slots = np.empty((ncells, CELL_SLOTS), dtype=np.int64)
    overflow = []
    pos = cells_start + ncells * CELL_SLOTS
    for c in range(ncells):
        ids = candidates[offsets[c]:offsets[c + 1]]
        if counts[c] <= CELL_SLOTS:
            slots[c, :counts[c]] = ids
            slots[c, counts[c]:] = ids[-1]
        else:
            slots[c] = (-1 - pos, counts[c], 0, 0)
            overflow.append(ids)
            pos += counts[c]
    return np.concatenate([[n_vertices, G, cells_start], slots.ravel(), *overflow]).astype(np.int64)


@kernel(inline="always")
def _best_candidate(f, ix, a, b, d0, d1, d2):
    """The first of the vertex ids ix[a:b] that maximises d.x."""
    best = ix[at(a)]
    best_val = _vertex_dot(f, best, d0, d1, d2)
    for k in range(a + 1, b):
        j = ix[at(k)]
        val = _vertex_dot(f, j, d0, d1, d2)
        if val > best_val:
            best_val = val
            best = j
    return best


@kernel(inline="always")
def polytope_support_index(f, ix, d0, d1, d2):
    """Index of the vertex maximising d.x: the best of d's cube-map cell's candidates (layout in kinds)."""
    c = ix[2] + CELL_SLOTS * cube_cell(d0, d1, d2, ix[1])
    first = ix[at(c)]
    if first < 0:  # more candidates than slots: the cell's list lies further on
        return _best_candidate(f, ix, -1 - first, -1 - first + ix[at(c + 1)], d0, d1, d2)
    return _best_candidate(f, ix, c, c + CELL_SLOTS, d0, d1, d2)
