"""Reader and writer of the sch-core STP-BV text format (spq.io.sch)."""

from __future__ import annotations

import numpy as np
import pytest

from spq.io.sch import _parse, read_sch_stp, sch_stp_discrepancies, write_sch_stp
from spq.stp.topology import NO_FACE, STPTopology

# file -> (V, F, real tori, degenerate tori, r, R)
SHARED_FILES = {
    "sch-samples/sample_stpbv1.txt": (42, 80, 120, 0, 0.001, 20.0),
    "sch-samples/sample_stpbv2.txt": (55, 106, 159, 0, 0.001, 20.0),
    "sch-samples/sample_stp_p.txt": (169, 334, 484, 17, 0.02, 1.0),
    "sch-creator-examples/stp/cube2x2.txt": (8, 12, 12, 6, 0.2, 300.0),
    "sch-creator-examples/stp/s2x2.txt": (12, 20, 24, 6, 0.2, 300.0),
}
TOPO_FIELDS = ("vertices", "faces", "face_centres", "edges", "edge_faces", "edge_real")


def tetrahedron_topology(r: float = 0.01, R: float = 5.0, size: float = 0.1) -> STPTopology:
    """A regular tetrahedron's STP-BV, built by hand: faces counter-clockwise seen from outside."""
    x = size * np.array([[1.0, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]])
    rho = R - r
    faces, centres = [], []
    for omit in range(4):
        tri = [i for i in range(4) if i != omit]
        a, b, c = x[tri]
        n = np.cross(b - a, c - a)
        if n @ (a - x[omit]) < 0:  # make the normal point away from the fourth vertex
            tri[1], tri[2] = tri[2], tri[1]
            a, b, c = x[tri]
            n = -n
        n /= np.linalg.norm(n)
        u, w = b - a, c - a
        uxw = np.cross(u, w)
        cc = a + np.cross(u @ u * w - w @ w * u, uxw) / (2 * uxw @ uxw)  # circumcentre
        rt = np.linalg.norm(cc - a)
        faces.append(tri)
        centres.append(cc - np.sqrt(rho ** 2 - rt ** 2) * n)  # moved towards the inside
    directed = {(f[j], f[(j + 1) % 3]): k for k, f in enumerate(faces) for j in range(3)}
    edges, edge_faces = [], []
    for a in range(4):
        for b in range(a + 1, 4):
            edges.append((a, b))
            edge_faces.append((directed[(a, b)], directed[(b, a)]))
    return STPTopology(r=r, R=R, vertices=x, faces=faces, face_centres=centres, edges=edges,
                       edge_faces=edge_faces, edge_real=np.ones(6, bool))


def assert_same_topology(t: STPTopology, u: STPTopology, tol: float = 0.0) -> None:
    assert (t.r, t.R) == pytest.approx((u.r, u.R), abs=tol, rel=0)
    for name in TOPO_FIELDS:
        a, b = getattr(t, name), getattr(u, name)
        assert a.shape == b.shape, name
        if a.dtype.kind == "f":
            np.testing.assert_allclose(a, b, rtol=0, atol=tol, err_msg=name)
        else:
            np.testing.assert_array_equal(a, b, err_msg=name)


@pytest.fixture
def tetra_file(tmp_path):
    path = tmp_path / "tetra.txt"
    write_sch_stp(tetrahedron_topology(), path)
    return path


# ---------------------------------------------------------------- the shared files


