"""STP-BV topology from a point cloud: the ball hull of the points at radius rho = R - r.

A *face* is a triple of points with a ball of radius rho through them that holds every point; the
ball's centre c_f is the centre of the face's big sphere (radius R, tangent to the three small
spheres of radius r). An *edge* joins two faces along two shared points; the *vertices* are the
points on some face. Points of the convex hull that no such ball touches drop out.

Method (NOTES section 2). Every face is a triangle t of the farthest-point Delaunay triangulation of
the convex-hull points. The centres of the balls through t's points lie on the line through t's
circumcentre o_t along its unit normal m_t, at o_t + s m_t, with squared radius rt^2 + s^2; the ball
holds a point p exactly when

    power(p, s) = |p - o_t|^2 - rt^2 - 2 s m_t.(p - o_t) <= 0,

which is linear in s. Along t's farthest-point Voronoi edge only the apexes of t's (one or two)
neighbouring tetrahedra bind, so the admissible s form an interval (a ray for a triangle on the
boundary of the triangulation, whose only neighbour bounds it on one side). t is a face at radius
rho on the side sigma = +-1 exactly when s = sigma h, h = sqrt(rho^2 - rt^2), passes both apexes;
both sides can hold. Each accepted face is then checked against every hull point, which also removes
what a joggled triangulation adds.

Degenerate input:
- duplicate points are merged first (the first occurrence is kept);
- a planar cloud (scipy's furthest-site Delaunay needs full rank in 3-D) uses the 2-D farthest-point
  triangulation in its plane: every triangle of it with circumradius <= rho is a face on both sides;
- a collinear cloud, or a cloud with no face at all (rho just above half a diametral pair), is the
  spindle of its two extreme points: 2 vertices, 1 edge with no face on either side;
- four or more points on one rho-sphere (cospherical: qhull needs 'QJ', and any triangulation of
  them is as good as another) are re-triangulated once from the points on that sphere, so that the
  faces of such a group cover its spherical polygon once, all with the same centre; the edges between
  them are zero-width tori (``edge_real`` False).

Two faces are neighbours across an edge (a, b) when the big-sphere centre, turning about the line
through a and b, meets the second after the first (the sch-creator wrapping step, done here only to
pair up the faces the triangulation found): this pairs the top and bottom faces of a flat cloud
correctly, where the same pair of points bounds four faces. The same pair of vertices can therefore
appear in two edges (the top and bottom diagonals of a flat square).

"On a sphere" and "the same centre" are decided with the tolerances below, relative to the cloud's
size D and to rho: points within them of one sphere are treated as cospherical. Everything is
computed in coordinates centred on the cloud (rounding then scales with the cloud's size, not with
its distance to the origin) and returned in the input frame, in the input's units.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull, Delaunay, QhullError

from spq.stp.topology import NO_FACE, STPTopology
from spq.validation import as_points

MERGE_TOL = 1e-12  # points closer than this, relative to the cloud's size D, are one point (m/m)
FLAT_TOL = 1e-11  # a cloud (or a cospherical group) thinner than this, relative to D, is planar (m/m)
POWER_TOL = 1e-12  # slack on |x - c|^2 - rho^2, relative to D (D + rho): inside / on a sphere (m^2/m^2)
CENTRE_TOL = 1e-9  # two big-sphere centres closer than this, relative to D + rho, coincide (m/m)
MEB_TOL = 1e-9  # a candidate smallest enclosing ball may miss a point by this, relative to D (m/m)
VERIFY_TOL = 1e-9  # final check |x - c_f| <= rho + VERIFY_TOL D + ROUNDING_TOL rho (m/m)
ROUNDING_TOL = 1e-14  # relative rounding of a distance to a centre rho away (50 eps) (m/m)
REPORT_DIGITS = 6  # significant digits of the smallest admissible R in the error message


def build_topology(points, r: float, R: float) -> STPTopology:
    """STP-BV of a point cloud with small radius r and big radius R.

    points : (n, 3) float, the cloud (metres; any unit works, r and R use the same one). Exact and
        near duplicates (closer than MERGE_TOL times the cloud's size) are merged, keeping the first.
    r, R : small and big radius, 0 < r < R, with R - r at least the radius of the smallest ball that
        encloses the points.

    Returns an :class:`STPTopology` whose vertices are the points on the ball hull at radius
    rho = R - r, ``source_index`` giving the input row of each; faces are counter-clockwise seen from
    outside, with their big-sphere centres.

    Raises ValueError for NaN/inf, a wrong shape, fewer than 2 distinct points, r <= 0, R <= r, or
    R too small to enclose the points (the message gives the smallest admissible R).
    """
    x, r, R = _validated(points, r, R)
    rho = R - r
    unique, source, origin, p, scale, frame, rank = _prepared(x)
    if rank == 1:
        pair = np.sort([np.argmin(p @ frame[0]), np.argmax(p @ frame[0])])  # the two ends
        _check_feasible(r, rho, 0.5 * float(np.linalg.norm(p[pair[0]] - p[pair[1]])), scale)
        return _spindle(unique[pair], source[pair], r, R)
    ctx, cand, r_meb = _candidates_and_radius(p, scale, frame, rank, rho)
    _check_feasible(r, rho, r_meb, scale)

    faces, centres, on_sphere = _faces(ctx, cand)
    if len(faces) == 0:
        pair = cand.longest_edge(p)
        _check_spindle_holds(ctx, pair)
        return _spindle(unique[pair], source[pair], r, R)

    faces, centres = _regroup_cospherical(ctx, cand.hull, faces, centres, on_sphere)
    _verify_faces(ctx, faces, centres)
    edges, edge_faces, edge_real = _pair_faces(ctx, faces, centres)

    used = np.unique(faces)  # ball-hull vertices, in input order (indices of unique rows)
    remap = np.full(len(p), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return STPTopology(r=r, R=R, vertices=unique[used], faces=remap[faces],
                       face_centres=centres + origin, edges=remap[edges], edge_faces=edge_faces,
                       edge_real=edge_real, source_index=source[used])


def enclosing_radius(points) -> float:
    """Radius of the smallest ball enclosing the points (their units): an STP-BV of them exists
    exactly when R - r is at least this."""
    x = as_points(points, "points", min_count=1)
    unique, source, origin, p, scale, frame, rank = _prepared(x)
    if len(unique) < 2:
        return 0.0
    if rank == 1:
        return 0.5 * float(np.ptp(p @ frame[0]))
    return _candidates_and_radius(p, scale, frame, rank, np.inf)[2]


def _prepared(x: np.ndarray):
    """Distinct points centred on their mean, their size, principal frame and affine rank."""
    unique, source = merge_duplicates(x, MERGE_TOL)
    if len(unique) < 2:
        raise ValueError(f"points need at least 2 distinct points; got {len(unique)} (from {len(x)} rows)")
    origin = unique.mean(axis=0)
    p = unique - origin
    scale = float(np.linalg.norm(np.ptp(p, axis=0)))
    frame, extent = _principal_frame(p)
    rank = int((extent > FLAT_TOL * scale).sum())
    return unique, source, origin, p, scale, frame, rank


def _candidates_and_radius(p, scale, frame, rank, rho):
    ctx = _Context(p=p, rho=rho, scale=scale)
    cand = _planar_candidates(ctx, frame) if rank == 2 else _solid_candidates(ctx)
    return ctx, cand, _enclosing_radius(ctx, cand)


# ----------------------------------------------------------------------------------------- input

def _validated(points, r, R) -> tuple[np.ndarray, float, float]:
    x = as_points(points, "points", min_count=2)
    try:
        r, R = float(r), float(R)
    except (TypeError, ValueError):
        raise ValueError(f"r and R must be numbers with 0 < r < R; got r = {r!r}, R = {R!r}") from None
    if not np.isfinite(r) or r <= 0.0:
        raise ValueError(f"r (small radius) must be finite and > 0; got {r}")
    if not np.isfinite(R) or R <= r:
        raise ValueError(f"R (big radius) must be finite and > r = {r}; got {R}")
    return x, r, R


def merge_duplicates(points: np.ndarray, rel_tol: float = MERGE_TOL) -> tuple[np.ndarray, np.ndarray]:
    """Points with duplicates removed, keeping the first occurrence.

    points : (n, 3) float. Two points closer than rel_tol times the cloud's size (bounding-box
    diagonal) are duplicates; -0.0 and 0.0 are equal. Returns the (m, 3) kept points, in input order,
    and (m,) int the input row of each.
    """
    from scipy.spatial import cKDTree

    x = points + 0.0  # turns -0.0 into 0.0
    _, first = np.unique(x, axis=0, return_index=True)
    first = np.sort(first)
    tol = rel_tol * float(np.linalg.norm(np.ptp(x, axis=0)))
    if tol > 0.0 and len(first) > 1:
        pairs = cKDTree(x[first]).query_pairs(tol, output_type="ndarray")
        if len(pairs):
            # keep the earliest of each cluster: drop the later point of every close pair
            drop = np.zeros(len(first), dtype=bool)
            for i, j in pairs[np.argsort(pairs.max(axis=1))]:
                if not drop[min(i, j)]:
                    drop[max(i, j)] = True
            first = first[~drop]
    return x[first], first.astype(np.int64)


def _principal_frame(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal axes (3, 3), rows by decreasing spread, and the extent (3,) of p along each."""
    _, _, vt = np.linalg.svd(np.vstack([p, np.zeros((3, 3))]), full_matrices=False)  # 3 rows of vt
    extent = np.ptp(p @ vt.T, axis=0)
    return vt, extent


