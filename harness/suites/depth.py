"""The depth suite: spq's penetration depth on STP-BV and CSE-BV pairs against an independent oracle
that shares no code with spq's kernels (harness.references.depth_oracle)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from harness.suites import Output, Table, frame_lines


@dataclass
class Config:
    object: str = "kuka_link_4"  # dataset name or mesh path
    per_bucket: int = 300  # poses per overlap bucket
    stp_per_bucket: int | None = None  # poses per bucket for pairs with an STP-BV (None: per_bucket; ~1 s a pose)
    pairs: list[str] = field(default_factory=lambda: ["STP-STP", "STP-PCH", "CSE-CSE", "CSE-PCH"])
    seed: int = 0
    progress: bool = False


def run(config: Config) -> Output:
    from datasets import load_object
    from harness.references import depth_oracle as do
    from harness.report.meta import run_metadata
    from spq.query import DEFAULT_TOL_ABS, DEFAULT_TOL_REL

    start = time.perf_counter()
    cfg = do.DepthConfig(object_name=config.object, per_bucket=config.per_bucket,
                         stp_per_bucket=config.stp_per_bucket or config.per_bucket, seed=config.seed,
                         pairs=tuple(config.pairs))
    table = do.run(cfg, load_object, progress=config.progress)
    summary = do.summarize(table)
    meta = run_metadata(command="spq depth", object=config.object, seed=config.seed, per_bucket=cfg.per_bucket,
                        stp_per_bucket=cfg.stp_per_bucket, pairs=list(cfg.pairs), r=cfg.r, R=cfg.R,
                        stp_points=do.STP_POINTS, tol=DEFAULT_TOL_ABS, rel_tol=DEFAULT_TOL_REL,
                        seconds=round(time.perf_counter() - start, 1))
    notes = ("spq's signed distance (batched, default tolerances) against an independent oracle that shares no code "
             "with spq's kernels (harness/references/depth_oracle.py: min over unit n of h_B(n) + h_A(-n) from closed-form "
             "superellipsoid supports, brute-force STP-BV supports from the generating points, and hull vertices; "
             f"{do.STARTS} starts, SLSQP from the {do.POLISH} best). Poses: per overlap bucket, depth = bucket x "
             "L, L = mean bounding radius; B moved along the oracle's normal to the target depth. contains: spq's "
             "[lower, upper] holds the oracle's value (widened by its spread). The STP-BV is built from "
             f"{do.STP_POINTS} of the link's hull vertices (r = {cfg.r} m, R = {cfg.R} m).")
    return Output(meta=meta, lines=frame_lines(summary), tables=[
        Table("depth_oracle", "Penetration depth against the independent oracle, per pose", table, notes),
        Table("depth_oracle_summary", "Penetration depth against the independent oracle", summary, notes)])