@pytest.mark.parametrize("name", sorted(SHARED_FILES))
def test_shared_file_reads_with_expected_counts(shared_datasets, name):
    V, F, real, deg, r, R = SHARED_FILES[name]
    t = read_sch_stp(shared_datasets / name)
    assert t.counts() == {"small_spheres": V, "big_spheres": F, "tori": real, "degenerate_tori": deg}
    assert (t.r, t.R) == (r, R)
    assert (t.source_index == -1).all()
    t.check()
    # faces counter-clockwise seen from outside: the winding normal points from c_f towards the face
    # and away from the rest of the body
    x = t.vertices[t.faces]
    n = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    assert (np.einsum("ij,ij->i", n, x.mean(axis=1) - t.face_centres) > 0).all()
    assert (np.einsum("ij,ij->i", n, x.mean(axis=1) - t.vertices.mean(axis=0)) > 0).all()
    # a degenerate torus lies between two faces with the same big-sphere centre
    deg_faces = t.edge_faces[~t.edge_real]
    gap = np.linalg.norm(t.face_centres[deg_faces[:, 0]] - t.face_centres[deg_faces[:, 1]], axis=1)
    assert (gap <= 1e-6 * t.R).all()


@pytest.mark.parametrize("name", sorted(SHARED_FILES))
def test_shared_file_derived_numbers_agree(shared_datasets, name):
    diffs = sch_stp_discrepancies(shared_datasets / name)
    expected = {"small_radius", "big_radius", "torus_tube_radius", "triangle_vertex", "big_sphere_touch",
                "cone_cos", "cone_axis", "plane_normal", "torus_radius", "torus_centre", "torus_axis"}
    assert expected <= set(diffs)
    # sch-creator writes 16 digits, the sch-core samples 6: bounds with a margin over what they show
    bound = 1e-12 if name.startswith("sch-creator") else 1e-3
    assert max(diffs.values()) <= bound, diffs
    # the radii and the triangle coordinates are copied, not computed: they agree exactly
    assert diffs["small_radius"] == diffs["big_radius"] == diffs["triangle_vertex"] == 0.0


@pytest.mark.parametrize("name", sorted(SHARED_FILES))
def test_shared_file_round_trip(shared_datasets, tmp_path, name):
    t = read_sch_stp(shared_datasets / name)
    out = tmp_path / "rt.txt"
    write_sch_stp(t, out)
    u = read_sch_stp(out)
    assert_same_topology(t, u, tol=1e-15)
    # the written derived numbers are the recomputed ones (to rounding)
    assert max(v for k, v in sch_stp_discrepancies(out).items() if k != "big_sphere_touch") <= 1e-12
    # same line structure as the original
    orig = [len(ln.split()) for ln in (shared_datasets / name).read_text().splitlines() if ln.strip()]
    new = [len(ln.split()) for ln in out.read_text().splitlines() if ln.strip()]
    assert orig == new


# ---------------------------------------------------------------- hand-made topology


def test_tetrahedron_write_read(tetra_file):
    t = tetrahedron_topology()
    t.check()
    assert np.allclose(np.linalg.norm(t.vertices[t.faces] - t.face_centres[:, None], axis=2), t.rho, atol=1e-14)
    u = read_sch_stp(tetra_file)
    assert_same_topology(t, u, tol=1e-15)
    assert u.counts() == {"small_spheres": 4, "big_spheres": 4, "tori": 6, "degenerate_tori": 0}
    assert max(sch_stp_discrepancies(tetra_file).values()) <= 1e-14


def test_tetrahedron_file_layout(tetra_file):
    rows = [ln.split() for ln in tetra_file.read_text().splitlines()]
    assert rows[0] == ["0.01", "5.0"] and rows[1] == ["4"]
    assert rows[2][0] == "0.01" and rows[3] == ["3"]  # each vertex of a tetrahedron has 3 tori
    # torus indices: 4 small spheres, 4 big spheres, then tori 8..13
    assert sorted(int(r[0]) for r in rows[4:7]) == [int(r[0]) for r in rows[4:7]]
    assert all(8 <= int(r[0]) <= 13 for r in rows[4:7])
    tori_start = 2 + 4 * 5 + 1 + 4 * 5
    assert rows[tori_start] == ["6"] and rows[tori_start + 1] == ["1"]
    assert len(rows) == tori_start + 1 + 6 * 6


