"""STP-BV topology from a point cloud: the ball hull of the points at radius rho = R - r.

A *face* is a triple of points with a ball of radius rho through them that holds every point; the
ball's centre c_f is the centre of the face's big sphere (radius R, tangent to the three small
spheres of radius r). An *edge* joins two faces along two shared points; the *vertices* are the
points on some face. Points of the convex hull that no such ball touches drop out.

Method (NOTES section 2). The faces are where the boundary of Q = {c : |c - x_i| <= rho for all i},
the set of admissible big-sphere centres, crosses the farthest-point Voronoi diagram of the
convex-hull points. Q's vertices are the face centres, its arcs the tori, its sphere patches the
vertices. The diagram is the dual of the farthest-point Delaunay triangulation (scipy/qhull):

- a tetrahedron T is a Voronoi vertex V_T, its circumcentre, with f(V_T) = circumradius rho_T the
  largest distance to any point; T is *in* (V_T in Q) when rho_T <= rho;
- a triangle t is a Voronoi edge, the segment of the line through t's circumcentre o_t along its
  normal m_t between the circumcentres of its two tetrahedra (a ray towards the apex of the only one
  for a triangle on the triangulation's boundary, whose open end, "infinity", is out). Along it
  f = sqrt(rt^2 + s^2), so it crosses the boundary of Q at most at s = +-h, h = sqrt(rho^2 - rt^2):
  once when one end is in and the other out, twice or never when both are out, never when both are in;
- a single crossing is a face on t centred on the side of t where the *in* tetrahedron's apex lies
  (f grows away from the in end); a double crossing is two faces, one on each side.

Every decision that joins faces is taken once per tetrahedron (in or out) and read by all of its four
triangles, and the sides come from the tetrahedra's orientations, made consistent across the whole
triangulation: so around every edge (a, b) of the triangulation the crossings alternate in and out
and the faces close, whatever rounding does to near-ties (cospherical points, a circumradius equal to
rho, flat tetrahedra of cocircular points). Pairing is combinatorial too: walking around the edge
(a, b) from a face, through the run of out tetrahedra on its far side, the crossing that ends the
run is the face across the torus of (a, b) (the torus's arc of centres joins the two). Geometry
enters only in the in/out test, the choice between a double crossing and none, and the face centres.

Every face's ball is then checked against every hull point. Where rounding took an in/out decision
against the geometry (circumradii within rounding of rho: nearly cospherical points, R at its
minimum), a face lands on the wrong side of its triangle or just off Q, and its ball misses a point:
the face's tetrahedron within its tie band (the out one first) flips and the faces around it are
redone, until every ball holds (flips keep the faces closed; they only move crossings).

The circumcentre of a tetrahedron comes from its own points when that is well conditioned, and from
qhull's lifted hyperplane otherwise, and always when qhull merged several tetrahedra into one facet
(cospherical points, which it triangulates into tetrahedra that share one hyperplane, some of them
flat): then they share one centre and one in/out decision, as the exact geometry has it.

Degenerate input:
- duplicate points are merged first (the first occurrence is kept);
- a planar cloud (scipy's furthest-site Delaunay needs full rank in 3-D) uses the 2-D farthest-point
  triangulation in its plane: every triangle of it with circumradius <= rho is a face on both sides;
  across an edge the top face meets the top face of the neighbouring triangle, or, where there is no
  such face, its own bottom face;
- a collinear cloud, or a cloud with no face at all (rho just above half a diametral pair), is the
  spindle of its two extreme points: 2 vertices, 1 edge with no face on either side;
- four or more points on one rho-sphere give faces with the same centre up to rounding; the edges
  between them are zero-width tori (``edge_real`` False).

The same pair of vertices can appear in two edges (the top and bottom diagonals of a flat square).
"Within rho", "the same centre" and "in" are decided with the tolerances below, relative to the
cloud's size D and to rho. Everything is computed in coordinates centred on the cloud, shifted
exactly (rounding then scales with the cloud's size, not with its distance to the origin, and the
difference of two near-duplicate points is exact), and returned in the input frame, in the input's
units.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull, Delaunay, QhullError

from spq.stp.farthest import farthest_distances
from spq.stp.topology import NO_FACE, STPTopology
from spq.validation import as_points

MERGE_TOL = 1e-12  # points closer than this, relative to the cloud's size D, are one point (m/m)
# a cloud thinner than this, relative to D, is planar (m/m): its faces' balls, centred off its plane,
# then miss the points off it by at most that (VERIFY_TOL leaves 10x), where its tetrahedra would be
# flat to 1e-15 and their circumcentres noise (a 1.4e-11 thin cloud of 3000 points)
FLAT_TOL = 1e-10
POWER_TOL = 1e-12  # slack on |x - c|^2 - rho^2, relative to D (D + rho): inside / on a sphere (m^2/m^2)
# two big-sphere centres closer than this, relative to D + rho, coincide (m/m): the rounding of a
# centre (some hundred eps), no more. The torus between two faces that coincide is dropped with the
# cones it gives its two vertices in the STP-BV's regions of directions; a real torus only a little
# wider (box corners just above their circumradius: Q's vertices 1e-11 apart; points on a sphere at
# its enclosing radius: 1e-13 .. 5e-12) must keep them
CENTRE_TOL = 1e-13
# a vertex whose faces all nearly coincide (some of its tori within NEAR_SHARED x CENTRE_TOL, some
# below CENTRE_TOL) keeps all its tori real: the cones of its real tori alone would not bound its
# region
NEAR_SHARED = 1e3
MEB_TOL = 1e-9  # a candidate smallest enclosing ball may miss a point by this, relative to D (m/m)
VERIFY_TOL = 1e-9  # |x - c_f| <= rho + VERIFY_TOL D + ROUNDING_TOL rho + INPUT_ULPS ulp(x) (m/m)
ROUNDING_TOL = 1e-14  # relative rounding of a distance to a centre rho away (50 eps) (m/m)
# the input's own rounding, in units in the last place of its largest coordinate: far from the
# origin it dominates, and a degenerate cloud amplifies it (rings on their enclosing sphere 3500
# sizes off the origin: faces missed points by 3000 ulps)
INPUT_ULPS = 1e4
# |det| of a tetrahedron's unit edge vectors from one vertex: below this its own circumcentre is
# ill-conditioned (1/this amplifies rounding) and qhull's hyperplane gives it instead
WELL_SHAPED = 1e-6
# |det| of the unit edge vectors above which a tetrahedron is solid: its volume's sign, which
# rounding cannot flip, must agree with the orientation its neighbours give it (or the triangulation
# overlaps itself); flatter ones, folded by rounding in qhull's merged facets, need not
SURE_ORIENTATION = 1e-6
# rounds of flipping tetrahedra whose crossing faces miss a point (each is flipped once at most)
MAX_REPAIRS = 256
# a tetrahedron may flip when its squared circumradius is within TIE_BAND D (D + rho) / shape of
# rho^2 (shape: |det| of its unit edge vectors). Points on a sphere at their enclosing radius,
# 264 sizes off the origin, gave radii straddling rho by up to 4e-12 D (D + rho) / shape
TIE_BAND = 1e-10
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
    ctx = _Context(p=p, rho=rho, scale=scale, ulp=float(np.spacing(np.abs(unique).max())))
    mesh = _planar_triangulation(ctx, frame) if rank == 2 else _solid_triangulation(ctx)
    _check_feasible(r, rho, _enclosing_radius(ctx, mesh.candidates()), scale)

    if rank == 2:
        face_tri, sigma = _planar_faces(ctx, mesh)
    else:
        face_tri, sigma = _solid_faces(ctx, mesh)
    if len(face_tri) == 0:
        pair = mesh.candidates().longest_edge(p)
        _check_spindle_holds(ctx, pair)
        return _spindle(unique[pair], source[pair], r, R)
    faces, centres = _face_arrays(ctx, mesh, face_tri, sigma)
    _verify_faces(ctx, faces, centres)
    if rank == 2:
        partner = _pair_planar(mesh, faces, face_tri, sigma)
    else:
        partner = _pair_solid(mesh, faces, face_tri, sigma)
    edges, edge_faces, edge_real = _edges(ctx, faces, centres, partner)

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
    ctx = _Context(p=p, rho=np.inf, scale=scale)
    mesh = _planar_triangulation(ctx, frame) if rank == 2 else _solid_triangulation(ctx)
    return _enclosing_radius(ctx, mesh.candidates())


def _prepared(x: np.ndarray):
    """Distinct points centred on their mean, their size, principal frame and affine rank.

    The shift is the mean rounded to a multiple of the coarsest spacing of the coordinates, so that
    subtracting it is exact for a cloud far from the origin: near-duplicate points keep their exact
    difference (their sliver faces are only well conditioned from it).
    """
    unique, source = merge_duplicates(x, MERGE_TOL)
    if len(unique) < 2:
        raise ValueError(f"points need at least 2 distinct points; got {len(unique)} (from {len(x)} rows)")
    step = np.spacing(np.abs(unique)).max(axis=0)  # powers of two, one per coordinate
    origin = np.round(unique.mean(axis=0) / step) * step
    p = unique - origin
    scale = float(np.linalg.norm(np.ptp(p, axis=0)))
    frame, extent = _principal_frame(p)
    rank = int((extent > FLAT_TOL * scale).sum())
    return unique, source, origin, p, scale, frame, rank


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


# ---------------------------------------------------------------------------------- triangulation

class _Context:
    """The centred points (n, 3), rho, the cloud size D and the spacing ulp of the input's largest
    coordinate, with the tolerances derived from them."""

    def __init__(self, p: np.ndarray, rho: float, scale: float, ulp: float = 0.0):
        self.p, self.rho, self.scale = p, rho, scale
        self.power_tol = POWER_TOL * scale * (scale + rho)
        self.centre_tol = CENTRE_TOL * (scale + rho)
        self.verify_tol = VERIFY_TOL * scale + ROUNDING_TOL * rho + INPUT_ULPS * ulp


class _Mesh:
    """The farthest-point Delaunay triangulation of the hull points, as the construction reads it.

    hull : (h,) point indices it uses. tri : (k, 3) point indices of its triangles, each once, wound
    as seen from their first tetrahedron (solid) or counter-clockwise about the plane's normal
    (planar); o (k, 3), rt2 (k,), m (k, 3): circumcentres, squared circumradii, unit normals of that
    winding. apex : (k, 2) point index of the fourth vertex of the tetrahedra on either side (-1:
    none; planar: none at all). Solid only: simp (K, 4), nb (K, 4) point indices and neighbours of
    the tetrahedra, tid (K, 4) the triangle opposite each vertex, side_a (k,) +-1 the side of m on
    which the first tetrahedron lies, tet (k, 2) the tetrahedra on either side (-1: infinity), and
    centre (K, 3), excess (K,), shape (K,) each tetrahedron's circumcentre, how far out of Q it lies
    (<= 0: in) and how far from flat (see _circumcentres). Planar only: nb2 (k, 3), the triangle
    across the edge opposite each vertex (-1: none).
    """

    def __init__(self, hull, tri, apex, planar: bool):
        self.hull, self.tri, self.apex, self.planar = hull, tri, apex, planar

    def circles(self, p: np.ndarray) -> None:
        self.o, self.rt2, self.m = _circumcircles(p[self.tri[:, 0]], p[self.tri[:, 1]], p[self.tri[:, 2]])

    def candidates(self) -> "_Candidates":
        """The triangles with their apex heights and powers, for the enclosing radius."""
        q = self.p_apex - self.o[:, None, :]
        d = np.einsum("kj,kij->ki", self.m, q)
        has = self.apex >= 0
        e = np.where(has, np.einsum("kij,kij->ki", q, q) - self.rt2[:, None], -np.inf)
        return _Candidates(self.hull, self.tri, self.o, self.rt2, self.m, np.where(has, d, 0.0), e)


class _Candidates:
    """Triangles of the farthest-point triangulation, with their circles and binding apexes.

    hull : (h,) indices of the points the triangulation uses.
    tri : (k, 3) point indices; o (k, 3) circumcentres; rt2 (k,) squared circumradii; m (k, 3) unit
        normals of the winding tri.
    d, e : (k, 2) for the apexes of the (up to two) neighbouring tetrahedra: height over the
        triangle's plane and power(apex, 0) = |apex - o|^2 - rt^2 (e = -inf where there is none).
        The ball centred at o + s m through the triangle holds the apex iff e - 2 s d <= 0.
    """

    def __init__(self, hull, tri, o, rt2, m, d, e):
        self.hull, self.tri, self.o, self.rt2, self.m, self.d, self.e = hull, tri, o, rt2, m, d, e

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
        """The two ends (2,) of the longest edge of the triangulation, for points p (n, 3), the
        smaller index first."""
        pairs = np.concatenate([self.tri[:, [0, 1]], self.tri[:, [1, 2]], self.tri[:, [2, 0]]])
        d = np.linalg.norm(p[pairs[:, 0]] - p[pairs[:, 1]], axis=1)
        return np.sort(pairs[int(np.argmax(d))])


def _circumcircles(a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Circumcentres (k, 3), squared circumradii (k,) and unit normals (k, 3) of triangles (a, b, c).

    The normal is along (b - a) x (c - a). A degenerate triangle gets rt2 = inf. Each triangle is
    solved from its widest corner (the vertex opposite its longest side), turned to the front
    cyclically (which keeps the normal): there the two sides are far from parallel and their cross
    product keeps its precision, also for a sliver between near-duplicate points.
    """
    pts = np.stack([a, b, c], axis=1)  # (k, 3 vertices, 3)
    side = np.stack([((c - b) ** 2).sum(1), ((a - c) ** 2).sum(1), ((b - a) ** 2).sum(1)], axis=1)
    first = np.argmax(side, axis=1)  # opposite the longest side
    turn = (first[:, None] + np.arange(3)) % 3
    a, b, c = (pts[np.arange(len(pts)), turn[:, k]] for k in range(3))
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


