"""Judging one fuzz case: spq (unsigned and signed) and the peers on the same pose pairs, each query
'ok', 'wrong' or 'failed'.

Cheap judging of every query (harness.suites.fuzz.oracle for the independent side):

- spq's certified interval [lower, upper] against the separation bounds at spq's own normal m, from the
  oracle's supports: the separation along m is a lower bound of the signed distance for any m, so an
  upper bound below it is wrong; apart, |b* - a*| is an upper bound, so a lower bound above it is wrong;
- the unsigned and the signed answer of the same pose pair must agree (their intervals meet; an overlap
  in one is not a clear separation in the other);
- each peer's signed distance (where the peer gives one, else its distance) within its own tolerance of
  spq's interval (polytope pairs only: the peers take meshes).

A query that fails a check, every spq query with status failed, and a stated random share of the others
(``sample``) go to the reference (suspects first, up to SPQ_REFERENCES per case and mode; suspects beyond
are counted 'disputed') (the exact Minkowski reference for two polytopes, else the depth
oracle). There spq is wrong when the reference lies outside its interval by more than the rounding slack
(for the oracle, whose value is a lower bound of the signed distance, raised to the separation along
spq's own normals: wrong when spq's upper bound lies below it; 'disputed' when spq's lower bound lies
above it even after a second, denser oracle run, which no direction the oracle tried confirms: reported
apart, never counted ok); a peer is wrong when it misses the reference by more than its tolerance. Peers' disagreements beyond ``peer_references`` per
case and peer are counted as 'disputed', not referenced.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

import spq
from harness.suites.fuzz.oracle import POLYTOPES, OracleShape, peer_polyhedron, reference, separation_bounds
from spq.kernels.gjk import OUT_DISTANCE, OUT_LOWER, OUT_NORMAL, OUT_STATUS, OUT_UPPER, FAILED, OVERLAPPING

EPS = np.finfo(float).eps
BAND = 1e-9  # m: |signed distance| within this is contact, either status right
SLACK_ULPS = 64  # rounding slack, in ulps of the largest coordinate of the pose pair and the shapes
PEER_TOL = {  # (absolute m, relative) as harness.suites.stability judges them, depth tolerances for overlaps
    "coal": ((1e-8, 1e-8), (1e-6, 1e-6)),
    "fcl": ((1e-6, 1e-6), (1e-6, 1e-6)),
    "mujoco": ((1e-6, 1e-6), (1e-6, 1e-6)),
    "bullet": ((1e-6, 1e-4), (1e-6, 1e-4)),
}
MODES = ("unsigned", "signed")
DENSE_STARTS, DENSE_POLISH = 2000, 8  # the depth oracle's second, denser run on a disputed query
DENSE_PER_CASE = 3  # dense runs per case; further disputes are counted as such (never as ok)
SPQ_REFERENCES = 25  # reference calls per case and mode for spq (suspects first); suspects beyond: disputed


@dataclass
class Bad:
    """One spq query judged wrong or failed: enough to replay it (specs, poses, mode) and why."""

    family: str
    a: dict
    b: dict
    pose_a: list
    pose_b: list
    mode: str
    verdict: str
    detail: str

    def as_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass
class CaseResult:
    counts: list = field(default_factory=list)  # dicts: family, engine, mode, queries, wrong, failed, ...
    bad: list = field(default_factory=list)  # Bad (spq only)
    seconds: dict = field(default_factory=dict)


def slack(poses_a, poses_b, oa: OracleShape, ob: OracleShape) -> np.ndarray:
    t = np.abs(poses_a[:, :3, 3]).max(axis=1) + np.abs(poses_b[:, :3, 3]).max(axis=1)
    return SLACK_ULPS * EPS * (t + oa.magnitude + ob.magnitude)


def spq_outputs(A, B, poses_a, poses_b, tol=spq.DEFAULT_TOL_ABS, rel_tol=spq.DEFAULT_TOL_REL) -> dict:
    """{mode: (n, OUT_SIZE) output rows} of spq's batched call, unsigned and signed."""
    out = {}
    for mode in MODES:
        r = spq.distances(A, B, poses_a, poses_b, tol=tol, rel_tol=rel_tol, signed=mode == "signed")
        out[mode] = output_rows(r)
    return out


