"""Sphere-torus-patch bounding volume (STP-BV): a strictly convex, C1 hull of a point set."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from spq.kernels import kinds
from spq.kernels import stp_support as ks
from spq.shapes.base import KernelData, Shape, box_centre
from spq.stp.topology import NO_FACE, STPTopology


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


SURFACE_PUSH = 1e-6  # how far past its support plane a point is pushed to find its patch (times the radius)


SAME_CENTRE_REL = 1e-6  # two face centres this close (relative to their distance from the torus's centre) are one
FLAT_EDGE_SIN = 1e-9  # sine below which a face's third corner counts as on a boundary plane
WIDE_ARC_SLACK = 1e-6  # rad: a torus arc wider than pi minus this is split (exactly pi is still a half-space)


def _across(v: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """The unit component of each v (n, 3) across its axis (n, 3)."""
    return _unit(v - np.einsum("ij,ij->i", v, axes)[:, None] * axes)


def _flat_boundary_axes(x, faces, a, b, f1, f2, centre):
    """Unit normals (n, 3) of the boundaries between the faces f1 (a -> b in its winding, owning the
    positive side) and f2 of zero-width tori (a, b), whose big spheres share ``centre``: the plane
    through the centre and the edge, as the faces' regions are the cones of their triangles seen
    from it. Where that plane does not part the two faces' third corners (the centre on the edge's
    line, e.g. the hypotenuse of a right triangle at R's minimum, or in the faces' own plane, e.g. the
    front and back of one triangle) any plane through the edge between the faces will do: the one
    halving the angle between them, or for two faces on one triangle that triangle's plane."""
    e = x[a] - x[b]
    axes = np.cross(e, x[b] - centre)
    third1, third2 = faces[f1].sum(axis=1) - a - b, faces[f2].sum(axis=1) - a - b
    size = np.linalg.norm(axes, axis=1)
    side1 = np.einsum("ij,ij->i", axes, x[third1] - centre)
    side2 = np.einsum("ij,ij->i", axes, x[third2] - centre)
    slack = FLAT_EDGE_SIN * size * np.maximum(np.linalg.norm(x[third1] - centre, axis=1),
                                             np.linalg.norm(x[third2] - centre, axis=1))
    bad = ~((side1 > slack) & (side2 < -slack))
    if bad.any():
        i = np.flatnonzero(bad)
        eu = _unit(e[i])
        t1 = _across(x[third1[i]] - x[b[i]], eu)
        t2 = _across(x[third2[i]] - x[b[i]], eu)
        split = t1 - t2
        n1 = _unit(np.cross(x[b[i]] - x[a[i]], x[third1[i]] - x[a[i]]))  # f1's outward normal
        folded = np.linalg.norm(split, axis=1) <= FLAT_EDGE_SIN
        axes[i] = np.where(folded[:, None], n1, split)
    return _unit(axes)