def _furthest_delaunay(q: np.ndarray, joggle: bool = False):
    """Simplices (k, d+1), neighbours (k, d+1) and lifted centres (k, d) of the furthest-site
    Delaunay of q (n, d), and whether qhull joggled it.

    scipy's, joggled ('QJ') when asked, when qhull rejects the input (cospherical, in 2-D
    cocircular, input makes it stop with QH6019/QH6154) or when it drops a corner of the hull
    (_keeps_corners); a joggled triangulation is a valid one of points moved by rounding amounts. The lifted centre of a simplex is the centre
    of the sphere of its hyperplane in qhull's lifting (inf where that is vertical): the tetrahedra
    qhull made from one merged facet share it. d + 1 points are their own simplex (qhull needs d + 2
    to lift them); their centre is left nan.
    """
    n, d = q.shape
    if n == d + 1:
        return np.arange(n)[None], np.full((1, n), -1), np.full((1, d), np.nan), False
    tri = None
    if not joggle:
        try:
            tri = Delaunay(q, furthest_site=True)
            if len(tri.coplanar) or not _keeps_corners(q, tri.simplices):
                tri = None
        except QhullError:
            tri = None
    if tri is None:
        joggle = True
        tri = Delaunay(q, furthest_site=True, qhull_options="QJ")
    eq = tri.equations
    with np.errstate(divide="ignore", invalid="ignore"):
        lifted = -eq[:, :d] / (2.0 * eq[:, d:d + 1] * tri.paraboloid_scale)
    lifted[~np.isfinite(lifted).all(axis=1)] = np.inf
    return tri.simplices, tri.neighbors, lifted, joggle


