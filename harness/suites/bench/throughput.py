"""Throughput benchmarks: queries per second of every engine on the same object and poses, one run.

Each engine runs its leanest per-query Python loop (``PreparedPair.distance_loop``); spq also runs its
batched compiled call (one per block of poses) and the plain ``spq.distance`` call in a loop. The
poses are cut into blocks, every engine runs block 1, then block 2, and so on, ``repeats`` rounds; an
engine's time is the sum over the blocks of its least time on each (harness.suites.bench.timing), and
every rate is divided by coal's PCH-PCH rate from the same run.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from harness.engines import available_engines
from harness.suites.bench.timing import BLOCK, blocked_calls, blocked_times
from harness.workloads.poses import random_poses

BASELINE = ("PCH-PCH", "coal")


@dataclass
class BenchConfig:
    object_name: str
    poses: int = 20000
    seed: int = 0
    translation_range: float = 0.3  # m: translations uniform in [-range, range]^3
    repeats: int = 3  # rounds: each block of poses timed this many times, its least time kept
    block: int = BLOCK  # poses per block (harness.suites.bench.timing.blocked_times)
    engines: list[str] | None = None
    r: float = 0.005  # STP-BV radii (m), for the STP pairs
    R: float = 2.0
    pairs: list[str] = field(default_factory=lambda: ["PCH-PCH"])
    workers: int = 1  # > 1: spq's batched rows also on this many threads (spq.workers), beside one thread's


def timing_modes(pair) -> list[tuple[str, object]]:
    """(mode, distances function) pairs to time: the batch where the engine has one (spq), and the
    leanest per-call loop."""
    modes = [("per-call", pair.distance_loop)]
    if hasattr(pair, "distance_batch"):
        modes.insert(0, ("batched", pair.distance_batch))
    return modes


def _shapes(config: BenchConfig, load_object) -> dict:
    from spq.shapes.stpbv import STPBV

    pch = load_object(config.object_name)
    shapes = {"PCH": pch}
    if any("STP" in p for p in config.pairs):
        shapes["STP"] = STPBV.from_points(pch.vertices, config.r, config.R)
    return shapes


def _signed_modes(shape_a, shape_b) -> list[tuple[str, object]]:
    """spq's signed timing modes (overlaps get their penetration depth), as timing_modes."""
    import spq

    pair = spq.Pair(shape_a, shape_b, signed=True)

    def per_call(poses_a, poses_b):
        query = pair.distance
        return np.array([query(pa, pb).distance for pa, pb in zip(poses_a, poses_b)])

    def batched(poses_a, poses_b):
        return spq.distances(shape_a, shape_b, poses_a, poses_b, signed=True).distance

    return [("batched signed", batched), ("per-call signed", per_call)]


def _plain_call_modes(shape_a, shape_b, tol: float, rel_tol: float) -> list[tuple[str, object]]:
    """The call a newcomer writes first, ``spq.distance(A, B, pose_a, pose_b)`` in a Python loop (a Pair
    made per call), unsigned and signed, as timing_modes: its own rows beside the prepared Pair's
    ("per-call")."""
    import spq

    def plain(signed: bool):
        def run(poses_a, poses_b):
            distance = spq.distance
            return np.array([distance(shape_a, shape_b, pa, pb, tol=tol, rel_tol=rel_tol, signed=signed).distance
                             for pa, pb in zip(poses_a, poses_b)])
        return run

    return [("plain call", plain(False)), ("plain call signed", plain(True))]


def _threaded_modes(shape_a, shape_b, tol: float, rel_tol: float, workers: int) -> list[tuple[str, object]]:
    """spq's batched modes, unsigned and signed, on ``workers`` threads (their results equal the
    one-thread batches' bit for bit), as timing_modes."""
    import spq

    def batched(signed: bool):
        def run(poses_a, poses_b):
            return spq.distances(shape_a, shape_b, poses_a, poses_b, tol=tol, rel_tol=rel_tol, signed=signed,
                                 workers=workers).distance
        return run

    return [(f"batched {workers} workers", batched(False)), (f"batched signed {workers} workers", batched(True))]