def output_rows(r) -> np.ndarray:
    """A BatchDistances as (n, OUT_SIZE) rows in the kernels' column layout (spq.kernels.gjk OUT_*)."""
    from spq.kernels.gjk import OUT_ITERATIONS, OUT_POINT_A, OUT_POINT_B, OUT_SIZE

    o = np.full((len(r), OUT_SIZE), np.nan)
    o[:, OUT_DISTANCE] = r.distance
    o[:, OUT_POINT_A:OUT_POINT_A + 3] = r.point_a
    o[:, OUT_POINT_B:OUT_POINT_B + 3] = r.point_b
    o[:, OUT_NORMAL:OUT_NORMAL + 3] = r.normal
    o[:, OUT_LOWER] = r.lower_bound
    o[:, OUT_UPPER] = r.upper_bound
    o[:, OUT_ITERATIONS] = r.iterations
    o[:, OUT_STATUS] = r.status_code
    return o


def cheap_suspects(out: dict, oa, ob, poses_a, poses_b, s) -> dict:
    """{mode: (n,) bool} queries whose answer the cheap checks cannot confirm (module docstring)."""
    suspects = {}
    signed = out["signed"]
    for mode in MODES:
        o = out[mode]
        lo, up, status = o[:, OUT_LOWER], o[:, OUT_UPPER], o[:, OUT_STATUS]
        m = o[:, OUT_NORMAL:OUT_NORMAL + 3]
        good = np.isfinite(m).all(axis=1) & (np.abs(np.linalg.norm(m, axis=1) - 1.0) < 1e-6)
        bad = status == FAILED
        if good.any():
            lower, upper = separation_bounds(oa, ob, poses_a[good], poses_b[good], m[good])
            if mode == "unsigned":
                lower = np.maximum(lower, 0.0)
            flag = (lower > up[good] + s[good]) | (np.nan_to_num(upper, nan=np.inf) < lo[good] - s[good])
            bad[np.flatnonzero(good)[flag]] = True
        if mode == "unsigned":  # agree with the signed answer
            sd_lo, sd_up = signed[:, OUT_LOWER], signed[:, OUT_UPPER]
            apart = status != OVERLAPPING
            bad |= apart & ((np.maximum(sd_lo, 0.0) > up + s) | (np.maximum(sd_up, 0.0) < lo - s))
            bad |= (status == OVERLAPPING) & (sd_lo > BAND + s)
            bad |= apart & (sd_up < -BAND - s) & (signed[:, OUT_STATUS] != FAILED)
        suspects[mode] = bad
    return suspects


def spq_verdict(o_row, ref_sd: float, unc: float, exact: bool, mode: str, s: float) -> str:
    """'ok' or 'wrong' for one spq output row against the reference signed distance."""
    lo, up, status = o_row[OUT_LOWER], o_row[OUT_UPPER], int(o_row[OUT_STATUS])
    if status == FAILED:
        return "failed"
    target = ref_sd if mode == "signed" else max(ref_sd, 0.0)
    if mode == "unsigned":
        if status == OVERLAPPING and ref_sd > BAND + s:
            return "wrong"
        if status != OVERLAPPING and ref_sd < -BAND - s:
            return "wrong"
    if exact:
        return "ok" if lo - s <= target <= up + s else "wrong"
    if up < target - s:  # the oracle's value is a lower bound of the signed distance
        return "wrong"
    return "ok" if lo <= target + s + unc else "disputed"


def peer_tol(name: str, value: float, overlap: bool) -> float:
    (da, dr), (pa, pr) = PEER_TOL.get(name, ((1e-6, 1e-6), (1e-6, 1e-6)))
    a, r = (pa, pr) if overlap else (da, dr)
    return a + r * abs(value)


