"""Support functions against brute force (an independent argmax over all vertices)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import spq
from spq.kernels import kinds
from spq.kernels.dispatch import support_many
from spq.kernels.support import CELL_SLOTS, cell_candidates, cube_cell, cube_cell_centres, cube_cell_corners


def _random_hull(seed, n=400):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3)) * [0.3, 0.2, 0.1]
    pts /= np.linalg.norm(pts / [0.3, 0.2, 0.1], axis=1)[:, None]  # on an ellipsoid: all on the hull
    return spq.Polyhedron.from_points(pts)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_polytope_support_value_matches_brute_force(seed):
    poly = _random_hull(seed)
    assert len(poly.vertices) > 6 * kinds.CUBE_MAP_CELLS**2  # more vertices than the least cube map has cells
    dirs = np.random.default_rng(10 + seed).normal(size=(20000, 3))
    kd = poly.kernel_data()
    s = support_many(kd.kind, kd.fdata, kd.idata, dirs)
    brute = (dirs @ poly.vertices.T).max(axis=1)
    np.testing.assert_allclose(np.einsum("ij,ij->i", dirs, s), brute, rtol=0, atol=1e-15)


def test_support_on_axis_and_zero_component_directions():
    poly = _random_hull(3)
    dirs = np.array([[1, 0, 0], [0, -1, 0], [0, 0, 1], [1, 1, 0], [0, 1e-300, -1], [-1, 0, 0]], float)
    kd = poly.kernel_data()
    s = support_many(kd.kind, kd.fdata, kd.idata, dirs)
    np.testing.assert_allclose(np.einsum("ij,ij->i", dirs, s), (dirs @ poly.vertices.T).max(axis=1), atol=1e-15)


def test_flat_regions_are_crossed_on_a_box_hull_with_many_coplanar_points():
    # a cube sampled with many points on its faces: large flat regions in every axis direction
    rng = np.random.default_rng(4)
    pts = rng.uniform(-1, 1, size=(3000, 3))
    axis = rng.integers(0, 3, size=3000)
    pts[np.arange(3000), axis] = np.sign(pts[np.arange(3000), axis])
    poly = spq.Polyhedron.from_points(pts)
    dirs = np.vstack([np.eye(3), -np.eye(3), rng.normal(size=(5000, 3))])
    kd = poly.kernel_data()
    s = support_many(kd.kind, kd.fdata, kd.idata, dirs)
    np.testing.assert_allclose(np.einsum("ij,ij->i", dirs, s), (dirs @ poly.vertices.T).max(axis=1), atol=1e-14)


def test_cube_cell_centres_fall_in_their_own_cells():
    G = 8
    centres = cube_cell_centres(G)
    cells = [cube_cell(*c, G) for c in centres]
    assert cells == list(range(6 * G * G))


@pytest.mark.parametrize("dense", [True, False])
@pytest.mark.parametrize("seed, n", [(5, 120), (6, 40), (7, 1500)])
def test_every_cells_candidates_hold_the_support_of_every_direction_in_it_borders_included(seed, n, dense):
    poly = _random_hull(seed, n=n)
    kd = poly.kernel_data(dense)
    G = kd.idata[1]
    n_vertices = len(poly.vertices)  # dense: 24 cells per vertex up to an edge of 64; never under 2 per vertex
    dense_edge = min(64, int(np.ceil(np.sqrt(n_vertices * 4)))) if dense else 0
    assert G == max(kinds.CUBE_MAP_CELLS, dense_edge, int(np.ceil(np.sqrt(n_vertices / 3))))
    counts = np.diff(cell_candidates(poly.vertices, G)[0])
    assert counts.min() >= 1 and counts.mean() < 4  # short lists: not every vertex in every cell
    corners = cube_cell_corners(G)  # (cells, 4, 3)
    weights = np.random.default_rng(seed).dirichlet(np.full(4, 0.3), size=(len(corners), 8))
    edges = 0.5 * (corners + np.roll(corners, 1, axis=1))  # where a direction's cell is decided by rounding
    dirs = np.vstack([corners.reshape(-1, 3), edges.reshape(-1, 3), np.einsum("mkc,mcj->mkj", weights,
                                                                                corners).reshape(-1, 3)])
    s = support_many(kd.kind, kd.fdata, kd.idata, dirs)
    chunks = np.array_split(dirs, len(dirs) // 20000 + 1)  # the dense maps' directions, in parts that fit
    brute = np.concatenate([(part @ poly.vertices.T).max(axis=1) for part in chunks])
    np.testing.assert_allclose(np.einsum("ij,ij->i", dirs, s), brute, rtol=0, atol=1e-15)


@pytest.mark.parametrize("seed, n", [(8, 60), (9, 150)])
def test_cell_candidates_are_the_vertices_no_other_vertex_beats_at_all_four_corners(seed, n):
    """Both cap searches (a scan, a walk over the hull's edges) against the definition, by brute force:
    every pair of vertices in every cell."""
    from spq.kernels.support import CANDIDATE_MARGIN, CELL_GROWTH

    poly = _random_hull(seed, n=n)
    V = poly.vertices
    G = 8
    scan = cell_candidates(V, G)
    offsets, ids = cell_candidates(V, G, (poly.adjacency_offsets, poly.adjacency))
    np.testing.assert_array_equal(scan[0], offsets)
    np.testing.assert_array_equal(scan[1], ids)
    corners = cube_cell_corners(G)
    centre = corners.mean(axis=1, keepdims=True)
    corners = centre + (corners - centre) * (1.0 + CELL_GROWTH)
    eps = CANDIDATE_MARGIN * np.linalg.norm(V, axis=1).max()
    M = np.einsum("ckj,vj->ckv", corners, V)  # (cells, 4, n)
    for c in range(len(corners)):
        beats = (M[c][:, :, None] > M[c][:, None, :] + eps).all(axis=0)  # [w, v]: w beats v
        expected = np.flatnonzero(~beats.any(axis=0))
        np.testing.assert_array_equal(ids[offsets[c]:offsets[c + 1]], expected)


def test_cells_with_more_candidates_than_slots_keep_them_all():
    """A 40-gon prism: the cells around its cap normals hold all 40 cap vertices (more than the
    CELL_SLOTS of a cell), so their lists lie past the slots; supports there match brute force."""
    angle = np.linspace(0.0, 2.0 * np.pi, 40, endpoint=False)
    ring = np.column_stack([np.cos(angle), np.sin(angle), np.zeros(40)])
    poly = spq.Polyhedron.from_points(np.vstack([ring + [0, 0, 0.3], ring - [0, 0, 0.3]]))
    kd = poly.kernel_data()
    G, start = kd.idata[1], kd.idata[2]
    slots = kd.idata[start:start + CELL_SLOTS * 6 * G * G].reshape(-1, CELL_SLOTS)
    assert (slots[:, 0] < 0).sum() >= 2 and slots[slots[:, 0] < 0, 1].max() >= 40
    rng = np.random.default_rng(3)
    dirs = np.vstack([[0, 0, 1], [0, 0, -1], rng.normal(size=(400, 3)) * [0.05, 0.05, 1.0]])
    s = support_many(kd.kind, kd.fdata, kd.idata, dirs)
    np.testing.assert_allclose(np.einsum("ij,ij->i", dirs, s), (dirs @ poly.vertices.T).max(axis=1), rtol=0,
                               atol=1e-15)


@pytest.mark.parametrize("walk", [False, True])
def test_more_candidates_than_the_first_guess_of_room_are_all_kept(walk):
    """A 300-gon prism: its cap cells hold 300 vertices each, more than cell_candidates first makes
    room for, so it runs again with room; supports from both searches' lists match brute force."""
    angle = np.linspace(0.0, 2.0 * np.pi, 300, endpoint=False)
    ring = np.column_stack([np.cos(angle), np.sin(angle), np.zeros(300)])
    poly = spq.Polyhedron.from_points(np.vstack([ring + [0, 0, 0.3], ring - [0, 0, 0.3]]))
    G = 8
    offsets, ids = cell_candidates(poly.vertices, G, (poly.adjacency_offsets, poly.adjacency) if walk else None)
    assert offsets[-1] > max(4 * 6 * G * G, 1024)
    rng = np.random.default_rng(5)
    dirs = np.vstack([[0, 0, 1], [0, 0, -1], rng.normal(size=(2000, 3)) * [1.0, 1.0, 3.0]])
    cells = np.array([cube_cell(*d, G) for d in dirs])
    best = [max(ids[offsets[c]:offsets[c + 1]], key=lambda v: d @ poly.vertices[v]) for d, c in zip(dirs, cells)]
    np.testing.assert_allclose(np.einsum("ij,ij->i", dirs, poly.vertices[best]), (dirs @ poly.vertices.T).max(axis=1),
                               rtol=0, atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 1e-9))
def test_primitive_supports_are_extreme(d):
    d = np.array(d)
    box = spq.Box(0.1, 0.2, 0.3)
    kd = box.kernel_data()
    s = support_many(kd.kind, kd.fdata, kd.idata, d[None])[0]
    corners = np.array([[x, y, z] for x in (-0.1, 0.1) for y in (-0.2, 0.2) for z in (-0.3, 0.3)])
    assert d @ s == pytest.approx((corners @ d).max(), abs=1e-12)
    cap = spq.Capsule(0.05, 0.4)
    kc = cap.kernel_data()
    sc = support_many(kc.kind, kc.fdata, kc.idata, d[None])[0]
    assert d @ sc == pytest.approx(max(0.4 * d[2], -0.4 * d[2]), abs=1e-12)
