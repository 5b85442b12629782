"""Distances with STP-BVs: patch finishing against the plain GJK descent, the containment bound
d_STP <= max(0, d_PCH - r) with coal's PCH distance, and the limit r -> 0, R -> infinity."""

from __future__ import annotations

import numpy as np
import pytest

import spq
from datasets import load_object
from harness.engines.coal_engine import CoalEngine
from harness.workloads.poses import random_poses
from spq.kernels import gjk
from spq.shapes.stpbv import STPBV
from tests.descent_oracle import plain_descent


@pytest.fixture(scope="module")
def link4():
    return load_object("kuka_link_4")


@pytest.fixture(scope="module")
def link2():
    return load_object("kuka_link_2")


@pytest.mark.parametrize("R", [0.3, 2.0])
def test_patch_finishing_agrees_with_the_plain_descent(link4, R):
    stp = STPBV.from_points(link4.vertices, 0.005, R)
    pa, pb = random_poses(150, seed=4, translation_range=0.3)
    for a, b in ((stp, link4), (stp, stp), (link4, stp), (stp, spq.Sphere(0.03))):
        batch = spq.distances(a, b, pa, pb)
        for i in range(len(pa)):
            st, upper, lower = plain_descent(a, b, pa[i], pb[i])
            if batch.status[i] == "separated":
                assert st == gjk.SEPARATED
                assert lower - 1e-9 <= batch.distance[i] <= upper + 1e-9
                assert batch.lower_bound[i] <= batch.distance[i] + 1e-15
                gap = np.linalg.norm(batch.point_b[i] - batch.point_a[i])
                assert abs(gap - batch.distance[i]) <= 1e-12
            elif batch.status[i] == "overlapping":
                assert st in (gjk.OVERLAPPING, gjk.TOUCHING) or upper <= 1e-9


def test_stp_distance_is_at_most_the_pch_distance_minus_r(link4, link2):
    r = 0.005
    a, b = STPBV.from_points(link4.vertices, r, 2.0), STPBV.from_points(link2.vertices, r, 1.0)
    pair = CoalEngine().prepare(link4, link2)
    pa, pb = random_poses(300, seed=5, translation_range=0.3)
    for i in range(len(pa)):
        d_pch = pair.query(pa[i], pb[i]).distance
        assert spq.distance(a, link2, pa[i], pb[i]).distance <= max(0.0, d_pch - r) + 1e-9
        assert spq.distance(a, b, pa[i], pb[i]).distance <= max(0.0, d_pch - 2 * r) + 1e-9


def test_stp_distance_tends_to_the_pch_distance_as_r_shrinks_and_r_grows(link4, link2):
    pair = CoalEngine().prepare(link4, link2)
    pa, pb = random_poses(40, seed=6, translation_range=0.4)
    d_pch = np.array([pair.query(pa[i], pb[i]).distance for i in range(len(pa))])
    keep = d_pch > 1e-3
    errors = []
    for r, R in ((1e-2, 0.5), (1e-3, 5.0), (1e-4, 50.0), (1e-5, 500.0)):
        a = STPBV.from_points(link4.vertices, r, R)
        b = STPBV.from_points(link2.vertices, r, R)
        d = spq.distances(a, b, pa[keep], pb[keep]).distance
        err = np.abs(d - d_pch[keep]).max()
        # the excess of each STP-BV over its hull is r + O(L^2 / rho): bounded by 2 r + L^2 / rho
        assert err <= 2 * r + 0.3**2 / (R - r)
        errors.append(err)
    assert all(e2 < e1 for e1, e2 in zip(errors, errors[1:]))
    assert errors[-1] < 1e-3