def _keeps_corners(q: np.ndarray, simplices: np.ndarray) -> bool:
    """Whether the points of q (n, d) that the simplices leave out lie on the convex hull of those
    they use (within FLAT_TOL of its size): a point inside a flat facet of the hull may go, a corner
    may not. qhull can leave corners out without listing them as coplanar (points on one sphere:
    it kept 5 of 904, one merged facet)."""
    used = np.unique(simplices)
    if len(used) == len(q):
        return True
    out = np.setdiff1d(np.arange(len(q)), used)
    try:
        eq = ConvexHull(q[used]).equations
    except QhullError:
        return False
    d = q.shape[1]
    size = float(np.linalg.norm(np.ptp(q, axis=0)))
    return bool((q[out] @ eq[:, :d].T + eq[:, d]).max() <= FLAT_TOL * size)


_OTHERS = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])  # the triangle opposite vertex j
# side of vertex j of a positively oriented tetrahedron relative to the normal of the triangle
# _OTHERS[j] (the sign of the permutation (_OTHERS[j], j))
_APEX_SIDE = np.array([-1, 1, -1, 1])


def _solid_triangulation(ctx: _Context, joggle: bool = False) -> _Mesh:
    """The 3-D farthest-point triangulation of the hull points, its triangles, their circles and
    sides, the tetrahedra's consistent orientations and their in/out decisions."""
    p = ctx.p
    hull = ConvexHull(p).vertices
    simp, nb, lifted, joggled = _furthest_delaunay(p[hull], joggle)
    simp = hull[simp]
    K = len(simp)
    tet_a, j_a, tet_b, j_b = [], [], [], []
    for j in range(4):  # the triangle opposite vertex j of each tetrahedron, once per triangle
        nbj = nb[:, j]
        keep = (nbj < 0) | (nbj > np.arange(K))
        t_idx = np.nonzero(keep)[0]
        n_idx = nbj[keep]
        back = np.full(len(t_idx), -1, dtype=np.int64)
        inner = n_idx >= 0
        back[inner] = np.argmax(nb[n_idx[inner]] == t_idx[inner, None], axis=1)
        tet_a.append(t_idx)
        j_a.append(np.full(len(t_idx), j))
        tet_b.append(n_idx)
        j_b.append(back)
    tet_a, j_a, tet_b, j_b = map(np.concatenate, (tet_a, j_a, tet_b, j_b))
    tri = simp[tet_a[:, None], _OTHERS[j_a]]
    tid = np.empty((K, 4), dtype=np.int64)
    tid[tet_a, j_a] = np.arange(len(tri))
    inner = tet_b >= 0
    tid[tet_b[inner], j_b[inner]] = np.nonzero(inner)[0]

    corners = _widest_corner(p, simp)  # (read by both the orientations and the circumcentres)
    orient, conflict = _orientations(corners[2], simp, tet_a, j_a, tet_b, j_b, tri)
    # qhull's merged facets can leave tetrahedra overlapping, or leave some out (the vertical facets
    # of coplanar points in its lifting: flat ones pinch the triangulation's boundary at an edge
    # between four boundary triangles, others dent it): joggled points are in general position
    broken = conflict or not _boundary_is_manifold(tri[~inner]) or not _fills_hull(p, hull, simp)
    if broken and not joggled:
        return _solid_triangulation(ctx, joggle=True)
    if broken:
        raise RuntimeError("the farthest-point triangulation does not fill the convex hull once")

    mesh = _Mesh(hull, tri, np.stack([simp[tet_a, j_a],
                                      np.where(inner, simp[np.maximum(tet_b, 0), np.maximum(j_b, 0)], -1)],
                                     axis=1), planar=False)
    mesh.circles(p)
    mesh.p_apex = p[np.maximum(mesh.apex, 0)]
    mesh.simp, mesh.nb, mesh.tid = simp, nb, tid
    mesh.tet = np.stack([tet_a, tet_b], axis=1)
    mesh.side_a = _APEX_SIDE[j_a] * orient[tet_a]
    mesh.centre, mesh.excess, mesh.shape = _circumcentres(ctx, simp, lifted, corners)
    # a tetrahedron's circumradius is at least each of its triangles': one with a triangle wider than
    # rho is out, whatever its centre says (qhull's, for a flat tetrahedron on three collinear
    # points, comes from joggled points; the triangle read from the true ones has no circle)
    wide = (mesh.rt2[tid] > ctx.rho * ctx.rho + ctx.power_tol).any(axis=1)
    mesh.excess[wide] = np.inf
    return mesh