def _check_feasible(r: float, rho: float, r_meb: float, scale: float) -> None:
    if rho < r_meb - MEB_TOL * scale:
        R_min = r + r_meb
        shown = _round_up(R_min, REPORT_DIGITS)
        raise ValueError(
            f"R is too small for these points: R - r = {rho:.{REPORT_DIGITS}g} is less than the radius "
            f"{r_meb:.{REPORT_DIGITS}g} of their smallest enclosing ball, so no ball of radius R - r "
            f"holds them; need R >= r + {r_meb:.{REPORT_DIGITS}g}, i.e. R >= {shown} (with r = {r})")


def _round_up(value: float, digits: int) -> str:
    """value rounded up to `digits` significant digits, as text (so that the text is admissible)."""
    if value == 0.0:
        return "0"
    step = 10.0 ** (math.floor(math.log10(abs(value))) - digits + 1)
    return f"{math.ceil(value / step) * step:.{digits}g}"


# ------------------------------------------------------------------------------------ candidates

class _Context:
    """The centred points (n, 3), rho and the cloud size D, with the tolerances derived from them."""

    def __init__(self, p: np.ndarray, rho: float, scale: float):
        self.p, self.rho, self.scale = p, rho, scale
        self.power_tol = POWER_TOL * scale * (scale + rho)
        self.centre_tol = CENTRE_TOL * (scale + rho)
        self.verify_tol = VERIFY_TOL * scale + ROUNDING_TOL * rho


