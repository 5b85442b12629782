"""Cross-check: every engine on the same distance-controlled poses, scored against the exact reference.

Output is one tidy table (a row per engine and query) and a summary per engine and bucket. Errors
are taken against :class:`harness.references.minkowski.MinkowskiReference`, which shares no code with spq's GJK.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from tqdm import tqdm

from harness.engines import available_engines
from harness.workloads.poses import BUCKETS, PoseSuite, bucket_suite

AMBIGUOUS_BAND = 1e-9  # m: |reference signed distance| below this counts as contact, either status is right


@dataclass
class CrosscheckConfig:
    objects: list[str]
    per_bucket: int  # poses per bucket, summed over all object pairs
    seed: int
    engines: list[str] | None = None  # None: every registered engine that imports
    buckets: list[str] | None = None  # None: all of harness.workloads.poses.BUCKETS


def object_pairs(names: list[str]) -> list[tuple[str, str]]:
    """Each object paired with the next (cyclically): every object appears on both sides."""
    if len(names) == 1:
        return [(names[0], names[0])]
    return [(names[i], names[(i + 1) % len(names)]) for i in range(len(names))]


def _split(total: int, parts: int) -> list[int]:
    base, extra = divmod(total, parts)
    return [base + (1 if i < extra else 0) for i in range(parts)]


def _surface_offset(poly, poses: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Signed distance (m) of world points to the hull boundary, each in its own pose's frame."""
    rot = poses[:, :3, :3]
    local = np.einsum("nji,nj->ni", rot, points - poses[:, :3, 3])
    return np.abs(poly.signed_distance_to_surface(local))


def status_verdict(ref_signed: np.ndarray, status: np.ndarray) -> np.ndarray:
    """'ok', 'false_overlap' (separated by > band, reported overlapping), 'missed_overlap' (overlapping
    by > band, reported separated or touching) or 'failed', per query."""
    verdict = np.full(len(status), "ok", dtype=object)
    verdict[(ref_signed > AMBIGUOUS_BAND) & (status == "overlapping")] = "false_overlap"
    verdict[(ref_signed < -AMBIGUOUS_BAND) & np.isin(status, ["separated", "touching"])] = "missed_overlap"
    verdict[status == "failed"] = "failed"
    return verdict


def score(suite: PoseSuite, engine_name: str, result, a, b, gives_depth: bool = False, bounds=None) -> pd.DataFrame:
    """Per-query rows for one engine's answers on one suite. gives_depth: the engine's raw_distance is
    a signed distance (minus the depth when overlapping), scored on the touching and overlap buckets
    against the reference's signed distance; bounds: its certified (lower, upper) arrays, if any."""
    dist = np.asarray(result.distance, dtype=np.float64)
    sep = suite.ref_signed > AMBIGUOUS_BAND
    err = dist - suite.ref_distance
    gap = np.linalg.norm(result.point_b - result.point_a, axis=1)
    off_a = np.full(len(dist), np.nan)
    off_b = np.full(len(dist), np.nan)
    ok = np.isfinite(result.point_a).all(axis=1) & np.isfinite(result.point_b).all(axis=1)
    if ok.any():
        off_a[ok] = _surface_offset(a, suite.pose_a[ok], result.point_a[ok])
        off_b[ok] = _surface_offset(b, suite.pose_b[ok], result.point_b[ok])
    raw = np.asarray(result.raw_distance, dtype=np.float64)
    signed_rows = (np.asarray(suite.target) <= 0.0) & gives_depth  # the touching and overlap buckets
    depth_err = np.where(signed_rows, raw - suite.ref_signed, np.nan)
    sign_error = signed_rows & (((suite.ref_signed < -AMBIGUOUS_BAND) & (raw >= 0.0))
                                | ((suite.ref_signed > AMBIGUOUS_BAND) & (raw < 0.0)))
    over = signed_rows & ok & (raw < 0.0)
    holds = np.full(len(dist), np.nan)
    if bounds is not None:
        lo, up = (np.asarray(x, dtype=np.float64) for x in bounds)
        slack = 4 * np.finfo(float).eps * np.maximum(np.abs(suite.ref_signed), 1.0)
        holds = np.where(signed_rows, ((lo <= suite.ref_signed + slack) & (suite.ref_signed - slack <= up)), np.nan)
    return pd.DataFrame({
        "pair": suite.pair_name,
        "engine": engine_name,
        "bucket": suite.bucket,
        "target": suite.target,
        "ref_distance": suite.ref_distance,
        "ref_signed": suite.ref_signed,
        "ref_status": suite.ref_status,
        "distance": dist,
        "status": np.asarray(result.status),
        "error": err,
        "abs_error": np.abs(err),
        "rel_error": np.where(sep, np.abs(err) / np.maximum(suite.ref_distance, 1e-300), np.nan),
        "witness_gap_error": np.where(sep & ok, np.abs(gap - dist), np.nan),
        "witness_off_surface": np.where(sep & ok, np.maximum(off_a, off_b), np.nan),
        "verdict": status_verdict(suite.ref_signed, np.asarray(result.status)),
        "gives_depth": bool(gives_depth),
        "raw_distance": raw,
        "depth_error": depth_err,
        "depth_abs_error": np.abs(depth_err),
        "depth_sign_error": sign_error,
        "depth_witness_gap_error": np.where(over, np.abs(gap + raw), np.nan),
        "depth_witness_off_surface": np.where(over, np.maximum(off_a, off_b), np.nan),
        "certificate_holds": holds,
    })


