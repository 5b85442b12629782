"""STP-BV topology from a point cloud (spq.stp.construction.build_topology).

Oracles: the definition of a face (a ball of radius rho = R - r through three points that holds every
point), enumerated by brute force over all triples of a small cloud; the files that the reference
generator sch-creator built from the same clouds; the convex hull, which the faces approach as R
grows; Euler's formula for the closed surface.
"""

from __future__ import annotations

import itertools
import re

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from spq.stp.construction import build_topology, merge_duplicates
from spq.stp.farthest import farthest_distances
from spq.stp.topology import NO_FACE

CUBE = np.array(list(itertools.product([-1.0, 1.0], repeat=3)))


# ------------------------------------------------------------------------------------- helpers

def brute_force_faces(points: np.ndarray, rho: float, tol: float = 1e-9) -> list[tuple]:
    """Every (sorted triple, centre) with a ball of radius rho through the triple holding all points."""
    x = np.asarray(points, dtype=float)
    tri = np.array(list(itertools.combinations(range(len(x)), 3)))
    a, b, c = x[tri[:, 0]], x[tri[:, 1]], x[tri[:, 2]]
    u, v = b - a, c - a
    w = np.cross(u, v)
    w2 = (w * w).sum(1)
    keep = w2 > 1e-20
    tri, a, u, v, w, w2 = tri[keep], a[keep], u[keep], v[keep], w[keep], w2[keep]
    o = a + ((u * u).sum(1)[:, None] * np.cross(v, w) + (v * v).sum(1)[:, None] * np.cross(w, u)) / (
        2 * w2[:, None])
    rt2 = ((o - a) ** 2).sum(1)
    fits = rt2 <= rho * rho
    h = np.sqrt(np.maximum(rho * rho - rt2, 0.0))
    m = w / np.sqrt(w2)[:, None]
    out = []
    for sign in (1.0, -1.0):
        centre = o + sign * h[:, None] * m
        far = np.linalg.norm(x[None, :, :] - centre[:, None, :], axis=2).max(axis=1)
        for k in np.nonzero(fits & (far <= rho + tol))[0]:
            out.append((tuple(tri[k]), centre[k]))
    return out


def same_faces(topo, expected: list[tuple], tol: float) -> bool:
    """The topology's faces, as (sorted input rows, centre), equal the expected list (as sets)."""
    ours = [(tuple(sorted(topo.source_index[f])), c) for f, c in zip(topo.faces, topo.face_centres)]
    if len(ours) != len(expected):
        return False
    unmatched = list(expected)
    for key, c in ours:
        hit = [i for i, (k, e) in enumerate(unmatched) if k == key and np.linalg.norm(e - c) <= tol]
        if not hit:
            return False
        unmatched.pop(hit[0])
    return True


def euler(topo) -> int:
    return len(topo.vertices) - len(topo.edges) + len(topo.faces)


def assert_well_formed(topo, points) -> None:
    """Consistent indices and windings, a closed surface, centres within rho of every point, faces
    counter-clockwise seen from outside, zero-width tori exactly where two faces share a centre."""
    topo.check()
    rho = topo.rho
    x = np.asarray(points, dtype=float)
    scale = np.linalg.norm(np.ptp(x, axis=0))
    far = np.linalg.norm(x[None] - topo.face_centres[:, None], axis=2).max(axis=1)
    tol = 1e-9 * scale + 1e-14 * rho  # the second term: rounding of distances to far centres
    assert (far <= rho + tol).all()
    assert np.allclose(topo.vertices, x[topo.source_index], rtol=0, atol=0)
    if len(topo.faces) == 0:
        return
    # a closed surface: every edge has two faces, and V - E + F = 2
    assert (topo.edge_faces != NO_FACE).all()
    assert 2 * len(topo.edges) == 3 * len(topo.faces)
    assert euler(topo) == 2
    # the three small spheres touch the big one: vertices at rho from their face's centre
    d = np.linalg.norm(topo.vertices[topo.faces] - topo.face_centres[:, None], axis=2)
    assert np.abs(d - rho).max() <= tol
    p = topo.vertices[topo.faces]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    outward = np.einsum("ij,ij->i", normal, p.mean(axis=1) - topo.face_centres)
    flat = np.abs(outward) <= 1e-9 * scale * np.linalg.norm(normal, axis=1) * (1 + rho / scale)
    assert (outward[~flat] > 0).all()
    gap = np.linalg.norm(topo.face_centres[topo.edge_faces[:, 0]] - topo.face_centres[topo.edge_faces[:, 1]],
                         axis=1)
    assert (topo.edge_real == (gap > 1e-9 * (scale + rho))).all()


