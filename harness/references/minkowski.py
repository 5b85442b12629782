"""Exact distance reference for two convex polytopes, independent of any GJK.

Method. With both bodies placed in the world, the Minkowski difference ``D = A - B`` is the convex
hull of the points ``a_i - b_j`` (hull vertices of A and B only). The bodies are separated iff the
origin lies outside D, and then their distance is the distance from the origin to D; when the origin
is inside, the penetration depth (the shortest translation of B that separates them) is the
distance from the origin to the boundary of D. Both come from one ``scipy.spatial.ConvexHull`` of
the difference points (qhull, triangulated output) and an exact point-to-triangle distance over all
hull triangles (every Voronoi region: vertex, edge, interior; near-zero-area triangles are handled
by their edges). The winning triangle's corners are differences ``a_i - b_j``; with the barycentric
coordinates ``lambda`` of the closest point, the witness points are ``sum lambda a_i`` on A and
``sum lambda b_j`` on B.

Speed. Of the ``n_A * n_B`` differences only pairs whose vertex normal cones can meet are given to
qhull (``a_i - b_j`` is a vertex of D only if some direction is maximised by ``a_i`` over A and
minimised by ``b_j`` over B, i.e. N_A(a_i) meets -N_B(b_j)). Stage 1 bounds each normal cone by a
spherical cap around the mean of its facet normals and drops pairs with disjoint caps; stage 2 drops
pairs that a plane orthogonal to an edge at ``a_i`` or at ``b_j`` strictly separates (first against
the other body's cap, then against its exact cone generators). Every step only drops pairs with a
proof of disjointness (caps wider than a hemisphere count as the whole sphere; margins of 1e-6 rad
and 1e-9 in cosine cover rounding), so all vertices of D are kept. For two 315-vertex robot links
about 1,520 of the 99,225 differences survive, essentially the ~1,517 hull vertices; one
reference (build + query) then takes about 20 ms. ``prefilter=False`` hulls all differences.

Precision. Differences are formed in a re-centred frame (rotated local vertices plus the relative
translation ``t_A - t_B``), so the absolute error is a few ulps of the bodies' size and separation,
not of their distance to the world origin: ~1e-16 m for metre-scale links.

Frames and units: poses are 4x4 homogeneous matrices (local -> world), lengths in metres, all
returned points and normals in the world frame.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from spq.shapes.polyhedron import Polyhedron, convex_hull
from spq.validation import as_pose

TOUCH_TOL = 1e-12  # m: |signed distance| at or below which the status is 'touching'
CONE_MARGIN = 1e-6  # rad added to every normal-cone cap (covers arccos rounding near 0)

STATUSES = ("separated", "touching", "overlapping")


@dataclass(frozen=True, eq=False)
class ReferenceResult:
    """Exact answer for one pair of posed polytopes (metres, world frame).

    distance : float, >= 0; 0 when overlapping.
    depth : float, >= 0; penetration depth (length of the shortest translation of B that separates
        the bodies) when overlapping, else 0.
    signed_distance : float; ``distance`` if separated or touching from outside, ``-depth`` if the
        origin is inside the Minkowski difference.
    point_a, point_b : (3,) float64; witness points on A and B. ``|point_b - point_a|`` equals the
        distance (or the depth when overlapping).
    normal : (3,) float64 unit vector from A to B: translating B by ``s * normal`` (small s) changes
        the signed distance by ``+s``; when overlapping it is the direction of least penetration.
    status : 'separated' | 'touching' | 'overlapping'; touching when ``|signed_distance| <= 1e-12``.
    """

    distance: float
    depth: float
    signed_distance: float
    point_a: np.ndarray
    point_b: np.ndarray
    normal: np.ndarray
    status: str


# --------------------------------------------------------------------------------------------------
# normal-cone caps of one polytope (local frame), cached per Polyhedron object
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class _Caps:
    """Normal-cone data of one polytope's hull vertices, local frame."""

    vertices: np.ndarray  # (k, 3) hull vertices
    axes: np.ndarray  # (k, 3) unit cap axes
    cos: np.ndarray  # (k,) cos of the cap half-angle (half-angle pi for "whole sphere")
    sin: np.ndarray  # (k,) sin of the cap half-angle
    whole: np.ndarray  # (k,) bool: cap is the whole sphere (no pruning for this vertex)
    edges: np.ndarray  # (k, w, 3) unit vectors to the hull neighbours, padded by repetition
    normals: np.ndarray  # (k, w, 3) distinct outward normals of the incident facets, padded
    sat: np.ndarray  # (k,) bool: edges/normals complete (degree <= SAT_MAX_DEGREE)


