"""spq.distance_gradient against central finite differences of spq.distance (tight solver tolerance)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import spq

TOL = dict(tol=1e-13, rel_tol=1e-13)
H = 1e-6  # m / rad: FD step; truncation ~h^2 d''' and noise ~tol/h, both far below 1e-6
AGREE = 1e-6  # relative agreement (to max(1, |grad|)) expected for smooth pairs


def perturb(pose: np.ndarray, k: int, h: float) -> np.ndarray:
    """Move coordinate k (0-2: world translation, 3-5: world rotation about the body origin) by h."""
    out = pose.copy()
    if k < 3:
        out[k, 3] += h
    else:
        w = np.zeros(3)
        w[k - 3] = h
        out[:3, :3] = Rotation.from_rotvec(w).as_matrix() @ pose[:3, :3]
    return out


def fd_gradient(A, pa, B, pb, h=H, coords=range(12)) -> np.ndarray:
    """(12,) central differences: coordinates 0-5 of A, 6-11 of B (NaN for coordinates not asked)."""
    g = np.full(12, np.nan)
    for k in coords:
        if k < 6:
            plus = spq.distance(A, B, perturb(pa, k, h), pb, **TOL).distance
            minus = spq.distance(A, B, perturb(pa, k, -h), pb, **TOL).distance
        else:
            plus = spq.distance(A, B, pa, perturb(pb, k - 6, h), **TOL).distance
            minus = spq.distance(A, B, pa, perturb(pb, k - 6, -h), **TOL).distance
        g[k] = (plus - minus) / (2 * h)
    return g


def random_pose(rng, offset) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = Rotation.random(random_state=rng.integers(1 << 31)).as_matrix()
    pose[:3, 3] = offset
    return pose


def analytic(A, pa, B, pb) -> tuple[np.ndarray, spq.DistanceResult]:
    res = spq.distance(A, B, pa, pb, **TOL)
    ga, gb = spq.distance_gradient(res, pa, pb)
    return np.concatenate([ga, gb]), res


@pytest.fixture(scope="module")
def cloud() -> np.ndarray:
    return spq.Polyhedron.from_points(np.random.default_rng(0).normal(size=(200, 3)) * 0.1).vertices


@pytest.fixture(scope="module")
def shapes(cloud):
    pch = spq.Polyhedron.from_points(cloud)
    stp = spq.STPBV.from_points(cloud, 0.005, 2.0)
    cse = spq.Superellipsoid(0.12, 0.08, 0.1, 0.6, 0.8)
    return {"PCH": pch, "STP": stp, "CSE": cse}


def pose_pairs(seed: int, count: int = 3, gap: float = 0.8):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        yield random_pose(rng, rng.normal(size=3) * 0.05), random_pose(rng, direction * gap)


@pytest.mark.parametrize("names", [("STP", "STP"), ("STP", "PCH"), ("PCH", "STP"), ("CSE", "CSE"),
                                   ("CSE", "STP")])
def test_smooth_pairs_all_coordinates(shapes, names):
    A, B = shapes[names[0]], shapes[names[1]]
    for pa, pb in pose_pairs(1):
        g, res = analytic(A, pa, B, pb)
        assert res.status == "separated" and res.distance > 0.01
        fd = fd_gradient(A, pa, B, pb)
        err = np.abs(g - fd).max() / max(1.0, np.abs(g).max())
        assert err < AGREE, (names, err, g, fd)


def test_superellipsoid_fit_pair():
    cloud = spq.Polyhedron.from_points(np.random.default_rng(2).normal(size=(100, 3)) * [0.1, 0.06, 0.04]).vertices
    fit = spq.Superellipsoid.fit(cloud)
    for pa, pb in pose_pairs(3, count=2):
        pa, pb = pa @ fit.pose, pb @ fit.pose
        g, res = analytic(fit.shape, pa, fit.shape, pb)
        assert res.status == "separated"
        fd = fd_gradient(fit.shape, pa, fit.shape, pb)
        assert np.abs(g - fd).max() < AGREE * max(1.0, np.abs(g).max())


def test_sphere_sphere_closed_form():
    a, b = spq.Sphere(0.1), spq.Sphere(0.25)
    rng = np.random.default_rng(4)
    for _ in range(3):
        pa, pb = random_pose(rng, rng.normal(size=3) * 0.1), random_pose(rng, [0.9, -0.3, 0.4])
        g, res = analytic(a, pa, b, pb)
        c = pb[:3, 3] - pa[:3, 3]
        n = c / np.linalg.norm(c)
        np.testing.assert_allclose(res.distance, np.linalg.norm(c) - 0.35, atol=1e-12)
        # closed form: centres are the origins, so rotations change nothing
        np.testing.assert_allclose(g, np.concatenate([-n, np.zeros(3), n, np.zeros(3)]), atol=1e-9)
        fd = fd_gradient(a, pa, b, pb)
        np.testing.assert_allclose(g, fd, atol=AGREE)


def test_offset_sphere_rotation_about_body_origin():
    """A sphere centred away from its body origin: rotation about the origin moves it; check the sign/pivot."""
    ball = spq.Sphere(0.05)
    pa = np.eye(4)
    pb = np.eye(4)
    pb[:3, 3] = [1.0, 0.0, 0.0]
    # sphere B is offset by the pose composed with a local shift
    shift = np.eye(4)
    shift[:3, 3] = [0.0, 0.3, 0.0]
    pb_shifted = pb @ shift  # body origin moves: gradient pivots about pb_shifted's translation, not pb's
    g, _ = analytic(ball, pa, ball, pb_shifted)
    fd = fd_gradient(ball, pa, ball, pb_shifted)
    np.testing.assert_allclose(g, fd, atol=AGREE)


def test_polyhedra_translations_only(shapes):
    pch = shapes["PCH"]
    for pa, pb in pose_pairs(5):
        g, res = analytic(pch, pa, pch, pb)
        assert res.status == "separated"
        coords = [0, 1, 2, 6, 7, 8]
        fd = fd_gradient(pch, pa, pch, pb, coords=coords)
        np.testing.assert_allclose(g[coords], fd[coords], atol=AGREE)


def test_kuka_link_stp():
    from datasets import load_object

    link = load_object("kuka_link_4")
    stp = spq.STPBV.from_points(link.vertices, 0.005, 2.0)
    for pa, pb in pose_pairs(6, count=2, gap=0.5):
        g, res = analytic(stp, pa, link, pb)
        assert res.status == "separated"
        fd = fd_gradient(stp, pa, link, pb)
        assert np.abs(g - fd).max() < AGREE * max(1.0, np.abs(g).max())


def test_nan_when_overlapping(shapes):
    stp = shapes["STP"]
    res = spq.distance(stp, stp, np.eye(4), np.eye(4))
    assert res.status == "overlapping"
    ga, gb = spq.distance_gradient(res, np.eye(4), np.eye(4))
    assert np.isnan(ga).all() and np.isnan(gb).all()


def test_batch_matches_single(shapes):
    A, B = shapes["STP"], shapes["CSE"]
    pairs = list(pose_pairs(7, count=4))
    pa = np.stack([p for p, _ in pairs] + [np.eye(4)])
    pb = np.stack([q for _, q in pairs] + [np.eye(4)])  # last row overlaps
    batch = spq.distances(A, B, pa, pb, **TOL)
    ga, gb = spq.distance_gradients(batch, pa, pb)
    assert ga.shape == gb.shape == (5, 6)
    for i in range(4):
        sa, sb = spq.distance_gradient(spq.distance(A, B, pa[i], pb[i], **TOL), pa[i], pb[i])
        np.testing.assert_allclose(ga[i], sa, atol=1e-9)
        np.testing.assert_allclose(gb[i], sb, atol=1e-9)
    assert np.isnan(ga[4]).all() and np.isnan(gb[4]).all()
    # a single pose broadcast for A
    batch1 = spq.distances(A, B, pa[0], pb[:4], **TOL)
    ga1, _ = spq.distance_gradients(batch1, pa[0], pb[:4])
    assert ga1.shape == (4, 6) and np.isfinite(ga1).all()