def _fills_hull(p: np.ndarray, hull: np.ndarray, simp: np.ndarray) -> bool:
    """Whether the tetrahedra's volumes add up to the convex hull's (within rounding)."""
    e = p[simp[:, 1:]] - p[simp[:, :1]]
    total = float(np.abs(np.linalg.det(e)).sum()) / 6.0
    whole = ConvexHull(p[hull]).volume
    scale = float(np.linalg.norm(np.ptp(p[hull], axis=0)))
    return abs(total - whole) <= 1e-9 * whole + 64 * np.finfo(float).eps * len(simp) * scale ** 3


def _boundary_is_manifold(boundary: np.ndarray) -> bool:
    """Whether every edge of the boundary triangles (b, 3) lies in exactly two of them."""
    pairs = np.sort(np.concatenate([boundary[:, [0, 1]], boundary[:, [1, 2]], boundary[:, [2, 0]]]), axis=1)
    # one integer per edge: numpy's unique over rows sorts them as records, ten times slower
    n = int(boundary.max()) + 1 if len(boundary) else 1
    _, count = np.unique(pairs[:, 0].astype(np.int64) * n + pairs[:, 1], return_counts=True)
    return bool((count == 2).all())


def _orientations(vol, simp, tet_a, j_a, tet_b, j_b, tri) -> tuple[np.ndarray, bool]:
    """+-1 per tetrahedron (K,): the orientation of its vertex order, consistent across shared
    triangles (the apexes of two neighbours lie on opposite sides), and whether a clearly solid
    tetrahedron disagrees with its own volume's sign (the triangulation overlaps itself).

    It is propagated from the most solid tetrahedron over the neighbour graph, not read from each
    volume's sign: qhull's triangulation of a merged (cospherical) facet, or of joggled points read
    at their true positions, holds flat tetrahedra folded by rounding, whose volume has the sign of
    noise; their neighbours say which side their apexes are on. vol: the signed volumes of
    _widest_corner.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order

    K = len(simp)
    inner = tet_b >= 0
    a, b = tet_a[inner], tet_b[inner]
    # parity of the triangle's winding in b relative to a: even iff b's order is a rotation of a's
    tb = simp[b[:, None], _OTHERS[j_b[inner]]]
    ta = tri[inner]
    pos0 = np.argmax(ta == tb[:, :1], axis=1)
    pos1 = np.argmax(ta == tb[:, 1:2], axis=1)
    parity = np.where((pos1 - pos0) % 3 == 1, 1, -1)
    # apexes on opposite sides: o_b = -parity * side(j_a) * side(j_b) * o_a
    rel = -parity * _APEX_SIDE[j_a[inner]] * _APEX_SIDE[j_b[inner]]
    link = coo_matrix((np.concatenate([rel, rel]) + 2, (np.concatenate([a, b]), np.concatenate([b, a]))),
                      shape=(K, K)).tocsr()  # rel + 2 in {1, 3}: no stored zeros
    orient = np.zeros(K, dtype=np.int64)
    for root in np.argsort(-np.abs(vol)):
        if orient[root]:
            continue
        order, pred = breadth_first_order(link, root, directed=False, return_predecessors=True)
        orient[root] = 1 if vol[root] >= 0 else -1
        if len(order) == 1:
            continue
        rel_pred = np.asarray(link[pred[order[1:]], order[1:]]).ravel() - 2
        for k, q, s in zip(order[1:], pred[order[1:]], rel_pred):
            orient[k] = s * orient[q]
        if (orient != 0).all():
            break
    solid = np.abs(vol) > SURE_ORIENTATION
    conflict = bool((orient[b] != rel * orient[a]).any() or (orient[solid] * vol[solid] < 0).any())
    return orient, conflict


def _widest_corner(p: np.ndarray, simp: np.ndarray):
    """For each tetrahedron (K, 4 point indices): the unit edge vectors (K, 3, 3) and lengths (K, 3)
    from the vertex where they are farthest from coplanar, the volume's sign times |det| of those
    unit vectors (K,) (+-1 for a right corner, 0 for a flat tetrahedron), and that vertex's position
    in the row (K,).

    From a vertex of a near-duplicate pair the short edge stays exact and square to the others; from
    a far vertex the two edges to the pair are almost parallel.
    """
    parity = (1.0, -1.0, 1.0, -1.0)  # (k, the others in order) against (0, 1, 2, 3)
    best = None
    for k in range(4):
        e = p[simp[:, [j for j in range(4) if j != k]]] - p[simp[:, k]][:, None, :]
        length = np.linalg.norm(e, axis=2)
        unit = e / length[..., None]
        vol = parity[k] * np.linalg.det(unit)
        if best is None:
            best = [unit, length, vol, np.zeros(len(simp), dtype=np.int64)]
            continue
        better = np.abs(vol) > np.abs(best[2])
        best[0][better], best[1][better], best[2][better], best[3][better] = unit[better], length[better], \
            vol[better], k
    return tuple(best)


def _circumcentres(ctx: _Context, simp: np.ndarray, lifted: np.ndarray, corners):
    """Circumcentres (K, 3) of the tetrahedra (inf where there is none), how far each lies out of
    Q (K,): its squared circumradius less rho^2 and the power tolerance (<= 0: in, so that points on
    one rho-sphere count as in), and its shape (K,), |det| of its unit edge vectors.

    The circumcentre is solved from the tetrahedron's own points (from its widest corner, edge
    vectors scaled to unit length, so that a short edge, as between near-duplicate points, costs no
    accuracy) when it is well shaped and not part of a merged facet; otherwise it is qhull's
    (lifted), which the tetrahedra of a merged facet share. The radius is the largest distance to
    its four points, which the centre's rounding can only increase. corners: _widest_corner's.
    """
    p = ctx.p
    unit, length, vol, base = corners
    shape = np.abs(vol)
    v0 = p[simp[np.arange(len(simp)), base]]
    finite = np.isfinite(lifted).all(axis=1)
    _, group, count = np.unique(np.where(finite[:, None], lifted, 0.0), axis=0, return_inverse=True,
                                return_counts=True)
    merged = finite & (count[group.ravel()] > 1)
    own = ((shape > WELL_SHAPED) & ~merged) | np.isnan(lifted).any(axis=1)  # nan: qhull never saw it
    centre = lifted.copy()
    if own.any():
        centre[own] = v0[own] + np.linalg.solve(unit[own], 0.5 * length[own][..., None])[..., 0]
    nan = ~np.isfinite(centre).all(axis=1) & ~own
    if nan.any():
        centre[nan] = np.inf
    with np.errstate(invalid="ignore"):
        r2 = ((p[simp] - centre[:, None, :]) ** 2).sum(axis=2).max(axis=1)
    r2 = np.where(np.isfinite(r2), r2, np.inf)
    return centre, r2 - (ctx.rho * ctx.rho + ctx.power_tol), shape


def _planar_triangulation(ctx: _Context, frame: np.ndarray) -> _Mesh:
    """The 2-D farthest-point triangulation of a planar cloud (in its plane), triangles wound
    counter-clockwise about frame[2], with their neighbours across each edge.

    Every such triangle's circle holds every point, so the centres o + s m hold them for all s.
    """
    p = ctx.p
    q = p @ frame[:2].T
    hull = ConvexHull(q).vertices
    simp, nb, _, _ = _furthest_delaunay(q[hull])
    a, b, c = (q[hull[simp[:, k]]] for k in range(3))
    cw = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) < 0
    simp = np.where(cw[:, None], simp[:, [0, 2, 1]], simp)
    nb = np.where(cw[:, None], nb[:, [0, 2, 1]], nb)
    mesh = _Mesh(hull, hull[simp], np.full((len(simp), 2), -1), planar=True)
    mesh.circles(p)
    mesh.p_apex = np.zeros((len(simp), 2, 3))
    mesh.nb2 = nb
    return mesh


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
        far = float(farthest_distances(pts, centre[k:k + 1])[0])
        if far <= radius[k] + MEB_TOL * ctx.scale:
            return float(max(far, radius[k]))
    raise RuntimeError("no enclosing ball found among the farthest-point Voronoi features")


# ------------------------------------------------------------------------------------------ faces

def _solid_faces(ctx: _Context, mesh: _Mesh) -> tuple[np.ndarray, np.ndarray]:
    """The crossings of the boundary of Q with the Voronoi edges: triangle index (F,) and side (F,)
    +-1 of each face's centre relative to the triangle's normal m.

    Where rounding decided a tetrahedron's in/out against the geometry (circumradii within rounding
    of rho, in clusters of nearly cospherical points), a crossing face's ball misses a point: the
    tetrahedron of that face (the out one first) is flipped if it is within its tie band, and the
    faces around it redone, until every face's ball holds the hull points. Flipping keeps the faces
    closed (closure holds for any decisions); it only moves crossings.
    """
    in_ = mesh.excess <= 0.0
    dips = _dips_into_q(ctx, mesh)
    miss = np.full((len(mesh.tri), 2), np.nan)  # per triangle and side (+m, -m): its ball's miss
    flipped = np.zeros(len(in_), dtype=bool)
    # the rounding of a squared circumradius grows as the tetrahedron flattens (1 / shape)
    band = TIE_BAND * ctx.scale * (ctx.scale + ctx.rho) / np.maximum(mesh.shape, WELL_SHAPED)
    for _ in range(MAX_REPAIRS):
        face_tri, sigma, double = _crossings(mesh, in_, dips)
        col = (sigma < 0).astype(np.int64)
        todo = np.isnan(miss[face_tri, col])
        if todo.any():
            miss[face_tri[todo], col[todo]] = _misses(ctx, mesh, face_tri[todo], sigma[todo])
        bad = miss[face_tri, col] > ctx.verify_tol
        if not bad.any():
            break
        dips[face_tri[bad & double]] = False  # a double crossing is both faces or none
        t = np.unique(face_tri[bad & ~double])
        if len(t) == 0:
            continue
        a, b = mesh.tet[t, 0], mesh.tet[t, 1]
        t_in = np.where(in_[a], a, b)
        t_out = np.where(in_[a], b, a)
        # each tetrahedron flips once at most (no cycles), and only within its tie band; out ones
        # first: a cluster of ties (points on one sphere at its enclosing radius) is one ball
        can = np.append(~flipped & (np.abs(mesh.excess) <= band), False)  # index -1: infinity
        pick = np.where(can[t_out], t_out, np.where(can[t_in], t_in, -1))
        pick = np.unique(pick[pick >= 0])
        if len(pick) == 0:
            break
        in_[pick] = ~in_[pick]
        flipped[pick] = True
    return face_tri, sigma


def _crossings(mesh: _Mesh, in_: np.ndarray, dips: np.ndarray):
    """Faces for the decisions in_ (K,) and the double crossings dips (k,): triangle (F,), side (F,)
    and whether each face is half of a double crossing (F,)."""
    inside = np.append(in_, False)  # index -1: infinity, out
    in_a, in_b = inside[mesh.tet[:, 0]], inside[mesh.tet[:, 1]]
    single = in_a != in_b
    # f grows from the in end to the out end: the crossing is on the in tetrahedron's apex side
    side = np.where(in_a, mesh.side_a, -mesh.side_a)
    double = ~in_a & ~in_b & dips
    t_single = np.nonzero(single)[0]
    t_double = np.nonzero(double)[0]
    face_tri = np.concatenate([t_single, t_double, t_double])
    sigma = np.concatenate([side[t_single], np.ones(len(t_double), np.int64),
                            -np.ones(len(t_double), np.int64)])
    is_double = np.concatenate([np.zeros(len(t_single), bool), np.ones(2 * len(t_double), bool)])
    return face_tri, sigma, is_double


def _misses(ctx: _Context, mesh: _Mesh, face_tri: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """By how much the ball of each face (F,) misses the farthest hull point (<= 0: holds them)."""
    return farthest_distances(ctx.p[mesh.hull], _centres(ctx, mesh, face_tri, sigma)) - ctx.rho


def _dips_into_q(ctx: _Context, mesh: _Mesh) -> np.ndarray:
    """(k,) bool: rt <= rho and the Voronoi edge of the triangle, from one tetrahedron's circumcentre
    to the other's (to infinity on the apex side of the only one), holds both s = -h and s = +h.

    Read from the circumcentres, not from the apexes: the apex of a flat tetrahedron lies on the
    triangle's circle and bounds nothing, while its circumcentre (qhull's) still bounds the edge.
    """
    near = mesh.rt2 <= ctx.rho * ctx.rho + ctx.power_tol
    h = np.sqrt(np.maximum(ctx.rho * ctx.rho - mesh.rt2, 0.0))
    ends = []
    for k in (0, 1):
        tet = mesh.tet[:, k]
        with np.errstate(invalid="ignore"):
            s = np.einsum("ij,ij->i", mesh.centre[np.maximum(tet, 0)] - mesh.o, mesh.m)
        # infinity: the ray runs to the apex side of the only tetrahedron
        ends.append(np.where(tet >= 0, s, mesh.side_a * np.inf))
    lo, hi = np.minimum(*ends), np.maximum(*ends)
    with np.errstate(invalid="ignore"):
        return near & (lo <= -h) & (hi >= h)


def _planar_faces(ctx: _Context, mesh: _Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Every triangle of the planar triangulation with rt <= rho, on both sides."""
    t = np.nonzero(mesh.rt2 <= ctx.rho * ctx.rho + ctx.power_tol)[0]
    return np.concatenate([t, t]), np.concatenate([np.ones(len(t), np.int64), -np.ones(len(t), np.int64)])