def pair_frames(k: int, na: str, nb: str, n: int, seed: int, buckets: dict, engines: dict, load_object,
                bar=None) -> list[pd.DataFrame]:
    """Pair k's (objects na, nb) bucket suite of n poses per bucket, drawn with seed ``seed + k``, and
    every engine's scored rows on it, one frame per engine in the order of ``engines``."""
    a, b = load_object(na), load_object(nb)
    suite = bucket_suite(a, b, n, seed=seed + k, buckets=buckets, progress=bar if bar is not None else False)
    suite.pair_name = f"{na}|{nb}"
    frames = []
    for name, engine in engines.items():
        prepared = engine.prepare(a, b)
        try:
            result = prepared.query_many(suite.pose_a, suite.pose_b)
        finally:
            prepared.close()
        frames.append(score(suite, name, result, a, b, getattr(engine, "gives_depth", False),
                            getattr(prepared, "last_bounds", None)))
    return frames


def run(config: CrosscheckConfig, load_object, progress: bool = True, engines: dict | None = None) -> pd.DataFrame:
    """Run every engine on every pair's bucket suite; returns the tidy table. engines: {name: Engine}
    to run (the caller keeps and closes them); default: config.engines from the registry."""
    pairs = object_pairs(config.objects)
    counts = _split(config.per_bucket, len(pairs))
    buckets = {k: BUCKETS[k] for k in (config.buckets or BUCKETS)}
    owned = engines is None
    if owned:
        engines = available_engines(config.engines)
    frames = []
    try:
        total = sum(counts) * len(buckets)
        bar = tqdm(total=total, desc="crosscheck poses", unit="pose", disable=not progress)
        for k, ((na, nb), n) in enumerate(zip(pairs, counts)):
            if n == 0:
                continue
            bar.set_postfix_str(f"{na} / {nb}")
            frames += pair_frames(k, na, nb, n, config.seed, buckets, engines, load_object, bar)
        bar.close()
    finally:
        if owned:
            for engine in engines.values():
                engine.close()
    return pd.concat(frames, ignore_index=True)


# ---------------------------------------------------------------- the same run spread over processes


