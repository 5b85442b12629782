"""The signed distance of two ball hulls, or of a ball hull and another body, from a set of centres
(spq.kernels.ball_hull_depth), judged by the fuzz campaign's independent references (the brute-force STP
support of harness.references.stp_oracle inside the depth oracle) and beside the EPA's own result."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import spq
from harness.suites.fuzz.families import cloud_random, cse_spec, pch, stp_spec
from harness.suites.fuzz.judge import slack
from harness.suites.fuzz.oracle import oracle_shape, reference, separation_bounds, spq_shape
from spq.kernels.ball_hull_depth import BH_NOT_BALLS, BH_OK, centre_set_bounds
from spq.kernels.gjk import IWORK_SIZE, WORK_ROWS

TOL = spq.DEFAULT_TOL_ABS
REL = spq.DEFAULT_TOL_REL


def _bounds(A, B, pose_a, pose_b):
    """(code, lower, upper, normal) of the cores, B in A's frame as the kernels take it."""
    ka, kb = A.kernel_data(), B.kernel_data()
    Ra = pose_a[:3, :3]
    R = np.ascontiguousarray(Ra.T @ pose_b[:3, :3])
    t = np.ascontiguousarray(Ra.T @ (pose_b[:3, 3] - pose_a[:3, 3]))
    work = np.zeros((WORK_ROWS, 4))
    iwork = np.zeros(IWORK_SIZE, dtype=np.int64)
    warm = np.zeros(2, dtype=np.int64)
    pair = (ka.kind, ka.margin, ka.fdata, ka.idata, kb.kind, kb.margin, kb.fdata, kb.idata, R, t)
    code, lo, up, u0, u1, u2, _ = centre_set_bounds(pair, TOL, REL, warm, work, iwork)
    return code, lo - ka.margin - kb.margin, up - ka.margin - kb.margin, np.array([u0, u1, u2])


def _nested_cases(seed, n):
    """STP-BV pairs with R just above its least value (the fuzz family stp-min-R), B's origin near
    A's: the deep overlaps where D is nearly a ball."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        factor = float(np.exp(rng.uniform(np.log(1e-6), np.log(1e-2))))
        a = stp_spec(rng, 1.0, factor)
        b = stp_spec(rng, float(np.exp(rng.uniform(np.log(0.2), np.log(5.0)))), factor)
        pose_a, pose_b = np.eye(4), np.eye(4)
        pose_a[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        pose_b[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        pose_b[:3, 3] = rng.uniform(-0.05, 0.05, 3)
        yield a, b, pose_a, pose_b


@pytest.mark.parametrize("seed", [0, 1])
def test_centre_bounds_hold_the_independent_depth_and_meet_the_epa(seed):
    for a, b, pose_a, pose_b in _nested_cases(seed, 6):
        A, B = spq_shape(a), spq_shape(b)
        code, lo, up, n = _bounds(A, B, pose_a, pose_b)
        assert code == BH_OK
        assert lo <= up and up - lo <= TOL + REL * abs(up)
        oa, ob = oracle_shape(a), oracle_shape(b)
        s = float(slack(pose_a[None], pose_b[None], oa, ob)[0])
        ref = reference(oa, ob, pose_a, pose_b)
        # the oracle's value is a lower bound on sd found by its own minimisation: the upper bound
        # must hold it, and the lower bound (reached along n) must not lie above it by more than its spread
        assert ref.signed_distance <= up + s
        assert lo <= ref.signed_distance + s + ref.uncertainty
        assert abs(np.linalg.norm(n) - 1.0) < 1e-12
        r = spq.distance(A, B, pose_a, pose_b, signed=True)
        if r.status != "failed":
            assert max(lo, r.lower_bound) <= min(up, r.upper_bound) + 1e-12


def test_a_ball_inside_an_stp_bv():
    rng = np.random.default_rng(3)
    a = stp_spec(rng, 1.0, 1e-3)
    A, S = spq_shape(a), spq.Sphere(0.3)
    pose_s = np.eye(4)
    pose_s[:3, 3] = [0.02, -0.01, 0.03]
    code, lo, up, _ = _bounds(A, S, np.eye(4), pose_s)
    assert code == BH_OK
    r = spq.distance(A, S, np.eye(4), pose_s, signed=True)
    assert r.status == "overlapping"
    assert max(lo, r.lower_bound) <= min(up, r.upper_bound) + 1e-12


def _held_cases(seed, n):
    """An STP-BV with R just above its least value holding a small superellipsoid or polytope deep inside,
    off its middle: D is then nearly a sphere piece about a point near the origin, where the EPA runs
    out of vertices (tests/fixtures/fuzz/stp-min-R-signed-failed-7.json)."""
    rng = np.random.default_rng(seed)
    for k in range(n):
        a = stp_spec(rng, 1.0, float(np.exp(rng.uniform(np.log(1e-6), np.log(1e-2)))))
        b = cse_spec(rng, 0.2) if k % 2 == 0 else pch(cloud_random(rng, 12) * 0.2)
        topology = spq_shape(a).topology
        middle = (topology.face_centres if len(topology.face_centres) else topology.vertices).mean(axis=0)
        pose_b = np.eye(4)
        pose_b[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        away = rng.normal(size=3)
        pose_b[:3, 3] = middle + rng.uniform(0.1, 0.3) * away / np.linalg.norm(away)
        yield a, b, np.eye(4), pose_b


@pytest.mark.parametrize("seed", [0, 1])
def test_a_body_held_deep_in_an_stp_bv_is_bounded_from_its_centres(seed):
    """sd = max over the STP-BV's centres c of sd_Y(c) - R, by point queries against Y, either side's
    order: the bounds close, hold the depth oracle's value, and the lower one is the separation along
    the normal given, by the oracle's own supports."""
    for a, b, pose_a, pose_b in _held_cases(seed, 4):
        oa, ob = oracle_shape(a), oracle_shape(b)
        ref = reference(oa, ob, pose_a, pose_b)
        for (sa, sb, pa, pb) in ((a, b, pose_a, pose_b), (b, a, pose_b, pose_a)):
            A, B = spq_shape(sa), spq_shape(sb)
            code, lo, up, n = _bounds(A, B, pa, pb)
            assert code == BH_OK, (sa["kind"], sb["kind"])
            assert lo <= up and up - lo <= TOL + REL * abs(up)
            s = float(slack(pose_a[None], pose_b[None], oa, ob)[0])
            assert ref.signed_distance <= up + s
            o1, o2 = oracle_shape(sa), oracle_shape(sb)
            along = separation_bounds(o1, o2, pa[None], pb[None], (pa[:3, :3] @ n)[None])[0][0]
            assert abs(along - lo) <= s + 1e-12
            r = spq.distance(A, B, pa, pb, signed=True)
            if r.status != "failed":
                assert max(lo, r.lower_bound) <= min(up, r.upper_bound) + 1e-12


def test_two_bodies_without_a_ball_hull_are_not_bounded():
    rng = np.random.default_rng(4)
    box = spq.Polyhedron.from_points(np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float))
    other = spq_shape(cse_spec(rng, 0.5))
    assert _bounds(other, box, np.eye(4), np.eye(4))[0] == BH_NOT_BALLS
