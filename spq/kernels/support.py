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

import math

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
# and robot hulls: 4.9 at one cell per vertex, 2.6 at six). That mean is not what a search sees: GJK's
# and the EPA's directions end on the hull's facet normals, where nearly flat stretches put many
# vertices in one cell (kuka_link_4 at 2 cells per vertex: 48% of the final normals' cells hold more
# than CELL_SLOTS candidates, 7.9 on average; at 24, 17%). So a map gets up to DENSE_CELLS_PER_VERTEX
# cells per vertex while its edge stays within DENSE_MAX_G (6 * 64^2 cells of 4 int32 slots, about
# 400 KB), and never fewer than CELLS_PER_VERTEX (large hulls' short lists).
CELLS_PER_VERTEX = 2.0
DENSE_CELLS_PER_VERTEX = 24.0
DENSE_MAX_G = 64


def cube_map_size(n_vertices: int, minimum: int, dense: bool = True) -> int:
    """Cells per cube face edge for a polytope of n_vertices: at least ``minimum``; if ``dense``,
    DENSE_CELLS_PER_VERTEX cells per vertex up to an edge of DENSE_MAX_G; and at least CELLS_PER_VERTEX
    cells per vertex, so that large hulls keep short candidate lists. A robot scene takes the sparse
    maps (dense=False): its all-pairs sweep runs through every hull, and the larger pools cost more in
    cache than the shorter lists saved (JVRC-1 cold auto 7% slower); its STP-BVs' embedded hulls
    take them too, so that a body's PCH and STP-BV still share one hull, and so do its
    superellipsoids' inner polytopes."""
    def edge(cells_per_vertex):
        return int(np.ceil(np.sqrt(n_vertices * cells_per_vertex / 6.0)))
    dense_edge = min(DENSE_MAX_G, edge(DENSE_CELLS_PER_VERTEX)) if dense else 0
    return max(minimum, dense_edge, edge(CELLS_PER_VERTEX))