@dataclass(frozen=True)
class Task:
    """One unit of a spread crosscheck: pair k's bucket suite and engines ("pair"), or its agreement
    with coal on random poses ("agreement"); n poses (per bucket for "pair"), seed as in the serial run."""

    kind: str
    k: int
    na: str
    nb: str
    n: int
    seed: int
    buckets: tuple = ()  # (name, target) pairs
    engines: tuple = ()  # registered engine names, in the serial run's order
    plugins: tuple = ()  # ("name", "module:Class") of engines registered from --engine in the parent
    load_object: object = None


def _judged_engines(names: tuple, plugins: tuple) -> dict:
    """The engines a worker process judges: registered as in the parent, native ones in children
    (harness.engines.isolated); built once per process and kept for its later tasks."""
    from harness.engines import register_plugin
    from harness.engines.isolated import isolated
    from harness.parallel.cluster import check_may_start_children, process_cache

    def build() -> dict:
        for name, spec in plugins:
            register_plugin(spec, name)
        check_may_start_children("the crosscheck")
        plain = available_engines(list(names))
        return {"plain": plain, "judged": isolated(plain)}

    def close(held: dict) -> None:
        for engine in {id(e): e for e in [*held["plain"].values(), *held["judged"].values()]}.values():
            engine.close()

    return process_cache(("crosscheck engines", names, plugins), build, close)["judged"]


def run_task(task: Task):
    """A task's result: the pair's engine frames, or its agreement row (see :class:`Task`)."""
    load = task.load_object
    if load is None:
        from datasets import load_object as load
    if task.kind == "pair":
        engines = _judged_engines(task.engines, task.plugins)
        return pair_frames(task.k, task.na, task.nb, task.n, task.seed, dict(task.buckets), engines, load)
    return agreement_row(task.k, task.na, task.nb, task.n, task.seed, load)


def tasks(config: CrosscheckConfig, engine_names: list[str], plugins: dict, agreement_poses: int,
          load_object=None) -> tuple[list[Task], list[int]]:
    """The crosscheck's tasks (every pair's suite, then every pair's agreement if agreement_poses > 0)
    and the order to hand them out in: the costliest first (the reference's cost grows with the
    product of the hulls' vertex counts), so that two workers end together."""
    from datasets import load_object as default_load

    load = load_object or default_load
    pairs = object_pairs(config.objects)
    buckets = tuple((k, BUCKETS[k]) for k in (config.buckets or BUCKETS))
    common = dict(seed=config.seed, load_object=load_object)
    out, cost = [], []
    sizes = {name: len(load(name).vertices) for name in dict.fromkeys(config.objects)}
    for k, ((na, nb), n) in enumerate(zip(pairs, _split(config.per_bucket, len(pairs)))):
        if n:
            out.append(Task("pair", k, na, nb, n, buckets=buckets, engines=tuple(engine_names),
                            plugins=tuple((name, plugins[name]) for name in engine_names if name in plugins), **common))
            cost.append(n * len(buckets) * (sizes[na] * sizes[nb] + 1e4))
    if agreement_poses > 0:
        for k, ((na, nb), n) in enumerate(zip(pairs, _split(agreement_poses, len(pairs)))):
            out.append(Task("agreement", k, na, nb, n, **common))
            cost.append(0.0)
    order = sorted(range(len(out)), key=lambda i: -cost[i])
    return out, order


def run_spread(config: CrosscheckConfig, engine_names: list[str], plugins: dict, agreement_poses: int, workers: int,
               scheduler: str | None, progress: bool = True, load_object=None,
               runner=None) -> tuple[pd.DataFrame, pd.DataFrame | None]:
    """The crosscheck table (and the agreement table, or None) of :func:`run` and :func:`agreement`,
    computed by tasks on ``workers`` processes or a Dask cluster (harness.parallel.cluster), or on the open
    ``runner`` (a harness.parallel.cluster.TaskRunner, kept open): equal to the serial run's, each pair's poses
    drawn from its own seed as there."""
    from contextlib import nullcontext

    from harness.parallel.cluster import TaskRunner

    todo, order = tasks(config, engine_names, plugins, agreement_poses, load_object)
    bar = tqdm(total=len(todo), desc="crosscheck tasks", unit="task", disable=not progress)
    with nullcontext(runner) if runner is not None else TaskRunner(workers, scheduler) as where:
        results = where.run(run_task, todo, order, done=lambda i, r: bar.update(1))
    bar.close()
    frames = [f for t, r in zip(todo, results) if t.kind == "pair" for f in r]
    rows = [r for t, r in zip(todo, results) if t.kind == "agreement"]
    return pd.concat(frames, ignore_index=True), (pd.DataFrame(rows) if agreement_poses > 0 else None)


