"""The R-tradeoff suite: what an STP-BV's big radius R trades (features, volume excess, query speed,
witness smoothness), with a recommended R (harness.suites.tradeoff.sweeps)."""

from __future__ import annotations

import time
from dataclasses import dataclass

from harness.suites import Figure, Output, Table, frame_lines
from harness.suites.bench.timing import BLOCK


@dataclass
class Config:
    object: str = "kuka_link_4"  # dataset name or mesh path
    r: float = 0.005  # small radius (m)
    R_max: float = 100.0  # largest R (m)
    R_values: list[float] | None = None  # explicit R values (m); None: swept up to R_max
    threshold_factor: float = 10.0  # recommendation: Lipschitz ratio at most this times the smallest seen
    seed: int = 0
    quick: bool = False
    progress: bool = False


def run(config: Config) -> Output:
    import numpy as np

    from datasets import load_object
    from harness.report.meta import run_metadata
    from harness.suites.tradeoff import sweeps as tr
    from spq.query import DEFAULT_TOL_ABS, DEFAULT_TOL_REL

    start = time.perf_counter()
    obj = config.object
    overrides = dict(r=config.r, R_max=config.R_max, threshold_factor=config.threshold_factor)
    if config.R_values:
        overrides["R_values"] = tuple(config.R_values)
    cfg = (tr.quick_rtradeoff_config(obj, config.seed, **overrides) if config.quick
           else tr.RTradeoffConfig(object_name=obj, seed=config.seed, **overrides))
    table, facts = tr.run_rtradeoff(cfg, load_object, progress=config.progress)
    pick, text = tr.recommend(table, cfg.threshold_factor)
    table["recommended"] = table.R == (pick.R if pick is not None else np.nan)
    meta = run_metadata(command="spq rtradeoff", quick=bool(config.quick), object=obj, seed=config.seed,
                        r=cfg.r, R_min=facts["R_min"], poses=cfg.poses,
                        translation_range_m=cfg.translation_range, volume_samples=cfg.volume_samples,
                        repeats=cfg.repeats, step_s=cfg.step, threshold_factor=cfg.threshold_factor,
                        spq_tol_abs=DEFAULT_TOL_ABS, spq_tol_rel=DEFAULT_TOL_REL,
                        seconds=round(time.perf_counter() - start, 1))
    notes = (f"STP-BVs of {obj}'s {facts['points']} hull vertices, r = {cfg.r} m, R swept from just above "
             f"the smallest admissible R = r + enclosing radius = {facts['R_min']:.6g} m (log-spaced in R - R_min). "
             "features: patches (stp.n_patches). volume_excess: Monte Carlo volume (harness.suites.table1.bv_rates.monte_carlo_volume, "
             f"{cfg.volume_samples} samples, seed {config.seed}, the same box and points for every R) / hull volume "
             f"({facts['hull_volume']:.6g} m^3, qhull) - 1. queries_per_s: spq.distances STP-PCH (the STP-BV against "
             f"the link's hull) on {cfg.poses} random poses (harness.workloads.poses.random_poses, ±{cfg.translation_range} m), "
             f"default tolerance, every R timed side by side in {cfg.repeats} rounds (blocks of up to {BLOCK:,} poses, each "
             "timed run just after an untimed one on the same block, each block's least time kept: harness.suites.bench.timing.blocked_times). witness_lipschitz: max |Δp| / step of the witness points "
             "(m/rad) for STP-PCH on harness.suites.continuity.witness_continuity's parallel_faces trajectory at one step (step_rad), on a "
             f"{cfg.grid}-point grid plus points straddling the {cfg.jumps} largest witness jumps.")
    title = f"STP-BV of {obj}, r = {cfg.r} m: what R trades"
    return Output(
        meta=meta,
        tables=[Table("rtradeoff", "STP-BV big radius R: features, volume, speed, smoothness", table,
                      notes + "\n\n## Recommendation\n\n" + text)],
        figures=[Figure("rtradeoff.png", lambda path: tr.plot_rtradeoff(table, path, facts, pick, title))],
        lines=[*frame_lines(table[["R", "R_minus_R_min", "features", "volume_excess", "queries_per_s",
                                   "witness_lipschitz", "recommended"]]), "", *text.splitlines()])
