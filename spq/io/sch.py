"""Reader and writer of the sch-core STP-BV text format (NOTES section 3).

Layout, one record per line (blank lines are ignored, CRLF is accepted)::

    r R
    V                                   small spheres (patch indices 0..V-1)
      V times:  r cx cy cz
                k                       number of real tori at this vertex
                k lines: torusIndex cos ax ay az
    F                                   big spheres (patch indices V..V+F-1)
      F times:  R cx cy cz
                x1 y1 z1 x2 y2 z2 x3 y3 z3
                3 lines: index nx ny nz     index: a real torus, or the neighbouring big sphere
                                            when the torus between them is degenerate
    E                                   tori (real ones: patch indices V+F.., in order)
      E times:  flag                    1 real, 0 degenerate (no patch index)
                a R mx my mz ex ey ez
                smallIndexA cos ax ay az
                smallIndexB cos ax ay az
                bigIndex1 nx ny nz
                bigIndex2 nx ny nz

Only the topology is kept (:class:`~spq.stp.topology.STPTopology`): vertices, faces, face centres,
edges with their faces and the real/degenerate flag. Every other number in the file (cone cosines
and axes, plane normals, torus circles) follows from it; the reader recomputes them and checks the
file against them (:func:`sch_stp_discrepancies` gives the differences), the writer recomputes them.
Lengths are in the file's unit (metres in this project); cosines and axes are dimensionless.

Conventions recovered from the reference files (and used by the writer):

- cone of vertex i towards its neighbour j: axis (x_i - x_j) / l, cos = l / (2 rho), l = |x_i - x_j|;
- plane of face f for its edge (u, w) in the face's winding: normal normalize((x_u - c_f) x (x_w - c_f))
  (it points into the face's region); a torus record repeats each face's own normal;
- torus of edge (a, b) (a = first cone line): centre (x_a + x_b) / 2, axis (x_a - x_b) / l,
  circle radius sqrt(rho^2 - l^2 / 4); its first plane line is the face holding a -> b;
- a torus flagged 0 lies between two faces with the same big-sphere centre; the vertices do not list it.

The five shared reference files also list each triangle counter-clockwise seen from outside; the
reader does not rely on it (it orients each face so that its normal points from c_f to the face).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spq.stp.topology import NO_FACE, STPTopology

# The sch-core samples print 6 significant digits (the C++ stream default), so the derived numbers
# they hold agree with recomputed ones only to about 1e-6 relative, and short edges amplify the
# rounding of the coordinates in the cone axes and plane normals (up to 7e-4 seen). The tolerances
# catch wrong indices and conventions (differences of order 1), not rounding.
DERIVED_TOL_UNIT = 5e-3  # cone axes, plane normals, torus axes (dimensionless, per component)
DERIVED_TOL_COS = 1e-4  # cone cosines
DERIVED_TOL_REL = 1e-4  # lengths, relative to r (small radii), R (big, tube and circle radii,
#                         |x_v - c_f| - rho, centre gaps) or the largest |coordinate| (positions)


class _Lines:
    """The non-blank lines of a file, split into tokens, read one record line at a time."""

    def __init__(self, path: Path, text: str):
        self.path = path
        self.rows = [(i + 1, ln.split()) for i, ln in enumerate(text.splitlines()) if ln.strip()]
        self.pos = 0
        self.last_line = self.rows[-1][0] if self.rows else 0

    def fail(self, lineno: int, problem: str):
        raise ValueError(f"{self.path}:{lineno}: {problem}")

    def next(self, ntok: int, what: str) -> tuple[int, list[str]]:
        if self.pos >= len(self.rows):
            self.fail(self.last_line + 1, f"file truncated: expected {what}")
        lineno, tok = self.rows[self.pos]
        self.pos += 1
        if len(tok) != ntok:
            self.fail(lineno, f"expected {ntok} value(s) '{what}', got {len(tok)}: {' '.join(tok)!r}")
        return lineno, tok

    def count(self, what: str) -> tuple[int, int]:
        lineno, tok = self.next(1, what)
        n = self.to_int(lineno, tok[0], what)
        if n < 0:
            self.fail(lineno, f"{what} must be >= 0, got {n}")
        return lineno, n

    def to_int(self, lineno: int, tok: str, what: str) -> int:
        try:
            return int(tok)
        except ValueError:
            self.fail(lineno, f"{what}: expected an integer, got {tok!r}")

    def to_floats(self, lineno: int, toks: list[str], what: str) -> np.ndarray:
        try:
            vals = np.array([float(t) for t in toks])
        except ValueError:
            self.fail(lineno, f"{what}: expected numbers, got {' '.join(toks)!r}")
        if not np.isfinite(vals).all():
            self.fail(lineno, f"{what}: NaN or infinite value in {' '.join(toks)!r}")
        return vals

    def index_line(self, what: str) -> tuple[int, int, np.ndarray]:
        """A line 'index x1 .. xk' (k = 3 or 4 numbers after the index, given by ``what``)."""
        nnum = len(what.split()) - 1
        lineno, tok = self.next(1 + nnum, what)
        return lineno, self.to_int(lineno, tok[0], what), self.to_floats(lineno, tok[1:], what)


@dataclass
class _SchFile:
    """Everything a file holds, as read (indices global, as in the file), with line numbers."""

    path: Path
    count_lines: list  # lines of V, F, E
    r: float
    R: float
    small_r: np.ndarray  # (V,)
    small_c: np.ndarray  # (V, 3)
    small_line: np.ndarray  # (V,) line of each small-sphere record
    small_tori: list  # per vertex: list of (line, torusIndex, [cos, ax, ay, az])
    big_R: np.ndarray  # (F,)
    big_c: np.ndarray  # (F, 3)
    big_tri: np.ndarray  # (F, 3, 3) triangle coordinates
    big_line: np.ndarray  # (F,)
    big_bounds: list  # per face: list of 3 (line, index, normal(3,))
    tor_flag: np.ndarray  # (E,) int
    tor_line: np.ndarray  # (E,) line of the flag
    tor_circle: np.ndarray  # (E, 8): a, R, m(3), e(3)
    tor_cones: list  # per torus: 2 (line, smallIndex, [cos, ax, ay, az])
    tor_planes: list  # per torus: 2 (line, bigIndex, normal(3,))


def _parse(path: Path) -> _SchFile:
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read sch STP-BV file: {exc}") from None
    L = _Lines(path, text)
    lineno, tok = L.next(2, "r R")
    r, R = (float(v) for v in L.to_floats(lineno, tok, "r R"))
    if not (r > 0.0 and R > r):
        L.fail(lineno, f"need 0 < r < R, got r = {r!r}, R = {R!r}")

    count_lines = []
    lineno, V = L.count("V (number of small spheres)")
    count_lines.append(lineno)
    small_r, small_c, small_line, small_tori = np.empty(V), np.empty((V, 3)), np.empty(V, int), []
    for i in range(V):
        lineno, tok = L.next(4, "r cx cy cz")
        vals = L.to_floats(lineno, tok, f"small sphere {i}")
        small_r[i], small_c[i], small_line[i] = vals[0], vals[1:], lineno
        if vals[0] <= 0.0:
            L.fail(lineno, f"small sphere {i}: radius must be positive, got {float(vals[0])!r}")
        _, k = L.count(f"number of tori at small sphere {i}")
        small_tori.append([L.index_line("torusIndex cos ax ay az") for _ in range(k)])

    lineno, F = L.count("F (number of big spheres)")
    count_lines.append(lineno)
    big_R, big_c, big_tri = np.empty(F), np.empty((F, 3)), np.empty((F, 3, 3))
    big_line, big_bounds = np.empty(F, int), []
    for f in range(F):
        lineno, tok = L.next(4, "R cx cy cz")
        vals = L.to_floats(lineno, tok, f"big sphere {V + f}")
        big_R[f], big_c[f], big_line[f] = vals[0], vals[1:], lineno
        if vals[0] <= 0.0:
            L.fail(lineno, f"big sphere {V + f}: radius must be positive, got {float(vals[0])!r}")
        lineno, tok = L.next(9, "x1 y1 z1 x2 y2 z2 x3 y3 z3")
        big_tri[f] = L.to_floats(lineno, tok, f"big sphere {V + f} triangle").reshape(3, 3)
        big_bounds.append([L.index_line("index nx ny nz") for _ in range(3)])

    lineno, E = L.count("E (number of tori)")
    count_lines.append(lineno)
    tor_flag, tor_line, tor_circle = np.empty(E, int), np.empty(E, int), np.empty((E, 8))
    tor_cones, tor_planes = [], []
    for k in range(E):
        lineno, tok = L.next(1, "flag")
        flag = L.to_int(lineno, tok[0], f"torus record {k} flag")
        if flag not in (0, 1):
            L.fail(lineno, f"torus record {k}: flag must be 0 or 1, got {flag}")
        tor_flag[k], tor_line[k] = flag, lineno
        lineno, tok = L.next(8, "a R mx my mz ex ey ez")
        tor_circle[k] = L.to_floats(lineno, tok, f"torus record {k} circle")
        tor_cones.append([L.index_line("smallIndex cos ax ay az") for _ in range(2)])
        tor_planes.append([L.index_line("bigIndex nx ny nz") for _ in range(2)])
    if L.pos < len(L.rows):
        lineno, tok = L.rows[L.pos]
        L.fail(lineno, f"unexpected data after the {E} tori: {' '.join(tok)!r}")
    return _SchFile(path, count_lines, float(r), float(R), small_r, small_c, small_line, small_tori, big_R, big_c,
                    big_tri, big_line, big_bounds, tor_flag, tor_line, tor_circle, tor_cones, tor_planes)


def _extent(vertices: np.ndarray) -> float:
    """Largest |coordinate| of the vertices (metres): the scale of position rounding."""
    return float(np.abs(vertices).max()) if len(vertices) else 0.0


def _tolerance(kind: str, topo: STPTopology) -> float:
    """Largest accepted |stored - recomputed| for a kind of derived number (see DERIVED_TOL_*)."""
    if kind in ("cone_axis", "plane_normal", "torus_axis"):
        return DERIVED_TOL_UNIT
    if kind == "cone_cos":
        return DERIVED_TOL_COS
    if kind == "small_radius":
        return DERIVED_TOL_REL * topo.r
    if kind in ("triangle_vertex", "torus_centre"):
        return DERIVED_TOL_REL * _extent(topo.vertices)
    return DERIVED_TOL_REL * topo.R


def _build(raw: _SchFile) -> STPTopology:
    """Recover the topology from the file's records; raise ValueError on inconsistencies."""
    path = raw.path
    V, F, E = len(raw.small_c), len(raw.big_c), len(raw.tor_flag)

    def fail(lineno, problem):
        raise ValueError(f"{path}:{lineno}: {problem}")

    if 2 * E != 3 * F or V - E + F != 2 or F < 2:
        fail(raw.count_lines[2], f"counts V = {V}, F = {F}, E = {E} do not describe a closed triangulated "
             f"surface (need 2E = 3F, V - E + F = 2, F >= 2)")
    n_real = int(raw.tor_flag.sum())
    real_global = np.full(E, -1)
    real_global[raw.tor_flag == 1] = V + F + np.arange(n_real)

    # faces: match the triangle coordinates to the small-sphere centres
    faces = np.empty((F, 3), dtype=np.int64)
    ext = _extent(raw.small_c)
    tol_match = 1e-6 * ext  # the same numbers as the centres, at the same precision
    for f in range(F):
        for j in range(3):
            d = np.linalg.norm(raw.small_c - raw.big_tri[f, j], axis=1)
            i = int(np.argmin(d)) if V else -1
            if i < 0 or d[i] > tol_match:
                fail(raw.big_line[f] + 1, f"big sphere {V + f}: triangle vertex {j + 1} "
                     f"{raw.big_tri[f, j].tolist()} is not a small-sphere centre")
            faces[f, j] = i
        if len(set(faces[f])) != 3:
            fail(raw.big_line[f] + 1, f"big sphere {V + f}: triangle repeats a vertex {faces[f].tolist()}")
        # counter-clockwise seen from outside: the normal points from c_f towards the face
        x = raw.small_c[faces[f]]
        n = np.cross(x[1] - x[0], x[2] - x[0])
        side = float(n @ (x.mean(axis=0) - raw.big_c[f]))
        if side < -1e-12 * (ext + raw.R) ** 3:
            faces[f, 1], faces[f, 2] = faces[f, 2], faces[f, 1]

    directed = {}  # (face, u, w) -> True for the face's winding
    for f in range(F):
        for j in range(3):
            directed[(f, faces[f, j], faces[f, (j + 1) % 3])] = True

    # edges from the torus records
    edges = np.empty((E, 2), dtype=np.int64)
    edge_faces = np.empty((E, 2), dtype=np.int64)
    seen_pairs = {}
    for k in range(E):
        (la, a, _), (lb, b, _) = raw.tor_cones[k]
        (l1, g1, _), (l2, g2, _) = raw.tor_planes[k]
        for ln, i in ((la, a), (lb, b)):
            if not 0 <= i < V:
                fail(ln, f"torus record {k}: small-sphere index {i} outside 0..{V - 1}")
        if a == b:
            fail(lb, f"torus record {k}: both cones name small sphere {a}")
        for ln, g in ((l1, g1), (l2, g2)):
            if not V <= g < V + F:
                fail(ln, f"torus record {k}: big-sphere index {g} outside {V}..{V + F - 1}")
        f1, f2 = g1 - V, g2 - V
        if f1 == f2:
            fail(l2, f"torus record {k}: both planes name big sphere {g1}")
        for ln, f in ((l1, f1), (l2, f2)):
            if a not in faces[f] or b not in faces[f]:
                fail(ln, f"torus record {k}: big sphere {V + f} (vertices {faces[f].tolist()}) does not "
                     f"contain the torus's small spheres {a} and {b}")
        if directed.get((f1, a, b)) and directed.get((f2, b, a)):
            pass
        elif directed.get((f2, a, b)) and directed.get((f1, b, a)):
            f1, f2 = f2, f1
        else:
            fail(l1, f"torus record {k}: big spheres {V + f1} and {V + f2} run through edge ({a}, {b}) "
                 f"in the same direction (inconsistent orientation)")
        key = (min(a, b), max(a, b))
        if key in seen_pairs:
            fail(raw.tor_line[k], f"torus record {k}: edge {key} already given by torus record {seen_pairs[key]}")
        seen_pairs[key] = k
        edges[k] = a, b
        edge_faces[k] = f1, f2

    # every face must be bounded by exactly its three tori, named as the format says
    expected = [[] for _ in range(F)]
    for k in range(E):
        f1, f2 = edge_faces[k]
        if raw.tor_flag[k]:
            expected[f1].append(real_global[k])
            expected[f2].append(real_global[k])
        else:
            expected[f1].append(V + f2)
            expected[f2].append(V + f1)
    for f in range(F):
        got = sorted(idx for _, idx, _ in raw.big_bounds[f])
        if got != sorted(expected[f]):
            fail(raw.big_bounds[f][0][0], f"big sphere {V + f}: boundary indices {got} do not match the "
                 f"torus records, which give {sorted(int(i) for i in expected[f])}")

    # every vertex must list exactly its real tori
    at_vertex = [[] for _ in range(V)]
    for k in np.flatnonzero(raw.tor_flag == 1):
        for i in edges[k]:
            at_vertex[i].append(int(real_global[k]))
    for i in range(V):
        got = sorted(idx for _, idx, _ in raw.small_tori[i])
        if got != sorted(at_vertex[i]):
            ln = raw.small_tori[i][0][0] if raw.small_tori[i] else raw.small_line[i] + 1
            fail(ln, f"small sphere {i}: torus indices {got} do not match the real tori at this vertex "
                 f"in the torus records, {sorted(at_vertex[i])}")

    topo = STPTopology(r=raw.r, R=raw.R, vertices=raw.small_c.copy(), faces=faces,
                       face_centres=raw.big_c.copy(), edges=edges, edge_faces=edge_faces,
                       edge_real=raw.tor_flag == 1)
    try:
        topo.check()
    except ValueError as exc:
        raise ValueError(f"{path}: inconsistent STP-BV: {exc}") from None
    return topo