def warm_worker(engine_names: tuple, plugins: tuple = (), agreement: bool = True) -> float:
    """Ready this process for crosscheck tasks (a benchmark's warm-up, run on every worker): the
    judged engines built and kept, as a task keeps them, and the code of spq, of the reference and of
    the scoring loaded, on one pose per bucket of a small pair (and an agreement row with coal if
    ``agreement``). Returns the seconds it took."""
    import time

    from datasets import load_object

    start = time.perf_counter()
    engines = _judged_engines(tuple(engine_names), tuple(plugins))
    pair_frames(0, "random_hull_50", "panda_hand", 1, 0, dict(BUCKETS), engines, load_object)
    if agreement:
        agreement_row(0, "random_hull_50", "panda_hand", 16, 0, load_object)
    return time.perf_counter() - start


_AGGREGATES = dict(
    n=("distance", "size"),
    max_abs_error=("abs_error", "max"),
    median_abs_error=("abs_error", "median"),
    max_rel_error=("rel_error", "max"),
    median_rel_error=("rel_error", "median"),
    mean_signed_error=("error", "mean"),
    max_witness_gap_error=("witness_gap_error", "max"),
    max_witness_off_surface=("witness_off_surface", "max"),
    false_overlaps=("verdict", lambda v: int((v == "false_overlap").sum())),
    missed_overlaps=("verdict", lambda v: int((v == "missed_overlap").sum())),
    failures=("verdict", lambda v: int((v == "failed").sum())),
)


def summarize(table: pd.DataFrame, by=("engine", "bucket")) -> pd.DataFrame:
    """Per group (default engine and bucket): counts, max/median absolute error (distance minus the
    reference distance, 0 when overlapping), relative error (separated poses), mean signed error
    (bias), witness checks, status disagreements and failures."""
    out = table.groupby(list(by), sort=False).agg(**_AGGREGATES).reset_index()
    if "bucket" in by:
        order = {b: i for i, b in enumerate(BUCKETS)}
        out["_o"] = out["bucket"].map(order)
        out = out.sort_values(["engine", "_o"], kind="stable").drop(columns="_o").reset_index(drop=True)
    return out


def worst_cases(table: pd.DataFrame, k: int = 5) -> pd.DataFrame:
    """The k largest absolute errors per engine."""
    sep = table.dropna(subset=["abs_error"])
    idx = sep.groupby("engine", sort=False)["abs_error"].nlargest(k).index.get_level_values(-1)
    cols = ["engine", "pair", "bucket", "ref_distance", "distance", "abs_error", "rel_error", "status"]
    return sep.loc[idx, cols].reset_index(drop=True)


DEPTH_BUCKETS = ("touching", "overlap-1e-4", "overlap-1e-3", "overlap-1e-2", "overlap-1e-1")


