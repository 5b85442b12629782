"""Triangle meshes of convex bodies from their support maps, with a certified error.

A convex body K is known here through its support map s(u): the point of K farthest along the unit
direction u, which lies on K's surface and has u as its outward normal there. A mesh is built as the
convex hull P of such surface points, so that

- every vertex lies on the true surface (exactly, up to rounding: about 1e-16 of the body's size),
- the mesh is watertight and convex, its triangles wound counter-clockwise seen from outside,
- P lies inside K, and the Hausdorff distance between P and K is certified after construction
  (:func:`hausdorff_bound`) and refined until it is at most the tolerance asked for.

The certificate. For P inside K the Hausdorff distance is max over unit u of h_K(u) - h_P(u), with h
the support functions. Over the normal cone of a vertex p of P, h_P(u) = u.p, and g(u) = h_K(u) - u.p
is convex and positively homogeneous, >= 0. The cone is spanned by the normals of the faces around
p; it is cut into spherical triangles (a fan from its centre direction, subdivided until every
triangle spans at most CONE_ANGLE), and on a triangle with corners n1, n2, n3 whose pairwise
angles are at most beta, any unit u = l1 n1 + l2 n2 + l3 n3 (l >= 0) has l1 + l2 + l3 <= 1/cos(beta),
so g(u) <= max g(n_k) / cos(beta). Every g(n_k) is computed exactly from the support map. Points
where the bound is largest are added (the support points of the worst corners) and the hull is
rebuilt, until the bound holds.

Frames and units: everything is in the body's local frame, in metres.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

CONE_ANGLE = 0.4  # rad: largest angle spanned by a piece of a vertex's normal cone in the bound (1/cos = 1.09)
CONE_DEPTH = 12  # most halvings of a cone piece (0.4 rad is reached from pi in 3)
MAX_ROUNDS = 40  # refinement rounds (each adds the support points of the worst directions)
MAX_POINTS = 1_000_000  # surface points a mesh may use: beyond, the tolerance is too fine for the body
MIN_REL_TOLERANCE = 1e-6  # tolerance / body radius below which a mesh would need too many points
MAX_REL_TOLERANCE = 0.5  # tolerance / body radius above which the 'mesh' says nothing about the body
DEFAULT_REL_TOLERANCE = 1e-3  # a mesh's default tolerance, times the body's bounding radius (0.1 mm at 0.1 m)
LATTICE_COVER = 2.75  # covering angle of an n-point Fibonacci lattice, times sqrt(n) (rad; measured: 2.73)
MERGE = 1e-9  # points closer than this (times the body's radius) are one: patch boundaries give twins
ROUNDING = 1e-12  # relative slack on the certificate: points computed in floating point (m/m of the radius)

Support = Callable[[np.ndarray], np.ndarray]  # (n, 3) unit directions -> (n, 3) support points, local frame


@dataclass(frozen=True, eq=False)
class SurfaceMesh:
    """A certified mesh of a convex body (local frame, metres).

    vertices (n, 3) on the true surface; faces (m, 3) int, counter-clockwise seen from outside;
    normals (n, 3): the outward unit normal of the true surface at each vertex (the direction whose
    support point it is); face_normals (m, 3) outward unit; max_error: certified bound (m) on the
    Hausdorff distance between the mesh and the body (the mesh lies inside the body); rounds: hull
    rebuilds the refinement took."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    face_normals: np.ndarray
    max_error: float
    rounds: int

    def to_trimesh(self, **metadata):
        """The mesh as a ``trimesh.Trimesh`` (vertices and faces as they are, the exact surface
        normals as its vertex normals); ``metadata`` plus max_error (m) go into ``mesh.metadata``."""
        import trimesh

        mesh = trimesh.Trimesh(vertices=self.vertices, faces=self.faces, vertex_normals=self.normals,
                               process=False, validate=False)
        mesh.metadata.update(max_error=self.max_error, **metadata)
        return mesh


def check_tolerance(tolerance, radius: float) -> float:
    """``tolerance`` (m) as a float within [MIN_REL_TOLERANCE, MAX_REL_TOLERANCE] x the body's
    bounding radius (m), or ValueError naming the admissible range; None gives
    DEFAULT_REL_TOLERANCE x the radius."""
    if tolerance is None:
        return DEFAULT_REL_TOLERANCE * radius
    try:
        tol = float(tolerance)
    except (TypeError, ValueError):
        raise ValueError(f"tolerance must be a distance in metres; got {tolerance!r}") from None
    lo, hi = MIN_REL_TOLERANCE * radius, MAX_REL_TOLERANCE * radius
    if not (math.isfinite(tol) and lo <= tol <= hi):
        raise ValueError(f"tolerance must lie in [{lo:.3g}, {hi:.3g}] m for this body (between "
                         f"{MIN_REL_TOLERANCE:g} and {MAX_REL_TOLERANCE:g} times its bounding radius "
                         f"{radius:.3g} m); got {tolerance!r}")
    return tol