class _Candidates:
    """Triangles of the farthest-point triangulation, with their circles and binding apexes.

    hull : (h,) indices of the points the triangulation uses.
    tri : (k, 3) point indices; o (k, 3) circumcentres; rt2 (k,) squared circumradii; m (k, 3) unit
        normals of the winding tri.
    d, e : (k, 2) for the apexes of the (up to two) neighbouring tetrahedra: height over the
        triangle's plane and power(apex, 0) = |apex - o|^2 - rt^2 (e = -inf where there is none).
        The ball centred at o + s m through the triangle holds the apex iff e - 2 s d <= 0.
    edge_pairs : (e, 2) the edges of the triangulation, each once.
    """

    def __init__(self, hull, tri, o, rt2, m, d, e):
        self.hull, self.tri, self.o, self.rt2, self.m, self.d, self.e = hull, tri, o, rt2, m, d, e
        pairs = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
        self.edge_pairs = np.unique(np.sort(pairs, axis=1), axis=0)

    def holds_apexes(self, s: np.ndarray, slack: np.ndarray) -> np.ndarray:
        """(k,) bool: the centre o + s m (s (k,)) holds both apexes, up to slack (k,) on the power."""
        return (self.e - 2.0 * s[:, None] * self.d).max(axis=1) <= slack

    def centre_range(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi), each (k,): the s for which o + s m holds both apexes (lo > hi: none)."""
        lo = np.full(len(self.tri), -np.inf)
        hi = np.full(len(self.tri), np.inf)
        for d, e in zip(self.d.T, self.e.T):
            with np.errstate(divide="ignore", invalid="ignore"):
                bound = e / (2.0 * d)
            lo = np.where(d > 0, np.maximum(lo, bound), lo)
            hi = np.where(d < 0, np.minimum(hi, bound), hi)
            lo = np.where((d == 0) & (e > 0), np.inf, lo)  # an apex outside t's circle, in its plane
        return lo, hi

    def longest_edge(self, p: np.ndarray) -> np.ndarray:
        """The two ends (2,) of the longest edge of the triangulation, for points p (n, 3)."""
        d = np.linalg.norm(p[self.edge_pairs[:, 0]] - p[self.edge_pairs[:, 1]], axis=1)
        return self.edge_pairs[int(np.argmax(d))]


def _circumcircles(a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Circumcentres (k, 3), squared circumradii (k,) and unit normals (k, 3) of triangles (a, b, c).

    The normal is along (b - a) x (c - a). A degenerate triangle gets rt2 = inf.
    """
    u, v = b - a, c - a
    w = np.cross(u, v)
    w2 = np.einsum("ij,ij->i", w, w)
    ok = w2 > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        o = a + (np.einsum("ij,ij->i", u, u)[:, None] * np.cross(v, w)
                 + np.einsum("ij,ij->i", v, v)[:, None] * np.cross(w, u)) / (2.0 * w2[:, None])
        m = w / np.sqrt(w2)[:, None]
    rt2 = (((o - a) ** 2).sum(1) + ((o - b) ** 2).sum(1) + ((o - c) ** 2).sum(1)) / 3.0
    rt2 = np.where(ok, rt2, np.inf)
    o = np.where(ok[:, None], o, 0.0)
    m = np.where(ok[:, None], m, 0.0)
    return o, rt2, m


