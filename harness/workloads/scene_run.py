"""Running a robot scene over many configurations: per-configuration closest pair and time, and the
posture where the robot comes closest to itself.

Each configuration is one call of :meth:`spq.Scene.distances_many` (forward kinematics and every
pair's query in compiled code), timed alone, so the times are what a control loop calling the scene
once per tick would see, Python call overhead (some 20 microseconds) included. Warm starts carry
from one call to the next when ``coherent`` is set, exactly as in a single batched call. Only the
per-configuration minimum is kept, plus every pair's result at the overall closest configuration,
so memory does not grow with pairs x configurations.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pandas as pd

from spq.kernels.gjk import STATUS_NAMES
from spq.scene import PRUNED_STATUS, Scene, SceneDistances

STATUSES = STATUS_NAMES + (PRUNED_STATUS,)
PROGRESS_DELAY = 2.0  # s: the progress bar appears only for runs longer than this


@dataclass(eq=False)
class SceneRun:
    """Results of :func:`run_scene` over n configurations.

    min_distance (n,) m (inf when every pair was pruned); min_pair (n,) index into scene.pairs;
    min_status (n,) str; overlapping (n,) pairs reported overlapping in each configuration;
    seconds (n,) wall time of each configuration's call; status_counts
    {status: pair results} over all configurations; closest: index of the configuration with the
    smallest distance (the first one on a tie) and closest_result, every pair's result there."""

    min_distance: np.ndarray
    min_pair: np.ndarray
    min_status: np.ndarray
    overlapping: np.ndarray
    seconds: np.ndarray
    status_counts: dict
    closest: int
    closest_result: SceneDistances

    @property
    def configurations(self) -> int:
        return len(self.seconds)


def run_scene(scene: Scene, qs: np.ndarray, coherent: bool, prune: float | None = None,
              progress: bool = False) -> SceneRun:
    """Run ``scene`` on configurations qs (n, ndof), one timed call each, from cold warm-start state.

    The first configuration is run once untimed beforehand (loads the compiled code), then the
    scene's warm starts are reset. progress: a tqdm bar, shown if the run lasts over PROGRESS_DELAY."""
    from tqdm import tqdm

    qs = scene.model.check_configurations(qs)
    if len(qs) == 0:
        raise ValueError("no configurations to run")
    if len(scene.pairs) == 0:
        raise ValueError("the scene has no pairs to query (every pair is skipped)")
    scene.distances_many(qs[:1], coherent, prune)
    scene.reset()
    n = len(qs)
    min_distance, seconds = np.empty(n), np.empty(n)
    min_pair, overlapping = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
    min_status = np.empty(n, dtype=object)
    counts = dict.fromkeys(STATUSES, 0)
    closest, closest_result = 0, None
    with tqdm(total=n, desc="scene", unit="config", delay=PROGRESS_DELAY, disable=not progress) as bar:
        for k in range(n):
            start = time.perf_counter()
            out = scene.distances_many(qs[k:k + 1], coherent, prune)
            seconds[k] = time.perf_counter() - start
            result = _summarize(scene, out[0], k, counts, min_distance, min_pair, min_status, overlapping)
            if closest_result is None or min_distance[k] < min_distance[closest]:
                closest, closest_result = k, result
            bar.update(1)
    return SceneRun(min_distance, min_pair, min_status.astype(str), overlapping, seconds, counts, closest,
                    closest_result)


def _summarize(scene: Scene, out: np.ndarray, k: int, counts: dict, min_distance, min_pair, min_status,
               overlapping) -> SceneDistances:
    """Configuration k's results (out: npairs x OUT_SIZE) into the run's arrays and status counts."""
    result = SceneDistances.from_out(scene.pairs, out)
    names, number = np.unique(result.status, return_counts=True)
    for name, c in zip(names, number):
        counts[str(name)] += int(c)
    overlapping[k] = int(np.count_nonzero(result.status == "overlapping"))
    i = result.min_index
    min_pair[k], min_distance[k], min_status[k] = i, result.distance[i], result.status[i]
    return result


SPREAD_BLOCK = 256  # configurations per call (per task on a cluster) of a spread sweep