def test_two_tori_facing_agree_with_the_plain_descent():
    # Boxes meet edge to edge at random poses; on their STP-BVs the closest patches are then often
    # two tori, the case solved by the far-point alternation with Aitken steps.
    corners = np.array([[x, y, z] for x in (-0.1, 0.1) for y in (-0.05, 0.05) for z in (-0.03, 0.03)])
    stp = STPBV.from_points(corners, 0.01, 0.5)
    first_torus = stp.n_small + stp.n_big
    pa, pb = random_poses(600, seed=11, translation_range=0.25)
    batch = spq.distances(stp, stp, pa, pb)
    checked = 0
    for i in np.flatnonzero(batch.status == "separated"):
        n = batch.normal[i]
        _, patch_a, _ = stp.support_patches(pa[i, :3, :3].T @ n)
        _, patch_b, _ = stp.support_patches(-(pb[i, :3, :3].T @ n))
        if patch_a[0] < first_torus or patch_b[0] < first_torus:
            continue
        st, upper, lower = plain_descent(stp, stp, pa[i], pb[i])
        assert st == gjk.SEPARATED
        assert lower - 1e-9 <= batch.distance[i] <= upper + 1e-9
        assert abs(np.linalg.norm(batch.point_b[i] - batch.point_a[i]) - batch.distance[i]) <= 1e-12
        checked += 1
    assert checked >= 10, f"only {checked} poses with two tori facing"


def test_torus_ball_against_a_segment_is_the_brute_force_nearest(link4):
    # Oracle: the torus patch's distance to a point y is the distance to the farthest point of its
    # centre circle minus R; sample the circle and the segment densely and take the best segment point.
    from spq.kernels.query import torus_against_segment

    stp = STPBV.from_points(link4.vertices, 0.005, 2.0)
    kd = stp.kernel_data()
    rng = np.random.default_rng(12)
    angles = np.linspace(0.0, 2 * np.pi, 4096, endpoint=False)
    lam = np.linspace(0.0, 1.0, 2001)
    for torus in rng.choice(stp.n_tori, 25, replace=False):
        m, e, a = stp.torus_centres[torus], stp.torus_axes[torus], stp.torus_radii[torus]
        b1 = np.cross(e, [1.0, 0.0, 0.0] if abs(e[0]) < 0.9 else [0.0, 1.0, 0.0])
        b1 /= np.linalg.norm(b1)
        b2 = np.cross(e, b1)
        circle = m + a * (np.cos(angles)[:, None] * b1 + np.sin(angles)[:, None] * b2)
        for _ in range(4):
            s, t = m + rng.normal(size=3) * 0.3, m + rng.normal(size=3) * 0.3
            # the Newton solve's start (the middle, a random point, one outside the segment) must not matter
            found = [np.array(torus_against_segment(kd.fdata, kd.idata, stp.n_small + stp.n_big + torus, *s, *t, g))
                     for g in (0.5, rng.uniform(), 2.0)]
            for other in found[1:]:  # the distance to first order; where on the segment, to the second
                assert abs(np.linalg.norm(other[:3]) - np.linalg.norm(found[0][:3])) <= 1e-12
                np.testing.assert_allclose(other[3:], found[0][3:], rtol=0, atol=1e-9)
            x, y = np.split(found[1], 2)
            points = s + lam[:, None] * (t - s)
            far = np.linalg.norm(points[:, None, :] - circle[None], axis=2).max(axis=1)
            # no sampled segment point is nearer to the patch (1e-6: the circle's sampling error), and the
            # best sampled one is as near up to the segment's sampling
            assert far.min() - 1e-4 <= np.linalg.norm(x) <= far.min() + 1e-6
            assert np.linalg.norm(np.cross(y - s, t - s)) <= 1e-9 * np.linalg.norm(t - s)  # y on the segment's line
            assert -1e-12 <= np.dot(y - s, t - s) <= np.dot(t - s, t - s) + 1e-12  # ... and between s and t
            # x runs from the circle point farthest from y to y
            assert abs(np.linalg.norm(x) - np.linalg.norm(y - circle, axis=1).max()) <= 1e-6
