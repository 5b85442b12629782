"""The Minkowski-hull reference against closed-form answers and a brute-force feature oracle."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from datasets import load_object
from datasets.generated import random_hull
from harness.references.minkowski import (
    TOUCH_TOL,
    MinkowskiReference,
    closest_points_on_triangles,
    reference_distance,
    reference_many,
)
from spq.shapes.polyhedron import Polyhedron


def box(hx, hy, hz) -> Polyhedron:
    s = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
    return Polyhedron.from_points(s * [hx, hy, hz])


def pose(rot=None, t=(0.0, 0.0, 0.0)) -> np.ndarray:
    out = np.eye(4)
    if rot is not None:
        out[:3, :3] = rot.as_matrix() if isinstance(rot, Rotation) else rot
    out[:3, 3] = t
    return out


def check_consistent(res, tol=1e-13):
    """Invariants of every result: signs, unit normal, witness gap = |signed distance|."""
    assert res.distance >= 0 and res.depth >= 0
    assert res.distance == 0 or res.depth == 0
    assert res.signed_distance == pytest.approx(res.distance - res.depth, abs=0)
    assert abs(np.linalg.norm(res.normal) - 1) < 1e-12
    gap = res.point_b - res.point_a
    assert abs(np.linalg.norm(gap) - abs(res.signed_distance)) <= tol
    if abs(res.signed_distance) > 1e-9:
        # the gap is along the normal: +normal when separated, -normal when overlapping
        assert np.allclose(gap, res.signed_distance * res.normal, atol=tol)
    expected = "touching" if abs(res.signed_distance) <= TOUCH_TOL else (
        "overlapping" if res.signed_distance < 0 else "separated")
    assert res.status == expected


# ------------------------------------------------------------------------------------------------
# brute-force oracle: separated distance = min over vertex-face, face-vertex and edge-edge pairs;
# penetration depth = min over candidate facet normals u of D = A - B of h_A(u) + h_B(-u)
# ------------------------------------------------------------------------------------------------


def world(poly, T):
    return poly.vertices @ T[:3, :3].T + T[:3, 3]


def edges_of(poly):
    f = poly.faces
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


def point_segment_d2(p, a, b):
    """Squared distances of points p (..., 3) to segments [a, b] (..., 3)."""
    e = b - a
    ee = np.einsum("...i,...i", e, e)
    t = np.clip(np.einsum("...i,...i", p - a, e) / np.where(ee > 0, ee, 1.0), 0.0, 1.0)
    q = a + t[..., None] * e - p
    return np.einsum("...i,...i", q, q)


def point_triangle_d2(p, a, b, c):
    """Squared distance of points p (P, 3) to triangles (T, 3) each: (P, T). Interior projection if
    inside, else the closest edge (written independently of the reference's implementation)."""
    p = p[:, None, :]
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    h = np.einsum("ptk,tk->pt", p - a, n) / nn
    q = p - h[..., None] * n
    inside = np.ones(q.shape[:2], dtype=bool)
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ptk,tk->pt", np.cross(v - u, q - u), n) >= 0
    best = np.minimum.reduce([point_segment_d2(p, u, v) for u, v in ((a, b), (b, c), (c, a))])
    face = np.einsum("ptk,ptk->pt", p - q, p - q)
    return np.where(inside, np.minimum(face, best), best)


def segment_segment_d2(p0, p1, q0, q1):
    """Squared distance between segment arrays (broadcasting): endpoint cases plus the interior
    (line-line) solution when both parameters fall strictly inside."""
    cands = [point_segment_d2(p0, q0, q1), point_segment_d2(p1, q0, q1),
             point_segment_d2(q0, p0, p1), point_segment_d2(q1, p0, p1)]
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a = np.einsum("...i,...i", d1, d1)
    e = np.einsum("...i,...i", d2, d2)
    b = np.einsum("...i,...i", d1, d2)
    c = np.einsum("...i,...i", d1, r)
    f = np.einsum("...i,...i", d2, r)
    den = a * e - b * b
    ok = den > 1e-14 * a * e
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (b * f - c * e) / den
        t = (a * f - b * c) / den
    ok &= (s > 0) & (s < 1) & (t > 0) & (t < 1)
    diff = p0 + s[..., None] * d1 - q0 - t[..., None] * d2
    inner = np.where(ok, np.einsum("...i,...i", diff, diff), np.inf)
    return np.minimum(np.minimum.reduce(cands), inner)


def brute_force_distance(pa, pb, Ta, Tb) -> float:
    va, vb = world(pa, Ta), world(pb, Tb)
    fa, fb = va[pa.faces], vb[pb.faces]
    d2 = min(point_triangle_d2(va, fb[:, 0], fb[:, 1], fb[:, 2]).min(),
             point_triangle_d2(vb, fa[:, 0], fa[:, 1], fa[:, 2]).min())
    ea, eb = va[edges_of(pa)], vb[edges_of(pb)]
    d2 = min(d2, segment_segment_d2(ea[:, None, 0], ea[:, None, 1], eb[None, :, 0], eb[None, :, 1]).min())
    return float(np.sqrt(d2))


def brute_force_depth(pa, pb, Ta, Tb) -> tuple[float, np.ndarray]:
    va, vb = world(pa, Ta), world(pb, Tb)
    na = pa.face_normals @ Ta[:3, :3].T
    nb = pb.face_normals @ Tb[:3, :3].T
    ea = va[edges_of(pa)[:, 1]] - va[edges_of(pa)[:, 0]]
    eb = vb[edges_of(pb)[:, 1]] - vb[edges_of(pb)[:, 0]]
    cross = np.cross(ea[:, None], eb[None, :]).reshape(-1, 3)
    norm = np.linalg.norm(cross, axis=1)
    cross = cross[norm > 1e-12 * norm.max()] / norm[norm > 1e-12 * norm.max(), None]
    u = np.concatenate([na, -nb, cross, -cross])
    h = (u @ va.T).max(axis=1) + (-(u @ vb.T)).max(axis=1)
    k = int(np.argmin(h))
    return float(h[k]), u[k]


# ------------------------------------------------------------------------------------------------
# closed-form cases
# ------------------------------------------------------------------------------------------------

A_BOX = box(1.0, 1.0, 1.0)
B_BOX = box(0.5, 0.5, 0.5)


@pytest.mark.parametrize(
    "t_b, dist, normal",
    [
        ((3.0, 0.0, 0.0), 1.5, (1, 0, 0)),  # face-face
        ((0.0, -2.0, 0.25), 0.5, (0, -1, 0)),  # face-face, partial overlap of the faces
        ((3.0, 3.0, 0.0), 1.5 * np.sqrt(2), (1, 1, 0)),  # edge-edge (parallel edges)
        ((3.0, 3.0, 3.0), 1.5 * np.sqrt(3), (1, 1, 1)),  # vertex-vertex
        ((-2.0, 2.5, -3.0), np.sqrt(0.5**2 + 1.0**2 + 1.5**2), (-0.5, 1.0, -1.5)),  # vertex-vertex
    ],
)
def test_boxes_closed_form(t_b, dist, normal):
    res = reference_distance(A_BOX, B_BOX, pose(), pose(t=t_b))
    check_consistent(res)
    assert res.status == "separated"
    assert res.distance == pytest.approx(dist, abs=1e-14)
    np.testing.assert_allclose(res.normal, np.array(normal) / np.linalg.norm(normal), atol=1e-14)
    assert A_BOX.signed_distance_to_surface(res.point_a)[0] == pytest.approx(0.0, abs=1e-14)
    assert B_BOX.signed_distance_to_surface(res.point_b - t_b)[0] == pytest.approx(0.0, abs=1e-14)


def test_vertex_vertex_witnesses_are_the_corners():
    res = reference_distance(A_BOX, B_BOX, pose(), pose(t=(3.0, 3.0, 3.0)))
    np.testing.assert_allclose(res.point_a, [1, 1, 1], atol=1e-15)
    np.testing.assert_allclose(res.point_b, [2.5, 2.5, 2.5], atol=1e-15)


def test_crossed_edges():
    # long thin boxes turned 45 degrees about their long axes: A's top is an edge along x, B's
    # bottom an edge along y; they cross above the origin
    a = box(1.0, 0.2, 0.2)
    b = box(0.2, 1.0, 0.2)
    c = 1.0
    Ta = pose(Rotation.from_euler("x", 45, degrees=True))
    Tb = pose(Rotation.from_euler("y", 45, degrees=True), (0.0, 0.0, c))
    res = reference_distance(a, b, Ta, Tb)
    check_consistent(res)
    r = 0.2 * np.sqrt(2)
    assert res.distance == pytest.approx(c - 2 * r, abs=1e-15)
    np.testing.assert_allclose(res.point_a, [0, 0, r], atol=1e-15)
    np.testing.assert_allclose(res.point_b, [0, 0, c - r], atol=1e-15)
    np.testing.assert_allclose(res.normal, [0, 0, 1], atol=1e-15)


def test_vertex_face():
    # B's corner (1, 1, 1) * 0.5 turned to point along -x, towards A's face x = 1
    rot, _ = Rotation.align_vectors([[-1.0, 0.0, 0.0]], [np.ones(3) / np.sqrt(3)])
    res = reference_distance(A_BOX, B_BOX, pose(), pose(rot, (3.0, 0.2, -0.1)))
    check_consistent(res)
    assert res.distance == pytest.approx(2.0 - 0.5 * np.sqrt(3), abs=1e-14)
    np.testing.assert_allclose(res.point_b, [3.0 - 0.5 * np.sqrt(3), 0.2, -0.1], atol=1e-14)
    np.testing.assert_allclose(res.point_a, [1.0, 0.2, -0.1], atol=1e-14)


def test_overlap_depth_and_direction():
    res = reference_distance(A_BOX, B_BOX, pose(), pose(t=(1.3, 0.1, -0.2)))
    check_consistent(res)
    assert res.status == "overlapping"
    assert res.distance == 0.0
    assert res.depth == pytest.approx(0.2, abs=1e-14)
    assert res.signed_distance == pytest.approx(-0.2, abs=1e-14)
    np.testing.assert_allclose(res.normal, [1, 0, 0], atol=1e-14)
    # B inside A, nearest wall is y = +1 at 0.3 from B's face y = 0.7
    res = reference_distance(A_BOX, B_BOX, pose(), pose(t=(0.0, 0.2, 0.0)))
    assert res.depth == pytest.approx(1.3, abs=1e-14)
    np.testing.assert_allclose(res.normal, [0, 1, 0], atol=1e-14)


def test_touching():
    for t_b in [(1.5, 0.2, -0.1), (1.5, 1.5, 0.0), (1.5, 1.5, 1.5)]:
        res = reference_distance(A_BOX, B_BOX, pose(), pose(t=t_b))
        check_consistent(res)
        assert res.status == "touching"
        assert abs(res.signed_distance) <= 1e-15


def test_rigid_invariance_and_swap():
    rng = np.random.default_rng(4)
    cases = [(3, 0, 0), (3, 3, 0), (3, 3, 3), (1.3, 0.1, -0.2), (0.0, -2.0, 0.25)]
    for t_b in cases:
        base = reference_distance(A_BOX, B_BOX, pose(), pose(t=t_b))
        G = pose(Rotation.random(random_state=rng), rng.uniform(-5, 5, 3))
        moved = reference_distance(A_BOX, B_BOX, G, G @ pose(t=t_b))
        check_consistent(moved)
        assert moved.signed_distance == pytest.approx(base.signed_distance, abs=1e-14)
        np.testing.assert_allclose(moved.normal, G[:3, :3] @ base.normal, atol=1e-13)
        swapped = reference_distance(B_BOX, A_BOX, G @ pose(t=t_b), G)
        assert swapped.signed_distance == pytest.approx(base.signed_distance, abs=1e-14)
        np.testing.assert_allclose(swapped.normal, -moved.normal, atol=1e-13)


def test_far_from_world_origin_keeps_precision():
    # re-centred differences: the answer does not degrade with the bodies' distance to the origin
    far = np.array([1e4, -2e4, 3e4])
    res = reference_distance(A_BOX, B_BOX, pose(t=far), pose(t=far + [3.0, 0.1, 0.2]))
    assert res.distance == pytest.approx(1.5, abs=1e-13)


# ------------------------------------------------------------------------------------------------
# brute-force oracle on random hulls and robot links
# ------------------------------------------------------------------------------------------------


def random_pair_poses(rng, spread):
    Ta = pose(Rotation.random(random_state=rng), rng.uniform(-0.05, 0.05, 3))
    Tb = pose(Rotation.random(random_state=rng), Ta[:3, 3] + rng.normal(size=3) * spread)
    return Ta, Tb


def test_against_brute_force_random_hulls():
    rng = np.random.default_rng(11)
    seen = {"separated": 0, "overlapping": 0}
    for k in range(40):
        a = random_hull(int(rng.integers(8, 40)), seed=1000 + k, axes=rng.uniform(0.2, 1.0, 3))
        b = random_hull(int(rng.integers(8, 40)), seed=2000 + k, axes=rng.uniform(0.2, 1.0, 3))
        Ta, Tb = random_pair_poses(rng, 0.12)
        res = reference_distance(a, b, Ta, Tb)
        check_consistent(res)
        seen[res.status] = seen.get(res.status, 0) + 1
        if res.status == "separated":
            assert res.distance == pytest.approx(brute_force_distance(a, b, Ta, Tb), abs=1e-15)
        else:
            depth, u = brute_force_depth(a, b, Ta, Tb)
            assert res.depth == pytest.approx(depth, abs=1e-15)
        # witness points lie on the bodies (within rounding)
        assert a.signed_distance_to_surface((res.point_a - Ta[:3, 3]) @ Ta[:3, :3])[0] <= 1e-15
        assert b.signed_distance_to_surface((res.point_b - Tb[:3, 3]) @ Tb[:3, :3])[0] <= 1e-15
    assert seen["separated"] >= 5 and seen["overlapping"] >= 5


def test_against_brute_force_robot_links():
    a, b = load_object("kuka_link_4"), load_object("panda_hand")
    rng = np.random.default_rng(5)
    for _ in range(3):
        Ta, Tb = random_pair_poses(rng, 0.3)
        res = reference_distance(a, b, Ta, Tb)
        check_consistent(res)
        if res.status == "separated":
            assert res.distance == pytest.approx(brute_force_distance(a, b, Ta, Tb), abs=2e-16)
        else:
            assert res.depth == pytest.approx(brute_force_depth(a, b, Ta, Tb)[0], abs=2e-16)


def test_prefilter_keeps_the_exact_hull():
    rng = np.random.default_rng(8)
    for name_a, name_b in [("kuka_link_4", "kuka_link_4"), ("panda_link_2", "kuka_link_6"), ("random_hull_200", "panda_hand")]:
        a, b = load_object(name_a), load_object(name_b)
        Ta, Tb = random_pair_poses(rng, 0.15)
        fast = MinkowskiReference(a, b, Ta, Tb)
        full = MinkowskiReference(a, b, Ta, Tb, prefilter=False)
        assert fast.n_candidates < full.n_candidates
        for off in (np.zeros(3), rng.normal(size=3) * 0.05):
            r1, r2 = fast.query(off), full.query(off)
            assert r1.signed_distance == pytest.approx(r2.signed_distance, abs=1e-16)
            assert r1.status == r2.status


def test_query_offset_matches_rebuilt_hull():
    a, b = load_object("random_hull_50"), load_object("random_hull_200")
    rng = np.random.default_rng(2)
    Ta, Tb = random_pair_poses(rng, 0.2)
    ref = MinkowskiReference(a, b, Ta, Tb)
    for _ in range(5):
        off = rng.normal(size=3) * 0.1
        Tb2 = Tb.copy()
        Tb2[:3, 3] += off
        r1, r2 = ref.query(off), reference_distance(a, b, Ta, Tb2)
        assert r1.signed_distance == pytest.approx(r2.signed_distance, abs=1e-15)
        assert r1.status == r2.status
        np.testing.assert_allclose(r1.normal, r2.normal, atol=1e-12)


def test_reference_many_matches_single():
    a, b = load_object("random_hull_50"), load_object("random_hull_50")
    rng = np.random.default_rng(3)
    pa, pb = zip(*(random_pair_poses(rng, 0.2) for _ in range(4)))
    many = reference_many(a, b, np.array(pa), np.array(pb))
    pooled = reference_many(a, b, np.array(pa), np.array(pb), processes=2, chunksize=1)
    for r, q, Ta, Tb in zip(many, pooled, pa, pb):
        assert r.signed_distance == q.signed_distance == reference_distance(a, b, Ta, Tb).signed_distance
        np.testing.assert_array_equal(r.point_a, q.point_a)


# ------------------------------------------------------------------------------------------------
# point-triangle kernel: every Voronoi region and degenerate triangles
# ------------------------------------------------------------------------------------------------


def test_closest_points_on_triangles_regions():
    def shifted(corners, p):  # triangle relative to the query point p
        return np.asarray(corners, float) - np.asarray(p, float)

    tri = [(0, 0, 0), (2, 0, 0), (0, 2, 0)]
    cases = [
        ((0.5, 0.5, 3.0), 9.0, (0.5, 0.25, 0.25)),  # interior
        ((1.5, 1.5, 0.0), 0.5, (0, 0.5, 0.5)),  # hypotenuse edge
        ((-1.0, 1.0, 1.0), 2.0, (0.5, 0, 0.5)),  # edge x = 0
        ((-1.0, -1.0, 0.0), 2.0, (1, 0, 0)),  # vertex 0
        ((3.0, -1.0, 0.0), 2.0, (0, 1, 0)),  # vertex 1
        ((0.0, 3.0, 4.0), 17.0, (0, 0, 1)),  # vertex 2
    ]
    for p, d2, lam in cases:
        got_d2, got_lam = closest_points_on_triangles(shifted(tri, p)[None])
        assert got_d2[0] == pytest.approx(d2, abs=1e-14)
        np.testing.assert_allclose(got_lam[0], lam, atol=1e-14)
    degenerate = [
        [(0, 0, 0), (1, 0, 0), (2, 0, 0)],  # collinear
        [(1, 0, 0), (1, 0, 0), (3, 0, 0)],  # repeated corner
        [(1, 1, 1), (1, 1, 1), (1, 1, 1)],  # a point
        [(0, 0, 0), (1, 1e-300, 0), (2, 0, 0)],  # near-zero area
    ]
    for corners in degenerate:
        c = np.asarray(corners, float) - [0.5, 1.0, 0.0]
        d2, lam = closest_points_on_triangles(c[None])
        expect = min(point_segment_d2(np.zeros(3), c[i], c[j]) for i, j in ((0, 1), (1, 2), (0, 2)))
        assert np.isfinite(d2[0]) and d2[0] == pytest.approx(expect, abs=1e-15)
        assert lam.min() >= 0 and lam.sum() == pytest.approx(1.0)
        assert np.linalg.norm(lam[0] @ c) ** 2 == pytest.approx(d2[0], abs=1e-15)


def test_random_triangles_against_sampling():
    rng = np.random.default_rng(0)
    tri = rng.normal(size=(200, 3, 3))
    d2, lam = closest_points_on_triangles(tri)
    w = rng.dirichlet(np.ones(3), size=4000)
    sampled = np.einsum("sk,tkx->tsx", w, tri)
    sampled_d2 = np.einsum("tsx,tsx->ts", sampled, sampled).min(axis=1)
    assert (d2 <= sampled_d2 + 1e-14).all()  # never worse than any point of the triangle
    pts = np.einsum("tk,tkx->tx", lam, tri)
    np.testing.assert_allclose(np.einsum("tx,tx->t", pts, pts), d2, atol=1e-14)
    np.testing.assert_allclose(d2, np.array([point_triangle_d2(np.zeros((1, 3)), t[None, 0], t[None, 1], t[None, 2])[0, 0] for t in tri]), atol=1e-13)


# ------------------------------------------------------------------------------------------------
# input validation
# ------------------------------------------------------------------------------------------------


def test_bad_input_raises_value_error():
    with pytest.raises(ValueError, match="Polyhedron"):
        MinkowskiReference(np.zeros((4, 3)), B_BOX, pose(), pose())
    with pytest.raises(ValueError, match="pose_b"):
        MinkowskiReference(A_BOX, B_BOX, pose(), np.eye(3))
    bad = pose()
    bad[0, 0] = 2.0
    with pytest.raises(ValueError, match="rotation"):
        MinkowskiReference(A_BOX, B_BOX, bad, pose())
    ref = MinkowskiReference(A_BOX, B_BOX, pose(), pose(t=(3, 0, 0)))
    with pytest.raises(ValueError, match="offset"):
        ref.query([1.0, 2.0])
    with pytest.raises(ValueError, match="offset"):
        ref.query([np.nan, 0, 0])
    with pytest.raises(ValueError, match="same length"):
        reference_many(A_BOX, B_BOX, np.stack([pose(), pose()]), pose())
