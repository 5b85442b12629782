"""The independent depth oracle (harness.references.depth_oracle): its supports against brute force and closed
forms, and spq's signed distance against it on pairs with an STP-BV or a superellipsoid."""

from __future__ import annotations

import numpy as np
import pytest

import spq
from harness.references import depth_oracle as do
from tests.conftest import require_shared_datasets

BOXY = (0.08, 0.05, 0.12, 0.42, 1.02)  # a, b, c (m), e1, e2: the fitted kuka_link_4 cover's exponents


def _units(n, seed):
    u = np.random.default_rng(seed).normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def _surface(a, b, c, e1, e2, m=1500):
    th, ph = np.meshgrid(np.linspace(-np.pi / 2, np.pi / 2, m), np.linspace(-np.pi, np.pi, 2 * m), indexing="ij")

    def f(w, e):
        return np.sign(w) * np.abs(w) ** e

    return np.stack([a * f(np.cos(th), e1) * f(np.cos(ph), e2), b * f(np.cos(th), e1) * f(np.sin(ph), e2),
                     c * f(np.sin(th), e1)], -1).reshape(-1, 3)


@pytest.mark.parametrize("shape", [BOXY, (0.1, 0.1, 0.1, 1.0, 1.0), (0.05, 0.2, 0.1, 1.5, 0.3)])
def test_superellipsoid_support_lies_on_the_surface_and_beats_every_sampled_point(shape):
    U = _units(40, 1)
    s, h = do.superellipsoid_support(*shape, U)
    np.testing.assert_allclose(do.superellipsoid_implicit(*shape, s), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.einsum("ij,ij->i", s, U), h, atol=1e-15)
    sampled = (_surface(*shape) @ U.T).max(axis=0)
    assert (sampled <= h + 1e-12).all()  # nothing of the body beyond the support plane
    assert np.abs(sampled - h).max() < 1e-5  # and the dense sampling nearly reaches it


def test_oracle_on_two_balls_and_a_ball_against_a_box_face():
    ball = do.Body("CSE", (0.1, 0.1, 0.1, 1.0, 1.0), np.eye(4))
    other = do.Body("CSE", (0.05, 0.05, 0.05, 1.0, 1.0), np.eye(4))
    pb = np.eye(4)
    pb[:3, 3] = [0.03, -0.08, 0.05]
    r = do.signed_distance(ball, np.eye(4), other, pb)
    assert abs(r.signed_distance - (np.linalg.norm(pb[:3, 3]) - 0.15)) < 1e-12
    np.testing.assert_allclose(r.normal, pb[:3, 3] / np.linalg.norm(pb[:3, 3]), atol=1e-6)
    corners = np.array([[x, y, z] for x in (-0.2, 0.2) for y in (-0.2, 0.2) for z in (-0.1, 0.1)])
    box = do.Body("PCH", (corners,), np.eye(4))
    pb = np.eye(4)
    pb[:3, 3] = [0.01, -0.02, 0.1 + 0.05 - 0.003]  # the ball 3 mm into the top face
    r = do.signed_distance(box, np.eye(4), other, pb)
    assert abs(r.signed_distance + 0.003) < 1e-12
    np.testing.assert_allclose(r.normal, [0, 0, 1], atol=1e-9)


def test_bad_input_raises():
    with pytest.raises(ValueError, match="kind"):
        do.body_of("XYZ", None)
    with pytest.raises(ValueError, match="unknown pairs"):
        do.run(do.DepthConfig(pairs=("STP-XYZ",)), None, progress=False)
    with pytest.raises(ValueError, match="below 2"):
        do.superellipsoid_support(1, 1, 1, 2.0, 1.0, np.eye(3))


@pytest.fixture(scope="module")
def bodies():
    require_shared_datasets()
    from datasets import load_object

    return do.shapes(do.DepthConfig(), load_object)


@pytest.mark.parametrize("pair", do.PAIRS)
def test_spq_depth_matches_the_oracle_and_its_interval_holds_it(bodies, pair):
    an, bn = pair.split("-")
    (sa, oa), (sb, ob) = bodies[an], bodies[bn]
    size = 0.5 * (sa.bounding_radius() + sb.bounding_radius())
    buckets = {"overlap-1e-3": 1e-3, "overlap-1e-1": 1e-1}
    suite = do.depth_suite(do.body_of(an, sa, oa), do.body_of(bn, sb, ob), size, 1 if "STP" in pair else 3, 5, pair,
                           buckets=buckets)
    np.testing.assert_allclose(-suite.oracle, suite.target, atol=do.AGREE)  # the suite reached its depths
    result = spq.distances(sa, sb, suite.pose_a @ oa, suite.pose_b @ ob, signed=True)
    table = do.compare(suite, result)
    assert (table.spq_status == "overlapping").all()
    assert table.abs_error_m.max() <= 1e-8
    assert table.contains.all()
    # acceptance 3 on these pairs: the witness points span the signed distance along the normal, and
    # lie on their bodies' surfaces as the oracle's own supports see them
    gap = result.point_b - result.point_a - result.distance[:, None] * result.normal
    assert np.abs(gap).max() <= 1e-12
    U = do.fibonacci_sphere(400)
    A, B = do.body_of(an, sa, oa), do.body_of(bn, sb, ob)
    for i in range(len(result.distance)):
        n = result.normal[i][None]
        for body, pose, point, along in ((A, suite.pose_a[i], result.point_a[i], n), (B, suite.pose_b[i],
                                                                                      result.point_b[i], -n)):
            _, h = body.world_support(pose, along)
            assert abs(along[0] @ point - h[0]) <= 1e-9  # on the support plane along the normal
            _, hu = body.world_support(pose, U)
            assert (U @ point <= hu + 1e-9).all()  # and within the body
