"""The coherent finish of an STP-BV patch against a polytope (spq.kernels.coherent_ball): along a
smooth motion it must settle most queries by itself, on spheres and tori and across patch changes,
and every result it gives must lie within the plain GJK descent's certified bounds (the oracle)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import spq
from datasets import load_object
from spq.kernels import batch as kb
from spq.kernels import gjk
from spq.kernels.coherent_ball import coherent_ball_finish
from spq.kernels.query import gjk_query
from spq.shapes.stpbv import STPBV
from tests.descent_oracle import plain_descent

TOL_ABS, TOL_REL, MAX_ITER = 1e-12, 1e-12, 200


def orbit(n: int, seed: int) -> np.ndarray:
    """(n, 4, 4) poses of a body tumbling slowly on an orbit of radius 0.37-0.45 m around the origin."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 1.0, n)
    axis_a, axis_b = rng.normal(size=3), rng.normal(size=3)
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Rotation.from_rotvec(np.outer(2.5 * s, axis_a / np.linalg.norm(axis_a))).as_matrix()
    phase = 2.0 * np.pi * s
    radius = 0.41 + 0.04 * np.sin(3.0 * phase)
    u = axis_b / np.linalg.norm(axis_b)
    e1 = np.cross(u, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    poses[:, :3, 3] = radius[:, None] * (np.cos(phase)[:, None] * e1 + np.sin(phase)[:, None] * e2)
    return poses


@pytest.mark.parametrize("stp_first", [True, False])
def test_coherent_ball_finish_settles_a_smooth_motion_within_the_plain_descents_bounds(stp_first):
    link4, link2 = load_object("kuka_link_4"), load_object("kuka_link_2")
    stp = STPBV.from_points(link4.vertices, 0.005, 0.5)
    a, b = (stp, link2) if stp_first else (link2, stp)
    ka, kb_ = a.kernel_data(), b.kernel_data()
    moving = orbit(400, seed=3)
    warm = np.zeros(gjk.WARM_SIZE, dtype=np.int64)
    direction = np.zeros(3)
    R, t, work = np.empty((3, 3)), np.empty(3), np.empty((gjk.WORK_ROWS, 4))
    iwork = np.empty(gjk.IWORK_SIZE, dtype=np.int64)
    out = np.empty(gjk.OUT_SIZE)
    pair = (ka.kind, ka.margin, ka.fdata, ka.idata, kb_.kind, kb_.margin, kb_.fdata, kb_.idata, R, t)
    first_torus = stp.n_small + stp.n_big
    stp_slot = 0 if stp_first else 1
    taken = tori = moves = separated = 0
    for i, pose in enumerate(moving):
        pose_a, pose_b = (np.eye(4), pose) if stp_first else (pose, np.eye(4))
        kb.relative_pose(pose_a, pose_b, R, t)
        if i > 0:
            trial_warm, trial_dir = warm.copy(), direction.copy()
            out[:] = np.nan
            used = coherent_ball_finish(pair, (TOL_ABS, TOL_REL, MAX_ITER), trial_dir, trial_warm, work, out)
            if used >= 0:
                taken += 1
                st, upper, lower = plain_descent(a, b, pose_a, pose_b)
                assert st == gjk.SEPARATED
                d = out[gjk.OUT_DISTANCE]
                assert lower - 1e-9 <= d <= upper + 1e-9
                assert out[gjk.OUT_LOWER] <= d + 1e-15
                gap = out[gjk.OUT_POINT_B:gjk.OUT_POINT_B + 3] - out[gjk.OUT_POINT_A:gjk.OUT_POINT_A + 3]
                assert abs(np.linalg.norm(gap) - d) <= 1e-12
                assert np.allclose(out[gjk.OUT_NORMAL:gjk.OUT_NORMAL + 3], gap / d, atol=1e-9)
                tori += trial_warm[stp_slot] >= first_torus
                moves += trial_warm[stp_slot] != warm[stp_slot]
            else:
                assert np.isnan(out).all() and np.array_equal(trial_warm, warm)  # nothing written
        gjk_query(pair, (TOL_ABS, TOL_REL, MAX_ITER), direction, np.zeros(6), warm, iwork, work, out, False)
        separated += out[gjk.OUT_STATUS] == gjk.SEPARATED
    # not vacuous: the fast path settles most steps, some on tori, some after a patch change
    assert separated >= 0.9 * len(moving), separated
    assert taken >= 0.8 * (separated - 1), (taken, separated)
    assert tori >= 10, tori
    assert moves >= 5, moves


@pytest.mark.parametrize("stp_first", [True, False])
def test_warm_queries_through_an_overlap_agree_with_the_plain_descent(stp_first):
    # a body passing through the STP-BV and out again: while they overlap, a warm query restarts
    # from the hulls' last simplex (no patch faces the other body), and once apart it finds the
    # patches again; every step against the plain descent on the shapes' own supports
    link4, link2 = load_object("kuka_link_4"), load_object("kuka_link_2")
    stp = STPBV.from_points(link4.vertices, 0.005, 0.5)
    n = 160
    s = np.linspace(-1.0, 1.0, n)
    moving = np.tile(np.eye(4), (n, 1, 1))
    moving[:, :3, :3] = Rotation.from_rotvec(np.outer(0.6 * s, [0.3, 1.0, 0.2])).as_matrix()
    moving[:, :3, 3] = np.outer(0.35 * s, [1.0, 0.4, -0.3]) + [0.0, 0.0, 0.05]
    fixed = np.broadcast_to(np.eye(4), moving.shape)
    a, b, pa, pb = (stp, link2, fixed, moving) if stp_first else (link2, stp, moving, fixed)
    warm = spq.distances(a, b, pa, pb, tol=1e-12, rel_tol=1e-12, coherent=True)
    overlapping = 0
    fast = 0
    for i in range(n):
        st, upper, lower = plain_descent(a, b, pa[i], pb[i])
        if st != gjk.OVERLAPPING and upper < 1e-9:
            continue  # touching: either verdict is right
        if st == gjk.OVERLAPPING:
            assert warm.status[i] == "overlapping", (i, warm.status[i], upper)
            overlapping += 1
            fast += i > 0 and warm.status[i - 1] == "overlapping" and warm.iterations[i] <= 1
        else:
            assert warm.status[i] == "separated", (i, warm.status[i], upper)
            assert lower - 1e-9 <= warm.distance[i] <= upper + 1e-9, i
    # not vacuous: both verdicts occur, and an overlap that persists is confirmed from the last simplex
    assert 20 <= overlapping <= n - 40, overlapping
    assert fast >= 0.8 * overlapping, (fast, overlapping)