def throughput(config: BenchConfig, load_object, progress: bool = True) -> pd.DataFrame:
    """Queries per second per pair type, engine and mode on two copies of one object, with the
    ratio to coal's PCH-PCH rate. External engines only run PCH-PCH (they have no STP-BV).
    config.workers > 1 adds spq's batched modes on that many threads.

    coal always runs with signed distance on (its EPA on overlaps); spq runs unsigned (overlaps get
    distance 0) and, in the modes named "signed", with signed=True. Every job runs on all poses
    (``poses`` = "all") and again on the overlapping ones alone ("overlapping": those coal's result
    calls overlapping), where a signed engine pays for its depth on every query; ratios are to coal's
    PCH-PCH rate on the same poses."""
    from tqdm import tqdm

    from spq.workers import check_workers

    workers = check_workers(config.workers)
    shapes = _shapes(config, load_object)
    poses_a, poses_b = random_poses(config.poses, config.seed, config.translation_range)
    engines = available_engines(config.engines)
    if "spq" in engines:  # the plain rows are spq unsigned; _signed_modes adds the signed ones
        from harness.engines.spq_engine import SpqEngine

        engines["spq"] = SpqEngine(signed=False)
    runs = [(p, name) for p in config.pairs for name in engines if p == "PCH-PCH" or name == "spq"]
    prepared, modes = [], {}
    try:
        for pair_type, name in runs:
            a_kind, b_kind = pair_type.split("-")
            pair = engines[name].prepare(shapes[a_kind], shapes[b_kind])
            prepared.append(pair)
            extra = []
            if name == "spq":
                extra = _signed_modes(shapes[a_kind], shapes[b_kind]) + _plain_call_modes(
                    shapes[a_kind], shapes[b_kind], engines[name].tolerance, engines[name].rel_tol)
            if name == "spq" and workers > 1:
                extra += _threaded_modes(shapes[a_kind], shapes[b_kind], engines[name].tolerance, engines[name].rel_tol,
                                         workers)
            for mode, fn in timing_modes(pair) + extra:
                fn(poses_a[:8], poses_b[:8])  # compile and warm
                modes[(pair_type, name, mode)] = fn
        overlapping = _overlapping(modes, poses_a, poses_b)
        subsets = {"all": (poses_a, poses_b)}
        if overlapping.any():
            subsets["overlapping"] = (poses_a[overlapping], poses_b[overlapping])
        jobs = {key + (subset,): (fn, pa, pb) for subset, (pa, pb) in subsets.items() for key, fn in modes.items()}
        with tqdm(total=blocked_calls(jobs, config.repeats, config.block), desc="bench", unit="run",
                  disable=not progress) as bar:
            timed = blocked_times(jobs, config.repeats, config.block, progress=bar)
    finally:
        for pair in prepared:
            pair.close()
        for engine in engines.values():
            engine.close()
    rows = [{"pair": pair_type, "engine": name, "mode": mode, "poses": subset, "queries": len(subsets[subset][0]),
             "seconds": seconds, "queries_per_s": len(subsets[subset][0]) / seconds,
             "overlapping": int(np.sum(np.concatenate(blocks) <= 0.0))}
            for (pair_type, name, mode, subset), (seconds, blocks) in timed.items()]
    table = pd.DataFrame(rows)
    table["ratio_to_coal_pch"] = np.nan
    for subset in subsets:
        here = table.poses == subset
        base = table.loc[here & (table.pair == BASELINE[0]) & (table.engine == BASELINE[1]), "queries_per_s"]
        if len(base):
            table.loc[here, "ratio_to_coal_pch"] = table.loc[here, "queries_per_s"] / base.iloc[0]
    table.insert(0, "object", config.object_name)
    table["features"] = table.pair.map(lambda p: "+".join(str(_feature_count(shapes[k])) for k in p.split("-")))
    table["seed"] = config.seed
    return table


def _overlapping(modes: dict, poses_a: np.ndarray, poses_b: np.ndarray) -> np.ndarray:
    """(N,) bool: the poses the baseline engine (coal, else spq) finds overlapping on PCH-PCH."""
    for engine in (BASELINE[1], "spq"):
        for (pair_type, name, _), fn in modes.items():
            if pair_type == BASELINE[0] and name == engine:
                return np.asarray(fn(poses_a, poses_b)) <= 0.0
    return np.zeros(len(poses_a), dtype=bool)


def _feature_count(shape) -> int:
    return getattr(shape, "n_patches", None) or len(shape.vertices)