def square_top_topology(lift: float = 0.0) -> STPTopology:
    """A pyramid whose top is a square split along (0, 2); with lift = 0 the two top triangles share a
    big sphere and the diagonal's torus is degenerate (flag 0). lift raises corner 3 (the diagonal
    is still flagged degenerate, which is then wrong)."""
    x = 0.1 * np.array([[-1.0, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1 + lift], [0, 0, -1.5]])
    r, R = 0.01, 3.0
    rho = R - r
    faces = [[0, 1, 2], [0, 2, 3], [0, 4, 1], [1, 4, 2], [2, 4, 3], [3, 4, 0]]

    def centre(tri):
        a, b, c = x[tri]
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n)
        u, w = b - a, c - a
        uxw = np.cross(u, w)
        cc = a + np.cross(u @ u * w - w @ w * u, uxw) / (2 * uxw @ uxw)
        return cc - np.sqrt(rho ** 2 - np.sum((cc - a) ** 2)) * n

    centres = [centre(f) for f in faces]
    if lift == 0.0:
        centres[1] = centres[0]  # the two top triangles share a centre exactly
    directed = {(f[j], f[(j + 1) % 3]): k for k, f in enumerate(faces) for j in range(3)}
    pairs = sorted({tuple(sorted(p)) for p in directed})
    return STPTopology(r=r, R=R, vertices=x, faces=faces, face_centres=centres, edges=pairs,
                       edge_faces=[(directed[(a, b)], directed[(b, a)]) for a, b in pairs],
                       edge_real=[p != (0, 2) for p in pairs])


def test_degenerate_torus_round_trip(tmp_path):
    t = square_top_topology()
    pairs = [tuple(p) for p in t.edges.tolist()]
    path = tmp_path / "deg.txt"
    write_sch_stp(t, path)
    u = read_sch_stp(path)
    assert_same_topology(t, u)
    assert u.counts()["degenerate_tori"] == 1 and u.counts()["tori"] == 8
    raw = _parse(path)
    assert raw.tor_flag.tolist() == [0 if p == (0, 2) else 1 for p in pairs]
    # the top faces (big spheres 5 and 6) name each other across the diagonal; real tori are 11..18
    assert sorted(i for _, i, _ in raw.big_bounds[0]) == [6, 11 + pairs.index((0, 1)), 11 + pairs.index((1, 2)) - 1]
    assert 5 in [i for _, i, _ in raw.big_bounds[1]]
    # the vertices list only real tori
    assert all(len(ts) == 3 for ts in raw.small_tori[:4]) and len(raw.small_tori[4]) == 4


# ---------------------------------------------------------------- malformed input


def _rows(path):
    return path.read_text().splitlines()


def _edit(path, lineno, new, tmp_path):
    """Copy of ``path`` with 1-based line ``lineno`` replaced by ``new`` (None: removed)."""
    lines = _rows(path)
    if new is None:
        del lines[lineno - 1]
    else:
        lines[lineno - 1] = new
    out = tmp_path / "bad.txt"
    out.write_text("\n".join(lines) + "\n")
    return out


def _find(path, predicate):
    """1-based number of the first line for which predicate(tokens) holds."""
    for i, ln in enumerate(_rows(path)):
        if predicate(ln.split()):
            return i + 1
    raise AssertionError("no such line")


def _raises(path, *fragments):
    with pytest.raises(ValueError) as info:
        read_sch_stp(path)
    msg = str(info.value)
    assert str(path) in msg, msg
    for frag in fragments:
        assert frag in msg, msg
    return msg


def test_unreadable_file(tmp_path):
    _raises(tmp_path / "missing.txt", "cannot read")
    _raises(tmp_path, "cannot read")  # a directory
    binary = tmp_path / "binary.txt"
    binary.write_bytes(b"\xff\xfe\x00\x81")
    _raises(binary, "cannot read")


def test_empty_and_truncated(tetra_file, tmp_path):
    empty = tmp_path / "empty.txt"
    empty.write_text("\n\n")
    _raises(empty, "truncated")
    lines = _rows(tetra_file)
    for keep in (1, 2, 5, 30, len(lines) - 1):
        cut = tmp_path / f"cut{keep}.txt"
        cut.write_text("\n".join(lines[:keep]) + "\n")
        _raises(cut, f":{keep + 1}:", "truncated")


