"""The signed distance of two ball hulls, or of a ball hull and another body, from a set of centres
(spq.kernels.ball_hull_depth), judged by the fuzz campaign's independent references (the brute-force STP
support of harness.references.stp_oracle inside the depth oracle) and beside the EPA's own result."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import spq
from harness.suites.fuzz.families import cloud_random, cse_spec, pch, stp_spec
from harness.suites.fuzz.judge import slack
from harness.suites.fuzz.oracle import oracle_shape, reference, separation_bounds, spq_shape
from harness.suites.fuzz.families import draw_case
from harness.suites.fuzz.judge import judge_case
from spq.kernels.ball_hull_depth import BH_BUDGET, BH_NOT_BALLS, BH_OK, FACE0, MAX_CUTS, SLOT0, centre_set_bounds
from spq.kernels.epa import CENTRES_AFTER, CENTRES_AFTER_BALLS, CENTRES_CUTS, CENTRES_EARLY_WIDTH
from spq.kernels.epa_layout import EPA_ALIVE, EPA_CORNERS, EPA_DEAD, EPA_FEATURES, EPA_PA, EPA_PB, EPA_TMP, EPA_W
from spq.kernels.gjk import DESCENT_ROWS, EPA_IOFF, EPA_ROW, IWORK_SIZE, WORK_ROWS

FIXTURES = Path(__file__).parent / "fixtures" / "fuzz"
TOL = spq.DEFAULT_TOL_ABS
REL = spq.DEFAULT_TOL_REL


def _kernel_pair(A, B, pose_a, pose_b):
    """The cores' pair as the kernels take it (B in A's frame), and their margins."""
    ka, kb = A.kernel_data(), B.kernel_data()
    Ra = pose_a[:3, :3]
    R = np.ascontiguousarray(Ra.T @ pose_b[:3, :3])
    t = np.ascontiguousarray(Ra.T @ (pose_b[:3, 3] - pose_a[:3, 3]))
    return (ka.kind, ka.margin, ka.fdata, ka.idata, kb.kind, kb.margin, kb.fdata, kb.idata, R, t), ka.margin + kb.margin


def _bounds(A, B, pose_a, pose_b, work=None, iwork=None):
    """(code, lower, upper, normal) of the cores, B in A's frame as the kernels take it."""
    pair, margins = _kernel_pair(A, B, pose_a, pose_b)
    work = np.zeros((WORK_ROWS, 4)) if work is None else work
    iwork = np.zeros(IWORK_SIZE, dtype=np.int64) if iwork is None else iwork
    warm = np.zeros(2, dtype=np.int64)
    code, lo, up, u0, u1, u2, _ = centre_set_bounds(pair, TOL, REL, MAX_CUTS, math.inf, warm, work, iwork)
    return code, lo - margins, up - margins, np.array([u0, u1, u2])


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


def _scratch_it_may_write():
    """Masks of the query's float rows and int entries centre_set_bounds may write: the descent's rows,
    the support rows, and the upper halves of the EPA's vertex blocks and per-face int blocks."""
    rows = np.zeros(WORK_ROWS, bool)
    rows[:DESCENT_ROWS + 2] = True
    rows[EPA_ROW + EPA_TMP:EPA_ROW + EPA_TMP + 3] = True
    for block in (EPA_W, EPA_PA, EPA_PB):
        rows[EPA_ROW + block + SLOT0:EPA_ROW + block + 2 * SLOT0] = True
    ints = np.zeros(IWORK_SIZE, bool)
    ints[:EPA_IOFF] = True
    ints[EPA_IOFF + EPA_CORNERS + 3 * FACE0:EPA_IOFF + EPA_CORNERS + 6 * FACE0] = True
    ints[EPA_IOFF + EPA_ALIVE + FACE0:EPA_IOFF + EPA_ALIVE + 2 * FACE0] = True
    ints[EPA_IOFF + EPA_DEAD:EPA_IOFF + EPA_FEATURES] = True  # an expansion's scratch
    return rows, ints


@pytest.mark.parametrize("seed", [0, 1])
def test_the_bounds_leave_an_epa_polytope_in_the_lower_halves_as_it_was(seed):
    """The EPA tries the centres midway through a run (CENTRES_AFTER) and goes on from its own polytope
    where they do not close, so the bounds must write nothing of the polytope's lower halves: every
    float and int outside what they may write keeps its value, with the scratch full of noise before."""
    rows, ints = _scratch_it_may_write()
    rng = np.random.default_rng(seed)
    cases = list(_nested_cases(seed, 2)) + list(_held_cases(seed, 2))
    for a, b, pose_a, pose_b in cases:
        work = rng.normal(size=(WORK_ROWS, 4))
        iwork = rng.integers(0, 1 << 40, IWORK_SIZE)
        work0, iwork0 = work.copy(), iwork.copy()
        code = _bounds(spq_shape(a), spq_shape(b), pose_a, pose_b, work, iwork)[0]
        assert code == BH_OK
        assert (work != work0).any(axis=1)[~rows].sum() == 0
        assert (iwork != iwork0)[~ints].sum() == 0
        assert (work != work0).any(axis=1)[EPA_ROW + EPA_PA + SLOT0:EPA_ROW + EPA_PA + 2 * SLOT0].any()


