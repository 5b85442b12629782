"""The brute-force STP-BV support oracle (tests/stp_oracle.py) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from harness.references.stp_oracle import (
    brute_force_centres_many,
    brute_force_support,
    brute_force_support_many,
    containment_lower_bound,
)


def unit_rows(rng, m):
    v = rng.normal(size=(m, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def ball_cloud(rng, n, radius=1.0):
    return unit_rows(rng, n) * radius * rng.uniform(0, 1, (n, 1)) ** (1 / 3)


def regular_tetrahedron(size=0.5):
    return size * np.array([[1.0, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]])


# ---------------------------------------------------------------- spindle (two points)


def spindle_support(x0, x1, r, R, v):
    """Closed form for two points: a vertex cone at each end, the lemon torus between."""
    rho = R - r
    u = v / np.linalg.norm(v)
    l = np.linalg.norm(x0 - x1)
    e = (x0 - x1) / l
    if u @ e >= l / (2 * rho):
        return x0 + r * u
    if -u @ e >= l / (2 * rho):
        return x1 + r * u
    m, a = (x0 + x1) / 2, np.sqrt(rho ** 2 - l ** 2 / 4)
    w = u - (u @ e) * e
    return m - a * w / np.linalg.norm(w) + R * u


def test_spindle_axis_and_perpendicular():
    x0, x1 = np.array([0.1, 0.2, 0.3]), np.array([0.4, -0.1, 0.5])
    r, R = 0.05, 1.0
    pts = np.array([x0, x1])
    l = np.linalg.norm(x0 - x1)
    e = (x0 - x1) / l
    np.testing.assert_allclose(brute_force_support(pts, r, R, e), x0 + r * e, atol=1e-14)
    np.testing.assert_allclose(brute_force_support(pts, r, R, -3 * e), x1 - r * e, atol=1e-14)
    perp = np.cross(e, [0.0, 0, 1])
    perp /= np.linalg.norm(perp)
    a = np.sqrt((R - r) ** 2 - l ** 2 / 4)
    torus = (x0 + x1) / 2 - a * perp + R * perp
    np.testing.assert_allclose(brute_force_support(pts, r, R, 2.5 * perp), torus, atol=1e-14)
    # across the axis the spindle bulges past the capsule by rho - a ~ l^2 / (8 rho)
    rho = R - r
    assert torus @ perp - x0 @ perp == pytest.approx(r + rho - a, abs=1e-14)
    assert 0 < rho - a < l ** 2 / (4 * rho)


def test_spindle_random_directions():
    rng = np.random.default_rng(1)
    for _ in range(5):
        x0, x1 = rng.uniform(-0.3, 0.3, (2, 3))
        r, R = rng.uniform(0.01, 0.1), rng.uniform(0.5, 3.0)
        V = rng.normal(size=(40, 3))
        S = brute_force_support_many([x0, x1], r, R, V)
        expect = np.array([spindle_support(x0, x1, r, R, v) for v in V])
        np.testing.assert_allclose(S, expect, atol=1e-13)


def test_single_point_is_a_ball():
    x = np.array([[0.3, -0.2, 0.1]])
    for v in unit_rows(np.random.default_rng(2), 10):
        np.testing.assert_allclose(brute_force_support(x, 0.1, 2.0, v), x[0] + 0.1 * v, atol=1e-14)


# ---------------------------------------------------------------- tetrahedron, large R -> polytope + r


def test_tetrahedron_tends_to_polytope_plus_r():
    x = regular_tetrahedron(0.5)
    L = np.linalg.norm(x[0] - x[1])
    r = 0.01
    U = unit_rows(np.random.default_rng(3), 60)
    h_poly = (U @ x.T).max(axis=1) + r  # support of the polytope grown by r
    # directions of the face normals and the edges (between two faces): the largest excesses
    normals = -x / np.linalg.norm(x, axis=1, keepdims=True)  # face opposite vertex i
    edge_dirs = np.array([normals[i] + normals[j] for i in range(4) for j in range(i + 1, 4)])
    edge_dirs /= np.linalg.norm(edge_dirs, axis=1, keepdims=True)
    rt2 = np.sum((x[1:].mean(axis=0) - x[1]) ** 2)  # squared circumradius of a face
    worst = []
    for R in (1e1, 1e2, 1e3, 1e4):
        rho = R - r
        S = brute_force_support_many(x, r, R, U)
        excess = np.einsum("ij,ij->i", U, S) - h_poly
        assert excess.min() >= -1e-12 * R
        assert excess.max() <= L ** 2 / rho  # the excess over the PCH + r is O(L^2 / rho)
        # along a face normal it is exactly rho - sqrt(rho^2 - rt^2) ~ rt^2 / (2 rho)
        Sf = brute_force_support_many(x, r, R, normals)
        excess_f = np.einsum("ij,ij->i", normals, Sf) - ((normals @ x.T).max(axis=1) + r)
        np.testing.assert_allclose(excess_f, rho - np.sqrt(rho ** 2 - rt2), rtol=1e-6, atol=1e-12 * R)
        Se = brute_force_support_many(x, r, R, edge_dirs)
        excess_e = np.einsum("ij,ij->i", edge_dirs, Se) - ((edge_dirs @ x.T).max(axis=1) + r)
        assert (excess_e > 0).all() and excess_e.max() <= L ** 2 / rho
        worst.append(max(excess_f.max(), excess_e.max()))
    assert all(a / 12 < b < a / 8 for a, b in zip(worst, worst[1:]))  # ~1/R
    # towards a vertex (inside its cone once R is large) the support is exactly that small sphere's
    for i in range(4):
        u = x[i] / np.linalg.norm(x[i])
        np.testing.assert_allclose(brute_force_support(x, r, 1e3, u), x[i] + r * u, atol=1e-11)


def test_tetrahedron_face_direction_gives_face_centre():
    """Along a face's outward normal c*(v) is the centre of that face's big sphere."""
    x = regular_tetrahedron(0.2)
    r, R = 0.01, 5.0
    rho = R - r
    for omit in range(4):
        a, b, c = x[[i for i in range(4) if i != omit]]
        n = np.cross(b - a, c - a)
        n *= np.sign(n @ (a - x[omit])) / np.linalg.norm(n)
        cc = (a + b + c) / 3  # circumcentre of an equilateral triangle
        cf = cc - np.sqrt(rho ** 2 - np.sum((cc - a) ** 2)) * n
        np.testing.assert_allclose(brute_force_centres_many(x, rho, n)[0], cf, atol=1e-13)
        np.testing.assert_allclose(brute_force_support(x, r, R, n), cf + R * n, atol=1e-13)


# ---------------------------------------------------------------- random clouds


@pytest.mark.parametrize("seed,n,R", [(4, 12, 2.0), (5, 30, 1.5), (6, 40, 10.0)])
def test_random_cloud_support_properties(seed, n, R):
    rng = np.random.default_rng(seed)
    x = ball_cloud(rng, n)  # enclosing radius <= 1 < rho
    r = 0.05
    U = unit_rows(rng, 40)
    S = brute_force_support_many(x, r, R, U)
    h = np.einsum("ij,ij->i", U, S)
    # contains every small sphere
    lower = np.array([containment_lower_bound(x, r, u) for u in U])
    assert (h >= lower - 1e-12).all()
    # s(u) maximises u.s over the other support points (all of them lie in the STP-BV)
    H = U @ S.T
    assert (h[:, None] >= H - 1e-12).all()
    # c* = s - R u lies in every ball B(x_i, rho)
    c = S - R * U
    assert np.linalg.norm(c[:, None] - x[None], axis=2).max() <= (R - r) * (1 + 1e-12)
    # single-direction form agrees, and the scale of v does not matter
    for k in range(3):
        np.testing.assert_array_equal(brute_force_support(x, r, R, U[k]), S[k])
        np.testing.assert_allclose(brute_force_support(x, r, R, 7.0 * U[k]), S[k], atol=1e-14)


def test_support_is_frame_covariant():
    rng = np.random.default_rng(7)
    x = ball_cloud(rng, 15, 0.5)
    r, R = 0.02, 1.0
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    t = rng.normal(size=3)
    U = unit_rows(rng, 10)
    S = brute_force_support_many(x, r, R, U)
    S2 = brute_force_support_many(x @ q.T + t, r, R, U @ q.T)
    np.testing.assert_allclose(S2, S @ q.T + t, atol=1e-12)


def test_bad_input():
    x = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    with pytest.raises(ValueError):
        brute_force_support(x, 0.1, 0.4, [1.0, 0, 0])  # 2 rho < distance: Q empty
    with pytest.raises(ValueError):
        brute_force_support(x, 0.5, 0.4, [1.0, 0, 0])  # R < r
    with pytest.raises(ValueError):
        brute_force_support(x, 0.1, 2.0, [0.0, 0, 0])
    # points that pass the diameter test but have no common rho-ball (equilateral triangle)
    tri = np.array([[1.0, 0, 0], [-0.5, np.sqrt(3) / 2, 0], [-0.5, -np.sqrt(3) / 2, 0]])
    with pytest.raises(ValueError):
        brute_force_support(tri, 0.01, 0.01 + 0.9, [0.0, 0, 1])  # 2 rho = 1.8 > sqrt(3), rho < 1


# ---------------------------------------------------------------- against the sch files' big spheres


@pytest.mark.parametrize("name,tol", [("sch-creator-examples/stp/cube2x2.txt", 1e-9),
                                      ("sch-creator-examples/stp/s2x2.txt", 1e-9),
                                      ("sch-samples/sample_stpbv1.txt", 2e-4)])
def test_oracle_finds_the_files_face_centres(shared_datasets, name, tol):
    """Towards the middle of each face's region, c* is that face's big-sphere centre."""
    from spq.io.sch import read_sch_stp

    t = read_sch_stp(shared_datasets / name)
    mid = t.vertices[t.faces].mean(axis=1) - t.face_centres
    C = brute_force_centres_many(t.vertices, t.rho, mid)
    assert np.abs(C - t.face_centres).max() <= tol * t.R
    if name.startswith("sch-creator"):  # 16 digits: c* is exactly where the face's three spheres meet
        dist = np.linalg.norm(C[:, None] - t.vertices[t.faces], axis=2)
        assert np.abs(dist - t.rho).max() <= 1e-12 * t.R
    # (the sch-core samples print 6 digits: after rounding a few of their faces, 2 of 80 in
    # sample_stpbv1, are no longer exact faces of the rounded points' ball hull, by ~1e-8)


def test_the_vectorised_brute_force_chooses_as_the_loop_does():
    from harness.references.stp_oracle import BruteForceSTP

    rng = np.random.default_rng(3)
    pts = rng.normal(size=(12, 3)) * 0.05
    V = rng.normal(size=(50, 3))
    np.testing.assert_allclose(BruteForceSTP(pts, 0.01, 0.5).support_many(V),
                               brute_force_support_many(pts, 0.01, 0.5, V), atol=1e-15)