def sweep_block(task: tuple) -> tuple:
    """A cold block of a spread sweep: (scene, qs, prune, threads) -> (seconds, raw results (n, npairs,
    OUT_SIZE)) of one Scene.distances_many call on ``threads`` threads."""
    scene, qs, prune, threads = task
    start = time.perf_counter()
    out = scene.distances_many(qs, coherent=False, prune=prune, workers=threads)
    return time.perf_counter() - start, out


def run_scene_spread(scene: Scene, qs: np.ndarray, prune: float | None = None, workers: int = 1,
                     scheduler: str | None = None, progress: bool = False) -> SceneRun:
    """:func:`run_scene` of a cold sweep, its configurations in blocks of SPREAD_BLOCK: with no scheduler,
    one call per block on ``workers`` threads here; with one, a task per block (the scene pickled into
    it) on a Dask cluster (harness.parallel.cluster). Every configuration's results equal the serial run's bit
    for bit (a cold query depends on its own configuration alone); ``seconds`` holds each block's wall
    time shared out over its configurations, a throughput, not the time of a call per configuration."""
    from tqdm import tqdm

    from harness.parallel.cluster import check_scheduler, run_tasks
    from spq.workers import check_workers

    workers, scheduler = check_workers(workers), check_scheduler(scheduler)
    qs = scene.model.check_configurations(qs)
    if len(qs) == 0:
        raise ValueError("no configurations to run")
    if len(scene.pairs) == 0:
        raise ValueError("the scene has no pairs to query (every pair is skipped)")
    scene.distances_many(qs[:1], False, prune, workers=workers)  # loads the compiled code
    scene.reset()
    n = len(qs)
    starts = list(range(0, n, SPREAD_BLOCK))
    threads = workers if scheduler is None else 1
    tasks = [(scene, qs[s0:s0 + SPREAD_BLOCK], prune, threads) for s0 in starts]
    with tqdm(total=n, desc="scene", unit="config", delay=PROGRESS_DELAY, disable=not progress) as bar:
        blocks = run_tasks(sweep_block, tasks, 1 if scheduler is None else workers, scheduler,
                           done=lambda i, r: bar.update(len(r[1])))
    min_distance, seconds = np.empty(n), np.empty(n)
    min_pair, overlapping = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
    min_status = np.empty(n, dtype=object)
    counts = dict.fromkeys(STATUSES, 0)
    closest, closest_result = 0, None
    for s0, (elapsed, out) in zip(starts, blocks):
        seconds[s0:s0 + len(out)] = elapsed / len(out)
        for j in range(len(out)):
            k = s0 + j
            result = _summarize(scene, out[j], k, counts, min_distance, min_pair, min_status, overlapping)
            if closest_result is None or min_distance[k] < min_distance[closest]:
                closest, closest_result = k, result
    return SceneRun(min_distance, min_pair, min_status.astype(str), overlapping, seconds, counts, closest,
                    closest_result)


def configurations_table(scene: Scene, run: SceneRun) -> pd.DataFrame:
    """One row per configuration: min_distance_m, the closest pair (body_a, body_b), its status, the
    number of overlapping pairs, time_ms."""
    names = scene.pair_names
    return pd.DataFrame({
        "configuration": np.arange(run.configurations),
        "min_distance_m": run.min_distance,
        "body_a": [names[i][0] for i in run.min_pair],
        "body_b": [names[i][1] for i in run.min_pair],
        "status": run.min_status,
        "overlapping_pairs": run.overlapping,
        "time_ms": run.seconds * 1e3,
    })


def closest_posture_table(scene: Scene, run: SceneRun) -> pd.DataFrame:
    """Every pair's result at the closest configuration: bodies, bounding volumes, distance (m),
    status, iterations, lower bound (m), witness points and unit normal (world frame, m)."""
    res = run.closest_result
    table = pd.DataFrame({
        "configuration": run.closest,
        "body_a": [a for a, _ in scene.pair_names],
        "body_b": [b for _, b in scene.pair_names],
        "bv_a": [a for a, _ in scene.pair_kinds],
        "bv_b": [b for _, b in scene.pair_kinds],
        "distance_m": res.distance,
        "status": res.status,
        "iterations": res.iterations,
        "lower_bound_m": res.lower_bound,
    })
    for name, arr in (("point_a", res.point_a), ("point_b", res.point_b), ("normal", res.normal)):
        for axis, column in zip("xyz", arr.T):
            table[f"{name}_{axis}"] = column
    return table