def judge_case(family: str, a: dict, b: dict, poses_a, poses_b, rng, peers: dict, sample: float,
               peer_references: int = 8, plant=None, modes=MODES) -> CaseResult:
    """Every query of one case judged (module docstring). peers: {name: Engine} (polytope pairs only);
    sample: share of spq's queries sent to the reference whatever the cheap checks said. plant: to judge
    another spq (harness.suites.fuzz.plant), a function of (spec A, spec B, poses) giving its
    {mode: output rows}. modes: the modes whose spq answers are judged (both are computed: each
    checks the other).

    A case on which spq raises (building a shape the family drew as valid, or answering) is judged
    whole: every query of each judged mode 'failed', one Bad per mode with the verdict 'raised' and the
    exception as its detail; the peers are not judged (there is no spq answer to hold them to)."""
    import time

    from harness.suites.fuzz.oracle import oracle_shape, spq_shape

    result = CaseResult()
    t0 = time.perf_counter()
    oa, ob = oracle_shape(a), oracle_shape(b)
    try:
        if plant is None:
            out = spq_outputs(spq_shape(a), spq_shape(b), poses_a, poses_b)
        else:
            out = plant(a, b, poses_a, poses_b)
    except Exception as e:  # noqa: BLE001 - any exception spq raises is a finding, not the campaign's end
        return _raised(family, a, b, poses_a, poses_b, modes, e)
    t1 = time.perf_counter()
    n = len(poses_a)
    s = slack(poses_a, poses_b, oa, ob)
    suspects = cheap_suspects(out, oa, ob, poses_a, poses_b, s)
    polytopes = a["kind"] in POLYTOPES and b["kind"] in POLYTOPES
    poly = (peer_polyhedron(a), peer_polyhedron(b)) if polytopes else None
    refs: dict[int, object] = {}
    normals = [out[m][:, OUT_NORMAL:OUT_NORMAL + 3] for m in MODES]

    def ref(i: int, dense: bool = False):
        """(signed distance, uncertainty, exact) at pose pair i. The oracle's value (a lower bound of
        the signed distance) is raised to the separation along spq's own normals where that is larger:
        still a lower bound, found where spq claims the optimum is."""
        key = (i, dense)
        if key not in refs:
            if dense:
                from harness.references.depth_oracle import signed_distance

                r = signed_distance(oa.core, poses_a[i], ob.core, poses_b[i], starts=DENSE_STARTS,
                                    polish=DENSE_POLISH)
                sd, unc, exact = float(r.signed_distance) - oa.radius - ob.radius, float(r.spread), False
            else:
                r = reference(oa, ob, poses_a[i], poses_b[i], poly)
                sd, unc, exact = r.signed_distance, r.uncertainty, r.exact
            if not exact:
                for m in normals:
                    if np.isfinite(m[i]).all() and abs(np.linalg.norm(m[i]) - 1.0) < 1e-6:
                        lower, _ = separation_bounds(oa, ob, poses_a[i:i + 1], poses_b[i:i + 1], m[i:i + 1])
                        sd = max(sd, float(lower[0]))
            refs[key] = (sd, unc, exact)
        return refs[key]

    dense_left = [DENSE_PER_CASE]
    t2 = time.perf_counter()
    sampled = rng.uniform(size=n) < sample
    for mode in modes:
        o = out[mode]
        flagged = np.flatnonzero(suspects[mode])
        check = np.concatenate([flagged, np.flatnonzero(sampled & ~suspects[mode])])
        wrong = failed = disputed = 0
        worst = 0.0
        for k, i in enumerate(check.tolist()):
            if k >= SPQ_REFERENCES and o[i, OUT_STATUS] != FAILED:
                disputed += int(suspects[mode][i])  # a suspect left unjudged: never counted ok
                continue
            if o[i, OUT_STATUS] == FAILED:
                failed += 1
                result.bad.append(_bad(family, a, b, poses_a[i], poses_b[i], mode, "failed", "status failed"))
                continue
            sd, unc, exact = ref(i)
            verdict = spq_verdict(o[i], sd, unc, exact, mode, s[i])
            if verdict == "disputed" and dense_left[0] > 0:
                dense_left[0] -= 1
                sd, unc, exact = ref(i, dense=True)
                verdict = spq_verdict(o[i], sd, unc, exact, mode, s[i])
            if verdict == "disputed":
                disputed += 1
                continue
            target = sd if mode == "signed" else max(sd, 0.0)
            err = max(o[i, OUT_LOWER] - target, target - o[i, OUT_UPPER], 0.0)
            if verdict == "wrong":
                wrong += 1
                worst = max(worst, err)
                result.bad.append(_bad(family, a, b, poses_a[i], poses_b[i], mode, "wrong",
                                       f"interval [{float(o[i, OUT_LOWER])!r}, {float(o[i, OUT_UPPER])!r}], reference {float(target)!r} "
                                       f"({'exact' if exact else 'oracle'})"))
        result.counts.append({"family": family, "engine": "spq", "mode": mode, "queries": n, "wrong": wrong,
                              "failed": failed, "referenced": min(len(check), SPQ_REFERENCES), "disputed": disputed, "worst_error_m": worst})
    t3 = time.perf_counter()
    if polytopes:
        for name, engine in peers.items():
            result.counts.append(_judge_peer(name, engine, poly, poses_a, poses_b, out["signed"], s, ref,
                                             family, peer_references))
    t4 = time.perf_counter()
    result.seconds = {"spq": t1 - t0, "checks": t2 - t1, "reference": t3 - t2, "peers": t4 - t3}
    return result