def test_radii(tetra_file, tmp_path):
    for header in ("0 5", "-0.01 5", "0.01 0.01", "0.02 0.01", "0.01 -5", "0.01 nan", "0.01 inf"):
        _raises(_edit(tetra_file, 1, header, tmp_path), ":1:")
    _raises(_edit(tetra_file, 1, "0.01", tmp_path), ":1:", "expected 2")
    # a small sphere with a non-positive radius
    _raises(_edit(tetra_file, 3, "-0.01 0.1 0.1 0.1", tmp_path), ":3:", "positive")


def test_non_numeric(tetra_file, tmp_path):
    _raises(_edit(tetra_file, 2, "four", tmp_path), ":2:", "integer")
    _raises(_edit(tetra_file, 3, "0.01 0.1 x 0.1", tmp_path), ":3:", "numbers")
    line = _find(tetra_file, lambda t: len(t) == 5)
    _raises(_edit(tetra_file, line, "8.0 0.1 1 0 0", tmp_path), f":{line}:", "integer")


def test_wrong_counts(tetra_file, tmp_path):
    _raises(_edit(tetra_file, 2, "3", tmp_path))  # fewer small spheres: the records no longer line up
    _raises(_edit(tetra_file, 2, "-1", tmp_path), ":2:", ">= 0")
    _raises(_edit(tetra_file, 4, "2", tmp_path), ":7:")  # 2 tori announced, 3 given
    # trailing data after the last torus
    extra = tmp_path / "extra.txt"
    extra.write_text(tetra_file.read_text() + "1 2 3\n")
    _raises(extra, "unexpected data")
    # F and E that do not describe a closed triangulated surface
    t = tetrahedron_topology()
    keep = 3
    sub = STPTopology(r=t.r, R=t.R, vertices=t.vertices, faces=t.faces[:keep], face_centres=t.face_centres[:keep],
                      edges=t.edges, edge_faces=np.where(t.edge_faces < keep, t.edge_faces, 0),
                      edge_real=t.edge_real)
    with pytest.raises(ValueError):
        write_sch_stp(sub, tmp_path / "sub.txt")  # the writer refuses the inconsistent topology


def test_index_out_of_range(tetra_file, tmp_path):
    # a vertex's torus index, a face's boundary index, a torus's small and big index
    line = _find(tetra_file, lambda t: len(t) == 5)
    tok = _rows(tetra_file)[line - 1].split()
    _raises(_edit(tetra_file, line, " ".join(["99"] + tok[1:]), tmp_path), f":{line}:", "99")
    lines = _rows(tetra_file)
    tori_start = 2 + 4 * 5 + 1 + 4 * 5 + 1  # 1-based line of E
    cone = tori_start + 3
    tok = lines[cone - 1].split()
    _raises(_edit(tetra_file, cone, " ".join(["7"] + tok[1:]), tmp_path), f":{cone}:", "outside 0..3")
    plane = tori_start + 5
    tok = lines[plane - 1].split()
    _raises(_edit(tetra_file, plane, " ".join(["3"] + tok[1:]), tmp_path), f":{plane}:", "outside 4..7")
    bound = 2 + 4 * 5 + 1 + 3  # first boundary line of big sphere 4
    tok = lines[bound - 1].split()
    _raises(_edit(tetra_file, bound, " ".join(["20"] + tok[1:]), tmp_path), "boundary indices")