def fibonacci_directions(n: int) -> np.ndarray:
    """(n, 3) unit vectors spread evenly over the sphere (a Fibonacci lattice); the largest angle from
    any unit vector to its nearest lattice point is about 2.1 / sqrt(n) rad."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = math.pi * (3.0 - math.sqrt(5.0)) * k
    rho = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    return np.column_stack([rho * np.cos(phi), rho * np.sin(phi), z])


def lattice_size(angle: float, limits: tuple[int, int]) -> int:
    """Points of a Fibonacci lattice whose covering angle is about ``angle`` (rad), within limits."""
    return int(np.clip(math.ceil((LATTICE_COVER / angle) ** 2), *limits))


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def hull(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Convex hull of (n, 3) points: (used (k,) indices into points, faces (m, 3) indexing the used
    points, planes (m, 4): outward unit normal n and offset d with n.x = d on the face). Triangles
    are wound counter-clockwise seen from outside; qhull's planes are kept (fitted to merged facets,
    exact where a sliver triangle's cross product is not)."""
    try:
        h = ConvexHull(points, qhull_options="Qt")
    except QhullError as exc:
        raise ValueError(f"qhull could not build a hull from the surface points: {exc}".splitlines()[0]) from None
    used = np.unique(h.simplices)
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    faces = remap[h.simplices]
    normal, offset = h.equations[:, :3], -h.equations[:, 3]
    a, b, c = (points[used][faces[:, k]] for k in range(3))
    flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), normal) < 0
    faces[flip, 1], faces[flip, 2] = faces[flip, 2], faces[flip, 1].copy()
    return used, faces, np.column_stack([normal, offset])


def _edge_twins(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every directed edge (a -> b) of every face f: (a, f, g) with g the face holding b -> a."""
    m = len(faces)
    start = faces.ravel()
    end = faces[:, [1, 2, 0]].ravel()
    face = np.repeat(np.arange(m), 3)
    n = int(faces.max()) + 1
    key = start.astype(np.int64) * n + end
    twin_key = end.astype(np.int64) * n + start
    order = np.argsort(key)
    pos = np.searchsorted(key[order], twin_key)
    pos = np.minimum(pos, len(order) - 1)
    twin = order[pos]
    if not np.array_equal(key[twin], twin_key):
        raise RuntimeError("hull is not a closed manifold: an edge has no twin")
    return start, face, face[twin]


def hausdorff_bound(vertices: np.ndarray, faces: np.ndarray, planes: np.ndarray, support: Support,
                    want_directions: float | None = None) -> tuple[float, np.ndarray]:
    """Certified bound (m) on the Hausdorff distance between the convex hull P of ``vertices`` (points
    of a convex body K, (n, 3)) and K itself, from K's support map (see the module docstring).

    faces (m, 3) and planes (m, 4) as :func:`hull` returns them. Returns (bound, directions): with
    ``want_directions`` = e (m), the unit directions (k, 3) whose support points would tighten the
    bound where it exceeds e (empty otherwise)."""
    normal = planes[:, :3]
    h_face = np.einsum("ij,ij->i", normal, support(normal))
    vertex, f, g = _edge_twins(faces)
    centre = np.zeros_like(vertices)
    np.add.at(centre, faces.ravel(), np.repeat(normal, 3, axis=0))
    centre = unit(centre)
    h_centre = np.einsum("ij,ij->i", centre, support(centre))
    p = vertices[vertex]
    # fan pieces of each vertex's normal cone: (centre, n_f, n_g) with g = h_K(u) - u.p at each corner
    corners = np.stack([centre[vertex], normal[f], normal[g]], axis=1)  # (k, 3, 3)
    values = np.stack([h_centre[vertex] - np.einsum("ij,ij->i", centre[vertex], p),
                       h_face[f] - np.einsum("ij,ij->i", normal[f], p),
                       h_face[g] - np.einsum("ij,ij->i", normal[g], p)], axis=1)
    owner = np.arange(len(vertex))
    cos_limit = math.cos(CONE_ANGLE)
    bounds, worst = [], []
    for depth in range(CONE_DEPTH + 1):
        cos_beta = np.min(np.stack([np.einsum("ij,ij->i", corners[:, 0], corners[:, 1]),
                                    np.einsum("ij,ij->i", corners[:, 1], corners[:, 2]),
                                    np.einsum("ij,ij->i", corners[:, 2], corners[:, 0])], axis=1), axis=1)
        done = (cos_beta >= cos_limit) | (depth == CONE_DEPTH)
        gmax = np.maximum(values[done].max(axis=1), 0.0)
        with np.errstate(divide="ignore"):
            piece = np.where(cos_beta[done] > 0.0, gmax / np.maximum(cos_beta[done], 0.0), np.inf)
        bounds.append(piece)
        if want_directions is not None:
            bad = piece > want_directions
            k = np.argmax(values[done][bad], axis=1)
            worst.append(corners[done][bad][np.arange(len(k)), k])
        corners, values, owner = corners[~done], values[~done], owner[~done]
        if len(corners) == 0:
            break
        # split each remaining piece in four at its normalised edge midpoints
        mid = unit(np.stack([corners[:, 0] + corners[:, 1], corners[:, 1] + corners[:, 2],
                             corners[:, 2] + corners[:, 0]], axis=1))
        flat = mid.reshape(-1, 3)
        pts = np.repeat(vertices[vertex[owner]], 3, axis=0)
        g_mid = (np.einsum("ij,ij->i", flat, support(flat)) - np.einsum("ij,ij->i", flat, pts)).reshape(-1, 3)
        c0, c1, c2 = corners[:, 0], corners[:, 1], corners[:, 2]
        m01, m12, m20 = mid[:, 0], mid[:, 1], mid[:, 2]
        v0, v1, v2 = values[:, 0], values[:, 1], values[:, 2]
        w01, w12, w20 = g_mid[:, 0], g_mid[:, 1], g_mid[:, 2]
        corners = np.concatenate([np.stack(t, axis=1) for t in
                                  ((c0, m01, m20), (m01, c1, m12), (m20, m12, c2), (m01, m12, m20))])
        values = np.concatenate([np.stack(t, axis=1) for t in
                                 ((v0, w01, w20), (w01, v1, w12), (w20, w12, v2), (w01, w12, w20))])
        owner = np.tile(owner, 4)
    bound = float(max(b.max(initial=0.0) for b in bounds))
    directions = np.concatenate(worst) if worst else np.zeros((0, 3))
    return bound, directions


def merge_close_points(points: np.ndarray, distance: float) -> np.ndarray:
    """Indices of the points to keep so that no two kept points are within ``distance`` (m) (the
    first of each close group stays). Twins from both sides of a patch boundary otherwise make
    zero-area triangles, whose winding no cross product can tell."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(points).query_pairs(distance, output_type="ndarray")
    drop = np.zeros(len(points), dtype=bool)
    for i, j in pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]:
        if not drop[i]:
            drop[j] = True
    return np.flatnonzero(~drop)


