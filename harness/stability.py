"""Numerical stability: every engine on configurations where distance methods are known to fail.

Case families (each a small set of poses, every one scored against the exact reference of
:mod:`harness.reference`): touching at 1e-4 .. 1e-12 m, shallow and deep overlaps, scales 1e-3 to
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
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

import spq
from harness.poses import pose_matrix, random_rotations
from harness.reference import MinkowskiReference, reference_distance

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
            extent: float) -> tuple[str, float]:
    """('ok' | 'wrong' | 'failed', allowed error in m)."""
    tol_abs, tol_rel = tolerance_of(engine)
    allowed = tol_abs + tol_rel * max(ref_distance, 0.0) + 64 * EPS * extent
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
                  extent: float) -> tuple[str, float]:
    """('ok' | 'wrong' | 'failed' | 'no depth', allowed error in m) of a signed distance where the
    reference overlaps or touches (see the module docstring)."""
    tol_abs, tol_rel = ENGINE_DEPTH_TOL.get(engine, tolerance_of(engine))
    allowed = tol_abs + tol_rel * abs(ref_signed) + 64 * EPS * extent
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


def run(config: StabilityConfig, load_object, progress: bool = False, workers: int = 1,
        scheduler: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(main table over all families and ENGINES, coal duality-gap sweep table). The native engines
    answer from child processes (harness.engines.isolated): a crash fails its queries, not the run.

    workers > 1 or a scheduler: every case is a task (its poses drawn here, as in the serial run)
    run on that many processes or on a Dask cluster (harness.cluster); the tables are the serial
    run's but for the time_us column."""
    from harness.cluster import check_scheduler
    from harness.engines import ENGINE_FACTORIES, PLUGIN_SPECS, available_engines
    from harness.engines.isolated import isolated
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
    if spread:
        for engine in engines.values():
            engine.close()
        plugins = tuple((n, PLUGIN_SPECS[n]) for n in engines if n in PLUGIN_SPECS)
        table = _run_spread(cases, CaseTask(None, tuple(engines), plugins), workers, scheduler, progress)
    else:
        judged = isolated(engines)
        try:
            table = run_cases(cases, judged, progress)
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


def _task_engines(task: CaseTask) -> dict:
    """The engines of a task, built once per worker process (see harness.cluster.process_cache)."""
    from harness.cluster import check_may_start_children, process_cache
    from harness.engines import available_engines, register_plugin
    from harness.engines.isolated import isolated

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
    """A task's rows (see :func:`case_rows`)."""
    return case_rows(task.case, _task_engines(task))


def _run_spread(cases: list[Case], template: CaseTask, workers: int, scheduler: str | None,
                progress: bool) -> pd.DataFrame:
    """run_cases' table, each case a task (see :class:`CaseTask`) on workers or a Dask cluster."""
    from dataclasses import replace

    from harness.cluster import run_tasks

    def done(i: int, _rows) -> None:
        if progress:
            print(f"  [{i + 1}/{len(cases)}] {cases[i].family} {cases[i].case} {cases[i].param:g}", flush=True)

    results = run_tasks(run_case_task, [replace(template, case=c) for c in cases], workers, scheduler, done=done)
    return pd.DataFrame([row for rows in results for row in rows])


def summarize(table: pd.DataFrame, by=("engine",)) -> pd.DataFrame:
    g = table.groupby(list(by), sort=False)
    out = g.agg(n=("verdict", "size"),
                ok=("verdict", lambda v: int((v == "ok").sum())),
                wrong=("verdict", lambda v: int((v == "wrong").sum())),
                failed=("verdict", lambda v: int((v == "failed").sum())),
                max_abs_error=("abs_error", "max"),
                max_rel_error=("rel_error", "max"),
                median_time_us=("time_us", "median"),
                depth_n=("depth_verdict", lambda v: int((v != "").sum())),
                depth_ok=("depth_verdict", lambda v: int((v == "ok").sum())),
                depth_wrong=("depth_verdict", lambda v: int((v == "wrong").sum())),
                depth_failed=("depth_verdict", lambda v: int((v == "failed").sum())),
                no_depth=("depth_verdict", lambda v: int((v == "no depth").sum())),
                max_abs_depth_error=("depth_abs_error", "max")).reset_index()
    return out


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