def ellipsoid_cloud(n: int, axes, seed: int) -> np.ndarray:
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1)[:, None] * np.asarray(axes)


def read_cloud(path) -> np.ndarray:
    tok = path.read_text().split()
    n = int(tok[1])
    return np.array(tok[2:2 + 3 * n], dtype=float).reshape(n, 3)


def read_stp(path) -> dict:
    """Counts and centres from an sch-core STP-BV text file (NOTES section 3)."""
    tok = iter(path.read_text().split())

    def num():
        return float(next(tok))

    def skip(k):
        for _ in range(k):
            next(tok)

    r, R = num(), num()
    small = []
    for _ in range(int(num())):
        num()
        small.append([num(), num(), num()])
        skip(5 * int(num()))
    big = []
    for _ in range(int(num())):
        num()
        big.append([num(), num(), num()])
        skip(9 + 12)
    flags = []
    for _ in range(int(num())):
        flags.append(int(num()))
        skip(8 + 5 + 5 + 4 + 4)
    assert next(tok, None) is None
    flags = np.array(flags)
    return {"r": r, "R": R, "small": np.array(small), "big": np.array(big),
            "tori": int((flags == 1).sum()), "degenerate_tori": int((flags == 0).sum())}


def same_point_sets(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    d = np.linalg.norm(a[:, None] - b[None], axis=2)
    return d.min(axis=1).max() <= tol and d.min(axis=0).max() <= tol


# ----------------------------------------------------------------------- reference generator

@pytest.mark.parametrize("name, counts", [
    ("cube2x2", (8, 12, 12, 6)),
    ("s2x2", (12, 20, 24, 6)),
])
def test_same_spheres_and_tori_as_sch_creator(shared_datasets, name, counts):
    root = shared_datasets / "sch-creator-examples"
    ref = read_stp(root / "stp" / f"{name}.txt")
    cloud = read_cloud(root / "cloud" / f"{name}.cloud")
    topo = build_topology(cloud, ref["r"], ref["R"])
    assert_well_formed(topo, cloud)
    got = topo.counts()
    assert (got["small_spheres"], got["big_spheres"], got["tori"], got["degenerate_tori"]) == counts
    assert (len(ref["small"]), len(ref["big"]), ref["tori"], ref["degenerate_tori"]) == counts
    assert same_point_sets(topo.vertices, ref["small"], 1e-9)
    assert same_point_sets(topo.face_centres, ref["big"], 1e-9)


# ------------------------------------------------------------------------------ definition

@pytest.mark.parametrize("kind", ["solid", "thin", "planar", "nearly planar"])
@pytest.mark.parametrize("seed", range(6))
def test_faces_are_exactly_the_triples_with_an_enclosing_ball_brute_force(kind, seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(12, 3))
    x[:, 2] *= {"solid": 1.0, "thin": 0.05, "planar": 0.0, "nearly planar": 1e-7}[kind]
    r = 0.01
    r_min = _smallest_admissible_R(x, r) - r
    for rho in (r_min * 1.001, r_min * 1.3, 4.0 * r_min, 50.0 * r_min):
        topo = build_topology(x, r, r + rho)
        assert_well_formed(topo, x)
        if len(topo.faces):
            assert same_faces(topo, brute_force_faces(x, rho), 1e-7 * (1 + rho))


def test_nondegenerate_cloud_has_2v_minus_4_faces():
    for seed in range(5):
        x = np.random.default_rng(seed).uniform(-1, 1, size=(60, 3))
        topo = build_topology(x, 0.01, 3.0)
        assert_well_formed(topo, x)
        assert len(topo.faces) == 2 * (len(topo.vertices) - 2)
        assert topo.edge_real.all()


def test_robot_mesh_at_two_radii():
    pybullet_data = pytest.importorskip("pybullet_data")
    trimesh = pytest.importorskip("trimesh")
    mesh = trimesh.load(f"{pybullet_data.getDataPath()}/kuka_iiwa/meshes/link_4.obj", force="mesh")
    hull = {tuple(v) for v in mesh.vertices[ConvexHull(mesh.vertices).vertices]}
    for R in (2.0, 0.3):
        topo = build_topology(mesh.vertices, 0.005, R)
        assert_well_formed(topo, mesh.vertices)
        assert len(topo.faces) == 2 * (len(topo.vertices) - 2)
        assert {tuple(v) for v in topo.vertices} <= hull


# ------------------------------------------------------------------------------ degenerate input

def test_duplicates_are_merged_keeping_the_first_row():
    x = np.random.default_rng(3).normal(size=(20, 3))
    x[4] = [0.0, 0.0, 0.0]
    doubled = np.vstack([x, x[::-1], [[-0.0, 0.0, -0.0]]])
    topo = build_topology(doubled, 0.01, 5.0)
    plain = build_topology(x, 0.01, 5.0)
    assert_well_formed(topo, doubled)
    assert np.array_equal(topo.source_index, plain.source_index)  # first occurrences: rows < 20
    assert np.array_equal(topo.faces, plain.faces)
    kept, rows = merge_duplicates(doubled)
    assert np.array_equal(rows, np.arange(20)) and np.array_equal(kept, x)


def test_hull_points_that_no_ball_touches_drop_out():
    # a point just outside the middle of a cube face is on the convex hull, but the big sphere of
    # that face (radius 10) bulges past it
    bump = np.array([[1.0 + 1e-3, 0.0, 0.0]])
    x = np.vstack([CUBE, bump])
    assert 8 in ConvexHull(x).vertices
    topo = build_topology(x, 0.01, 10.0)
    assert_well_formed(topo, x)
    assert 8 not in topo.source_index
    assert topo.counts() == {"small_spheres": 8, "big_spheres": 12, "tori": 12, "degenerate_tori": 6}
    # with a flatter big sphere the bump pokes out and becomes a vertex
    topo = build_topology(x, 0.01, 1e4)
    assert_well_formed(topo, x)
    assert 8 in topo.source_index


def test_cospherical_cube_corners_have_zero_width_tori_across_square_faces():
    topo = build_topology(CUBE, 0.1, 100.0)
    assert_well_formed(topo, CUBE)
    assert topo.counts() == {"small_spheres": 8, "big_spheres": 12, "tori": 12, "degenerate_tori": 6}
    # the zero-width tori are the diagonals of the squares, the real ones the cube's edges
    length = np.linalg.norm(CUBE[topo.edges[:, 0]] - CUBE[topo.edges[:, 1]], axis=1)
    assert np.allclose(length[topo.edge_real], 2.0) and np.allclose(length[~topo.edge_real], np.sqrt(8))
    assert len(np.unique(np.round(topo.face_centres, 9), axis=0)) == 6


def test_cube_at_its_circumradius_is_one_ball():
    for rho in (np.sqrt(3.0), np.sqrt(3.0) * (1 - 1e-13)):
        topo = build_topology(CUBE, 0.1, 0.1 + rho)
        assert_well_formed(topo, CUBE)
        assert topo.counts() == {"small_spheres": 8, "big_spheres": 12, "tori": 0, "degenerate_tori": 18}
        assert np.abs(topo.face_centres).max() < 1e-9


def test_cylinder_end_caps_and_side_quads_are_cospherical_groups():
    k = 16
    angle = 2 * np.pi * np.arange(k) / k
    ring = np.c_[np.cos(angle), np.sin(angle), np.zeros(k)]
    x = np.vstack([ring + [0, 0, -1], ring + [0, 0, 1]])
    topo = build_topology(x, 0.01, 10.0)
    assert_well_formed(topo, x)
    # caps: k - 3 diagonals each; sides: one diagonal per quad
    assert topo.counts() == {"small_spheres": 2 * k, "big_spheres": 4 * k - 4, "tori": 3 * k,
                             "degenerate_tori": 2 * (k - 3) + k}


def test_planar_square_has_the_same_two_triangles_on_both_sides():
    x = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    topo = build_topology(x, 0.1, 2.0)
    assert_well_formed(topo, x)
    assert topo.counts() == {"small_spheres": 4, "big_spheres": 4, "tori": 4, "degenerate_tori": 2}
    assert sorted(np.sign(topo.face_centres[:, 2])) == [-1, -1, 1, 1]


def test_planar_polygon_at_its_circumradius_is_one_ball():
    k = 12
    angle = 2 * np.pi * np.arange(k) / k
    x = np.c_[np.cos(angle), np.sin(angle), np.zeros(k)]
    topo = build_topology(x, 0.1, 1.1)
    assert_well_formed(topo, x)
    assert topo.counts() == {"small_spheres": k, "big_spheres": 2 * (k - 2), "tori": 0,
                             "degenerate_tori": 3 * (k - 2)}


def test_planar_cloud_whose_big_triangles_do_not_fit():
    # a long thin planar cloud just above its enclosing radius: some triangles of the farthest-point
    # triangulation have circles wider than rho, so edges join a top face to a bottom face
    x = ellipsoid_cloud(40, [1.0, 0.15, 0.0], seed=4)
    r_min = _smallest_admissible_R(x, 0.01) - 0.01
    topo = build_topology(x, 0.01, 0.01 + 1.02 * r_min)
    assert_well_formed(topo, x)
    assert same_faces(topo, brute_force_faces(x, 1.02 * r_min), 1e-7)


def test_spindle_just_above_a_diametral_pair():
    x = np.array([[-1.0, 0, 0], [1, 0, 0], [0, 0.01, 0], [0.5, 0, 0.005], [0, -0.005, 0.003]])
    with pytest.raises(ValueError, match="too small"):
        build_topology(x, 0.1, 0.1 + 1.0 - 1e-6)
    topo = build_topology(x, 0.1, 0.1 + 1.0 + 1e-6)
    assert_well_formed(topo, x)
    assert list(topo.source_index) == [0, 1]
    assert len(topo.faces) == 0 and topo.edges.tolist() == [[0, 1]]
    assert topo.edge_faces.tolist() == [[NO_FACE, NO_FACE]] and topo.edge_real.tolist() == [True]


def test_collinear_points_and_two_points_are_spindles():
    line = np.outer(np.linspace(-1.0, 1.0, 7), [1.0, 2.0, 3.0])[[3, 0, 5, 6, 1, 2, 4]]
    topo = build_topology(line, 0.1, 5.0)
    assert list(topo.source_index) == [1, 3]  # the two ends, in input order
    assert topo.edge_faces.tolist() == [[NO_FACE, NO_FACE]] and topo.edge_real.all()
    topo = build_topology([[0.0, 0, 0], [1, 0, 0]], 0.1, 0.7)
    assert topo.counts() == {"small_spheres": 2, "big_spheres": 0, "tori": 1, "degenerate_tori": 0}


def test_three_points_give_two_faces_one_on_each_side():
    x = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    topo = build_topology(x, 0.1, 2.0)
    assert_well_formed(topo, x)
    assert topo.counts() == {"small_spheres": 3, "big_spheres": 2, "tori": 3, "degenerate_tori": 0}
    assert sorted(np.sign(topo.face_centres[:, 2])) == [-1, 1]
    assert all(sorted(ef) == [0, 1] for ef in topo.edge_faces.tolist())


def test_very_large_R_gives_the_convex_hull():
    x = np.random.default_rng(8).normal(size=(200, 3))
    hull = ConvexHull(x)
    for R in (1e6, 1e12):
        topo = build_topology(x, 0.01, R)
        assert_well_formed(topo, x)
        assert set(topo.source_index.tolist()) == set(hull.vertices.tolist())
        assert ({frozenset(topo.source_index[f].tolist()) for f in topo.faces}
                == {frozenset(s.tolist()) for s in hull.simplices})


def test_result_does_not_depend_on_where_the_cloud_sits():
    x = np.random.default_rng(9).normal(size=(50, 3)) * 0.1
    shift = np.array([1e3, -2e3, 5e2])
    a, b = build_topology(x, 0.01, 0.5), build_topology(x + shift, 0.01, 0.5)
    assert np.array_equal(a.faces, b.faces) and np.array_equal(a.edges, b.edges)
    assert np.abs(a.face_centres + shift - b.face_centres).max() < 1e-9


# ------------------------------------------------------------------------------------ bad input

def _smallest_admissible_R(points, r) -> float:
    """The smallest admissible R, read from the error raised for an R far too small."""
    with pytest.raises(ValueError) as info:
        build_topology(points, r, r * (1 + 1e-12))
    return float(re.search(r"R >= ([0-9.e+-]+) \(with r", str(info.value)).group(1))


@pytest.mark.parametrize("points, r, R, message", [
    ([[0, 0, 0], [1, 0, np.nan]], 0.1, 2.0, "NaN or inf"),
    ([[0, 0, 0], [1, 0, np.inf]], 0.1, 2.0, "NaN or inf"),
    ([[0, 0], [1, 0]], 0.1, 2.0, "shape"),
    ([[0, 0, 0]], 0.1, 2.0, "at least 2"),
    ([[1, 2, 3], [1, 2, 3], [1, 2, 3]], 0.1, 2.0, "at least 2 distinct"),
    ([[0, 0, 0], [1, 0, 0]], 0.0, 2.0, "r .* > 0"),
    ([[0, 0, 0], [1, 0, 0]], -1.0, 2.0, "r .* > 0"),
    ([[0, 0, 0], [1, 0, 0]], 0.1, 0.1, "> r"),
    ([[0, 0, 0], [1, 0, 0]], 0.1, np.inf, "finite"),
    ([[0, 0, 0], [1, 0, 0]], 0.1, 0.5, "too small"),
])
def test_bad_input_raises_value_error_naming_the_problem(points, r, R, message):
    with pytest.raises(ValueError, match=message):
        build_topology(np.array(points, dtype=float), r, R)


def test_too_small_R_reports_the_smallest_admissible_R():
    # enclosing ball of the cube corners: radius sqrt(3)
    R_min = _smallest_admissible_R(CUBE, 0.25)
    assert 0.25 + np.sqrt(3) <= R_min <= 0.25 + np.sqrt(3) + 1e-5
    build_topology(CUBE, 0.25, R_min)  # the printed value is admissible
    # a flat triangle: its circumradius; a diametral pair: half its length
    assert _smallest_admissible_R([[0, 0, 0], [2, 0, 0], [1, 1.5, 0]], 1.0) == pytest.approx(
        1.0 + 1.0833333, abs=1e-5)
    assert _smallest_admissible_R([[0, 0, 0], [4, 0, 0], [2, 0.5, 0.5]], 1.0) == pytest.approx(3.0, abs=1e-5)


@pytest.mark.parametrize("n, k, far", [(1, 1, 1.0), (7, 40, 0.0), (500, 300, 2.0), (2000, 5, 100.0)])
def test_farthest_distances_match_every_pair_measured(n, k, far):
    rng = np.random.default_rng(n + k)
    x = rng.normal(size=(n, 3)) * [0.1, 0.05, 0.02] + [3.0, -1.0, 0.5]
    c = x.mean(axis=0) + rng.normal(size=(k, 3)) * far
    every_pair = np.sqrt(((x[:, None, :] - c[None, :, :]) ** 2).sum(axis=2))  # (n, k), the definition
    got = farthest_distances(x, c)
    assert got.shape == (k,)
    np.testing.assert_allclose(got, every_pair.max(axis=0), rtol=4e-16, atol=0.0)
    # strided points, and centres on points of the cloud (the distance to itself is 0, not the max)
    on_cloud = np.sqrt(((x[:, None, :] - x[None, :3, :]) ** 2).sum(axis=2)).max(axis=0)
    np.testing.assert_allclose(farthest_distances(x[::-1], x[:3]), on_cloud, rtol=4e-16, atol=0.0)


# ------------------------------------------------------------------------------------------ size

@pytest.mark.parametrize("R", [2.0, 0.3])
def test_a_thousand_points_give_a_closed_surface_whose_balls_hold_every_point(R):
    """(Its speed is a benchmark's business, not a test's: the machines are shared.)"""
    x = ellipsoid_cloud(1000, [0.1, 0.07, 0.05], seed=0)
    topo = build_topology(x, 0.005, R)
    assert len(topo.vertices) == 1000 and len(topo.faces) == 1996  # Euler: F = 2V - 4, all on the hull
    far = np.sqrt(((x[:, None, :] - topo.face_centres[None, :, :]) ** 2).sum(axis=2)).max(axis=0)
    assert far.max() <= (R - 0.005) * (1.0 + 1e-12)


def _edge_counts(tris) -> dict:
    """How many triangles hold each undirected edge, counted one by one in plain Python."""
    counts: dict = {}
    for t in tris:
        for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            key = (min(int(a), int(b)), max(int(a), int(b)))
            counts[key] = counts.get(key, 0) + 1
    return counts


@pytest.mark.parametrize("seed", range(6))
def test_boundary_is_manifold_agrees_with_edges_counted_one_by_one(seed):
    from spq.stp.construction import _boundary_is_manifold

    rng = np.random.default_rng(seed)
    closed = ConvexHull(rng.normal(size=(30 + 10 * seed, 3))).simplices
    open_ = closed[1:]
    doubled = np.vstack([closed, closed[:1]])
    # vertex ids far apart, so that an edge key mixing its two ends would collide if it were wrong
    relabelled = np.where(closed == closed.max(), 10**6, closed)
    cases = {"closed": closed, "one face missing": open_, "one face doubled": doubled, "relabelled": relabelled}
    expected = {"closed": True, "one face missing": False, "one face doubled": False, "relabelled": True}
    for name, tris in cases.items():
        oracle = all(c == 2 for c in _edge_counts(tris).values())
        assert oracle == expected[name], name  # the cases are what they say
        assert _boundary_is_manifold(tris) == oracle, name