def _judged(family, a, b, pose_a, pose_b):
    result = judge_case(family, a, b, pose_a[None], pose_b[None], np.random.default_rng(0), {}, sample=1.0,
                        modes=("signed",))
    return [(x.verdict, x.detail) for x in result.bad]


@pytest.mark.parametrize("seed", [0, 1])
def test_nearly_round_overlaps_settle_from_their_centres_early(seed):
    """Two STP-BVs near their least R, one deep in the other, took the EPA 800 to 4,100 expansions (1.8 to
    15 ms; the fuzz family stp-min-R); between two ball hulls whose sets of centres are narrow it now tries
    the centres after CENTRES_AFTER_BALLS (the other runs after CENTRES_AFTER), which close them in a few
    cuts. Each query, judged against the depth oracle like a campaign's, is right, and ends within the
    expansions and cuts of that early attempt, before the later one would start (43 to 73 iterations)."""
    for a, b, pose_a, pose_b in _nested_cases(seed, 6):
        r = spq.distance(spq_shape(a), spq_shape(b), pose_a, pose_b, signed=True)
        assert r.status == "overlapping"
        assert r.iterations <= CENTRES_AFTER_BALLS + CENTRES_CUTS < CENTRES_AFTER
        assert not _judged("stp-min-R", a, b, pose_a, pose_b)


def test_a_wide_set_of_centres_ends_its_early_attempt_at_its_box():
    """Between two STP-BVs with R well above their least (a 0.1 m body at R = 2 m, as the benches' and a
    robot's), the set of centres is wider than the balls' radii, where the cuts close slowly: the early
    attempt ends after the box's six supports, with no cut, where a narrow set (R near its least) goes on."""
    rng = np.random.default_rng(7)
    pose_b = np.eye(4)
    pose_b[:3, 3] = [0.02, -0.01, 0.03]
    wide = [spq.STPBV.from_points(cloud_random(rng, 40) * 0.1, 0.005, 2.0) for _ in range(2)]
    narrow = [spq_shape(s) for s in next(_nested_cases(3, 1))[:2]]
    work, iwork, warm = np.zeros((WORK_ROWS, 4)), np.zeros(IWORK_SIZE, dtype=np.int64), np.zeros(2, dtype=np.int64)
    pair = _kernel_pair(wide[0], wide[1], np.eye(4), pose_b)[0]
    code, _, _, _, _, _, cuts = centre_set_bounds(pair, TOL, REL, CENTRES_CUTS, CENTRES_EARLY_WIDTH, warm, work,
                                                  iwork)
    assert (code, cuts) == (BH_BUDGET, 0)
    assert centre_set_bounds(pair, TOL, REL, 2, math.inf, warm, work, iwork)[6] > 0  # any width: it cuts
    pair = _kernel_pair(narrow[0], narrow[1], np.eye(4), pose_b)[0]
    assert centre_set_bounds(pair, TOL, REL, CENTRES_CUTS, CENTRES_EARLY_WIDTH, warm, work, iwork)[0] == BH_OK


def test_the_nearly_round_reproducer_settles_early():
    """stp-min-R-signed-failed-7 ran the EPA's whole budget (4,084 expansions, about 10 ms) before its
    centres settled it; the EPA's own attempt after CENTRES_AFTER settles it within that attempt."""
    case = json.loads((FIXTURES / "stp-min-R-signed-failed-7.json").read_text())
    pose_a, pose_b = np.asarray(case["pose_a"], float), np.asarray(case["pose_b"], float)
    r = spq.distance(spq_shape(case["a"]), spq_shape(case["b"]), pose_a, pose_b, signed=True)
    assert r.status == "overlapping"
    assert r.iterations <= CENTRES_AFTER + CENTRES_CUTS + 64
    assert not _judged(case["family"], case["a"], case["b"], pose_a, pose_b)


# (case, pose) of the fuzz family stp-min-R, seed 9002: an STP-BV holding a superellipsoid deep inside whose
# centres' attempt does not close (its farthest vertex inside the superellipsoid; its 64 cuts spent), so
# the EPA goes on from its own polytope after it
_GO_ON = [(85, 131), (277, 148)]


@pytest.mark.parametrize("case, pose", _GO_ON)
def test_a_run_goes_on_from_its_polytope_after_centres_that_do_not_close(case, pose):
    """Where the attempt after CENTRES_AFTER does not close, the run goes on from the polytope it had (the
    attempt wrote only rows that polytope does not use): the query is answered right."""
    a, b, poses_a, poses_b, _ = draw_case("stp-min-R", np.random.default_rng([9002, case]), 200)
    A, B = spq_shape(a), spq_shape(b)
    r = spq.distance(A, B, poses_a[pose], poses_b[pose], signed=True)
    assert r.status == "overlapping"
    pair = _kernel_pair(A, B, poses_a[pose], poses_b[pose])[0]
    work, iwork, warm = np.zeros((WORK_ROWS, 4)), np.zeros(IWORK_SIZE, dtype=np.int64), np.zeros(2, dtype=np.int64)
    # the attempt does not close
    assert centre_set_bounds(pair, TOL, REL, CENTRES_CUTS, math.inf, warm, work, iwork)[0] != BH_OK
    assert r.iterations > CENTRES_AFTER + CENTRES_CUTS  # the run went on past it
    assert not _judged("stp-min-R", a, b, poses_a[pose], poses_b[pose])
