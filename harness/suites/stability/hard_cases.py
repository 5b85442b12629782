"""Numerical stability: every engine on configurations where distance methods are known to fail.

Case families (each a small set of poses, every one scored against the exact reference of
:mod:`harness.references.minkowski`): touching at 1e-4 .. 1e-12 m, shallow and deep overlaps, scales 1e-3 to
1e3 m, bodies 1e4 m from the origin, flat and needle-like bodies, near-parallel faces, the box gap
where FCL's progress-based stop is reported to return 3.16 instead of 3.0 (NOTES 5), and a sweep of
coal's DualityGap + Relative convergence criterion over gjk_tolerance (NOTES 6).

Verdict per query: 'failed' (status failed), 'ok' (|distance - reference| within the engine's
tolerance and a status consistent with the reference outside the contact band; inside the band
|d_ref| <= max(1e-9 m, engine tolerance) any non-failed status with a distance within tolerance is
ok), 'wrong' otherwise. Overlaps are scored on the status there (distance 0); their depths separately:

Depth verdict per query where the reference overlaps (or touches within the band): 'ok' when the
engine's raw signed distance is the reference's within its depth tolerance (ENGINE_DEPTH_TOL), and on
the same side of the +-1e-9 m band; 'wrong' otherwise; 'failed'; 'no depth' for an engine that gives
none. The penetration families (pen_*) exist for these: shallow 1e-12 .. 1e-3 m, containment, parallel
faces, scales, far from the origin, degenerate GJK simplices and long faces against a tiny depth.

Generated cases (draw_rows): beside these hand-built cases, cases drawn from the fuzz campaign's families
(harness.suites.fuzz.families), a case being one shape pair at one pose, seeded so that case k is a pure
function of (seed, k). Polytope pairs are judged for every engine against the exact reference; pairs
with an STP-BV, a superellipsoid, a sphere or a capsule for spq alone (the peers take meshes) against
the fuzz campaign's independent oracle (harness.suites.fuzz.oracle), with the same verdicts and tolerances,
plus 'disputed' where only the oracle's lower bound stands against spq's answer.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

import spq
from harness.references.minkowski import MinkowskiReference, reference_distance
from harness.workloads.poses import pose_matrix, random_rotations

AMBIGUOUS_BAND = 1e-9  # m
ENGINES = ("spq", "fcl", "coal", "bullet", "bullet-margin", "mujoco")
EPS = np.finfo(float).eps

# (absolute m, relative) tolerance each engine is judged by; see the module docstring and the MD notes
ENGINE_TOL = {
    "spq": (spq.DEFAULT_TOL_ABS, spq.DEFAULT_TOL_REL),  # its certificate
    "fcl": (1e-6, 1e-6),  # FCL's internal GJK tolerance (not exposed by python-fcl)
    "coal": (1e-8, 1e-8),  # gjk_tolerance set by the adapter
    "bullet": (1e-6, 1e-4),  # NOTES 6: ~1e-4 relative on curved hulls with margin 0
    "bullet-margin": (2e-3 + 1e-6, 1e-4),  # 1 mm default margin per shape: 2 mm bias accepted
    "mujoco": (1e-6, 1e-6),  # MuJoCo's default ccd_tolerance
}
# (absolute m, relative) tolerance of each engine's penetration depth: spq's certificate; coal's
# epa_tolerance (1e-6 by default); FCL's EPA (libccd, 1e-6, not exposed by python-fcl); Bullet's EPA
# accuracy (1e-4, relative); the margin engine's 2 mm bias on top; MuJoCo's ccd_tolerance (1e-6)
ENGINE_DEPTH_TOL = {
    "spq": (spq.DEFAULT_TOL_ABS, spq.DEFAULT_TOL_REL),
    "fcl": (1e-6, 1e-6),
    "coal": (1e-6, 1e-6),
    "bullet": (1e-6, 1e-4),
    "bullet-margin": (2e-3 + 1e-6, 1e-4),
    "mujoco": (1e-6, 1e-6),
}
DUALITY_TOLERANCES = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
DUALITY_TOLERANCES_QUICK = (1e-4, 1e-8, 1e-12)


@dataclass
class StabilityConfig:
    seed: int = 0
    quick: bool = False
    engines: list[str] | None = None
    links: tuple[str, str] = ("kuka_link_4", "panda_link_2")
    fcl_gap: bool = True  # the fcl_box_gap_3 family
    coal_sweep: bool = True  # coal's DualityGap + Relative sweep (when coal runs)
    generated: bool = True  # the cases generated from the fuzz families (see generated_draw)
    generated_cases: int = 10_000  # how many, in a full run (quick: QUICK_DRAWS x QUICK_POSES)

    def __post_init__(self):
        if not isinstance(self.generated_cases, int) or self.generated_cases < 0:
            raise ValueError(f"generated_cases must be an integer >= 0, got {self.generated_cases!r}")

    @property
    def n(self) -> int:  # random poses per (case, parameter)
        return 1 if self.quick else 3


@dataclass
class Case:
    family: str
    case: str
    param: float
    a: spq.Polyhedron
    b: spq.Polyhedron
    poses: list = field(default_factory=list)  # (pose_a, pose_b)


def box(sx: float, sy: float, sz: float) -> spq.Polyhedron:
    """Box of full sizes (sx, sy, sz) m centred on its origin, from its 8 corners."""
    c = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    return spq.Polyhedron.from_points(c * np.array([sx, sy, sz]))


def rot_axis(axis, angle: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def place(a, b, rot_a, rot_b, t_a, direction, target: float) -> tuple[np.ndarray, np.ndarray]:
    """Poses with B moved along the exact separation normal so the signed distance is ``target``
    (exact for target >= 0: moving along the normal changes a separated distance linearly)."""
    direction = np.asarray(direction, float) / np.linalg.norm(direction)
    r = a.bounding_radius() + b.bounding_radius()
    pose_a = pose_matrix(rot_a, t_a)
    pose_b = pose_matrix(rot_b, np.asarray(t_a) + 1.05 * r * direction)
    start = MinkowskiReference(a, b, pose_a, pose_b).query()
    pose_b = pose_b.copy()
    pose_b[:3, 3] = pose_b[:3, 3] + (target - start.distance) * start.normal
    return pose_a, pose_b


def _unit(rng) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def _random_placements(a, b, target, n, rng, t_a=None):
    out = []
    for _ in range(n):
        rot = random_rotations(2, rng)
        out.append(place(a, b, rot[0], rot[1], np.zeros(3) if t_a is None else t_a, _unit(rng), target))
    return out


def _scaled(a, b, base, s: float):
    """(a, b, poses) with every length times s: the bodies' vertices and the poses' translations."""
    poses = []
    for pa, pb in base:
        pa, pb = pa.copy(), pb.copy()
        pa[:3, 3] *= s
        pb[:3, 3] *= s
        poses.append((pa, pb))
    return spq.Polyhedron.from_points(a.vertices * s), spq.Polyhedron.from_points(b.vertices * s), poses


def build_cases(config: StabilityConfig, load_object) -> list[Case]:
    rng = np.random.default_rng(config.seed)
    n = config.n
    unit = box(1, 1, 1)
    la, lb = (load_object(name) for name in config.links)
    lname = f"{config.links[0]}|{config.links[1]}"
    cases: list[Case] = []

    # touching
    for d in (1e-4, 1e-6, 1e-8, 1e-10, 1e-12):
        aligned = place(unit, unit, np.eye(3), np.eye(3), np.zeros(3), [1, 0, 0], d)
        cases.append(Case("touching", "box|box face-face", d, unit, unit, [aligned]))
        cases.append(Case("touching", "box|box random", d, unit, unit, _random_placements(unit, unit, d, n, rng)))
        cases.append(Case("touching", lname, d, la, lb, _random_placements(la, lb, d, n, rng)))

    # overlapping (shallow: depth 1e-6..1e-3 m; deep: half the size)
    for depth in (1e-6, 1e-5, 1e-4, 1e-3):
        cases.append(Case("overlap_shallow", "box|box random", depth, unit, unit,
                          _random_placements(unit, unit, -depth, n, rng)))
        cases.append(Case("overlap_shallow", lname, depth, la, lb, _random_placements(la, lb, -depth, n, rng)))
    cases.append(Case("overlap_deep", "box|box random", 0.5, unit, unit, _random_placements(unit, unit, -0.5, n, rng)))
    size = 0.5 * (la.bounding_radius() + lb.bounding_radius())
    cases.append(Case("overlap_deep", lname, 0.5 * size, la, lb, _random_placements(la, lb, -0.5 * size, n, rng)))

    # scales: same pair, same relative pose, every length times s
    base_box = _random_placements(unit, unit, 0.05, n, rng)
    base_link = _random_placements(la, lb, 0.01, n, rng)
    for s in (1e-3, 1e-2, 1e-1, 1.0, 1e1, 1e2, 1e3):
        for name, (a, b), base in (("box|box", (unit, unit), base_box), (lname, (la, lb), base_link)):
            cases.append(Case("scale", name, s, *_scaled(a, b, base, s)))

    # far from the origin: both bodies shifted by 1e4 m, same relative pose
    for gap in (1e-2, 1e-4, 1e-6):
        for name, (a, b) in (("box|box", (unit, unit)), (lname, (la, lb))):
            poses = []
            for pa, pb in _random_placements(a, b, gap, n, rng):
                shift = 1e4 * _unit(rng)
                pa, pb = pa.copy(), pb.copy()
                pa[:3, 3] += shift
                pb[:3, 3] += shift
                poses.append((pa, pb))
            cases.append(Case("far_from_origin", name, gap, a, b, poses))

    # flat and needle-like bodies
    flat, needle = box(1, 1, 1e-4), box(1e-4, 1e-4, 1)
    for name, (a, b) in (("flat|flat", (flat, flat)), ("needle|needle", (needle, needle)),
                         ("flat|needle", (flat, needle)), ("flat|box", (flat, unit))):
        for gap in (1e-1, 1e-3, 1e-6, -1e-5):
            cases.append(Case("flat_needle", name, gap, a, b, _random_placements(a, b, gap, n, rng)))

    # near-parallel faces: B's facing face tilted by theta about y (and about a diagonal), gap d
    for theta in (1e-3, 1e-5, 1e-7, 1e-9):
        for gap in (1e-3, 1e-6):
            poses = [place(unit, unit, np.eye(3), rot_axis(axis, theta), np.zeros(3), [1, 0, 0], gap)
                     for axis in ([0, 1, 0], [0, 1, 1])]
            cases.append(Case("near_parallel", f"box|box gap {gap:g}", theta, unit, unit, poses))
    return cases


def penetration_cases(config: StabilityConfig, load_object) -> list[Case]:
    """The penetration families (pen_*, see FAMILY_NOTES), scored on depth as well as status."""
    rng = np.random.default_rng(config.seed + 3)
    n = config.n
    unit = box(1, 1, 1)
    la, lb = (load_object(name) for name in config.links)
    lname = f"{config.links[0]}|{config.links[1]}"
    size = 0.5 * (la.bounding_radius() + lb.bounding_radius())
    cases: list[Case] = []
    for depth in (1e-12, 1e-10, 1e-8, 1e-6, 1e-4, 1e-3):
        aligned = place(unit, unit, np.eye(3), np.eye(3), np.zeros(3), [1, 0, 0], -depth)
        cases.append(Case("pen_shallow", "box|box face-face", depth, unit, unit, [aligned]))
        cases.append(Case("pen_shallow", "box|box random", depth, unit, unit, _random_placements(unit, unit, -depth, n,
                                                                                                  rng)))
        cases.append(Case("pen_shallow", lname, depth, la, lb, _random_placements(la, lb, -depth, n, rng)))
    small = box(0.2, 0.2, 0.2)
    for name, t in (("small box centred in unit box", [0.0, 0.0, 0.0]),
                    ("small box off-centre in unit box", [0.25, 0.1, -0.2])):
        poses = [(np.eye(4), pose_matrix(r, t)) for r in random_rotations(n, rng)]
        cases.append(Case("pen_containment", name, 0.0, unit, small, poses))
    big = spq.Polyhedron.from_points(la.vertices * 2.0)
    cases.append(Case("pen_containment", f"{config.links[0]} in its 2x copy", 0.0, big, la,
                      [(np.eye(4), pose_matrix(np.eye(3), 0.01 * _unit(rng))) for _ in range(n)]))
    for theta in (0.0, 1e-9, 1e-6):
        poses = [place(unit, unit, np.eye(3), rot_axis(axis, theta), np.zeros(3), [1, 0, 0], -1e-3)
                 for axis in ([0, 1, 0], [0, 1, 1])]
        cases.append(Case("pen_parallel", "box|box depth 1e-3", theta, unit, unit, poses))
    base_box = _random_placements(unit, unit, -0.01, n, rng)
    base_link = _random_placements(la, lb, -0.01 * size, n, rng)
    for s in (1e-3, 1e-1, 1.0, 1e1, 1e3):
        for name, (a, b), base in (("box|box", (unit, unit), base_box), (lname, (la, lb), base_link)):
            cases.append(Case("pen_scale", name, s, *_scaled(a, b, base, s)))
    for name, (a, b) in (("box|box", (unit, unit)), (lname, (la, lb))):
        poses = []
        for pa, pb in _random_placements(a, b, -1e-3, n, rng):
            shift = 1e4 * _unit(rng)
            pa, pb = pa.copy(), pb.copy()
            pa[:3, 3] += shift
            pb[:3, 3] += shift
            poses.append((pa, pb))
        cases.append(Case("pen_far_from_origin", name, 1e-3, a, b, poses))
    # GJK ends with the origin on a segment or a triangle of its simplex for aligned boxes
    for name, t in (("aligned, offset along x", [0.9, 0, 0]), ("aligned, offset along a face diagonal", [0.9, 0.9, 0]),
                    ("aligned, offset along the body diagonal", [0.9, 0.9, 0.9])):
        cases.append(Case("pen_degenerate_simplex", name, 0.1, unit, unit, [(np.eye(4), pose_matrix(np.eye(3), t))]))
    plate, slab = box(1, 1, 1e-3), box(100, 100, 1)
    for depth in (1e-9, 1e-6):
        poses = [(np.eye(4), pose_matrix(rot_axis([0, 0, 1], ang), [dx, 0.0, 0.5 + 0.5e-3 - depth]))
                 for ang, dx in ((0.0, 0.0), (0.7, 30.0))]
        cases.append(Case("pen_long_face", "slab 100x100x1 | plate 1x1x1e-3", depth, slab, plate, poses))
    return cases


def fcl_gap_cases(config: StabilityConfig) -> list[Case]:
    """Boxes of sizes 1 and 2 with an exact 3.0 gap: one rotated about z (0..90 degrees), and a
    few random rotations (NOTES 5: FCL's libccd path reported a 3.0 gap as 3.16)."""
    rng = np.random.default_rng(config.seed + 1)
    small, big = box(1, 1, 1), box(2, 2, 2)
    cases = []
    angles = (0, 15, 30, 45, 60, 75) if config.quick else tuple(range(0, 91, 5))
    for deg in angles:
        rb = rot_axis([0, 0, 1], math.radians(deg))
        poses = [place(small, big, np.eye(3), rb, np.zeros(3), d, 3.0) for d in ([1, 0, 0], [1, 1, 0], [1, 0.3, 0.2])]
        cases.append(Case("fcl_box_gap_3", "box1|box2 rot z", float(deg), small, big, poses))
    unit = box(1, 1, 1)
    for axis in range(3):  # fcl issue #508: unit boxes 4 m apart along y or z gave 3.16228
        for gap in (1.0, 2.0, 3.0):
            t = np.zeros(3)
            t[axis] = 1.0 + gap
            cases.append(Case("fcl_box_gap_3", f"box1|box1 aligned along {'xyz'[axis]}", gap, unit, unit,
                              [(np.eye(4), pose_matrix(np.eye(3), t))]))
        t = np.zeros(3)
        t[axis] = 1.5 + 3.0
        cases.append(Case("fcl_box_gap_3", f"box1|box2 aligned along {'xyz'[axis]}", 3.0, small, big,
                          [(np.eye(4), pose_matrix(np.eye(3), t))]))
    k = 2 if config.quick else 8
    poses = _random_placements(small, big, 3.0, k, rng)
    cases.append(Case("fcl_box_gap_3", "box1|box2 random rot", float("nan"), small, big, poses))
    return cases


def tolerance_of(engine: str) -> tuple[float, float]:
    if engine in ENGINE_TOL:
        return ENGINE_TOL[engine]
    if engine.startswith("coal-dg"):
        tol = float(engine.split("tol")[-1])
        return max(tol, 1e-8), max(tol, 1e-8)
    return 1e-6, 1e-6


def verdict(engine: str, status: str, distance: float, ref_distance: float, ref_signed: float,
            extent: float, uncertainty: float = 0.0) -> tuple[str, float]:
    """('ok' | 'wrong' | 'failed', allowed error in m). uncertainty (m): the reference's own, added to
    the allowed error (0 for the exact reference; the depth oracle's spread otherwise)."""
    tol_abs, tol_rel = tolerance_of(engine)
    allowed = tol_abs + tol_rel * max(ref_distance, 0.0) + 64 * EPS * extent + uncertainty
    if status == "failed" or not math.isfinite(distance):
        return "failed", allowed
    band = max(AMBIGUOUS_BAND, tol_abs)
    if abs(distance - ref_distance) > allowed:
        return "wrong", allowed
    if ref_signed > band and status == "overlapping":
        return "wrong", allowed
    if ref_signed < -band and status != "overlapping":
        return "wrong", allowed
    return "ok", allowed


def depth_verdict(engine: str, gives_depth: bool, status: str, raw: float, ref_signed: float,
                  extent: float, uncertainty: float = 0.0) -> tuple[str, float]:
    """('ok' | 'wrong' | 'failed' | 'no depth', allowed error in m) of a signed distance where the
    reference overlaps or touches (see the module docstring); uncertainty as in :func:`verdict`."""
    tol_abs, tol_rel = ENGINE_DEPTH_TOL.get(engine, tolerance_of(engine))
    allowed = tol_abs + tol_rel * abs(ref_signed) + 64 * EPS * extent + uncertainty
    if not gives_depth:
        return "no depth", allowed
    if status == "failed" or not math.isfinite(raw):
        return "failed", allowed
    if abs(raw - ref_signed) > allowed:
        return "wrong", allowed
    if (ref_signed < -AMBIGUOUS_BAND and raw >= 0.0) or (ref_signed > AMBIGUOUS_BAND and raw < 0.0):
        return "wrong", allowed
    return "ok", allowed


def case_rows(case: Case, engines: dict) -> list[dict]:
    """One row per pose and engine of a case: the reference, the engine's answer and its verdicts."""
    rows = []
    refs = []
    for pa, pb in case.poses:
        try:
            refs.append(reference_distance(case.a, case.b, pa, pb))
        except Exception as exc:  # a reference failure skips the pose, never the run
            refs.append(exc)
    for name, engine in engines.items():
        try:
            prepared = engine.prepare(case.a, case.b)
        except Exception as exc:
            prepared = None
            prep_error = f"{type(exc).__name__}: {exc}"
        try:
            for k, ((pa, pb), ref) in enumerate(zip(case.poses, refs)):
                row = dict(family=case.family, case=case.case, param=case.param, pose=k, engine=name)
                if isinstance(ref, Exception):
                    rows.append({**row, "verdict": "no_reference", "message": str(ref)})
                    continue
                extent = float(np.abs(case.a.vertices).max() + np.abs(case.b.vertices).max()
                               + np.abs(pa[:3, 3]).max() + np.abs(pb[:3, 3]).max())
                row.update(ref_distance=ref.distance, ref_signed=ref.signed_distance, ref_status=ref.status)
                if prepared is None:
                    res_status, dist, raw, msg, dt = "failed", float("nan"), float("nan"), prep_error, float("nan")
                else:
                    try:
                        t0 = time.perf_counter()
                        r = prepared.query(pa, pb)
                        dt = time.perf_counter() - t0
                        res_status, dist, raw, msg = r.status, r.distance, r.raw_distance, r.message
                    except Exception as exc:
                        res_status, dist, raw, msg, dt = ("failed", float("nan"), float("nan"),
                                                          f"{type(exc).__name__}: {exc}", float("nan"))
                v, allowed = verdict(name, res_status, dist, ref.distance, ref.signed_distance, extent)
                err = dist - ref.distance
                dv, d_allowed, d_err = "", float("nan"), float("nan")
                if ref.signed_distance <= AMBIGUOUS_BAND:
                    dv, d_allowed = depth_verdict(name, getattr(engines[name], "gives_depth", False),
                                                  res_status, raw, ref.signed_distance, extent)
                    if dv != "no depth":
                        d_err = raw - ref.signed_distance
                rows.append({**row, "distance": dist, "raw_distance": raw, "status": res_status,
                             "error": err, "abs_error": abs(err),
                             "rel_error": abs(err) / ref.distance if ref.distance > AMBIGUOUS_BAND else float("nan"),
                             "ref_depth": ref.depth, "allowed_error": allowed, "time_us": dt * 1e6,
                             "verdict": v, "depth_error": d_err, "depth_abs_error": abs(d_err),
                             "allowed_depth_error": d_allowed, "depth_verdict": dv, "message": msg})
        finally:
            if prepared is not None:
                try:
                    prepared.close()
                except Exception:
                    pass
    return rows


def run_cases(cases: list[Case], engines: dict, progress: bool = False) -> pd.DataFrame:
    rows = []
    for ci, case in enumerate(cases):
        rows += case_rows(case, engines)
        if progress:
            print(f"  [{ci + 1}/{len(cases)}] {case.family} {case.case} {case.param:g}", flush=True)
    return pd.DataFrame(rows)


def coal_dualitygap_engines(tolerances=DUALITY_TOLERANCES) -> dict:
    """coal with the DualityGap + Relative convergence criterion at each gjk_tolerance."""
    import coal

    from harness.engines.coal_engine import CoalEngine

    class CoalDualityGap(CoalEngine):
        def __init__(self, tolerance: float):
            super().__init__(tolerance=tolerance, name=f"coal-dg-rel-tol{tolerance:g}")
            self._request.gjk_convergence_criterion = coal.GJKConvergenceCriterion.DualityGap
            self._request.gjk_convergence_criterion_type = coal.GJKConvergenceCriterionType.Relative

    engines = {}
    for tol in tolerances:
        e = CoalDualityGap(tol)
        engines[e.name] = e
    return engines


def coal_sweep_cases(config: StabilityConfig, load_object) -> list[Case]:
    """Separated link poses (gaps 1e-6 .. 1e-2 m) for the coal criterion sweep."""
    rng = np.random.default_rng(config.seed + 2)
    la, lb = (load_object(name) for name in config.links)
    per = 3 if config.quick else 20
    return [Case("coal_duality_gap", f"{config.links[0]}|{config.links[1]}", gap, la, lb,
                 _random_placements(la, lb, gap, per, rng)) for gap in (1e-6, 1e-4, 1e-2)]


# --- generated cases: the fuzz campaign's families as stability cases ---------------------------------
# A generated case is one shape pair at one pose, judged by every engine that takes the pair's shapes:
# spq always (unsigned, and signed for the depth), the peers on polytope pairs only (they take meshes).
# Case k is pose k % POSES_PER_DRAW of draw k // POSES_PER_DRAW; draw j is the fuzz family
# GENERATED_SCHEDULE[j % len] drawn by harness.suites.fuzz.families.draw_case with the generator
# np.random.default_rng([seed, GENERATED_STREAM, j]): a case is a pure function of (seed, k).
POSES_PER_DRAW = 10  # cases per drawn pair: its preparation (hulls, meshes sent to the peers' processes)
# is shared by its poses, and 10,000 cases still hold 1,000 distinct pairs
QUICK_DRAWS, QUICK_POSES = 11, 1  # the quick run: the first pose of draws 0 .. 10 (one per family)
GENERATED_STREAM = 44  # draw j's seed is [seed, 44, j]: not the fuzz campaign's [seed, k], so the suite's
# pairs are not the campaign's first cases (44: the issue that asked for them)
# draws per round of the schedule. The hull families' poses get the exact reference (20 ms each on average);
# a pair with an STP-BV or a superellipsoid needs the depth oracle (0.5 .. 1 s a pose) on every pose its
# cheap bracket cannot settle, about half of them (the overlapping ones): those families get 1 draw to
# the others' 12, about 100 cases each at full size, what the time budget allows.
FAMILY_DRAWS = {"hull-random": 12, "hull-sliver": 12, "hull-needle": 12, "hull-coplanar": 12, "hull-duplicates": 12,
                "hull-scale": 12, "hull-far": 12, "primitives": 12, "stp-min-R": 1, "stp-big-R": 1, "cse": 1}
SLOW_FAMILIES = ("stp-min-R", "stp-big-R", "cse")  # judged by the depth oracle: handed out first


def _schedule(draws: dict) -> tuple[str, ...]:
    """One round of families: each once (so that the first len(draws) draws cover every family), then
    their remaining draws interleaved."""
    left = {f: n - 1 for f, n in draws.items()}
    out = list(draws)
    while any(left.values()):
        for f in draws:
            if left[f] > 0:
                out.append(f)
                left[f] -= 1
    return tuple(out)


GENERATED_SCHEDULE = _schedule(FAMILY_DRAWS)


def generated_draw(seed: int, j: int):
    """(family, spec A, spec B, poses_a (POSES_PER_DRAW, 4, 4), poses_b, regimes) of draw j."""
    from harness.suites.fuzz.families import draw_case

    if j < 0:
        raise ValueError(f"a draw index is >= 0, got {j}")
    family = GENERATED_SCHEDULE[j % len(GENERATED_SCHEDULE)]
    rng = np.random.default_rng([seed, GENERATED_STREAM, j])
    return (family, *draw_case(family, rng, POSES_PER_DRAW))


def generated_case(seed: int, k: int) -> dict:
    """Generated case k: family, specs a and b (harness.suites.fuzz.families), pose_a, pose_b (4x4), regime."""
    if k < 0:
        raise ValueError(f"a case index is >= 0, got {k}")
    family, a, b, pa, pb, regimes = generated_draw(seed, k // POSES_PER_DRAW)
    i = k % POSES_PER_DRAW
    return {"family": family, "a": a, "b": b, "pose_a": pa[i], "pose_b": pb[i], "regime": str(regimes[i])}


def generated_indices(config: "StabilityConfig") -> list[int]:
    """The generated cases a run judges: 0 .. generated - 1, or in quick mode the first QUICK_POSES poses
    of draws 0 .. QUICK_DRAWS - 1."""
    if config.quick and config.generated:
        return [j * POSES_PER_DRAW + i for j in range(QUICK_DRAWS) for i in range(QUICK_POSES)]
    return list(range(config.generated_cases)) if config.generated else []


def generated_tasks(config: "StabilityConfig") -> list[tuple[int, int, tuple]]:
    """(seed, draw j, pose indices) per draw holding cases of the run: the unit of work."""
    draws: dict[int, list] = {}
    for k in generated_indices(config):
        draws.setdefault(k // POSES_PER_DRAW, []).append(k % POSES_PER_DRAW)
    return [(config.seed, j, tuple(p)) for j, p in draws.items()]


def _spec_label(spec: dict) -> str:
    """A shape spec in a few characters: its kind and, for point sets, their count."""
    return f"{spec['kind']}({len(spec['points'])})" if "points" in spec else spec["kind"]


def _verdicts(name: str, answer: dict, i: int, sd: float, extent: float, unc: float = 0.0) -> dict:
    """The row fields of engine ``name``'s answer at pose i against the signed distance sd (m)."""
    status, d, d_status, raw = answer["status"][i], answer["distance"][i], answer["depth_status"][i], answer["raw"][i]
    v, allowed = verdict(name, status, d, max(sd, 0.0), sd, extent, unc)
    err = d - max(sd, 0.0)
    out = {"ref_distance": max(sd, 0.0), "ref_signed": sd, "ref_depth": max(-sd, 0.0), "distance": d,
           "raw_distance": raw, "status": status, "error": err, "abs_error": abs(err),
           "rel_error": abs(err) / sd if sd > AMBIGUOUS_BAND else float("nan"), "allowed_error": allowed,
           "verdict": v, "depth_verdict": "", "depth_error": float("nan"), "depth_abs_error": float("nan"),
           "allowed_depth_error": float("nan")}
    if sd <= AMBIGUOUS_BAND:
        dv, d_allowed = depth_verdict(name, answer["gives_depth"], d_status, raw, sd, extent, unc)
        out.update(depth_verdict=dv, allowed_depth_error=d_allowed)
        if dv != "no depth":
            out.update(depth_error=raw - sd, depth_abs_error=abs(raw - sd))
    return out


def _unproven(fields: dict, upper: float) -> bool:
    """A 'wrong' that a lower bound of the signed distance (the depth oracle's value) does not prove:
    the engine answers above it, where the oracle may have missed the minimum, and not above ``upper``
    (m, the distance of two points of the bodies: an upper bound of the distance; NaN if none) by more
    than the allowed error."""
    def above_upper(value: float, allowed: float) -> bool:
        return bool(np.isfinite(upper) and value > upper + allowed)

    return ((fields["verdict"] == "wrong" and fields["distance"] >= fields["ref_distance"]
             and not above_upper(fields["distance"], fields["allowed_error"]))
            or (fields["depth_verdict"] == "wrong" and fields["raw_distance"] >= fields["ref_signed"]
                and not above_upper(fields["raw_distance"], fields["allowed_depth_error"])))


def draw_rows(seed: int, j: int, picks: tuple, engines: dict) -> list[dict]:
    """One row per judged pose and engine of draw j (poses ``picks``), as case_rows' rows plus source,
    case_index, regime, reference ('exact', 'bracket', 'oracle', 'dense oracle') and ref_uncertainty.

    Polytope pairs: every engine against the exact Minkowski reference. Other pairs (an STP-BV, a
    superellipsoid, a sphere or a capsule) only spq, against the independent support functions of
    harness.suites.fuzz.oracle: first the bracket at spq's own normals (lower: the separation along the normal,
    a lower bound of the signed distance for any normal; upper: the distance between the two support
    points, apart), taken when spq's verdicts are the same at both of its ends; else the depth
    oracle's value (a lower bound of the signed distance), raised to the separation along spq's normals;
    a 'wrong' that this lower bound does not prove (spq above it, and not above the distance of the
    support points along the oracle's normal, an upper bound) goes to a denser oracle run (up to
    DENSE_PER_CASE per draw) and stays 'disputed' if that does not settle it."""
    from harness.references.depth_oracle import signed_distance as oracle_sd
    from harness.suites.fuzz.judge import DENSE_PER_CASE, DENSE_POLISH, DENSE_STARTS, MODES, spq_outputs
    from harness.suites.fuzz.oracle import POLYTOPES, oracle_shape, peer_polyhedron, reference, separation_bounds, spq_shape
    from spq.kernels.gjk import OUT_DISTANCE, OUT_NORMAL, OUT_STATUS, STATUS_NAMES

    family, a, b, poses_a, poses_b, regimes = generated_draw(seed, j)
    idx = np.asarray(picks, dtype=int)
    poses_a, poses_b, regimes = poses_a[idx], poses_b[idx], regimes[idx]
    n = len(idx)
    oa, ob = oracle_shape(a), oracle_shape(b)
    # the rounding slack's length (harness.suites.fuzz.judge.slack): translations and the shapes' coordinates
    extent = (np.abs(poses_a[:, :3, 3]).max(axis=1) + np.abs(poses_b[:, :3, 3]).max(axis=1)
              + oa.magnitude + ob.magnitude)
    polytopes = a["kind"] in POLYTOPES and b["kind"] in POLYTOPES
    answers: dict[str, dict] = {}
    normals = []
    poly = (peer_polyhedron(a), peer_polyhedron(b)) if polytopes else None
    if "spq" in engines:
        # a hull spec's spq shape is the peers' Polyhedron: built once (qhull on up to 10,000 points)
        shapes = [p_ if p_ is not None and spec["kind"] == "pch" else spq_shape(spec)
                  for p_, spec in zip(poly or (None, None), (a, b))]
        t0 = time.perf_counter()
        out = spq_outputs(*shapes, poses_a, poses_b)
        dt = (time.perf_counter() - t0) / (2 * n)
        names = np.array(STATUS_NAMES)
        unsigned, signed = out["unsigned"], out["signed"]
        answers["spq"] = {"status": names[unsigned[:, OUT_STATUS].astype(int)], "distance": unsigned[:, OUT_DISTANCE],
                          "depth_status": names[signed[:, OUT_STATUS].astype(int)], "raw": signed[:, OUT_DISTANCE],
                          "gives_depth": True, "time_us": dt * 1e6, "message": ""}
        normals = [out[m][:, OUT_NORMAL:OUT_NORMAL + 3] for m in MODES]
    if polytopes:
        for name, engine in engines.items():
            if name == "spq":
                continue
            t0 = time.perf_counter()
            try:
                with engine.prepare(*poly) as prepared:
                    r = prepared.query_many(poses_a, poses_b)
                message = ""
            except Exception as exc:  # the engine cannot load this pair: every pose failed
                from harness.engines.base import BatchResult

                r, message = BatchResult.empty(n), f"{type(exc).__name__}: {exc}"
            raw = np.asarray(r.raw_distance, float)
            answers[name] = {"status": np.asarray(r.status).astype(str), "distance": np.asarray(r.distance, float),
                             "depth_status": np.asarray(r.status).astype(str), "raw": raw,
                             "gives_depth": bool(getattr(engine, "gives_depth", False)),
                             "time_us": (time.perf_counter() - t0) / n * 1e6, "message": message}

    def lowers(i: int) -> list:
        """Separation along each of spq's normals at pose i, and the support points' distance (apart)."""
        got = []
        for m in normals:
            if np.isfinite(m[i]).all() and abs(np.linalg.norm(m[i]) - 1.0) < 1e-6:
                lo, up = separation_bounds(oa, ob, poses_a[i:i + 1], poses_b[i:i + 1], m[i:i + 1])
                got.append((float(lo[0]), float(up[0])))
        return got

    def oracle_upper(normal) -> float:
        """|b* - a*| of the support points along the oracle's normal at pose p (NaN unless apart)."""
        _, up = separation_bounds(oa, ob, poses_a[p:p + 1], poses_b[p:p + 1], np.asarray(normal, float)[None])
        return float(up[0])

    dense_left = DENSE_PER_CASE
    rows = []
    for p in range(n):
        base = {"family": family, "case": f"{_spec_label(a)}|{_spec_label(b)}", "param": float("nan"),
                "pose": int(idx[p]), "source": "generated", "case_index": j * POSES_PER_DRAW + int(idx[p]),
                "regime": str(regimes[p])}
        judged: dict[str, dict] = {}
        if polytopes:
            try:
                sd, unc, kind = reference(oa, ob, poses_a[p], poses_b[p], poly).signed_distance, 0.0, "exact"
            except Exception as exc:  # a reference failure skips the pose, never the run
                rows += [{**base, "engine": name, "verdict": "no_reference", "depth_verdict": "", "message": str(exc)}
                         for name in answers]
                continue
            judged = {name: _verdicts(name, ans, p, sd, extent[p]) for name, ans in answers.items()}
        elif "spq" in answers:
            ans, kind, unc = answers["spq"], "", 0.0
            bounds = lowers(p)
            if bounds:
                lo = max(b_[0] for b_ in bounds)
                up = min((b_[1] for b_ in bounds if np.isfinite(b_[1])), default=float("nan"))
                up = max(up, lo)  # the two bounds cross by a rounding when spq's normal is the optimal one
                if lo > 0 and np.isfinite(up):
                    ends = [_verdicts("spq", ans, p, s_, extent[p]) for s_ in (lo, up, 0.5 * (lo + up))]
                    # narrower than the allowed error, the same verdict at both ends is the verdict for any
                    # signed distance between them (|answer - sd| is convex in sd)
                    if (up - lo <= ends[0]["allowed_error"]
                            and len({(e["verdict"], e["depth_verdict"]) for e in ends}) == 1):
                        sd, unc, kind = 0.5 * (lo + up), 0.5 * (up - lo), "bracket"
                        judged = {"spq": ends[2]}
            if not judged:
                # the depth oracle as harness.suites.fuzz.oracle.reference runs it, its normal kept: the
                # distance of the support points there is an upper bound of the distance (apart)
                r = oracle_sd(oa.core, poses_a[p], ob.core, poses_b[p])
                sd = max([float(r.signed_distance) - oa.radius - ob.radius, *(b_[0] for b_ in bounds)])
                unc, kind, upper = float(r.spread), "oracle", oracle_upper(r.normal)
                fields = _verdicts("spq", ans, p, sd, extent[p], unc)
                if _unproven(fields, upper) and dense_left > 0:
                    dense_left -= 1
                    rd = oracle_sd(oa.core, poses_a[p], ob.core, poses_b[p], starts=DENSE_STARTS, polish=DENSE_POLISH)
                    sd = max(sd, float(rd.signed_distance) - oa.radius - ob.radius)
                    upper = np.fmin(upper, oracle_upper(rd.normal))
                    unc, kind = max(unc, float(rd.spread)), "dense oracle"
                    fields = _verdicts("spq", ans, p, sd, extent[p], unc)
                if _unproven(fields, upper):  # never counted ok, never wrong without proof
                    for key in ("verdict", "depth_verdict"):
                        if fields[key] == "wrong":
                            fields[key] = "disputed"
                judged = {"spq": fields}
        for name, fields in judged.items():
            ans = answers[name]
            rows.append({**base, "engine": name, **fields, "ref_status": _ref_status(fields["ref_signed"]),
                         "reference": kind, "ref_uncertainty": unc, "time_us": ans["time_us"],
                         "message": ans["message"]})
    return rows


def _ref_status(sd: float) -> str:
    from harness.references.minkowski import TOUCH_TOL

    return "touching" if abs(sd) <= TOUCH_TOL else ("overlapping" if sd < 0 else "separated")


def run(config: StabilityConfig, load_object, progress: bool = False, workers: int = 1,
        scheduler: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(main table over all families and ENGINES, coal duality-gap sweep table). The native engines
    answer from child processes (harness.engines.isolated): a crash fails its queries, not the run.

    workers > 1 or a scheduler: every case is a task (its poses drawn here, as in the serial run)
    run on that many processes or on a Dask cluster (harness.parallel.cluster); the tables are the serial
    run's but for the time_us column."""
    from harness.engines import ENGINE_FACTORIES, PLUGIN_SPECS, available_engines
    from harness.engines.isolated import isolated
    from harness.parallel.cluster import check_scheduler
    from spq.workers import check_workers

    workers, scheduler = check_workers(workers), check_scheduler(scheduler)
    spread = workers > 1 or scheduler is not None
    names = config.engines or [e for e in ENGINES if e in ENGINE_FACTORIES]
    engines = {}
    for name in names:
        try:
            engines.update(available_engines([name]))
        except Exception as exc:  # a missing package drops its engine only
            print(f"engine {name} skipped: {exc}")
    cases = (build_cases(config, load_object) + penetration_cases(config, load_object)
             + (fcl_gap_cases(config) if config.fcl_gap else []))
    draws = generated_tasks(config)
    if spread:
        for engine in engines.values():
            engine.close()
        plugins = tuple((n, PLUGIN_SPECS[n]) for n in engines if n in PLUGIN_SPECS)
        template = CaseTask(None, tuple(engines), plugins)
        tasks = [replace(template, draw=d) for d in draws] + [replace(template, case=c) for c in cases]
        # the depth oracle's draws take seconds each: handed out first, so no worker is left with one at the end
        order = sorted(range(len(tasks)), key=lambda i: not _slow(tasks[i]))
        table = _run_spread(tasks, None, workers, scheduler, progress, order)
    else:
        judged = isolated(engines)
        try:
            table = run_cases(cases, judged, progress)
            rows = []
            for t, d in enumerate(draws):
                rows += draw_rows(*d, judged)
                if progress:
                    print(f"  [{t + 1}/{len(draws)}] generated draw {d[1]}", flush=True)
            table = _with_generated(table, pd.DataFrame(rows))
        finally:
            for engine in {id(e): e for e in [*engines.values(), *judged.values()]}.values():
                engine.close()
    sweep = pd.DataFrame()
    if config.coal_sweep and ("coal" in engines or config.engines is None):
        tolerances = DUALITY_TOLERANCES_QUICK if config.quick else DUALITY_TOLERANCES
        try:
            dg = {"coal": available_engines(["coal"])["coal"], **coal_dualitygap_engines(tolerances)}
            if spread:
                sweep = _run_spread(coal_sweep_cases(config, load_object), CaseTask(None, sweep=tolerances), workers,
                                    scheduler, progress)
            else:
                sweep = run_cases(coal_sweep_cases(config, load_object), dg, progress)
        except ImportError as exc:
            print(f"coal sweep skipped: {exc}")
    return table, sweep


@dataclass(frozen=True)
class CaseTask:
    """One stability case to judge in a worker: by the registered engines named (plugins re-registered
    there, native engines in child processes), or with sweep set, by coal and its DualityGap
    engines at those tolerances."""

    case: Case | None
    engines: tuple = ()
    plugins: tuple = ()  # ("name", "module:Class") of engines registered from --engine in the parent
    sweep: tuple | None = None
    draw: tuple | None = None  # (seed, draw j, pose indices): a generated draw instead of a case (draw_rows)


def _task_engines(task: CaseTask) -> dict:
    """The engines of a task, built once per worker process (see harness.parallel.cluster.process_cache)."""
    from harness.engines import available_engines, register_plugin
    from harness.engines.isolated import isolated
    from harness.parallel.cluster import check_may_start_children, process_cache

    if task.sweep is not None:
        return process_cache(("stability sweep", task.sweep), lambda: {
            "coal": available_engines(["coal"])["coal"], **coal_dualitygap_engines(task.sweep)})

    def build() -> dict:
        for name, spec in task.plugins:
            register_plugin(spec, name)
        check_may_start_children("the stability suite")
        plain = available_engines(list(task.engines))
        return {"plain": plain, "judged": isolated(plain)}

    def close(held: dict) -> None:
        for engine in {id(e): e for e in [*held["plain"].values(), *held["judged"].values()]}.values():
            engine.close()

    return process_cache(("stability engines", task.engines, task.plugins), build, close)["judged"]


def run_case_task(task: CaseTask) -> list[dict]:
    """A task's rows (see :func:`case_rows` and :func:`draw_rows`)."""
    if task.draw is not None:
        return draw_rows(*task.draw, _task_engines(task))
    return case_rows(task.case, _task_engines(task))


def _slow(task: CaseTask) -> bool:
    return task.draw is not None and GENERATED_SCHEDULE[task.draw[1] % len(GENERATED_SCHEDULE)] in SLOW_FAMILIES


def _with_generated(table: pd.DataFrame, generated: pd.DataFrame) -> pd.DataFrame:
    """The hand-built cases' rows (source 'hand-built') followed by the generated ones."""
    table = table.assign(source="hand-built")
    return pd.concat([table, generated], ignore_index=True) if len(generated) else table


def _run_spread(cases: list, template: CaseTask | None, workers: int, scheduler: str | None,
                progress: bool, order: list | None = None) -> pd.DataFrame:
    """run_cases' table, each case a task (see :class:`CaseTask`) on workers or a Dask cluster. cases:
    Cases (each made a task from template) or, template None, CaseTasks (hand-built and generated, the
    table then as run's: the hand-built rows, then the generated ones, in task order)."""
    from harness.parallel.cluster import run_tasks

    tasks = cases if template is None else [replace(template, case=c) for c in cases]

    def done(i: int, _rows) -> None:
        if progress:
            t = tasks[i]
            what = (f"generated draw {t.draw[1]}" if t.draw is not None
                    else f"{t.case.family} {t.case.case} {t.case.param:g}")
            print(f"  [{i + 1}/{len(tasks)}] {what}", flush=True)

    results = run_tasks(run_case_task, tasks, workers, scheduler, order=order, done=done)
    hand = pd.DataFrame([row for t, rows in zip(tasks, results) if t.draw is None for row in rows])
    if template is not None:
        return hand
    return _with_generated(hand, pd.DataFrame([row for t, rows in zip(tasks, results) if t.draw is not None
                                               for row in rows]))


def summarize(table: pd.DataFrame, by=("engine",)) -> pd.DataFrame:
    """Verdict counts per group: n queries (one case judged by one engine), ok, wrong, failed, disputed
    (generated cases only: a 'wrong' the depth oracle's lower bound does not prove, see draw_rows), the
    depth verdicts likewise, the largest errors and the median time per query."""
    table = table.assign(depth_verdict=table.depth_verdict.fillna(""))
    g = table.groupby(list(by), sort=False)
    out = g.agg(n=("verdict", "size"),
                ok=("verdict", lambda v: int((v == "ok").sum())),
                wrong=("verdict", lambda v: int((v == "wrong").sum())),
                failed=("verdict", lambda v: int((v == "failed").sum())),
                disputed=("verdict", lambda v: int((v == "disputed").sum())),
                max_abs_error=("abs_error", "max"),
                max_rel_error=("rel_error", "max"),
                median_time_us=("time_us", "median"),
                depth_n=("depth_verdict", lambda v: int((v != "").sum())),
                depth_ok=("depth_verdict", lambda v: int((v == "ok").sum())),
                depth_wrong=("depth_verdict", lambda v: int((v == "wrong").sum())),
                depth_failed=("depth_verdict", lambda v: int((v == "failed").sum())),
                depth_disputed=("depth_verdict", lambda v: int((v == "disputed").sum())),
                no_depth=("depth_verdict", lambda v: int((v == "no depth").sum())),
                max_abs_depth_error=("depth_abs_error", "max")).reset_index()
    return out


BAD = ("wrong", "failed")


def failure_grid(table: pd.DataFrame) -> pd.DataFrame:
    """Per family and engine: n (cases the engine was judged on), bad (cases whose distance verdict or
    depth verdict is wrong or failed), share = bad / n, and source (hand-built or generated); the
    families in the table's order, hand-built first."""
    t = table.assign(bad=table.verdict.isin(BAD) | table.depth_verdict.fillna("").isin(BAD),
                     source=table.get("source", pd.Series("hand-built", index=table.index)).fillna("hand-built"))
    grid = t.groupby(["source", "family", "engine"], sort=False).agg(n=("bad", "size"), bad=("bad", "sum"))
    grid = grid.reset_index()
    grid["bad"] = grid.bad.astype(int)
    grid["share"] = grid.bad / grid.n
    return grid


def case_count(table: pd.DataFrame) -> dict:
    """Cases (one shape pair at one pose) in a table: {'hand-built': n, 'generated': n}."""
    source = table.get("source", pd.Series("hand-built", index=table.index)).fillna("hand-built")
    hand = table[source == "hand-built"]
    gen = table[source == "generated"]
    return {"hand-built": int(len(hand.drop_duplicates(["family", "case", "param", "pose"]))),
            "generated": int(gen.case_index.nunique()) if len(gen) else 0}


def depth_worst_cases(table: pd.DataFrame, k: int = 3) -> pd.DataFrame:
    """The k largest depth errors per engine and family."""
    t = table.dropna(subset=["depth_abs_error"])
    idx = t.groupby(["engine", "family"], sort=False)["depth_abs_error"].nlargest(k).index.get_level_values(-1)
    cols = ["engine", "family", "case", "param", "ref_signed", "raw_distance", "depth_abs_error",
            "allowed_depth_error", "depth_verdict"]
    return t.loc[idx, cols].reset_index(drop=True)


def coal_sweep_summary(sweep: pd.DataFrame) -> pd.DataFrame:
    if sweep.empty:
        return sweep
    sep = sweep.ref_signed > AMBIGUOUS_BAND
    false_ov = sep & (sweep.status == "overlapping")
    false_contact = sep & (sweep.status != "failed") & (sweep.distance <= AMBIGUOUS_BAND)
    s = sweep.assign(false_overlap=false_ov.astype(int), false_collision=false_contact.astype(int))
    out = s.groupby("engine", sort=False).agg(
        n=("verdict", "size"), false_collisions=("false_collision", "sum"), false_overlaps=("false_overlap", "sum"),
        min_raw_distance=("raw_distance", "min"),
        wrong=("verdict", lambda v: int((v == "wrong").sum())),
        failed=("verdict", lambda v: int((v == "failed").sum())),
        max_abs_error=("abs_error", "max"), median_time_us=("time_us", "median")).reset_index()
    return out


def fcl_gap_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per engine and case of the fcl_box_gap_3 family: the answer furthest from the reference."""
    t = table[(table.family == "fcl_box_gap_3")].dropna(subset=["abs_error"])
    if t.empty:
        return t
    worst = t.loc[t.groupby(["engine", "case"], sort=False).abs_error.idxmax()]
    counts = t.groupby(["engine", "case"], sort=False).agg(
        n=("verdict", "size"), wrong=("verdict", lambda v: int((v == "wrong").sum()))).reset_index()
    worst = worst[["engine", "case", "param", "ref_distance", "distance", "abs_error"]].rename(
        columns={"param": "worst_param", "ref_distance": "worst_ref_distance", "distance": "worst_distance",
                 "abs_error": "max_abs_error"})
    return counts.merge(worst, on=["engine", "case"])


FAMILY_NOTES = {
    "touching": "Touching: B placed along the exact separation normal at 1e-4 .. 1e-12 m (unit boxes face to "
                "face and randomly rotated, and two robot links). Below 1e-9 m any non-failed status is accepted "
                "if the distance is within the engine's tolerance.",
    "overlap_shallow": "Shallow overlaps: B pushed 1e-6 .. 1e-3 m past contact along the normal; scored on the "
                       "status (overlapping expected when the depth exceeds the engine's tolerance).",
    "overlap_deep": "Deep overlaps: B pushed by half the body size past contact.",
    "scale": "Scales: the same pair and relative pose with every length multiplied by 1e-3 .. 1e3; compare "
             "rel_error across the parameter (the scale).",
    "far_from_origin": "Far from the origin: both bodies shifted by 1e4 m (random direction), gaps 1e-2 .. 1e-6 m; "
                       "engines that transform vertices to world coordinates lose ~1e-12 m per ulp there.",
    "flat_needle": "Flat (1 x 1 x 1e-4) and needle-like (1e-4 x 1e-4 x 1) boxes, random rotations, gaps 0.1 .. "
                   "1e-6 m and a 1e-5 m overlap.",
    "near_parallel": "Near-parallel faces: two unit boxes face to face, B tilted by 1e-3 .. 1e-9 rad (about an "
                     "in-face axis and a diagonal one), gaps 1e-3 and 1e-6 m.",
    "pen_shallow": "Penetration, shallow: B pushed 1e-12 .. 1e-3 m past contact along the exact normal (unit boxes "
                   "face to face and random, two links); depth scored against the reference's.",
    "pen_containment": "Penetration, containment: a 0.2 m box inside a unit box (centred and off-centre, random "
                       "rotations), a link inside its copy scaled by 2.",
    "pen_parallel": "Penetration, parallel faces: unit boxes face to face 1e-3 m deep, B tilted by 0, 1e-9 and 1e-6 "
                    "rad.",
    "pen_scale": "Penetration, scales: the same pair and relative pose, 1% of the size deep, every length times "
                 "1e-3 .. 1e3.",
    "pen_far_from_origin": "Penetration 1e-3 m deep with both bodies 1e4 m from the origin.",
    "pen_degenerate_simplex": "Penetration where GJK ends on a segment or a triangle: axis-aligned unit boxes offset "
                              "by 0.9 m along x, a face diagonal and the body diagonal (0.1 m deep).",
    "pen_long_face": "Penetration of a 1 x 1 x 1e-3 plate into a 100 x 100 x 1 slab by 1e-9 and 1e-6 m (long faces "
                     "against a tiny depth), centred and 30 m off-centre turned 0.7 rad.",
    "fcl_box_gap_3": "FCL 3.0 gap (NOTES 5, fcl issue #508): axis-aligned unit boxes translated by 1 + gap along "
                     "x, y or z (param: the gap, 1, 2 or 3 m), boxes of sizes 1 and 2 aligned with a 3.0 m gap, B "
                     "(size 2) rotated about z by 0 .. 90 degrees (param: degrees) or randomly at an exact 3.0 m "
                     "gap.",
}