def depth_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per engine and bucket of DEPTH_BUCKETS: the signed distance (minus the penetration depth) against
    the reference's: max and median |error| (m), sign errors (over/under the +-1e-9 m band on the
    wrong side), witness checks on the overlaps (| |p_B - p_A| - depth |, points off their surfaces),
    and for an engine with a certificate the share of poses whose interval holds the reference. An
    engine without depth gets one row saying so."""
    rows = []
    for engine, t in table[table.bucket.isin(DEPTH_BUCKETS)].groupby("engine", sort=False):
        if not t.gives_depth.iloc[0]:
            rows.append({"engine": engine, "bucket": "all", "n": len(t), "depth": "no depth"})
            continue
        for bucket in DEPTH_BUCKETS:
            b = t[t.bucket == bucket]
            if b.empty:
                continue
            rows.append({"engine": engine, "bucket": bucket, "n": len(b), "depth": "yes",
                         "max_abs_depth_error": b.depth_abs_error.max(),
                         "median_abs_depth_error": b.depth_abs_error.median(),
                         "mean_depth_error": b.depth_error.mean(),
                         "sign_errors": int(b.depth_sign_error.sum()),
                         "failures": int((b.verdict == "failed").sum()),
                         "max_witness_gap_error": b.depth_witness_gap_error.max(),
                         "max_witness_off_surface": b.depth_witness_off_surface.max(),
                         "certificate_holds_pct": 100.0 * b.certificate_holds.mean()
                         if b.certificate_holds.notna().any() else np.nan})
    return pd.DataFrame(rows)


def depth_worst_cases(table: pd.DataFrame, k: int = 5) -> pd.DataFrame:
    """The k largest depth errors per engine (touching and overlap buckets)."""
    t = table.dropna(subset=["depth_abs_error"])
    idx = t.groupby("engine", sort=False)["depth_abs_error"].nlargest(k).index.get_level_values(-1)
    cols = ["engine", "pair", "bucket", "ref_signed", "raw_distance", "depth_abs_error", "status"]
    return t.loc[idx, cols].reset_index(drop=True)


AGREEMENT_TOL = 1e-7  # m: spq and coal (gjk_tolerance 1e-8) must agree to this on separated poses


def agreement_row(k: int, na: str, nb: str, n: int, seed: int, load_object) -> dict:
    """Pair k's (na, nb) agreement row: spq batched against coal on n random poses drawn with seed + k."""
    import spq
    from harness.engines.coal_engine import CoalEngine
    from harness.workloads.poses import random_poses

    a, b = load_object(na), load_object(nb)
    pa, pb = random_poses(n, seed + k, a.bounding_radius() + b.bounding_radius())
    mine = spq.distances(a, b, pa, pb)
    coal_pair = CoalEngine().prepare(a, b)
    theirs = coal_pair.distance_loop(pa, pb)
    sep = (mine.status == "separated") & (theirs > AGREEMENT_TOL)
    over_spq = mine.status == "overlapping"
    over_coal = theirs <= 0.0
    band = (np.abs(theirs) <= AGREEMENT_TOL) | (mine.distance <= AGREEMENT_TOL)
    diff = np.abs(mine.distance[sep] - theirs[sep])
    return {"pair": f"{na}|{nb}", "poses": n, "results": 2 * n, "separated": int(sep.sum()),
            "overlapping_spq": int(over_spq.sum()), "overlapping_coal": int(over_coal.sum()),
            "status_disagreements": int(((over_spq != over_coal) & ~band).sum()),
            "max_abs_difference": float(diff.max()) if len(diff) else 0.0,
            "over_tolerance": int((diff > AGREEMENT_TOL).sum()),
            "spq_failed": int((mine.status == "failed").sum())}


def agreement(objects: list[str], poses_total: int, seed: int, load_object, progress: bool = True) -> pd.DataFrame:
    """spq (batched) against coal on many random poses: one row per object pair.

    Cheap where the exact reference is not (its hull costs ~20 ms a pose), so it scales to millions of
    results; coal is independent of spq and accurate to its 1e-8 tolerance on these hulls.
    Translations are uniform in +-(r_A + r_B), so that both overlap and separation occur.
    """
    pairs = object_pairs(objects)
    rows = []
    for k, ((na, nb), n) in enumerate(tqdm(list(zip(pairs, _split(poses_total, len(pairs)))), desc="agreement",
                                           unit="pair", disable=not progress)):
        rows.append(agreement_row(k, na, nb, n, seed, load_object))
    return pd.DataFrame(rows)