def _furthest_delaunay(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Simplices (k, d+1) and neighbours (k, d+1) of the furthest-site Delaunay of q (n, d).

    scipy's, joggled ('QJ') when qhull rejects the input or drops a point: cospherical (cocircular
    in 2-D) input makes qhull stop with QH6019/QH6154, and a joggled triangulation is one of the
    valid ones up to ties, which the later steps resolve. d + 1 points are their own simplex (qhull
    needs d + 2 to lift them).
    """
    n, d = q.shape
    if n == d + 1:
        return np.arange(n)[None], np.full((1, n), -1)
    try:
        tri = Delaunay(q, furthest_site=True)
        if len(tri.coplanar) == 0:
            return tri.simplices, tri.neighbors
    except QhullError:
        pass
    tri = Delaunay(q, furthest_site=True, qhull_options="QJ")
    return tri.simplices, tri.neighbors


def _solid_candidates(ctx: _Context) -> _Candidates:
    """Triangles of the 3-D farthest-point triangulation of the hull points, with their ranges."""
    p = ctx.p
    hull = ConvexHull(p).vertices
    simp, nb = _furthest_delaunay(p[hull])
    n_simp = len(simp)
    others = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])
    tris, apex1, apex2 = [], [], []
    for k in range(4):  # the triangle opposite vertex k of each tetrahedron, once per triangle
        nbk = nb[:, k]
        keep = (nbk < 0) | (nbk > np.arange(n_simp))
        tris.append(simp[keep][:, others[k]])
        apex1.append(simp[keep, k])
        t_idx, n_idx = np.nonzero(keep)[0], nbk[keep]
        a2 = np.full(len(t_idx), -1, dtype=np.int64)
        inner = n_idx >= 0
        back = np.argmax(nb[n_idx[inner]] == t_idx[inner, None], axis=1)
        a2[inner] = simp[n_idx[inner], back]
        apex2.append(a2)
    tri = hull[np.concatenate(tris)]
    apex1 = hull[np.concatenate(apex1)]
    a2 = np.concatenate(apex2)
    apex2 = np.where(a2 >= 0, hull[np.maximum(a2, 0)], -1)

    o, rt2, m = _circumcircles(p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]])
    apex = np.stack([apex1, apex2], axis=1)
    q = p[np.maximum(apex, 0)] - o[:, None, :]
    d = np.einsum("kj,kij->ki", m, q)
    e = np.where(apex >= 0, np.einsum("kij,kij->ki", q, q) - rt2[:, None], -np.inf)
    return _Candidates(hull, tri, o, rt2, m, np.where(apex >= 0, d, 0.0), e)


def _planar_candidates(ctx: _Context, frame: np.ndarray) -> _Candidates:
    """Triangles of the 2-D farthest-point triangulation of a planar cloud (in its plane).

    Every such triangle's circle holds every point, so the centres o + s m hold them for all s.
    """
    p = ctx.p
    q = p @ frame[:2].T
    hull = ConvexHull(q).vertices
    simp, _ = _furthest_delaunay(q[hull])
    tri = hull[simp]
    o, rt2, m = _circumcircles(p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]])
    none = np.zeros((len(tri), 2))
    return _Candidates(hull, tri, o, rt2, m, none, none - np.inf)


# ------------------------------------------------------------------------------ enclosing ball

def _enclosing_radius(ctx: _Context, cand: _Candidates) -> float:
    """Radius of the smallest ball enclosing the points.

    Its centre minimises the farthest distance f; it lies on the farthest-point Voronoi diagram, on an
    edge (the line of a triangle, where f = sqrt(rt^2 + s^2) is least at s clipped to [lo, hi]; the
    tetrahedra's circumcentres are the ends of these edges) or, for a diametral pair, at the middle of
    the longest edge of the triangulation. The best candidate is checked against every point.
    (trimesh.nsphere.minimum_nsphere only tries the Voronoi vertices and a least-squares fit, which
    overestimates the radius when two or three points define the ball, and it divides by the
    smallest extent, zero for a flat cloud.)
    """
    p = ctx.p
    lo, hi = cand.centre_range()
    s = np.clip(0.0, lo, hi)
    ok = (lo <= hi) & np.isfinite(cand.rt2) & np.isfinite(s)
    s = s[ok]
    radius = np.sqrt(cand.rt2[ok] + s * s)
    centre = cand.o[ok] + s[:, None] * cand.m[ok]
    a, b = cand.longest_edge(p)
    radius = np.append(radius, 0.5 * np.linalg.norm(p[a] - p[b]))
    centre = np.vstack([centre, 0.5 * (p[a] + p[b])])
    pts = p[cand.hull]
    for k in np.argsort(radius):
        far = np.sqrt(((pts - centre[k]) ** 2).sum(axis=1).max())
        if far <= radius[k] + MEB_TOL * ctx.scale:
            return float(max(far, radius[k]))
    raise RuntimeError("no enclosing ball found among the farthest-point Voronoi features")


# ------------------------------------------------------------------------------------------ faces

def _faces(ctx: _Context, cand: _Candidates):
    """Faces (F, 3), counter-clockwise from outside, their big-sphere centres (F, 3), and which hull
    points (h, F) bool lie on each face's sphere (|x - c|^2 - rho^2 >= -power tolerance)."""
    rho2 = ctx.rho * ctx.rho
    near = cand.rt2 <= rho2 + ctx.power_tol
    h = np.sqrt(np.maximum(rho2 - cand.rt2, 0.0), where=near, out=np.zeros(len(cand.tri)))
    # |x - c|^2 - rho^2 = |x|^2 - 2 x.c + const, const = |o|^2 - rt^2 + 2 s m.o: this form keeps the
    # rounding at eps D (D + rho) where |c|^2 - rho^2 would lose eps rho^2
    tris, centres, const = [], [], []
    for sigma in (1.0, -1.0):
        s = sigma * h
        # rounding in e - 2 s d grows with |s| D: the slack does too
        ok = near & cand.holds_apexes(s, POWER_TOL * ctx.scale * (ctx.scale + np.abs(s)))
        c = cand.o[ok] + s[ok, None] * cand.m[ok]
        t = cand.tri[ok]
        # the outward normal points away from the centre: -sigma m, so sigma = +1 reverses (a, b, c)
        tris.append(t[:, [0, 2, 1]] if sigma > 0 else t)
        centres.append(c)
        const.append(np.einsum("ij,ij->i", cand.o[ok], cand.o[ok]) - cand.rt2[ok]
                     + 2.0 * s[ok] * np.einsum("ij,ij->i", cand.m[ok], cand.o[ok]))
    faces, centres, const = np.concatenate(tris), np.concatenate(centres), np.concatenate(const)
    # the triangulation may be joggled or hold ties: keep what holds every hull point
    x = ctx.p[cand.hull]
    power = (x * x).sum(axis=1)[:, None] - 2.0 * x @ centres.T + const[None, :]
    keep = power.max(axis=0) <= ctx.power_tol
    return faces[keep], centres[keep], power[:, keep] >= -ctx.power_tol


def _regroup_cospherical(ctx: _Context, hull: np.ndarray, faces: np.ndarray, centres: np.ndarray,
                         on: np.ndarray):
    """Replace the faces whose rho-sphere holds 4+ hull points by one triangulation per sphere.

    hull : (h,) point indices; on : (h, F) bool, hull point i on the sphere of face f.
    The triangulation's choice among cospherical points can overlap or leave out triangles (a flat
    joggled tetrahedron gives both diagonals of a square); the points on one sphere define the
    face's spherical polygon, triangulated once here, every triangle with the same centre (the mean
    of the group's centres). A face joins the group of a sphere that holds its three points (also a
    face that, by rounding, does not see a fourth point on its own sphere). The common case, a
    polygon of cocircular points on one side of its centre (the quads of a CAD mesh), is done for all
    groups of one size at once; the rest one by one.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    degenerate = np.nonzero(on.sum(axis=0) > 3)[0]
    if len(degenerate) == 0:
        return faces, centres
    row = np.full(len(ctx.p), -1, dtype=np.int64)
    row[hull] = np.arange(len(hull))
    t = row[faces]
    on_deg = on[:, degenerate]
    inside = on_deg[t[:, 0]] & on_deg[t[:, 1]] & on_deg[t[:, 2]]  # (F, D): f's points on g's sphere
    # one link per face, to the first sphere that holds it, is enough to connect a group (all its
    # faces are held by its first sphere) and keeps the graph small for a polygon of many points
    f_idx = np.nonzero(inside.any(axis=1))[0]
    g_idx = np.argmax(inside[f_idx], axis=1)
    graph = coo_matrix((np.ones(len(f_idx)), (f_idx, degenerate[g_idx])), shape=(len(faces),) * 2)
    _, comp = connected_components(graph, directed=False)
    grouped = np.isin(comp, comp[degenerate])
    members = np.nonzero(grouped)[0]
    _, group = np.unique(comp[members], return_inverse=True)  # 0 .. G-1 per grouped face
    n_groups = int(group.max()) + 1

    # the points on each group's sphere: (group, hull row) pairs, sorted by group
    face_of, pt = np.nonzero(on[:, members].T)
    pairs = np.unique(group[face_of] * len(hull) + pt)
    pair_group, pair_pt = pairs // len(hull), hull[pairs % len(hull)]
    size = np.bincount(pair_group, minlength=n_groups)
    start = np.concatenate([[0], np.cumsum(size)[:-1]])
    first = np.empty(n_groups, dtype=np.int64)
    first[group[::-1]] = members[::-1]  # one face of each group
    centre = np.zeros((n_groups, 3))
    np.add.at(centre, group, centres[members])
    centre /= np.bincount(group, minlength=n_groups)[:, None]
    # a group whose centres all coincide is one sphere; the others need a closer look
    spread = np.linalg.norm(centres[members] - centres[first[group]], axis=1) > ctx.centre_tol
    simple = np.ones(n_groups, dtype=bool)
    simple[group[spread]] = False

    new_faces, new_centres = [faces[~grouped]], [centres[~grouped]]
    rest = list(np.nonzero(~simple)[0])
    for k in np.unique(size[simple]):
        gs = np.nonzero(simple & (size == k))[0]
        ring = pair_pt[start[gs][:, None] + np.arange(k)]
        tri, ok = _fan_cocircular(ctx, ring, centre[gs])
        new_faces.append(tri[ok].reshape(-1, 3))
        new_centres.append(np.repeat(centre[gs[ok]], k - 2, axis=0))
        rest.extend(gs[~ok])
    for g in rest:
        on_sphere = pair_pt[start[g]:start[g] + size[g]]
        for c in _distinct_spheres(ctx, on_sphere, centres[members[group == g]]):
            tri, c = _triangulate_cap(ctx, on_sphere, c)
            new_faces.append(tri)
            new_centres.append(np.repeat(c[None], len(tri), axis=0))
    return np.concatenate(new_faces), np.concatenate(new_centres)


def _distinct_spheres(ctx: _Context, on_sphere: np.ndarray, centres: np.ndarray) -> list[np.ndarray]:
    """The distinct centres (3,) among centres (k, 3) of faces with the same points on their spheres.

    Points not in one plane are on one sphere only: one centre (differences are rounding, or an
    ill-conditioned rho just above the enclosing radius). Points in one plane lie on a circle, on the
    spheres centred on its axis at +-h, h = sqrt(rho^2 - rt^2): one centre per side, or one centre
    in the plane when h is within the tolerance.
    """
    x = ctx.p[on_sphere]
    mean = x.mean(axis=0)
    _, _, vt = np.linalg.svd(x - mean, full_matrices=False)
    off = (x - mean) @ vt[2]
    if np.ptp(off) > FLAT_TOL * ctx.scale:
        return [centres.mean(axis=0)]
    height = (centres - mean) @ vt[2]
    if np.abs(height).max() ** 2 <= ctx.power_tol:
        return [centres.mean(axis=0)]
    return [centres[side].mean(axis=0) for side in (height > 0, height <= 0) if side.any()]


def _fan_cocircular(ctx: _Context, members: np.ndarray, c: np.ndarray):
    """Fans of G polygons of k points each, members (G, k), seen from centres c (G, 3).

    Returns triangles (G, k - 2, 3), counter-clockwise seen from outside (away from c), and ok (G,)
    bool: the points are coplanar (hence cocircular, being on one sphere: in convex position, so
    their angle about the centroid orders them) and c is clearly off their plane. The plane comes
    from three far-apart points of each polygon (a batched SVD costs more than the rest together).
    """
    g = np.arange(len(members))
    x = ctx.p[members]  # (G, k, 3)
    base = x[:, 0]
    far = np.argmax(((x - base[:, None]) ** 2).sum(axis=2), axis=1)
    e1 = x[g, far] - base
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    normal = np.cross(e1[:, None, :], x - base[:, None])  # (G, k, 3)
    widest = np.argmax((normal ** 2).sum(axis=2), axis=1)
    normal = normal[g, widest]
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    centroid = x.mean(axis=1)
    height = np.einsum("gj,gj->g", centroid - c, normal)  # signed distance of the plane from c
    normal *= np.where(height < 0, -1.0, 1.0)[:, None]  # now pointing away from c: outward
    off = np.einsum("gkj,gj->gk", x - centroid[:, None], normal)
    ok = (np.ptp(off, axis=1) <= FLAT_TOL * ctx.scale) & (height * height > ctx.power_tol)
    e2 = np.cross(normal, e1)
    d = x - centroid[:, None]
    angle = np.arctan2(np.einsum("gkj,gj->gk", d, e2), np.einsum("gkj,gj->gk", d, e1))
    poly = np.take_along_axis(members, np.argsort(angle, axis=1), axis=1)  # counter-clockwise
    k = members.shape[1]
    fan = np.stack([np.repeat(poly[:, :1], k - 2, axis=1), poly[:, 1:-1], poly[:, 2:]], axis=2)
    return fan, ok


def _triangulate_cap(ctx: _Context, members: np.ndarray, c: np.ndarray):
    """Triangles (k, 3) covering the part of the sphere (c, rho) spanned by the points `members`,
    and the centre (3,) to give them.

    Seen from c, the face is the cone over these points: the facets of hull(points + {c}) that do
    not touch c, outward = away from c. Coplanar (hence cocircular) points: their polygon, fanned;
    when c lies in its plane (within the tolerance; the ball is then the face on both sides, as for
    3 points at rt = rho) both orientations, with c moved into the plane.
    """
    u = ctx.p[members] - c
    mean = u.mean(axis=0)
    d = u - mean
    _, _, vt = np.linalg.svd(d, full_matrices=False)
    normal = np.array([vt[0, 1] * vt[1, 2] - vt[0, 2] * vt[1, 1],  # vt[0] x vt[1]: vt may be
                       vt[0, 2] * vt[1, 0] - vt[0, 0] * vt[1, 2],  # left-handed
                       vt[0, 0] * vt[1, 1] - vt[0, 1] * vt[1, 0]])
    off = d @ normal
    if off.max() - off.min() <= FLAT_TOL * ctx.scale:
        # cocircular points are in convex position: their angle about the centroid orders them
        poly = members[np.argsort(np.arctan2(d @ vt[1], d @ vt[0]))]  # counter-clockwise about normal
        fan = np.stack([np.repeat(poly[0], len(poly) - 2), poly[1:-1], poly[2:]], axis=1)
        height = float(mean @ normal)  # signed distance of the polygon's plane from c
        if height * height <= ctx.power_tol:
            return np.concatenate([fan, fan[:, [0, 2, 1]]]), c + height * normal
        return (fan if height > 0 else fan[:, [0, 2, 1]]), c
    q = np.vstack([u, np.zeros((1, 3))])
    hull = ConvexHull(q)
    outer = ~(hull.simplices == len(u)).any(axis=1)
    simp, normals = hull.simplices[outer], hull.equations[outer, :3]
    w = np.cross(q[simp[:, 1]] - q[simp[:, 0]], q[simp[:, 2]] - q[simp[:, 0]])
    flip = np.einsum("ij,ij->i", w, normals) < 0
    simp = np.where(flip[:, None], simp[:, [0, 2, 1]], simp)
    return members[simp], c


def _verify_faces(ctx: _Context, faces: np.ndarray, centres: np.ndarray) -> None:
    """Check the definition: every point within rho (+ tolerance) of every face centre."""
    x = ctx.p
    d2 = (x * x).sum(axis=1)[:, None] - 2.0 * x @ centres.T + (centres * centres).sum(axis=1)[None, :]
    far = np.sqrt(np.maximum(d2.max(axis=0), 0.0))
    worst = int(np.argmax(far - ctx.rho))
    if far[worst] > ctx.rho + ctx.verify_tol:
        raise RuntimeError(f"face {faces[worst]} has a point at {far[worst]!r} from its centre, "
                           f"more than rho = {ctx.rho!r}")


# ------------------------------------------------------------------------------------------ edges

def _pair_faces(ctx: _Context, faces: np.ndarray, centres: np.ndarray):
    """Edges (E, 2), their faces (E, 2) and real flags (E,) from the faces' half-edges.

    Half-edge a -> b of face f1 pairs with a half-edge b -> a of the face f2 whose centre comes first
    when f1's centre turns about the axis from b to a (the way it moves as the sphere rolls over
    (a, b) onto the next face); a centre equal to f1's comes first of all (zero-width torus).
    """
    n_faces = len(faces)
    a = faces.ravel()
    b = faces[:, [1, 2, 0]].ravel()
    owner = np.repeat(np.arange(n_faces), 3)
    n_pts = int(faces.max()) + 1
    key = a * n_pts + b
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    rev = b * n_pts + a
    first = np.searchsorted(sorted_key, rev, side="left")
    last = np.searchsorted(sorted_key, rev, side="right")
    count = last - first
    if (count == 0).any():
        h = int(np.nonzero(count == 0)[0][0])
        raise RuntimeError(f"the faces do not close: edge ({a[h]}, {b[h]}) of face {owner[h]} "
                           f"has no face on its other side")
    partner = np.where(count == 1, order[np.minimum(first, len(order) - 1)], -1)
    for h in np.nonzero(count > 1)[0]:
        cands = order[first[h]:last[h]]
        mirror = (np.sort(faces[owner[cands]], axis=1) == np.sort(faces[owner[h]])).all(axis=1)
        partner[h] = cands[_first_by_rotation(ctx, a[h], b[h], centres[owner[h]],
                                              centres[owner[cands]], mirror)]
    if not (partner[partner] == np.arange(len(partner))).all():
        raise RuntimeError("the faces do not pair up consistently across their edges")
    one = a < b
    edges = np.stack([a[one], b[one]], axis=1)
    edge_faces = np.stack([owner[one], owner[partner[one]]], axis=1)
    gap = np.linalg.norm(centres[edge_faces[:, 0]] - centres[edge_faces[:, 1]], axis=1)
    return edges, edge_faces, gap > ctx.centre_tol


def _first_by_rotation(ctx: _Context, a: int, b: int, c1: np.ndarray, cands: np.ndarray,
                       mirror: np.ndarray) -> int:
    """Index in cands (k, 3) of the centre met first turning c1 about the axis from b to a.

    A centre equal to c1 comes first (zero rotation); among those, the mirror image of the face
    itself (mirror (k,) bool: same three points, the other side of a ball at rt = rho) comes last, as
    it is the neighbour only across the rim of such a flat face.
    """
    pa, pb = ctx.p[a], ctx.p[b]
    e = (pa - pb) / np.linalg.norm(pa - pb)
    mid = 0.5 * (pa + pb)
    u1 = c1 - mid
    u1 -= (u1 @ e) * e
    u = cands - mid
    u -= np.outer(u @ e, e)
    angle = np.mod(np.arctan2(np.cross(u1, u) @ e, u @ u1), 2.0 * np.pi)
    angle[np.linalg.norm(cands - c1, axis=1) <= ctx.centre_tol] = -1.0
    angle[mirror] = np.where(angle[mirror] < 0.0, -0.5, angle[mirror])
    return int(np.argmin(angle))


# ---------------------------------------------------------------------------------------- spindle

def _check_spindle_holds(ctx: _Context, pair: np.ndarray) -> None:
    """No face was found: the hull must be the spindle of `pair`; check that it holds every point."""
    pa, pb = ctx.p[pair[0]], ctx.p[pair[1]]
    half = 0.5 * np.linalg.norm(pb - pa)
    e = (pb - pa) / (2.0 * half)
    q = ctx.p - 0.5 * (pa + pb)
    t = q @ e
    radial = np.linalg.norm(q - np.outer(t, e), axis=1)
    # inside every rho-ball through pa and pb: radial <= sqrt(rho^2 - t^2) - sqrt(rho^2 - half^2)
    a = math.sqrt(max(ctx.rho ** 2 - half ** 2, 0.0))
    slack = np.sqrt(np.maximum(ctx.rho ** 2 - t * t, 0.0)) - a - radial
    if (np.abs(t) > half + ctx.verify_tol).any() or slack.min() < -ctx.verify_tol:
        raise RuntimeError("no face found, but the points do not fit the spindle of their two "
                           "farthest points")


def _spindle(ends: np.ndarray, source: np.ndarray, r: float, R: float) -> STPTopology:
    """The face-less STP-BV of two points (2, 3), input rows source (2,) in increasing order: two
    small spheres joined by one closed torus."""
    return STPTopology(r=r, R=R, vertices=ends, faces=np.zeros((0, 3), dtype=np.int64),
                       face_centres=np.zeros((0, 3)), edges=np.array([[0, 1]]),
                       edge_faces=np.array([[NO_FACE, NO_FACE]]), edge_real=np.array([True]),
                       source_index=source)
