"""Polyhedron construction, adjacency and the qhull reader."""

import numpy as np
import pytest
from scipy.spatial import ConvexHull

import spq


def test_hull_drops_interior_points_and_orients_faces_outward():
    rng = np.random.default_rng(0)
    pts = np.vstack([rng.normal(size=(200, 3)), rng.normal(size=(50, 3)) * 0.01])
    poly = spq.Polyhedron.from_points(pts)
    hull = ConvexHull(pts)
    assert len(poly.vertices) == len(hull.vertices)
    centre = poly.vertices.mean(axis=0)
    assert (np.einsum("ij,ij->i", poly.face_normals, poly.vertices[poly.faces[:, 0]] - centre) > 0).all()
    # every vertex lies inside every face plane
    assert (poly.vertices @ poly.face_normals.T - poly.face_offsets).max() < 1e-12


def test_adjacency_is_symmetric_and_matches_the_triangle_edges():
    poly = spq.Polyhedron.from_points(np.random.default_rng(1).normal(size=(300, 3)))
    edges = set()
    for a, b, c in poly.faces:
        edges |= {(a, b), (b, a), (b, c), (c, b), (c, a), (a, c)}
    csr = {(i, j) for i in range(len(poly.vertices))
           for j in poly.adjacency[poly.adjacency_offsets[i]:poly.adjacency_offsets[i + 1]]}
    assert csr == edges
    # Euler's formula for a closed triangulated sphere: E = 3F/2, V - E + F = 2
    assert len(poly.vertices) - len(edges) // 2 + len(poly.faces) == 2


@pytest.mark.parametrize("points, what", [
    (np.zeros((3, 3)), "at least 4"),
    (np.random.default_rng(0).normal(size=(10, 2)), "shape"),
    (np.c_[np.random.default_rng(0).normal(size=(10, 2)), np.zeros(10)], "flat"),
    (np.outer(np.arange(10.0), [1.0, 2.0, 3.0]), "flat"),
    (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, np.nan]]), "NaN"),
    (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, np.inf]]), "NaN or inf"),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [1, 1, 1]] * 1 + [[1, 1, 1]], None),
])
def test_bad_point_clouds_raise_value_error(points, what):
    if what is None:  # duplicates are fine
        assert len(spq.Polyhedron.from_points(points).vertices) == 5
        return
    with pytest.raises(ValueError, match=what):
        spq.Polyhedron.from_points(points)


def test_qhull_reader_on_the_sch_sample(shared_datasets):
    path = shared_datasets / "sch-samples" / "sample_polyhedron.otp"
    poly = spq.Polyhedron.from_qhull_file(path)
    from spq.io.qhull import read_qhull_off

    points, facets = read_qhull_off(path)
    assert points.shape == (96, 3) and len(facets) == 188
    # the hull of the file's points is the file's polyhedron: same vertex set, same facet count
    assert len(poly.vertices) == 96
    assert len(poly.faces) == 188


def test_qhull_reader_on_jvrc1_hulls_with_interior_points(shared_datasets):
    for name in ("PELVIS_S", "R_KNEE_S", "L_WRIST_Y_S"):
        poly = spq.Polyhedron.from_qhull_file(shared_datasets / "jvrc1" / "convex" / f"{name}-ch.txt")
        assert len(poly.vertices) >= 4
        assert (poly.vertices @ poly.face_normals.T - poly.face_offsets).max() < 1e-9


@pytest.mark.parametrize("text, what", [
    ("", "too short"),
    ("4\n1 0 0\n0 0 0\n", "dimension 3"),
    ("3\n2 1 0\n0 0 0\n1 1\n3 0 1 0\n", "three coordinates"),
    ("3\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 9\n", "outside"),
    ("3\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n", "fewer lines"),
])
def test_malformed_qhull_files_raise_value_error(tmp_path, text, what):
    path = tmp_path / "bad.txt"
    path.write_text(text)
    with pytest.raises(ValueError, match=what):
        spq.Polyhedron.from_qhull_file(path)


def test_unreadable_files_raise_value_error(tmp_path):
    with pytest.raises(ValueError, match="cannot read"):
        spq.Polyhedron.from_qhull_file(tmp_path / "missing.txt")
    with pytest.raises(ValueError, match="not found"):
        spq.Polyhedron.from_mesh(tmp_path / "missing.obj")
    bad = tmp_path / "bad.obj"
    bad.write_bytes(b"\x00\x01garbage")
    with pytest.raises(ValueError):
        spq.Polyhedron.from_mesh(bad)


def test_preparing_a_large_hull_takes_memory_linear_in_its_vertices():
    """The cube map's candidate lists of a hull are computed a chunk of cells at a time: all cells'
    centres against all vertices at once took 16 n^2 bytes (6.5 GB at 20,000 vertices, 400 MB at the
    5,000 here). Oracle: numpy's allocations as tracemalloc counts them."""
    import tracemalloc

    p = np.random.default_rng(5).normal(size=(5_000, 3))
    hull = spq.Polyhedron.from_points(p / np.linalg.norm(p, axis=1, keepdims=True))
    assert len(hull.vertices) == 5_000
    tracemalloc.start()
    try:
        hull.kernel_data()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 100e6  # bytes; a chunk's values (64 cells x 4 corners x n) are 10 MB