def _normal(x_u, x_w, c):
    n = np.cross(x_u - c, x_w - c)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def _differences(raw: _SchFile, topo: STPTopology) -> dict:
    """Per kind of stored number: (max abs difference to the recomputed value, line where it occurs)."""
    x, c, rho = topo.vertices, topo.face_centres, topo.rho
    V, F = len(x), len(c)
    out = {}

    def record(kind, diffs, lines):
        diffs = np.asarray(diffs, dtype=float).reshape(-1)
        if len(diffs) == 0:
            return
        j = int(np.argmax(diffs))
        prev = out.get(kind)
        if prev is None or diffs[j] > prev[0]:
            out[kind] = (float(diffs[j]), int(np.asarray(lines).reshape(-1)[j]))

    record("small_radius", np.abs(raw.small_r - topo.r), raw.small_line)
    record("big_radius", np.abs(raw.big_R - topo.R), raw.big_line)
    record("torus_tube_radius", np.abs(raw.tor_circle[:, 1] - topo.R), raw.tor_line + 1)
    if F:
        # triangle coordinates against the matched centres (in file order: match by nearest)
        d = np.linalg.norm(raw.big_tri[:, :, None, :] - x[None, None, :, :], axis=-1).min(axis=2)
        record("triangle_vertex", d.max(axis=1), raw.big_line + 1)
        touch = np.abs(np.linalg.norm(x[topo.faces] - c[:, None, :], axis=-1) - rho)
        record("big_sphere_touch", touch.max(axis=1), raw.big_line)

    edge_of = {}  # unordered pair -> edge index
    for k, (a, b) in enumerate(topo.edges):
        edge_of[(min(a, b), max(a, b))] = k
    real_global = np.full(len(topo.edges), -1)
    real_global[topo.edge_real] = V + F + np.arange(int(topo.edge_real.sum()))
    torus_of_global = {int(g): k for k, g in enumerate(real_global) if g >= 0}
    edge_between = {}
    for k, (f1, f2) in enumerate(topo.edge_faces):
        edge_between[(f1, f2)] = edge_between[(f2, f1)] = k

    def face_normal(f, k):
        a, b = topo.edges[k]
        if topo.edge_faces[k, 0] != f:
            a, b = b, a
        return _normal(x[a], x[b], c[f])

    def cone(i, k):
        a, b = topo.edges[k]
        j = b if a == i else a
        d = x[i] - x[j]
        ln = np.linalg.norm(d)
        return ln / (2 * rho), d / ln

    # vertex cones
    cos_d, ax_d, lines = [], [], []
    for i in range(V):
        for ln, g, vals in raw.small_tori[i]:
            cs, ax = vals[0], vals[1:]
            cs0, ax0 = cone(i, torus_of_global[g])
            cos_d.append(abs(cs - cs0))
            ax_d.append(np.abs(ax - ax0).max())
            lines.append(ln)
    for k in range(len(topo.edges)):
        for ln, i, vals in raw.tor_cones[k]:
            cs, ax = vals[0], vals[1:]
            cs0, ax0 = cone(i, k)
            cos_d.append(abs(cs - cs0))
            ax_d.append(np.abs(ax - ax0).max())
            lines.append(ln)
    record("cone_cos", cos_d, lines)
    record("cone_axis", ax_d, lines)

    # plane normals, in the face records and in the torus records
    n_d, lines = [], []
    for f in range(F):
        for ln, g, nrm in raw.big_bounds[f]:
            k = torus_of_global[g] if g >= V + F else edge_between[(f, g - V)]
            n_d.append(np.abs(nrm - face_normal(f, k)).max())
            lines.append(ln)
    for k in range(len(topo.edges)):
        for ln, g, nrm in raw.tor_planes[k]:
            n_d.append(np.abs(nrm - face_normal(g - V, k)).max())
            lines.append(ln)
    record("plane_normal", n_d, lines)

    # torus circles
    if len(topo.edges):
        xa, xb = x[topo.edges[:, 0]], x[topo.edges[:, 1]]
        ln = np.linalg.norm(xa - xb, axis=1)
        lines = raw.tor_line + 1
        record("torus_radius", np.abs(raw.tor_circle[:, 0] - np.sqrt(np.maximum(rho ** 2 - ln ** 2 / 4, 0.0))), lines)
        record("torus_centre", np.abs(raw.tor_circle[:, 2:5] - (xa + xb) / 2).max(axis=1), lines)
        record("torus_axis", np.abs(raw.tor_circle[:, 5:8] - (xa - xb) / ln[:, None]).max(axis=1), lines)
        deg = ~topo.edge_real
        if deg.any():
            gap = np.linalg.norm(c[topo.edge_faces[deg, 0]] - c[topo.edge_faces[deg, 1]], axis=1)
            record("degenerate_centre_gap", gap, raw.tor_line[deg])
    return out