def _torus_arcs(centres, axes, face_axes, f1, f2, face_centres):
    """Each torus's arc of directions across its axis: (start (T, 3), turn (T, 3), arc (T,) rad).

    It starts at its first face's boundary, pointing away from that face's centre, and turns towards
    the torus's side of the face's plane (turn, a unit vector across the axis) until the second
    face's boundary; a torus missing a face (a spindle) goes the whole turn."""
    T = len(centres)
    both = (f1 != NO_FACE) & (f2 != NO_FACE)
    start = np.zeros((T, 3))
    turn = np.zeros((T, 3))
    arc = np.full(T, 2.0 * np.pi)
    if both.any():
        i = np.flatnonzero(both)
        start[i] = _across(centres[i] - face_centres[f1[i]], axes[i])
        turn[i] = -face_axes[i, 0]  # the torus lies where the face's plane is negative
        end = _across(centres[i] - face_centres[f2[i]], axes[i])
        arc[i] = np.mod(np.arctan2(np.einsum("ij,ij->i", end, turn[i]), np.einsum("ij,ij->i", end, start[i])),
                        2.0 * np.pi)
        # Faces whose centres coincide up to rounding (R at its minimum: Q is a point) leave the
        # arc's side to noise; it is then the short one (an arc of a whole turn less a rounding
        # would need Q's edge to go all round its circle but for a gap of that size)
        chord = np.linalg.norm(face_centres[f1[i]] - face_centres[f2[i]], axis=1)
        size = np.linalg.norm(centres[i] - face_centres[f1[i]], axis=1)
        tiny = chord <= SAME_CENTRE_REL * size
        arc[i[tiny]] = np.minimum(arc[i[tiny]], 2.0 * np.pi - arc[i[tiny]])
    spindle = np.flatnonzero(~both)
    if len(spindle):
        e = axes[spindle]
        fallback = np.where(np.abs(e[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        start[spindle] = _across(fallback, e)
        turn[spindle] = np.cross(e, start[spindle])
    return start, turn, arc


class STPBV(Shape):
    """An STP-BV in its local frame (metres): small spheres of radius r on the vertices, big
    spheres of radius R on the faces, tori on the edges (paper section II, NOTES section 1).

    Build it with :meth:`from_points`, :meth:`from_mesh` or :meth:`from_sch_file`.

    Attributes
    ----------
    topology : STPTopology
    r, R : float
    torus_centres, torus_axes : (T, 3); torus_radii : (T,); torus_edges : (T,) topology edge, in patch
        order: the real tori, then the second halves of those whose arc is wider than half a turn
    torus_start, torus_turn : (T, 3); torus_arc : (T,) each torus patch's arc of directions across its
        axis: from torus_start, turning towards torus_turn, through torus_arc radians
    boundary_axes : (B, 3); boundary_cos : (B,)  every region boundary, stored once
    patch_offsets : (P + 1,); records : (nrec, 3) int: (boundary, side, neighbour patch) per patch
    hull : Polyhedron or None, the convex hull of the small-sphere centres (the underlying PCH)
    hull_to_small : (H,) int, small-sphere index of each hull vertex
    method : 'naive' | 'march' | 'hull', the feature search the solver uses
    """

    def __init__(self, topology: STPTopology, method: str = "hull"):
        topology.check()
        self.topology = topology
        self.r, self.R = float(topology.r), float(topology.R)
        self._build_patches()
        self._build_hull()
        self._kernel = None
        self._aim = None  # aim_point's, made on first use
        self.method = method

    # --- constructors -------------------------------------------------------------------------
    @classmethod
    def from_points(cls, points, r: float, R: float, method: str = "hull") -> "STPBV":
        """STP-BV of a point cloud ((n, 3), metres) with small radius r and big radius R > r.

        Raises ValueError for bad points or radii; if R is too small for the cloud, the message
        gives the smallest admissible R.
        """
        from spq.stp.construction import build_topology

        return cls(build_topology(points, r, R), method)

    @classmethod
    def from_mesh(cls, mesh, r: float, R: float, method: str = "hull") -> "STPBV":
        """STP-BV of a mesh's vertices; ``mesh`` is a path trimesh can load or a trimesh object."""
        from spq.io.mesh import load_mesh_vertices

        return cls.from_points(load_mesh_vertices(mesh), r, R, method)

    @classmethod
    def from_sch_file(cls, path, method: str = "hull") -> "STPBV":
        """Read an STP-BV in the sch-core text format (NOTES section 3)."""
        from spq.io.sch import read_sch_stp

        return cls(read_sch_stp(Path(path)), method)

    def to_sch_file(self, path) -> None:
        """Write this STP-BV in the sch-core text format."""
        from spq.io.sch import write_sch_stp

        write_sch_stp(self.topology, Path(path))

    # --- structure ----------------------------------------------------------------------------
    def _build_patches(self) -> None:
        topo = self.topology
        x = topo.vertices
        V, F = len(x), len(topo.faces)
        rho = topo.rho
        real = np.flatnonzero(topo.edge_real)
        a, b = topo.edges[real, 0], topo.edges[real, 1]
        length = np.linalg.norm(x[a] - x[b], axis=1)
        centres = 0.5 * (x[a] + x[b])
        axes = (x[a] - x[b]) / length[:, None]
        f1, f2 = topo.edge_faces[real, 0], topo.edge_faces[real, 1]
        # the face boundaries' planes, oriented towards the face: a face owns u where u.axis >= 0
        face_axes = np.zeros((len(real), 2, 3))
        for side, (f, u, w) in enumerate(((f1, a, b), (f2, b, a))):
            m = f != NO_FACE
            c = topo.face_centres[f[m]]
            face_axes[m, side] = _unit(np.cross(x[u[m]] - x[w[m]], x[w[m]] - c))
        start, turn, arc = _torus_arcs(centres, axes, face_axes, f1, f2, topo.face_centres)
        # A torus's region is the wedge between its faces' planes, an intersection of two half-spaces,
        # which cannot hold an arc wider than half a turn (a lens-shaped Q at R near its minimum has
        # such edges): such a torus becomes two patches on one geometry, split at its arc's middle.
        wide = np.flatnonzero((arc > np.pi - WIDE_ARC_SLACK) & (f1 != NO_FACE) & (f2 != NO_FACE))
        half = 0.5 * arc[wide]
        middle = np.cos(half)[:, None] * start[wide] + np.sin(half)[:, None] * turn[wide]
        towards_end = np.cos(half)[:, None] * turn[wide] - np.sin(half)[:, None] * start[wide]
        arc[wide] = half
        order = np.concatenate([np.arange(len(real)), wide])  # the second halves' tori last
        self.torus_edges = real[order]
        self.torus_centres, self.torus_axes = centres[order], axes[order]
        self.torus_radii = np.sqrt(np.maximum(rho * rho - 0.25 * length[order] ** 2, 0.0))
        # per torus patch, its arc of directions across the axis: from torus_start, turning towards
        # torus_turn, through torus_arc radians (the tessellation walks it)
        self.torus_start = np.concatenate([start, middle])
        self.torus_turn = np.concatenate([turn, towards_end])
        self.torus_arc = np.concatenate([arc, half])
        T = len(order)
        torus = V + F + np.arange(T)
        second = V + F + len(real) + np.arange(len(wide))
        # Every region boundary, built in bulk (a Python loop over edges took seconds on hulls of a
        # few thousand vertices). Order, as the records and the feature searches expect: per torus
        # patch its face (or middle) boundaries, then its va and vb boundaries; then one boundary per
        # zero-width torus.
        face_axes = face_axes[order]
        neighbours = np.stack([V + f1, V + f2], axis=1)[order]
        present = np.stack([f1 != NO_FACE, f2 != NO_FACE], axis=1)[order]
        n = len(real)
        # the first half keeps face 1 and meets its second half at the middle, which keeps face 2
        face_axes[wide, 1], neighbours[wide, 1] = towards_end, second
        ends = np.stack([a, b], axis=1)[order]
        cos_t = length[order] / (2.0 * rho)
        block_axes = np.concatenate([face_axes, self.torus_axes[:, None], -self.torus_axes[:, None]], axis=1)
        block_cos = np.stack([np.zeros(T), np.zeros(T), cos_t, cos_t], axis=1)
        block_inside = np.concatenate([neighbours, ends], axis=1)
        present = np.concatenate([present, np.ones((T, 2), bool)], axis=1)
        present[n:, 0] = False  # a middle boundary is recorded once, from the first half's side
        flat = np.flatnonzero(~topo.edge_real)
        g1 = topo.edge_faces[flat, 0]
        ga, gb = topo.edges[flat, 0], topo.edges[flat, 1]
        axes = np.concatenate([block_axes[present].reshape(-1, 3),
                               _flat_boundary_axes(x, topo.faces, ga, gb, g1, topo.edge_faces[flat, 1],
                                                   topo.face_centres[g1])])
        coss = np.concatenate([block_cos[present], np.zeros(len(flat))])
        inside = np.concatenate([block_inside[present], V + g1])
        outside = np.concatenate([np.broadcast_to(torus[:, None], present.shape)[present],
                                  V + topo.edge_faces[flat, 1]])
        # a vertex whose tori all have zero width (R at its minimum) owns no direction: an empty
        # region (u.axis >= 2, never) keeps it reachable from its first face
        lonely = np.setdiff1d(np.arange(V), topo.edges[real].ravel()) if F else np.zeros(0, dtype=np.int64)
        if len(lonely):
            first_face = np.full(V, -1, dtype=np.int64)
            first_face[topo.faces[::-1].ravel()] = np.repeat(np.arange(F)[::-1], 3)
            axes = np.concatenate([axes, np.tile([[1.0, 0.0, 0.0]], (len(lonely), 1))])
            coss = np.concatenate([coss, np.full(len(lonely), 2.0)])
            inside = np.concatenate([inside, lonely])
            outside = np.concatenate([outside, V + first_face[lonely]])
        k = np.arange(len(coss))
        # two records per boundary, (patch, boundary, side, neighbour), one from each side
        recs = np.stack([np.stack([inside, k, np.ones_like(k), outside], axis=1),
                         np.stack([outside, k, -np.ones_like(k), inside], axis=1)], axis=1)
        self.boundary_axes = np.ascontiguousarray(axes, dtype=np.float64).reshape(-1, 3)
        self.boundary_cos = np.ascontiguousarray(coss, dtype=np.float64)
        recs = recs.astype(np.int64).reshape(-1, 4)
        order = np.argsort(recs[:, 0], kind="stable")
        recs = recs[order]
        P = V + F + T
        self.patch_offsets = np.zeros(P + 1, dtype=np.int64)
        np.cumsum(np.bincount(recs[:, 0], minlength=P), out=self.patch_offsets[1:])
        self.records = np.ascontiguousarray(recs[:, 1:])

    def _build_hull(self) -> None:
        from spq.shapes.polyhedron import Polyhedron

        x = self.topology.vertices
        try:
            self.hull = Polyhedron.from_points(x)
        except ValueError:  # fewer than 4 points or a flat cloud: the march starts from patch 0
            self.hull = None
            self.hull_to_small = np.zeros(0, dtype=np.int64)
            return
        index = {tuple(p): i for i, p in enumerate(x)}
        self.hull_to_small = np.array([index[tuple(p)] for p in self.hull.vertices], dtype=np.int64)

    def use_hull(self, hull) -> bool:
        """Take the Polyhedron ``hull`` as the underlying hull if it has exactly the vertices of this
        one (in any order): the same polytope, whose cube map (seconds to build for a few thousand
        vertices) a caller may already hold. Returns whether it did; only before kernel_data()."""
        own = self.hull
        if own is None or own is hull or self._kernel is not None or own.vertices.shape != hull.vertices.shape:
            return own is hull
        order_own, order_new = np.lexsort(own.vertices.T), np.lexsort(hull.vertices.T)
        if not np.array_equal(own.vertices[order_own], hull.vertices[order_new]):
            return False
        small = np.empty_like(self.hull_to_small)
        small[order_new] = self.hull_to_small[order_own]
        self.hull, self.hull_to_small = hull, small
        return True

    # --- counts -------------------------------------------------------------------------------
    @property
    def n_small(self) -> int:
        return len(self.topology.vertices)

    @property
    def n_big(self) -> int:
        return len(self.topology.faces)

    @property
    def n_tori(self) -> int:
        return len(self.torus_edges)

    @property
    def n_patches(self) -> int:
        """Feature count: small spheres + big spheres + (real) tori."""
        return self.n_small + self.n_big + self.n_tori

    def counts(self) -> dict:
        return self.topology.counts()

    # --- kernel view --------------------------------------------------------------------------
    @property
    def method(self) -> str:
        return self._method

    @method.setter
    def method(self, name: str) -> None:
        if name not in ks.METHOD_NAMES:
            raise ValueError(f"unknown support method {name!r}; choose one of {ks.METHOD_NAMES}")
        self._method = name
        for kd in (self._kernel or {}).values():
            kd.idata[ks.IDX_METHOD] = ks.METHOD_NAMES.index(name)

    def kernel_data(self, dense: bool = True) -> KernelData:
        """What the kernels see of this STP-BV. dense: its embedded hull's support cube map at the
        denser size (a standalone STP-BV); False: the sparse one, which a robot scene's pools take
        (Polyhedron.kernel_data says why)."""
        if self._kernel is None:
            self._kernel = {}
        if dense not in self._kernel:
            topo = self.topology
            tori = np.hstack([self.torus_centres, self.torus_axes, self.torus_radii[:, None]])
            b = self.records[:, 0]
            planes = np.hstack([self.boundary_axes[b], self.boundary_cos[b, None]])  # each record's own copy
            hull_f = self.hull.vertices if self.hull is not None else np.zeros((0, 3))
            table = self._hull_vertex_table()
            fdata = np.concatenate([[self.r, self.R, topo.rho], topo.vertices.ravel(), topo.face_centres.ravel(),
                                    tori.ravel(), planes.ravel(), table.ravel(), hull_f.ravel()])
            hull_i = self.hull.kernel_data(dense).idata if self.hull is not None else np.zeros(0, dtype=kinds.IDATA_DTYPE)
            o_po = ks.HEADER_SIZE
            o_rec = o_po + len(self.patch_offsets)
            o_map = o_rec + 2 * len(self.records)
            o_hull = o_map + len(self.hull_to_small)
            header = [self.n_small, self.n_big, self.n_tori, len(self.records),
                      ks.METHOD_NAMES.index(self._method), len(self.hull_to_small), o_po, o_rec, o_hull, o_map,
                      table.shape[1] if table.size else 0]
            # the hull last in both arrays: a scene may then store it once for this body's PCH and STP-BV
            idata = np.concatenate([header, self.patch_offsets, self.records[:, 1:].ravel(), self.hull_to_small, hull_i])
            self._kernel[dense] = KernelData(kinds.STP, 0.0, np.ascontiguousarray(fdata, dtype=np.float64),
                                      np.ascontiguousarray(idata, dtype=kinds.IDATA_DTYPE))
        return self._kernel[dense]

    def _hull_vertex_table(self) -> np.ndarray:
        """(H, S, TABLE_RECORD): each hull vertex's small-sphere records as (side * axis, side * cos,
        neighbour patch), padded to S with (0, 0, 0, -1, -1) (layout in spq.kernels.stp_support)."""
        small = self.hull_to_small
        counts = np.diff(self.patch_offsets)[small]
        S = int(counts.max()) if len(small) else 0
        table = np.zeros((len(small), S, ks.TABLE_RECORD))
        table[:, :, 3:] = -1.0
        for h, p in enumerate(small):
            rec = self.records[self.patch_offsets[p]:self.patch_offsets[p + 1]]
            side = rec[:, 1, None].astype(np.float64)
            table[h, :len(rec), 0:3] = side * self.boundary_axes[rec[:, 0]]
            table[h, :len(rec), 3] = side[:, 0] * self.boundary_cos[rec[:, 0]]
            table[h, :len(rec), 4] = rec[:, 2]
        return table

    def bounding_radius(self) -> float:
        topo = self.topology
        return float(np.sqrt((topo.vertices**2).sum(axis=1).max()) + self.r)

    def aim_point(self) -> np.ndarray:
        """See :meth:`Shape.aim_point`: the centre of the box about its points."""
        if self._aim is None:
            self._aim = box_centre(self.topology.vertices)
        return self._aim

    # --- queries ------------------------------------------------------------------------------
    def support(self, directions, method: str | None = None, coherent: bool = False) -> np.ndarray:
        """Support point(s) (local frame, m) along direction(s) (3,) or (m, 3), any length.

        method: 'naive', 'march' or 'hull' (default: this object's method). coherent: warm-start
        each search from the previous direction's patch (as along a smooth path)."""
        from spq.kernels.stp_batch import support_batch

        d = np.asarray(directions, dtype=np.float64)
        single = d.ndim == 1
        d = np.ascontiguousarray(d.reshape(-1, 3))
        if not np.isfinite(d).all():
            raise ValueError("directions must be finite")
        kd = self.kernel_data()
        m = ks.METHOD_NAMES.index(method or self._method) if (method or self._method) in ks.METHOD_NAMES else -1
        if m < 0:
            raise ValueError(f"unknown support method {method!r}; choose one of {ks.METHOD_NAMES}")
        points, _, _ = support_batch(kd.fdata, kd.idata, m, d, coherent)
        return points[0] if single else points

    def support_patches(self, directions, method: str | None = None, coherent: bool = False):
        """(points (m, 3), patches (m,), search steps (m,)) for an (m, 3) array of directions."""
        from spq.kernels.stp_batch import support_batch

        kd = self.kernel_data()
        m = ks.METHOD_NAMES.index(method or self._method)
        d = np.ascontiguousarray(np.asarray(directions, dtype=np.float64).reshape(-1, 3))
        return support_batch(kd.fdata, kd.idata, m, d, coherent)

    def owner_counts(self, directions) -> np.ndarray:
        """For each direction, how many patches' regions hold it (1 everywhere for a sound STP-BV)."""
        from spq.kernels.stp_batch import owner_counts

        kd = self.kernel_data()
        return owner_counts(kd.fdata, kd.idata, np.ascontiguousarray(np.asarray(directions, dtype=np.float64)))

    # --- mesh ---------------------------------------------------------------------------------
    PATCH_KINDS = ("small_sphere", "big_sphere", "torus")

    def patch_kind(self, patches) -> np.ndarray:
        """Kind index (0 small sphere, 1 big sphere, 2 torus; see PATCH_KINDS) of patch indices (n,)."""
        p = np.asarray(patches)
        return np.where(p < self.n_small, 0, np.where(p < self.n_small + self.n_big, 1, 2))

    def to_mesh(self, tolerance: float | None = None):
        """Triangle mesh of this STP-BV, a ``trimesh.Trimesh`` in the local frame (metres).

        Every patch is tessellated within its own region of directions (spq.stp.tessellation: the
        big spheres' spherical triangles subdivided, the tori on (psi, t) grids, the small spheres
        on an even lattice of directions), each sample mapped through the patch's closed-form
        support, so that every vertex lies on the true surface (to rounding, ~1e-16 of the size)
        and the samples follow the patch boundaries. The mesh is the convex hull of these points:
        watertight, convex, inside the STP-BV, triangles counter-clockwise seen from outside. Its
        error is certified (spq.tessellation.hausdorff_bound, from this body's exact support) and
        refined until the Hausdorff distance between mesh and body is at most ``tolerance``:

            0 <= h_STP(u) - h_mesh(u) <= tolerance   for every unit direction u.

        tolerance: metres, default 1e-3 x the bounding radius; ValueError outside [1e-6, 0.5] x the
        bounding radius, or if the mesh would need over a million points.
        ``mesh.vertex_normals``: the exact outward normals of the surface at the vertices.
        ``mesh.metadata``: max_error (the certified bound, m), tolerance (m), face_patch (m,) the
        patch under each triangle's centre (:meth:`surface_patches`), face_kind (m,) its kind
        ('small_sphere', 'big_sphere', 'torus'). Export with trimesh: ``mesh.export("link.glb")`` (or .obj, .stl).
        """
        from spq import tessellation as ts
        from spq.stp.tessellation import patch_samples

        radius = self.bounding_radius()
        tol = ts.check_tolerance(tolerance, radius)
        points, normals, _ = patch_samples(self, tol)
        surface = ts.support_mesh(lambda d: self.support(d), points, normals, tol, radius)
        patches = self.surface_patches(surface.vertices[surface.faces].mean(axis=1), surface.face_normals)
        return surface.to_trimesh(tolerance=tol, face_patch=patches,
                                  face_kind=np.array(self.PATCH_KINDS)[self.patch_kind(patches)])

    def surface_patches(self, points, normals) -> np.ndarray:
        """Patch (m,) of the surface point nearest to each of (m, 3) local points near the surface
        (on a mesh's triangle, say), each first pushed just outside along its (m, 3) unit normal
        (past the support plane): the patch that the point's piece of surface lies on. A triangle's
        normal alone would not do: the tori are narrow bands (width about r times the angle between
        the neighbouring faces) whose regions of directions are wide."""
        from spq.query import distances
        from spq.shapes.primitives import Sphere

        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        gap = np.einsum("ij,ij->i", n, self.support(n) - p)
        poses = np.tile(np.eye(4), (len(p), 1, 1))
        poses[:, :3, 3] = p + (np.maximum(gap, 0.0) + SURFACE_PUSH * self.bounding_radius())[:, None] * n
        res = distances(self, Sphere(SURFACE_PUSH * self.bounding_radius() / 2), np.eye(4), poses)
        _, patches, _ = self.support_patches(res.normal)
        return patches

    def __repr__(self) -> str:
        return (f"STPBV(r={self.r}, R={self.R}: {self.n_small} small spheres, {self.n_big} big spheres, "
                f"{self.n_tori} tori)")
