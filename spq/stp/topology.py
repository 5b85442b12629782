"""The combinatorial description of an STP-BV, shared by construction, file I/O and the shape.

An STP-BV (NOTES section 1) is the ball hull of its small-sphere centres at radius rho = R - r,
grown by r. It is fully described by:

- the small-sphere centres x_i (its vertices),
- its faces: triples of vertices (counter-clockwise seen from outside) with the centre c_f of the
  big sphere of radius R that touches their three small spheres,
- its edges: pairs of vertices (a, b) between the two faces (f1, f2) that share them; f1 holds
  a -> b in its winding, f2 holds b -> a. An edge whose two faces have the same big-sphere centre
  has a zero-width torus: it is kept (file formats list it, flagged 0) but is not a patch.

Everything else (torus circles, region boundaries, the patch graph) follows from these.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

NO_FACE = -1  # edge_faces entry of a spindle edge, which has no face on that side


@dataclass(eq=False)
class STPTopology:
    """Vertices, faces and edges of an STP-BV (all coordinates in the local frame, metres).

    r, R : small and big radius, 0 < r < R.
    vertices : (V, 3) small-sphere centres.
    faces : (F, 3) int, vertex indices, counter-clockwise seen from outside.
    face_centres : (F, 3) big-sphere centres.
    edges : (E, 2) int, vertex indices (a, b).
    edge_faces : (E, 2) int, (f1, f2): f1 has a -> b in its winding, f2 has b -> a; NO_FACE where
        there is no face (the spindle, whose single torus closes on itself).
    edge_real : (E,) bool, False for a zero-width torus (f1 and f2 share a centre).
    source_index : (V,) int, index of each vertex in the point cloud it was built from (-1 if
        unknown, e.g. read from a file).
    """

    r: float
    R: float
    vertices: np.ndarray
    faces: np.ndarray
    face_centres: np.ndarray
    edges: np.ndarray
    edge_faces: np.ndarray
    edge_real: np.ndarray
    source_index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __post_init__(self):
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int64).reshape(-1, 3)
        self.face_centres = np.ascontiguousarray(self.face_centres, dtype=np.float64).reshape(-1, 3)
        self.edges = np.ascontiguousarray(self.edges, dtype=np.int64).reshape(-1, 2)
        self.edge_faces = np.ascontiguousarray(self.edge_faces, dtype=np.int64).reshape(-1, 2)
        self.edge_real = np.ascontiguousarray(self.edge_real, dtype=bool).reshape(-1)
        if len(self.source_index) == 0:
            self.source_index = np.full(len(self.vertices), -1, dtype=np.int64)

    @property
    def rho(self) -> float:
        return self.R - self.r

    def counts(self) -> dict:
        """Numbers of small spheres, big spheres, real tori and zero-width tori."""
        return {"small_spheres": len(self.vertices), "big_spheres": len(self.faces),
                "tori": int(self.edge_real.sum()), "degenerate_tori": int((~self.edge_real).sum())}

    def check(self) -> None:
        """Raise ValueError if the arrays are inconsistent (indices, winding, shared edges)."""
        V, F, E = len(self.vertices), len(self.faces), len(self.edges)
        if not (0.0 < self.r < self.R) or not np.isfinite([self.r, self.R]).all():
            raise ValueError(f"need 0 < r < R; got r = {self.r}, R = {self.R}")
        if F and (self.faces.min() < 0 or self.faces.max() >= V):
            raise ValueError("faces index vertices out of range")
        if E and (self.edges.min() < 0 or self.edges.max() >= V):
            raise ValueError("edges index vertices out of range")
        if E and (self.edge_faces.min() < NO_FACE or self.edge_faces.max() >= F):
            raise ValueError("edge_faces index faces out of range")
        if len(self.face_centres) != F or len(self.edge_faces) != E or len(self.edge_real) != E:
            raise ValueError("faces/face_centres and edges/edge_faces/edge_real must have matching lengths")
        for k, ((a, b), (f1, f2)) in enumerate(zip(self.edges, self.edge_faces)):
            for f, (u, w) in ((f1, (a, b)), (f2, (b, a))):
                if f == NO_FACE:
                    continue
                tri = list(self.faces[f])
                i = tri.index(u) if u in tri else -1
                if i < 0 or tri[(i + 1) % 3] != w:
                    raise ValueError(f"edge {k} ({a}, {b}) is not {u} -> {w} in face {f} {tri}")