def read_sch_stp(path, *, check_derived: bool = True) -> STPTopology:
    """Read an STP-BV file in the sch-core text format.

    Returns an :class:`STPTopology` (coordinates in the file's unit and frame; ``source_index`` is -1).
    Faces are ordered counter-clockwise seen from outside, edges as (first cone, second cone) with
    f1 the face holding a -> b. With ``check_derived`` the stored derived numbers (radii, cones,
    planes, torus circles, triangle coordinates) must agree with the ones recomputed from the
    topology to the tolerances DERIVED_TOL_* (cosines and unit vectors absolute, lengths relative).
    Raises ValueError naming the file, the line and the problem on anything malformed.
    """
    path = Path(path)
    raw = _parse(path)
    topo = _build(raw)
    if check_derived:
        for kind, (diff, line) in _differences(raw, topo).items():
            tol = _tolerance(kind, topo)
            if not diff <= tol:
                raise ValueError(f"{path}:{line}: stored {kind.replace('_', ' ')} differs from the value "
                                 f"recomputed from the topology by {diff:.3g} (tolerance {tol:.3g})")
    return topo


def sch_stp_discrepancies(path) -> dict[str, float]:
    """Max abs difference between each kind of stored number and its value recomputed from the topology.

    Kinds: small_radius, big_radius, torus_tube_radius, triangle_vertex (lengths: |stored - centre|),
    big_sphere_touch (| |x_v - c_f| - rho |), cone_cos, cone_axis, plane_normal, torus_radius,
    torus_centre, torus_axis (per-component max) and, when there are degenerate tori,
    degenerate_centre_gap (|c_f1 - c_f2|, 0 in exact arithmetic). Lengths in the file's unit.
    """
    path = Path(path)
    raw = _parse(path)
    return {kind: d for kind, (d, _) in _differences(raw, _build(raw)).items()}