def cell_candidates(vertices: np.ndarray, G: int, adjacency=None) -> tuple[np.ndarray, np.ndarray]:
    """Each cube-map cell's support candidates as CSR: (offsets (6 G^2 + 1,), vertex ids ascending), int64.

    A direction d of a cell is a non-negative combination of the cell's four corner directions q_k
    (the cell is a flat quadrilateral on the cube). If vertex w beats vertex v at all four corners,
    q_k.w > q_k.v, it beats it at every d of the cell, so v is never the cell's support and is
    dropped; the kept vertices (those no single vertex beats at all four corners) therefore include
    the support of every direction of the cell. Cells are grown by CELL_GROWTH and a vertex must lose
    by CANDIDATE_MARGIN times the largest vertex norm, so that neither the rounding of the dot
    products nor a direction that cube_cell's rounding puts just outside the cell can miss its
    support (both are some 1e-16 relative).

    Only vertices near the cell's best can be kept. A kept v is not beaten by any vertex s, so at
    some corner q_k.(s - v) <= eps, and along the cell's centre c,
    c.(s - v) = q_k.(s - v) - (q_k - c).(s - v) <= eps + spread |s - v| (spread: the largest
    |q_k - c|). With s the best vertex along c, that is a small disc about s. Beating is transitive,
    so a vertex of the disc beaten by any vertex is beaten by an unbeaten one, which lies in the disc:
    the disc's own unbeaten vertices are the kept ones.

    adjacency: (offsets, neighbours), the CSR edge graph of the triangles that bound the vertices'
    convex hull (qhull's), or None. With it, each cell's disc is found by a walk over the edges from
    the last cell's best vertex (_cap_by_walk); without it, by a scan of every vertex (those within
    ``reach`` of the best value along c, |s - v| bounded by twice the largest vertex norm, then the
    disc). The lists are the same. For a hull of 20,000 vertices, comparing every vertex with
    probes in every cell took 14-17 s, the scan 2-3.7 s and the walk 0.4-1.1 s."""
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    corners = cube_cell_corners(G)
    centres = corners.mean(axis=1, keepdims=True)
    corners = np.ascontiguousarray(centres + (corners - centres) * (1.0 + CELL_GROWTH))
    centres = np.ascontiguousarray(centres[:, 0, :])
    norm = max(float(np.linalg.norm(V, axis=1).max()), np.finfo(float).tiny)
    eps = CANDIDATE_MARGIN * norm
    spread = float(np.linalg.norm(corners - centres[:, None, :], axis=2).max())
    reach = 2.0 * (eps + spread * 2.0 * norm)
    n = len(V)
    counts = np.empty(len(corners), dtype=np.int64)
    ids = np.empty(max(4 * len(corners), 1024), dtype=np.int64)
    scratch = (np.empty(n), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64), np.empty((n, 4)),
               np.empty(n, dtype=np.int64))
    if adjacency is None:
        graph = (np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))
    else:
        graph = (np.ascontiguousarray(adjacency[0], dtype=np.int64), np.ascontiguousarray(adjacency[1], dtype=np.int64),
                 np.zeros(n, dtype=np.int64))
    walk = adjacency is not None
    total = _cell_caps(V, corners, centres, eps, spread, reach, walk, graph, scratch, counts, ids)
    if total > len(ids):  # more candidates than room: once more, with room for all
        ids = np.empty(total, dtype=np.int64)
        _cell_caps(V, corners, centres, eps, spread, reach, walk, graph, scratch, counts, ids)
    offsets = np.zeros(len(corners) + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    return offsets, ids[:total].copy()


@kernel(inline="always")
def _beats(M, w, v, eps):
    """Whether cap vertex w beats cap vertex v by more than eps at all four corners (M: their values)."""
    return (M[w, 0] > M[v, 0] + eps and M[w, 1] > M[v, 1] + eps
            and M[w, 2] > M[v, 2] + eps and M[w, 3] > M[v, 3] + eps)


@kernel(inline="always")
def _dot_row(V, v, c0, c1, c2):
    return V[v, 0] * c0 + V[v, 1] * c1 + V[v, 2] * c2


@kernel
def _cap_by_scan(V, c0, c1, c2, reach, value, cap):
    """The vertices within reach of the best value along (c0, c1, c2), ascending, into cap. Returns
    (their count, the first best vertex)."""
    n = V.shape[0]
    best, top = -np.inf, 0
    for v in range(n):
        x = _dot_row(V, v, c0, c1, c2)
        value[v] = x
        if x > best:
            best, top = x, v
    k = 0
    for v in range(n):
        if value[v] >= best - reach:
            cap[k] = v
            k += 1
    return k, top


@kernel
def _cap_by_walk(V, offsets, neighbours, seen, stamp, start, c0, c1, c2, eps, spread, cap):
    """A superset of the vertices near the best one s along c = (c0, c1, c2) (_cell_caps), in the
    order reached, into cap, by a walk over the hull's edge graph (seen: (n,) marks, stamp this
    cell's): up from ``start`` to a local maximum s, then across the vertices v with
    c.(s - v) <= 4 (eps + spread |s - v|). Returns (count, s).

    That set is the complement of a convex set: the segment from s to any v in it stays in it (the
    test is linear along it), so a plane separates the segment from the complement, and the
    vertices on the segment's side, all in the set, form a cap that the polytope's graph connects.
    The factor 4, twice _cell_caps' 2, keeps the vertices of such paths in despite rounding."""
    top = start
    best = _dot_row(V, top, c0, c1, c2)
    climbing = True
    while climbing:
        climbing = False
        for e in range(offsets[top], offsets[top + 1]):
            x = _dot_row(V, neighbours[e], c0, c1, c2)
            if x > best:
                best, top, climbing = x, neighbours[e], True
    seen[top] = stamp
    cap[0] = top
    k, head = 1, 0
    while head < k:
        v = cap[head]
        head += 1
        for e in range(offsets[v], offsets[v + 1]):
            w = neighbours[e]
            if seen[w] != stamp:
                seen[w] = stamp
                d0, d1, d2 = V[w, 0] - V[top, 0], V[w, 1] - V[top, 1], V[w, 2] - V[top, 2]
                if best - _dot_row(V, w, c0, c1, c2) <= 4.0 * (eps + spread * math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)):
                    cap[k] = w
                    k += 1
    return k, top