SAT_MAX_DEGREE = 24  # vertices with more neighbours or facet normals skip the second filter stage
SAT_MARGIN = 1e-9  # a separating direction must clear the other cone by this cosine

_CAPS_CACHE: "weakref.WeakKeyDictionary[Polyhedron, tuple[np.ndarray, _Caps]]" = weakref.WeakKeyDictionary()


def _padded(rows: list[np.ndarray], width: int) -> tuple[np.ndarray, np.ndarray]:
    out = np.empty((len(rows), width, 3))
    ok = np.ones(len(rows), dtype=bool)
    for v, r in enumerate(rows):
        if len(r) > width:
            ok[v] = False
            r = r[:width]
        out[v, : len(r)] = r
        out[v, len(r) :] = r[0]
    return out, ok


def _hull_caps(poly: Polyhedron) -> _Caps:
    cached = _CAPS_CACHE.get(poly)
    if cached is not None and cached[0] is poly.vertices:
        return cached[1]
    verts, tris, planes = convex_hull(np.asarray(poly.vertices, dtype=np.float64))
    verts = verts.copy()
    simp = tris.ravel()
    normals = np.repeat(planes[:, :3], 3, axis=0)  # one row per (facet, corner)
    k = len(verts)
    # stage 1: one spherical cap around each normal cone
    axes = np.zeros((k, 3))
    np.add.at(axes, simp, normals)
    norm = np.linalg.norm(axes, axis=1)
    whole = norm <= 1e-9
    axes[~whole] /= norm[~whole, None]
    mincos = np.ones(k)
    np.minimum.at(mincos, simp, np.einsum("ij,ij->i", axes[simp], normals))
    angle = np.arccos(np.clip(mincos, -1.0, 1.0)) + CONE_MARGIN
    whole |= angle >= np.pi / 2  # a cap wider than a hemisphere is not convex: keep everything
    angle[whole] = np.pi
    # stage 2: the cone itself, as its generators (facet normals) and its facets' normals (edges)
    order = np.argsort(simp, kind="stable")
    starts = np.searchsorted(simp[order], np.arange(k + 1))
    facet_of = order // 3
    nbr_edges, nbr_normals = [], []
    for v in range(k):
        fac = facet_of[starts[v] : starts[v + 1]]
        nbrs = np.unique(tris[fac].ravel())
        nbrs = nbrs[nbrs != v]
        e = verts[nbrs] - verts[v]
        nbr_edges.append(e / np.linalg.norm(e, axis=1)[:, None])
        nbr_normals.append(np.unique(planes[fac, :3], axis=0))
    width = min(SAT_MAX_DEGREE, max(max(len(e) for e in nbr_edges), max(len(n) for n in nbr_normals)))
    edges, ok_e = _padded(nbr_edges, width)
    cone_normals, ok_n = _padded(nbr_normals, width)
    caps = _Caps(verts, axes, np.cos(angle), np.sin(angle), whole, edges, cone_normals, ok_e & ok_n)
    _CAPS_CACHE[poly] = (poly.vertices, caps)
    return caps