def raised_detail(error: BaseException) -> str:
    """How a 'raised' verdict names its exception: type and message, which a replay must match."""
    return f"{type(error).__name__}: {error}"


def _raised(family, a, b, poses_a, poses_b, modes, error) -> CaseResult:
    result = CaseResult()
    n = len(poses_a)
    for mode in modes:
        result.counts.append({"family": family, "engine": "spq", "mode": mode, "queries": n, "wrong": 0,
                              "failed": n, "referenced": 0, "disputed": 0, "worst_error_m": 0.0})
        result.bad.append(_bad(family, a, b, poses_a[0], poses_b[0], mode, "raised", raised_detail(error)))
    return result


def _bad(family, a, b, pose_a, pose_b, mode, verdict, detail) -> Bad:
    return Bad(family, a, b, np.asarray(pose_a).tolist(), np.asarray(pose_b).tolist(), mode, verdict, detail)


def _judge_peer(name, engine, poly, poses_a, poses_b, signed_out, s, ref, family, budget) -> dict:
    """One peer's counts on a polytope case: its answers against spq's signed interval, disagreements
    against the reference (up to ``budget`` of them)."""
    with engine.prepare(*poly) as prepared:
        res = prepared.query_many(poses_a, poses_b)
    depth = getattr(engine, "gives_depth", True)
    value = np.where(np.isfinite(res.raw_distance), res.raw_distance, res.distance) if depth else res.distance
    failed = (res.status == "failed") | ~np.isfinite(value)
    lo, up = signed_out[:, OUT_LOWER], signed_out[:, OUT_UPPER]
    if not depth:
        lo, up = np.maximum(lo, 0.0), np.maximum(up, 0.0)
    spq_ok = signed_out[:, OUT_STATUS] != FAILED
    tol = np.array([peer_tol(name, v, v < 0) for v in np.nan_to_num(value)])
    agree = spq_ok & (value >= lo - tol - s) & (value <= up + tol + s)
    open_ = np.flatnonzero(~failed & ~agree)
    wrong = disputed = 0
    worst = 0.0
    for k, i in enumerate(open_.tolist()):
        if k >= budget:
            disputed += len(open_) - budget
            break
        sd = ref(i)[0]
        target = sd if depth else max(sd, 0.0)
        err = abs(value[i] - target)
        if err > peer_tol(name, target, target < 0) + s[i] + ref(i)[1]:
            wrong += 1
            worst = max(worst, err)
    return {"family": family, "engine": name, "mode": "signed" if depth else "unsigned", "queries": len(value),
            "wrong": wrong, "failed": int(failed.sum()), "referenced": min(len(open_), budget),
            "disputed": disputed, "worst_error_m": worst}