@kernel
def _cell_caps(V, corners, centres, eps, spread, reach, walk, graph, scratch, counts, ids):
    """cell_candidates' lists, cell after cell, into ids (counts[c] in cell c); returns their total.
    Past len(ids) only the counts are kept (the caller calls again with room). walk: find the caps
    over graph = (offsets, neighbours, marks (n,)), else by a scan. scratch: (value (n,), cap (n,),
    near (n,), the near vertices' corner values (n, 4), survivors (n,)).

    Of the cap, only the vertices v near enough to the centre's best vertex s can be kept:
    c.(s - v) <= eps + spread |s - v| (cell_candidates), here with a factor 2 for rounding; that
    is a small disc about s where the cap's plane cuts a wide one. Among them: first the vertices
    that no probe (s, and the best at each corner) beats, which leaves few, then those that no other
    of those beats."""
    value, cap, near, M, survivors = scratch
    offsets, neighbours, seen = graph
    seen[:] = 0  # (marks of a run before are stamps of this one)
    total = 0
    start = 0
    for c in range(corners.shape[0]):
        c0, c1, c2 = centres[c, 0], centres[c, 1], centres[c, 2]
        if walk:
            k, start = _cap_by_walk(V, offsets, neighbours, seen, c + 1, start, c0, c1, c2, eps, spread, cap)
        else:
            k, start = _cap_by_scan(V, c0, c1, c2, reach, value, cap)
        s = start
        best = _dot_row(V, s, c0, c1, c2)
        kn = top = 0
        for i in range(k):
            v = cap[i]
            d0, d1, d2 = V[v, 0] - V[s, 0], V[v, 1] - V[s, 1], V[v, 2] - V[s, 2]
            if best - _dot_row(V, v, c0, c1, c2) <= 2.0 * (eps + spread * math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)):
                if v == s:
                    top = kn
                near[kn] = v
                for j in range(4):
                    M[kn, j] = V[v, 0] * corners[c, j, 0] + V[v, 1] * corners[c, j, 1] + V[v, 2] * corners[c, j, 2]
                kn += 1
        k = kn
        probes = (top, _argmax_column(M, k, 0), _argmax_column(M, k, 1), _argmax_column(M, k, 2),
                  _argmax_column(M, k, 3))
        m = 0
        for i in range(k):
            beaten = False
            for p in probes:
                if _beats(M, p, i, eps):
                    beaten = True
                    break
            if not beaten:
                survivors[m] = i
                m += 1
        kept = 0
        for j in range(m):
            lost = False
            for i in range(m):
                if _beats(M, survivors[i], survivors[j], eps):
                    lost = True
                    break
            if not lost:
                if total + kept < ids.shape[0]:
                    ids[total + kept] = near[survivors[j]]
                kept += 1
        if walk and total + kept <= ids.shape[0]:  # the walk's order: ascending ids, as the scan gives them
            _sort(ids, total, total + kept)
        counts[c] = kept
        total += kept
    return total


@kernel
def _sort(a, lo, hi):
    """Insertion sort of a[lo:hi] (a cell's few candidates)."""
    for i in range(lo + 1, hi):
        x = a[i]
        j = i - 1
        while j >= lo and a[j] > x:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = x


@kernel(inline="always")
def _argmax_column(M, k, j):
    """The first of rows 0..k-1 of M with the largest value in column j."""
    best = 0
    for i in range(1, k):
        if M[i, j] > M[best, j]:
            best = i
    return best


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