def _candidate_pairs(ca: _Caps, cb: _Caps, rot_a: np.ndarray, rot_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) for which a_i - b_j may be a vertex of A - B (a superset of them).

    a_i - b_j is a vertex only if the normal cone N_A(a_i) meets -N_B(b_j) beyond the origin. Stage 1
    drops pairs whose bounding caps are disjoint. Stage 2 drops pairs with a strictly separating
    plane through the origin orthogonal to an edge at a_i or at b_j: every d in N_A(a_i) has
    d.(a_k - a_i) <= 0 for each neighbour a_k, so if every generator -f of -N_B(b_j) has
    -f.(a_k - a_i) > 0 the cones meet only at the origin (and symmetrically for B's edges).
    """
    # work in A's frame: B's directions rotated by R_A^T R_B
    rel = rot_a.T @ rot_b
    ub = cb.axes @ rel.T
    eb = cb.edges @ rel.T
    ka, w_a = ca.edges.shape[:2]
    kb, w_b = eb.shape[:2]
    # stage 1: angle(u_a, -u_b) <= theta_a + theta_b  <=>  -u_a.u_b >= cos(theta_a + theta_b); both
    # half-angles are < pi/2 unless flagged whole, so the sum is < pi where cos is monotonic
    keep = -(ca.axes @ ub.T) >= np.outer(ca.cos, cb.cos) - np.outer(ca.sin, cb.sin)
    keep |= ca.whole[:, None] | cb.whole[None, :]
    # stage 2a: edges of one body against the other's cap (dense products, no gathers)
    # cap(-u_b, theta_b) strictly on the positive side of an A edge e: -u_b.e > sin(theta_b)
    ea_ub = (ca.edges.reshape(-1, 3) @ -ub.T).reshape(ka, w_a, kb).max(axis=1)
    sep = (ea_ub > cb.sin[None, :] + SAT_MARGIN) & ~cb.whole[None, :]
    # cap(u_a, theta_a) strictly on the negative side of a B edge e: u_a.e < -sin(theta_a)
    eb_ua = (eb.reshape(-1, 3) @ ca.axes.T).reshape(kb, w_b, ka).min(axis=1).T
    sep |= (eb_ua < -ca.sin[:, None] - SAT_MARGIN) & ~ca.whole[:, None]
    keep &= ~sep
    ii, jj = np.nonzero(keep)
    # stage 2b: edges of one body against the other's cone generators
    test = ca.sat[ii] & cb.sat[jj]
    ti, tj = ii[test], jj[test]
    if len(ti):
        nb = cb.normals @ rel.T
        # edge e_k of A separates if f.e_k < -margin for every facet normal f of B at b_j
        m1 = np.matmul(ca.edges[ti], nb[tj].transpose(0, 2, 1))
        sep = m1.max(axis=2).min(axis=1) < -SAT_MARGIN
        # edge e_l of B separates if f.e_l < -margin for every facet normal f of A at a_i
        m2 = np.matmul(ca.normals[ti], eb[tj].transpose(0, 2, 1))
        sep |= m2.max(axis=1).min(axis=1) < -SAT_MARGIN
        drop = np.zeros(len(ii), dtype=bool)
        drop[np.flatnonzero(test)[sep]] = True
        ii, jj = ii[~drop], jj[~drop]
    return ii, jj


# --------------------------------------------------------------------------------------------------
# exact closest point of a batch of triangles to the origin
# --------------------------------------------------------------------------------------------------


def closest_points_on_triangles(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest point to the origin of each triangle in ``tri`` ((m, 3, 3), corners in rows).

    Returns ``(dist2, lam)``: squared distances (m,) and barycentric coordinates (m, 3) of the
    closest points (non-negative, summing to 1, so the point always lies on the triangle). Exact in
    every Voronoi region: the closest point is either interior (the plane projection, accepted only
    when all three barycentrics of the projection are >= 0) or on one of the three closed edges
    (clamped segment projections, which also cover the vertices). Degenerate triangles (zero area,
    coincident corners) are covered by their edges.
    """
    tri = np.asarray(tri, dtype=np.float64)
    m = tri.shape[0]
    d2 = np.empty((m, 4))
    params = np.empty((m, 4))  # edge parameter t, or unused for the face
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for k, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
            a, e = tri[:, i], tri[:, j] - tri[:, i]
            ee = np.einsum("ij,ij->i", e, e)
            t = np.where(ee > 0.0, -np.einsum("ij,ij->i", a, e) / ee, 0.0)
            t = np.clip(np.nan_to_num(t, nan=0.0), 0.0, 1.0)
            q = a + t[:, None] * e
            d2[:, k] = np.einsum("ij,ij->i", q, q)
            params[:, k] = t
        p0 = tri[:, 0]
        e1, e2 = tri[:, 1] - p0, tri[:, 2] - p0
        n = np.cross(e1, e2)
        nn = np.einsum("ij,ij->i", n, n)
        r = -p0
        l1 = np.einsum("ij,ij->i", n, np.cross(r, e2)) / nn
        l2 = np.einsum("ij,ij->i", n, np.cross(e1, r)) / nn
        l0 = 1.0 - l1 - l2
        ok = (nn > 0.0) & np.isfinite(l1) & np.isfinite(l2) & (l0 >= 0.0) & (l1 >= 0.0) & (l2 >= 0.0)
        q = p0 + l1[:, None] * e1 + l2[:, None] * e2
        d2[:, 3] = np.where(ok, np.einsum("ij,ij->i", q, q), np.inf)
    best = np.argmin(d2, axis=1)
    rows = np.arange(m)
    lam = np.zeros((m, 3))
    for k, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
        sel = best == k
        lam[sel, i] = 1.0 - params[sel, k]
        lam[sel, j] = params[sel, k]
    sel = best == 3
    lam[sel, 0], lam[sel, 1], lam[sel, 2] = l0[sel], l1[sel], l2[sel]
    return d2[rows, best], lam


# --------------------------------------------------------------------------------------------------
# the reference
# --------------------------------------------------------------------------------------------------


def _as_offset(offset) -> np.ndarray:
    if offset is None:
        return np.zeros(3)
    try:
        off = np.array(offset, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"offset must be a 3-vector of numbers: {exc}") from None
    if off.shape != (3,):
        raise ValueError(f"offset must have shape (3,); got {np.shape(offset)}")
    if not np.isfinite(off).all():
        raise ValueError(f"offset must be finite; got {off}")
    return off


class MinkowskiReference:
    """Hull of the Minkowski difference of two posed polytopes, built once, queried many times.

    Parameters
    ----------
    a, b : Polyhedron
        The bodies, in their local frames (metres).
    pose_a, pose_b : (4, 4) array_like
        Rigid transforms local -> world.
    prefilter : bool
        Drop differences that cannot be hull vertices before calling qhull (default; exact, see the
        module docstring). ``False`` hulls all ``n_A * n_B`` differences.

    Attributes
    ----------
    n_candidates : int
        Number of difference points given to qhull.
    n_facets : int
        Number of hull triangles.
    joggled : bool
        True if qhull failed on the exact points and 'QJ' (joggled input) was used; the triangle
        corners are still the exact difference points.
    """

    def __init__(self, a: Polyhedron, b: Polyhedron, pose_a, pose_b, prefilter: bool = True):
        for name, body in (("a", a), ("b", b)):
            if not isinstance(body, Polyhedron):
                raise ValueError(f"{name} must be a spq Polyhedron; got {type(body).__name__}")
        pa = as_pose(pose_a, "pose_a")
        pb = as_pose(pose_b, "pose_b")
        ca, cb = _hull_caps(a), _hull_caps(b)
        ra_rot, rb_rot = pa[:3, :3], pb[:3, :3]
        self._ra = ca.vertices @ ra_rot.T  # rotated, relative to t_a
        self._rb = cb.vertices @ rb_rot.T  # rotated, relative to t_b
        self._ta = pa[:3, 3].copy()
        self._tb = pb[:3, 3].copy()
        dt = self._ta - self._tb

        if prefilter:
            ia, jb = _candidate_pairs(ca, cb, ra_rot, rb_rot)
        else:
            ia, jb = np.divmod(np.arange(len(self._ra) * len(self._rb)), len(self._rb))
        pts = self._ra[ia] - self._rb[jb] + dt
        self.joggled = False
        try:
            hull = ConvexHull(pts)
        except QhullError:
            hull = ConvexHull(pts, qhull_options="QJ")
            self.joggled = True
        used = np.unique(hull.simplices)
        remap = np.full(len(pts), -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        self._pts = pts[used]
        self._ia = ia[used]
        self._jb = jb[used]
        self._simplices = remap[hull.simplices]
        self._normals = np.ascontiguousarray(hull.equations[:, :3])
        self._offsets = np.ascontiguousarray(hull.equations[:, 3])
        self.n_candidates = int(len(pts))
        self.n_facets = int(len(self._simplices))

    def query(self, offset=np.zeros(3)) -> ReferenceResult:
        """Exact result with B translated by the extra world vector ``offset`` ((3,), metres).

        The hull is reused: translating B by ``offset`` translates the Minkowski difference by
        ``-offset`` without changing its facets.
        """
        off = _as_offset(offset)
        pts = self._pts - off
        tri = pts[self._simplices]
        dist2, lam = closest_points_on_triangles(tri)
        k = int(np.argmin(dist2))
        lam_k = lam[k]
        corners = self._simplices[k]
        c = lam_k @ pts[corners]  # closest boundary point of D: p_a - p_b
        dist = float(np.sqrt(dist2[k]))
        plane = self._offsets + self._normals @ off  # plane values at the origin
        inside = bool(plane.max() <= 0.0)
        signed = -dist if inside else dist
        status = "touching" if abs(signed) <= TOUCH_TOL else ("overlapping" if inside else "separated")
        # outward normal of D at c, which is the A -> B normal in every case
        # (the facet's own normal when the closest point is interior to it, or when c is too short to
        # give a direction; else the direction of c, exact for edge and vertex contacts)
        norm_c = float(np.linalg.norm(c))
        if lam_k.min() > 0.0 or norm_c <= TOUCH_TOL:
            normal = self._normals[k].copy()
        else:
            normal = c / norm_c if inside else -c / norm_c
        point_a = lam_k @ self._ra[self._ia[corners]] + self._ta
        point_b = lam_k @ self._rb[self._jb[corners]] + (self._tb + off)
        return ReferenceResult(
            distance=0.0 if inside else dist,
            depth=dist if inside else 0.0,
            signed_distance=signed,
            point_a=point_a,
            point_b=point_b,
            normal=normal,
            status=status,
        )


def reference_distance(a: Polyhedron, b: Polyhedron, pose_a, pose_b) -> ReferenceResult:
    """Exact distance / penetration depth of two posed polytopes (see :class:`MinkowskiReference`)."""
    return MinkowskiReference(a, b, pose_a, pose_b).query()


_POOL_BODIES: tuple[Polyhedron, Polyhedron] | None = None


def _pool_init(a: Polyhedron, b: Polyhedron) -> None:
    global _POOL_BODIES
    _POOL_BODIES = (a, b)  # once per worker, so each worker builds the bodies' cone data once


def _pool_task(poses: tuple[np.ndarray, np.ndarray]) -> ReferenceResult:
    a, b = _POOL_BODIES
    return reference_distance(a, b, poses[0], poses[1])


def reference_many(
    a: Polyhedron, b: Polyhedron, poses_a, poses_b, processes: int | None = 1, chunksize: int = 16
) -> list[ReferenceResult]:
    """Reference results for N pose pairs (``poses_a``, ``poses_b``: (N, 4, 4)), in order.

    ``processes`` > 1 spreads the poses over a process pool (None: one worker per CPU); 1 runs in
    this process.
    """
    from spq.validation import as_poses

    pa = as_poses(poses_a, "poses_a")
    pb = as_poses(poses_b, "poses_b")
    if len(pa) != len(pb):
        raise ValueError(f"poses_a and poses_b must have the same length; got {len(pa)} and {len(pb)}")
    if processes is not None and (not isinstance(processes, int) or processes < 1):
        raise ValueError(f"processes must be None or an integer >= 1; got {processes!r}")
    if processes == 1 or len(pa) < 2:
        return [reference_distance(a, b, pa[i], pb[i]) for i in range(len(pa))]
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=processes, initializer=_pool_init, initargs=(a, b)) as pool:
        return list(pool.map(_pool_task, zip(pa, pb), chunksize=max(1, int(chunksize))))