def _centres(ctx: _Context, mesh: _Mesh, face_tri: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Big-sphere centres (F, 3) of the faces on triangles face_tri (F,), sides sigma (F,)."""
    h2 = ctx.rho * ctx.rho - mesh.rt2[face_tri]
    if mesh.planar:
        # every point is in the triangle's plane: a centre moved into it by h stays rho from them
        # to second order (h^2 / rho), and top and bottom faces of a circle of radius rho then
        # share it, as they should, instead of splitting by the rounding of sqrt(h^2 ~ 0)
        h2 = np.where(h2 <= ctx.power_tol, 0.0, h2)
    h = np.sqrt(np.maximum(h2, 0.0))
    return mesh.o[face_tri] + (sigma * h)[:, None] * mesh.m[face_tri]


def _face_arrays(ctx: _Context, mesh: _Mesh, face_tri: np.ndarray, sigma: np.ndarray):
    """Faces (F, 3), counter-clockwise from outside, and their big-sphere centres (F, 3)."""
    t = mesh.tri[face_tri]
    # the outward normal points away from the centre: -sigma m, so sigma = +1 reverses (a, b, c)
    faces = np.where((sigma > 0)[:, None], t[:, [0, 2, 1]], t)
    return faces, _centres(ctx, mesh, face_tri, sigma)


def _verify_faces(ctx: _Context, faces: np.ndarray, centres: np.ndarray) -> None:
    """Check the definition: every point within rho (+ tolerance) of every face centre."""
    far = farthest_distances(ctx.p, centres)
    worst = int(np.argmax(far - ctx.rho))
    if far[worst] > ctx.rho + ctx.verify_tol:
        raise RuntimeError(f"face {faces[worst]} has a point at {far[worst]!r} from its centre, "
                           f"more than rho = {ctx.rho!r}")


# ------------------------------------------------------------------------------------------ edges

def _half_edges(faces: np.ndarray):
    """Tails (3F,), heads (3F,) and faces (3F,) of the faces' half-edges, face by face."""
    return faces.ravel(), faces[:, [1, 2, 0]].ravel(), np.repeat(np.arange(len(faces)), 3)


def _pair_solid(mesh: _Mesh, faces: np.ndarray, face_tri: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """For each half-edge a -> b (3F,), the face holding b -> a across the torus of (a, b).

    The face on triangle t with its centre on side sigma bounds the run of out tetrahedra around
    (a, b) that starts at the tetrahedron on side -sigma of t; walking around (a, b) through that
    run (infinity joins the two boundary triangles through (a, b)), the first triangle with a face
    centred away from the current tetrahedron holds the other end of the torus.
    """
    a, b, owner = _half_edges(faces)
    n_tri = len(mesh.tri)
    tface = np.full((n_tri, 2), -1, dtype=np.int64)  # column 0: centre on +m side, 1: on -m side
    tface[face_tri, (sigma < 0).astype(np.int64)] = np.arange(len(faces))
    # boundary triangles through each hull edge: the two of them, keyed by the sorted pair
    boundary = np.nonzero(mesh.tet[:, 1] < 0)[0]
    n_pts = int(mesh.tri.max()) + 1
    bt = mesh.tri[boundary]
    bkey = np.concatenate([np.sort(bt[:, [0, 1]], axis=1), np.sort(bt[:, [1, 2]], axis=1),
                           np.sort(bt[:, [2, 0]], axis=1)])
    bkey = bkey[:, 0] * n_pts + bkey[:, 1]
    btri = np.tile(boundary, 3)
    order = np.argsort(bkey, kind="stable")
    bkey, btri = bkey[order], btri[order]

    t_prev = face_tri[owner].copy()
    s = sigma[owner]
    node = np.where(mesh.side_a[t_prev] == -s, mesh.tet[t_prev, 0], mesh.tet[t_prev, 1])
    partner = np.full(len(a), -1, dtype=np.int64)
    active = np.arange(len(a))
    for _ in range(len(mesh.simp) + 2):
        if len(active) == 0:
            break
        k, tp, u, v = node[active], t_prev[active], a[active], b[active]
        at_inf = k < 0
        t_next = np.empty(len(active), dtype=np.int64)
        side_k = np.empty(len(active), dtype=np.int64)
        # a tetrahedron: its other triangle through (u, v)
        ki = k[~at_inf]
        verts = mesh.simp[ki]
        other = (verts != u[~at_inf, None]) & (verts != v[~at_inf, None])  # the two local j
        j1 = np.argmax(other, axis=1)
        j2 = 3 - np.argmax(other[:, ::-1], axis=1)
        tj1 = mesh.tid[ki, j1]
        j = np.where(tj1 == tp[~at_inf], j2, j1)
        tn = mesh.tid[ki, j]
        t_next[~at_inf] = tn
        side_k[~at_inf] = np.where(mesh.tet[tn, 0] == ki, mesh.side_a[tn], -mesh.side_a[tn])
        # infinity: the other boundary triangle through (u, v); infinity lies opposite its tetrahedron
        if at_inf.any():
            key = np.minimum(u[at_inf], v[at_inf]) * n_pts + np.maximum(u[at_inf], v[at_inf])
            first = np.searchsorted(bkey, key)
            t0, t1 = btri[first], btri[np.minimum(first + 1, len(btri) - 1)]
            tn = np.where(t0 == tp[at_inf], t1, t0)
            t_next[at_inf] = tn
            side_k[at_inf] = -mesh.side_a[tn]
        found = tface[t_next, (side_k > 0).astype(np.int64)]  # the face centred on side -side_k
        done = found >= 0
        partner[active[done]] = found[done]
        go = ~done
        step_from = np.where(at_inf, -1, k)
        nxt = np.where(at_inf, mesh.tet[t_next, 0],
                       np.where(mesh.tet[t_next, 0] == step_from, mesh.tet[t_next, 1], mesh.tet[t_next, 0]))
        node[active[go]] = nxt[go]
        t_prev[active[go]] = t_next[go]
        active = active[go]
    if len(active):
        raise RuntimeError(f"the faces do not close: edge ({a[active[0]]}, {b[active[0]]}) of face "
                           f"{owner[active[0]]} has no face on its other side")
    return partner


def _pair_planar(mesh: _Mesh, faces: np.ndarray, face_tri: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """For each half-edge (3F,), the face across it: the same side's face of the neighbouring
    triangle if it has one (the circle of centres through the edge meets both triangles' axes on
    that side), else the face on the other side of the same triangle (it meets only this axis)."""
    a, b, owner = _half_edges(faces)
    tface = np.full((len(mesh.tri), 2), -1, dtype=np.int64)
    tface[face_tri, (sigma < 0).astype(np.int64)] = np.arange(len(faces))
    t = face_tri[owner]
    s = (sigma[owner] < 0).astype(np.int64)
    verts = mesh.tri[t]
    opposite = np.argmax((verts != a[:, None]) & (verts != b[:, None]), axis=1)
    nbr = mesh.nb2[t, opposite]
    across = np.where(nbr >= 0, tface[np.maximum(nbr, 0), s], -1)
    return np.where(across >= 0, across, tface[t, 1 - s])


def _edges(ctx: _Context, faces: np.ndarray, centres: np.ndarray, partner: np.ndarray):
    """Edges (E, 2), their faces (E, 2) and real flags (E,) from the pairing of the half-edges."""
    a, b, owner = _half_edges(faces)
    # the partner's half-edge b -> a, and that it pairs back
    pf = faces[partner]
    back = np.nonzero((pf == b[:, None]) & (np.roll(pf, -1, axis=1) == a[:, None]))
    if len(back[0]) != len(a):
        h = int(np.setdiff1d(np.arange(len(a)), back[0])[0])
        raise RuntimeError(f"the faces do not close: edge ({a[h]}, {b[h]}) of face {owner[h]} "
                           f"has no face on its other side")
    mate = np.empty(len(a), dtype=np.int64)
    mate[back[0]] = 3 * partner[back[0]] + back[1]
    if not (mate[mate] == np.arange(len(a))).all():
        raise RuntimeError("the faces do not pair up consistently across their edges")
    one = a < b
    edges = np.stack([a[one], b[one]], axis=1)
    edge_faces = np.stack([owner[one], partner[one]], axis=1)
    gap = np.linalg.norm(centres[edge_faces[:, 0]] - centres[edge_faces[:, 1]], axis=1)
    return edges, edge_faces, _real_tori(edges, gap, ctx.centre_tol)


def _real_tori(edges: np.ndarray, gap: np.ndarray, tol: float) -> np.ndarray:
    """(E,) bool: the edges whose faces do not share a centre (gap (E,) > tol), and every edge of a
    vertex that also has a real torus almost as thin (gap <= NEAR_SHARED tol).

    A zero-width torus gives its vertices no cone: that is right at a corner of a cospherical
    polygon, whose sides (clearly real tori) bound the corner's region, and wrong at a vertex among
    faces that all nearly coincide (rounding splits their gaps on either side of tol), whose region
    then has too few bounds.
    """
    real = gap > tol
    thin = real & (gap <= NEAR_SHARED * tol)
    n = int(edges.max()) + 1 if len(edges) else 0
    while True:
        mixed = (np.bincount(edges[thin].ravel(), minlength=n) > 0) & \
            (np.bincount(edges[~real].ravel(), minlength=n) > 0)
        grow = ~real & (mixed[edges[:, 0]] | mixed[edges[:, 1]])
        if not grow.any():
            return real
        real |= grow
        thin |= grow


# ---------------------------------------------------------------------------------------- spindle

def _check_spindle_holds(ctx: _Context, pair: np.ndarray) -> None:
    """No face was found: the hull must be the spindle of `pair`; check that it holds every point."""
    pa, pb = ctx.p[pair[0]], ctx.p[pair[1]]
    half = 0.5 * np.linalg.norm(pb - pa)
    e = (pb - pa) / (2.0 * half)
    q = ctx.p - 0.5 * (pa + pb)
    t = q @ e
    radial = np.linalg.norm(q - np.outer(t, e), axis=1)
    # inside every rho-ball through pa and pb: radial + a <= sqrt(rho^2 - t^2), a = sqrt(rho^2 - half^2),
    # squared: where rho is half the pair's length, sqrt(rho^2 - t^2) is the root of rounding
    a = math.sqrt(max(ctx.rho ** 2 - half ** 2, 0.0))
    excess = ((radial + a) ** 2 + t * t - ctx.rho ** 2) / (2.0 * ctx.rho)
    if (np.abs(t) > half + ctx.verify_tol).any() or excess.max() > ctx.verify_tol:
        raise RuntimeError("no face found, but the points do not fit the spindle of their two "
                           "farthest points")


def _spindle(ends: np.ndarray, source: np.ndarray, r: float, R: float) -> STPTopology:
    """The face-less STP-BV of two points (2, 3), input rows source (2,) in increasing order: two
    small spheres joined by one closed torus."""
    return STPTopology(r=r, R=R, vertices=ends, faces=np.zeros((0, 3), dtype=np.int64),
                       face_centres=np.zeros((0, 3)), edges=np.array([[0, 1]]),
                       edge_faces=np.array([[NO_FACE, NO_FACE]]), edge_real=np.array([True]),
                       source_index=source)
