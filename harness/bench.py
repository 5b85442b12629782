"""Throughput benchmarks: queries per second of every engine on the same object and poses, one run.

Each engine runs its leanest per-query Python loop (``PreparedPair.distance_loop``); spq also runs its
batched compiled call. The figure reported is the best of ``repeats`` timed runs (the least disturbed
by other load on the machine), and every rate is divided by coal's from the same run.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pandas as pd

from harness.engines import available_engines
from harness.poses import random_poses

BASELINE = "coal"


@dataclass
class BenchConfig:
    object_name: str
    poses: int = 20000
    seed: int = 0
    translation_range: float = 0.3  # m: translations uniform in [-range, range]^3
    repeats: int = 3
    engines: list[str] | None = None


def _best_time(fn, repeats: int) -> tuple[float, np.ndarray]:
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def _timed_rows(pair, name: str, poses_a, poses_b, repeats: int) -> list[dict]:
    """Warm up (compilation, caches) on a few poses, then time the loop and, for spq, the batch."""
    n = len(poses_a)
    modes = [("per-call", pair.distance_loop)]
    if hasattr(pair, "distance_batch"):
        modes.insert(0, ("batched", pair.distance_batch))
    rows = []
    for mode, fn in modes:
        fn(poses_a[:8], poses_b[:8])
        seconds, dist = _best_time(lambda: fn(poses_a, poses_b), repeats)
        rows.append({"engine": name, "mode": mode, "queries": n, "seconds": seconds,
                     "queries_per_s": n / seconds, "overlapping": int(np.sum(np.asarray(dist) <= 0.0))})
    return rows


def throughput(config: BenchConfig, load_object, progress: bool = True) -> pd.DataFrame:
    """Queries per second per engine (and mode) on two copies of one object, with ratios to coal."""
    from tqdm import tqdm

    obj = load_object(config.object_name)
    poses_a, poses_b = random_poses(config.poses, config.seed, config.translation_range)
    engines = available_engines(config.engines)
    rows = []
    try:
        for name, engine in tqdm(engines.items(), desc="bench", unit="engine", disable=not progress):
            pair = engine.prepare(obj, obj)
            try:
                rows += _timed_rows(pair, name, poses_a, poses_b, config.repeats)
            finally:
                pair.close()
    finally:
        for engine in engines.values():
            engine.close()
    table = pd.DataFrame(rows)
    base = table.loc[table.engine == BASELINE, "queries_per_s"]
    table["ratio_to_coal"] = table.queries_per_s / base.iloc[0] if len(base) else np.nan
    table.insert(0, "object", config.object_name)
    table["vertices"] = len(obj.vertices)
    table["seed"] = config.seed
    return table