def _fmt(x) -> str:
    return repr(float(x))


def _line(*vals) -> str:
    return " ".join(_fmt(v) for v in vals)


def write_sch_stp(topology: STPTopology, path) -> None:
    """Write ``topology`` in the sch-core STP-BV text format (numbers in repr precision).

    Derived numbers (cones, planes, torus circles) are recomputed from the topology. Edges are
    written in the topology's order (degenerate ones flagged 0, taking no patch index), each torus
    with cone lines (a, b) and plane lines (f1, f2). Raises ValueError if the topology is
    inconsistent or cannot be stored (no faces / a spindle edge, an edge longer than 2 rho).
    """
    path = Path(path)
    t = topology
    try:
        t.check()
    except ValueError as exc:
        raise ValueError(f"{path}: cannot write an inconsistent topology: {exc}") from None
    x, c, rho = t.vertices, t.face_centres, t.rho
    V, F, E = len(x), len(t.faces), len(t.edges)
    if F == 0 or (E and (t.edge_faces == NO_FACE).any()):
        raise ValueError(f"{path}: the sch-core format needs two faces per edge (spindles cannot be stored)")
    l = np.linalg.norm(x[t.edges[:, 0]] - x[t.edges[:, 1]], axis=1)
    if not (l > 0).all() or not (l < 2 * rho).all():
        raise ValueError(f"{path}: every edge length must lie in (0, 2 rho); got {l.min():.17g} .. {l.max():.17g}")
    real_global = np.full(E, -1)
    real_global[t.edge_real] = V + F + np.arange(int(t.edge_real.sum()))
    in_face = {}  # (face, u, w) -> edge, for u -> w in the face's winding
    for k, ((a, b), (f1, f2)) in enumerate(zip(t.edges, t.edge_faces)):
        in_face[(f1, a, b)] = k
        in_face[(f2, b, a)] = k
    at_vertex = [[] for _ in range(V)]
    for k in np.flatnonzero(t.edge_real):
        a, b = t.edges[k]
        at_vertex[a].append((real_global[k], k, b))
        at_vertex[b].append((real_global[k], k, a))

    out = [_line(t.r, t.R), f" {V}"]
    for i in range(V):
        out.append(_line(t.r, *x[i]))
        out.append(str(len(at_vertex[i])))
        for g, k, j in sorted(at_vertex[i]):
            d = x[i] - x[j]
            lij = np.linalg.norm(d)
            out.append(f"{g} " + _line(lij / (2 * rho), *(d / lij)))
    out.append(str(F))
    for f in range(F):
        tri = t.faces[f]
        out.append(_line(t.R, *c[f]))
        out.append(_line(*x[tri].reshape(-1)))
        for j in range(3):
            u, w = tri[j], tri[(j + 1) % 3]
            k = in_face.get((f, u, w))
            if k is None:
                raise ValueError(f"{path}: face {f} edge ({u}, {w}) has no edge record")
            other = t.edge_faces[k, 1] if t.edge_faces[k, 0] == f else t.edge_faces[k, 0]
            g = real_global[k] if t.edge_real[k] else V + other
            out.append(f"{g} " + _line(*_normal(x[u], x[w], c[f])))
    out.append(str(E))
    for k in range(E):
        a, b = t.edges[k]
        f1, f2 = t.edge_faces[k]
        e = (x[a] - x[b]) / l[k]
        cos = l[k] / (2 * rho)
        out.append("1" if t.edge_real[k] else "0")
        out.append(_line(np.sqrt(rho ** 2 - l[k] ** 2 / 4), t.R, *((x[a] + x[b]) / 2), *e))
        out.append(f"{a} " + _line(cos, *e))
        out.append(f"{b} " + _line(cos, *(-e)))
        out.append(f"{V + f1} " + _line(*_normal(x[a], x[b], c[f1])))
        out.append(f"{V + f2} " + _line(*_normal(x[b], x[a], c[f2])))
    try:
        path.write_text("\n".join(out) + "\n")
    except OSError as exc:
        raise ValueError(f"{path}: cannot write sch STP-BV file: {exc}") from None