def support_mesh(support: Support, points: np.ndarray, normals: np.ndarray, tolerance: float,
                 radius: float) -> SurfaceMesh:
    """Certified mesh of a convex body from its support map and initial surface points.

    support: (n, 3) unit directions -> (n, 3) support points (local frame, m). points (n, 3): points
    on the surface, each the support point of its unit normal in ``normals`` (n, 3). tolerance (m):
    the largest Hausdorff distance accepted between mesh and body; radius (m): the body's bounding
    radius (scales the rounding slack). Adds support points where the certificate is loose and
    rebuilds the hull until it holds; ValueError if that would take more than MAX_POINTS points."""
    slack = ROUNDING * radius
    points, normals = np.asarray(points, dtype=np.float64), unit(np.asarray(normals, dtype=np.float64))
    keep = merge_close_points(points, MERGE * radius)
    points, normals = points[keep], normals[keep]
    for rounds in range(1, MAX_ROUNDS + 1):
        if len(points) > MAX_POINTS:
            raise ValueError(f"a mesh within {tolerance:.3g} m would need more than {MAX_POINTS:,} surface points; "
                             "give a larger tolerance")
        used, faces, planes = hull(points)
        vertices = points[used]
        bound, worst = hausdorff_bound(vertices, faces, planes, support, want_directions=tolerance)
        if bound <= tolerance + slack or rounds == MAX_ROUNDS:
            break
        worst = np.unique(np.round(worst, 12), axis=0)
        points = np.concatenate([vertices, support(worst)])
        normals = np.concatenate([normals[used], worst])
        keep = merge_close_points(points, MERGE * radius)
        points, normals = points[keep], normals[keep]
    if bound > tolerance + slack:  # pragma: no cover - the refinement converges long before
        raise RuntimeError(f"mesh refinement stopped at a certified error of {bound:.3g} m > {tolerance:.3g} m")
    return SurfaceMesh(vertices, faces, normals[used], planes[:, :3].copy(), bound, rounds)
