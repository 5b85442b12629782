"""The tradeoff suite: speed against accuracy, every engine's tolerance swept on one suite of separated
distance-controlled poses (harness.suites.tradeoff.sweeps)."""

from __future__ import annotations

import time
from dataclasses import dataclass

from harness.suites import Figure, Output, Table, frame_lines
from harness.suites.bench.timing import BLOCK


@dataclass
class Config:
    per_bucket: int | None = None  # poses per separated bucket (None: 200; quick 10)
    repeats: int | None = None  # rounds of timed runs, each setting's least time kept (None: 5; quick 2)
    seed: int = 0
    quick: bool = False
    progress: bool = False


def run(config: Config) -> Output:
    from datasets import load_object
    from harness.report.meta import run_metadata
    from harness.suites.tradeoff import sweeps as tr

    start = time.perf_counter()
    overrides = {k: v for k, v in (("per_bucket", config.per_bucket), ("repeats", config.repeats)) if v is not None}
    cfg = (tr.quick_tradeoff_config(config.seed, **overrides) if config.quick
           else tr.TradeoffConfig(seed=config.seed, **overrides))
    table, suite = tr.run_tradeoff(cfg, load_object, progress=config.progress)
    meta = run_metadata(command="spq tradeoff", quick=bool(config.quick), seed=config.seed,
                        objects=[cfg.object_a, cfg.object_b], buckets=list(cfg.buckets), per_bucket=cfg.per_bucket,
                        queries=len(suite), repeats=cfg.repeats, spq_tols=list(cfg.spq_tols),
                        coal_tols=list(cfg.coal_tols), seconds=round(time.perf_counter() - start, 1))
    notes = (f"{cfg.object_a} against {cfg.object_b}, {len(suite)} separated distance-controlled poses "
             f"(harness.workloads.poses.bucket_suite, buckets {', '.join(cfg.buckets)}, {cfg.per_bucket} each, seed "
             f"{config.seed}; reference distances {suite.ref_distance.min():.3g} to {suite.ref_distance.max():.3g} m). "
             "All engines on the same poses in the same run, side by side: in each of "
             f"{cfg.repeats} rounds every setting runs once (in blocks of up to {BLOCK:,} poses, each timed run just after "
             "an untimed one on the same block, each block's least time kept: harness.suites.bench.timing.blocked_times), after a warm-up on 8 poses. spq: tol = rel_tol = tolerance (stops when "
             "upper - lower bound <= tol + rel_tol * distance); coal: gjk_tolerance = tolerance; mujoco: ccd_tolerance = tolerance (native GJK/EPA); fcl, bullet "
             "(margin 0) and bullet-margin (pybullet's default margin) at their own settings. batched: one compiled "
             "call for all poses (cold starts); per-call: one Python call per query (spq.Pair keeps its warm start). "
             "Errors: |distance - exact reference| in m, from the distances of the timed run itself. failures: "
             f"non-finite distance or |distance| above {tr.FAIL_DISTANCE:g} m (coal at loose tolerances can return "
             "-DBL_MAX on a separated pose); "
             "max_abs_error and mean_abs_error leave failures out, median_abs_error counts them as infinite. "
             "zero_error_fraction: share of queries whose error is exactly 0. pareto_max / pareto_median: on the "
             "Pareto front of queries/s against that error over all rows (rows with failures are not on the "
             f"max-error front). In the chart, errors of exactly 0 are clipped to {tr.ZERO_CLIP:g} m for the log axis "
             "(dashed line); rows with failures are circled in red.")
    title = f"Speed vs accuracy, {cfg.object_a} | {cfg.object_b}, {len(suite)} separated poses"
    return Output(
        meta=meta, tables=[Table("tradeoff", "Speed against accuracy", table, notes)],
        figures=[Figure("tradeoff.png", lambda path: tr.plot_tradeoff(table, path, title))],
        lines=frame_lines(table[["engine", "mode", "tolerance", "queries_per_s", "max_abs_error", "median_abs_error",
                                 "zero_error_fraction", "failures", "pareto_max", "pareto_median"]]))
