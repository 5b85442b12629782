"""Polyhedral convex hull bounding volume (PCH-BV)."""

from __future__ import annotations


import numpy as np
from scipy.spatial import ConvexHull, QhullError

from spq.io.mesh import load_mesh_vertices
from spq.io.qhull import read_qhull_off
from spq.kernels import kinds
from spq.kernels.support import cell_candidates, cube_map_idata, cube_map_size
from spq.shapes.base import KernelData, Shape, box_centre
from spq.validation import as_points

FLATNESS_TOL = 1e-9  # smallest/largest singular value of the centred cloud below which it is flat


def _check_full_dimensional(points: np.ndarray) -> None:
    centred = points - points.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[0] == 0.0 or sv[-1] <= FLATNESS_TOL * sv[0]:
        raise ValueError(
            "points are flat or degenerate: a convex polyhedron needs at least 4 affinely independent "
            f"points (singular values of the centred cloud {np.array2string(sv, precision=3)}; "
            f"the smallest must exceed {FLATNESS_TOL:g} x the largest)"
        )


def convex_hull(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """qhull's convex hull of (n, 3) points: (vertices (k, 3), triangles (m, 3) indexing them,
    planes (m, 4) as n.x + offset = 0 with outward unit n). Raises ValueError if qhull fails."""
    try:
        hull = ConvexHull(points)
    except QhullError as exc:
        raise ValueError(f"qhull could not build a hull from these points: {exc}".splitlines()[0]) from None
    used = np.unique(hull.simplices)
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return points[used], remap[hull.simplices], hull.equations


def _csr_adjacency(n: int, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertex adjacency of a triangle mesh as CSR (offsets (n+1,), neighbours), sorted, no repeats."""
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    edges = np.concatenate([edges, edges[:, ::-1]])
    edges = np.unique(edges, axis=0)
    counts = np.bincount(edges[:, 0], minlength=n)
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    return offsets, np.ascontiguousarray(edges[:, 1], dtype=np.int64)


class Polyhedron(Shape):
    """Convex hull of a point set, in the points' own frame (metres).

    Attributes
    ----------
    vertices : (n, 3) float64
        Hull vertices (points strictly inside the hull are dropped).
    faces : (m, 3) int64
        Triangles of the hull, counter-clockwise seen from outside.
    adjacency_offsets, adjacency : int64 arrays
        Vertex adjacency in CSR form: the neighbours of vertex i are
        ``adjacency[adjacency_offsets[i]:adjacency_offsets[i + 1]]``.
    face_normals : (m, 3) float64, face_offsets : (m,) float64
        Outward unit normals n and offsets d of the face planes n.x = d.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, planes: np.ndarray | None = None):
        """From hull vertices, outward triangles and optionally their planes ((m, 4): n, -d with
        n.x + (-d) = 0, as qhull gives them); without planes they come from cross products."""
        self.vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        self.adjacency_offsets, self.adjacency = _csr_adjacency(len(self.vertices), self.faces)
        if planes is None:
            a, b, c = (self.vertices[self.faces[:, k]] for k in range(3))
            normal = np.cross(b - a, c - a)
            self.face_normals = normal / np.linalg.norm(normal, axis=1)[:, None]
            self.face_offsets = np.einsum("ij,ij->i", self.face_normals, a)
        else:
            # qhull's facet planes are fitted to all of a facet's vertices: accurate even for the
            # sliver triangles its triangulation makes, where a cross product is not
            self.face_normals = np.ascontiguousarray(planes[:, :3])
            self.face_offsets = np.ascontiguousarray(-planes[:, 3])
        self._kernel = None
        self._aim = None  # aim_point's, made on first use
        # whether the triangles are qhull's (the boundary of the vertices' convex hull): the cube map
        # is then built by walks over their edges (spq.kernels.support.cell_candidates), which needs
        # that; triangles from elsewhere get the scan, which does not
        self._hull_triangles = False

    # --- constructors -------------------------------------------------------------------------
    @classmethod
    def from_points(cls, points) -> "Polyhedron":
        """Convex hull of ``points`` ((n, 3), metres). Needs 4 affinely independent finite points."""
        pts = as_points(points, "points", min_count=4)
        _check_full_dimensional(pts)
        vertices, faces, planes = convex_hull(pts)
        # qhull's equations are outward; orient each triangle to agree with its facet's normal
        a, b, c = (vertices[faces[:, k]] for k in range(3))
        flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), planes[:, :3]) < 0
        faces[flip, 1], faces[flip, 2] = faces[flip, 2], faces[flip, 1].copy()
        poly = cls(vertices, faces, planes)
        poly._hull_triangles = True
        return poly

    @classmethod
    def from_mesh(cls, mesh) -> "Polyhedron":
        """Convex hull of a mesh's vertices; ``mesh`` is a path trimesh can load or a trimesh object."""
        return cls.from_points(load_mesh_vertices(mesh))

    @classmethod
    def from_qhull_file(cls, path) -> "Polyhedron":
        """Convex hull of the points that the facets of a qhull ``o f`` file use (NOTES section 3)."""
        points, facets = read_qhull_off(path)
        used = np.unique(np.concatenate(facets)) if facets else np.arange(len(points))
        return cls.from_points(points[used])

    # --- kernel view --------------------------------------------------------------------------
    def kernel_data(self, dense: bool = True) -> KernelData:
        """What the kernels see of this hull. dense: the support's cube map with cube_map_size's denser
        cells (a standalone hull, or the hull embedded in a standalone STP-BV); False: the sparse one,
        which a robot scene's pools take (spq.kernels.support.cube_map_size)."""
        if self._kernel is None:
            self._kernel = {}
        if dense not in self._kernel:
            n = len(self.vertices)
            G = cube_map_size(n, kinds.CUBE_MAP_CELLS, dense)
            graph = (self.adjacency_offsets, self.adjacency) if self._hull_triangles else None
            idata = cube_map_idata(n, G, *cell_candidates(self.vertices, G, graph)).astype(kinds.IDATA_DTYPE)
            self._kernel[dense] = KernelData(kinds.POLYTOPE, 0.0, self.vertices.ravel().copy(), idata)
        return self._kernel[dense]

    def bounding_radius(self) -> float:
        return float(np.sqrt((self.vertices**2).sum(axis=1).max()))

    def aim_point(self) -> np.ndarray:
        """See :meth:`Shape.aim_point`: the centre of the box about its points."""
        if self._aim is None:
            self._aim = box_centre(self.vertices)
        return self._aim

    def to_mesh(self):
        """This hull as a ``trimesh.Trimesh`` (local frame, metres): its vertices and outward
        triangles as they are (watertight, exact: ``mesh.metadata['max_error']`` is 0). Export with
        ``mesh.export("hull.glb")`` (or .obj, .stl)."""
        import trimesh

        mesh = trimesh.Trimesh(vertices=self.vertices.copy(), faces=self.faces.copy(), process=False, validate=False)
        mesh.metadata.update(max_error=0.0, tolerance=0.0)
        return mesh

    def signed_distance_to_surface(self, points) -> np.ndarray:
        """Signed distance (m) of local-frame points to the hull boundary: > 0 outside, < 0 inside.

        Exact inside; outside it is the largest face-plane excess, a lower bound that is exact for
        points whose nearest feature is a face (used to check witness points, which lie on it).
        """
        p = np.atleast_2d(np.asarray(points, dtype=np.float64))
        return (p @ self.face_normals.T - self.face_offsets).max(axis=1)

    def __repr__(self) -> str:
        return f"Polyhedron({len(self.vertices)} vertices, {len(self.faces)} faces)"