def test_torus_faces_must_contain_its_vertices(tetra_file, tmp_path):
    t = tetrahedron_topology()
    lines = _rows(tetra_file)
    tori_start = 2 + 4 * 5 + 1 + 4 * 5 + 1
    plane = tori_start + 5  # first torus, first plane line: name a face that misses one of its vertices
    a, b = t.edges[0]
    other = next(f for f in range(4) if not {a, b} <= set(t.faces[f]))
    tok = lines[plane - 1].split()
    _raises(_edit(tetra_file, plane, " ".join([str(4 + other)] + tok[1:]), tmp_path), f":{plane}:",
            "does not contain")
    # a triangle vertex that is not a small-sphere centre
    tri = 2 + 4 * 5 + 1 + 2
    _raises(_edit(tetra_file, tri, "0.5 0.5 0.5 " + " ".join(lines[tri - 1].split()[3:]), tmp_path),
            f":{tri}:", "not a small-sphere centre")


def test_torus_flag_and_derived_numbers(tetra_file, tmp_path):
    tori_start = 2 + 4 * 5 + 1 + 4 * 5 + 1
    _raises(_edit(tetra_file, tori_start + 1, "2", tmp_path), f":{tori_start + 1}:", "flag")
    # a flipped plane normal: rejected when checking derived numbers, accepted without
    plane = tori_start + 5
    tok = _rows(tetra_file)[plane - 1].split()
    flipped = _edit(tetra_file, plane, " ".join([tok[0]] + [repr(-float(v)) for v in tok[1:]]), tmp_path)
    _raises(flipped, f":{plane}:", "plane normal")
    assert_same_topology(read_sch_stp(flipped, check_derived=False), tetrahedron_topology(), tol=1e-15)
    # a wrong torus circle radius
    tok = _rows(tetra_file)[tori_start + 1].split()
    bad = _edit(tetra_file, tori_start + 2, " ".join(["4.0"] + tok[1:]), tmp_path)
    _raises(bad, f":{tori_start + 2}:", "torus radius")


def test_writer_rejects_what_the_format_cannot_hold(tmp_path):
    x = np.array([[0.0, 0, 0], [0.1, 0, 0]])
    spindle = STPTopology(r=0.01, R=1.0, vertices=x, faces=np.zeros((0, 3)), face_centres=np.zeros((0, 3)),
                          edges=[(0, 1)], edge_faces=[(NO_FACE, NO_FACE)], edge_real=[True])
    with pytest.raises(ValueError, match="spindle"):
        write_sch_stp(spindle, tmp_path / "s.txt")
    t = tetrahedron_topology()
    t.faces = t.faces[:, [0, 2, 1]]  # clockwise: edges no longer match their faces
    with pytest.raises(ValueError, match="inconsistent"):
        write_sch_stp(t, tmp_path / "t.txt")
    with pytest.raises(ValueError, match="cannot write"):
        write_sch_stp(tetrahedron_topology(), tmp_path / "no_such_dir" / "t.txt")


def test_degenerate_torus_needs_a_shared_centre(tmp_path):
    path = tmp_path / "lifted.txt"
    write_sch_stp(square_top_topology(lift=0.05), path)
    _raises(path, "degenerate centre gap")
    assert read_sch_stp(path, check_derived=False).counts()["degenerate_tori"] == 1


def test_radii_must_match_the_header(tetra_file, tmp_path):
    _raises(_edit(tetra_file, 3, "0.011 0.1 0.1 0.1", tmp_path), ":3:", "small radius")
    line = 2 + 4 * 5 + 2
    tok = _rows(tetra_file)[line - 1].split()
    _raises(_edit(tetra_file, line, " ".join(["5.1"] + tok[1:]), tmp_path), f":{line}:", "big radius")


def test_euler_counts(tetra_file, tmp_path):
    """An extra small sphere without tori: the counts no longer describe a closed surface."""
    lines = _rows(tetra_file)
    lines[1] = "5"
    lines[22:22] = ["0.01 1.0 1.0 1.0", "0"]  # after the 4th small sphere's record
    bad = tmp_path / "extra_vertex.txt"
    bad.write_text("\n".join(lines) + "\n")
    e_line = 2 + (4 * 5 + 2) + 1 + 4 * 5 + 1  # header, small spheres (+ the new one), F, big spheres, E
    _raises(bad, f":{e_line}:", "counts V = 5, F = 4, E = 6")
