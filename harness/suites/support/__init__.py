"""The support-scaling suite (the paper's Fig. 6 and 7): time per STP-BV support call against the
feature count, for the naive scan, the guided march and the hull-accelerated search, cold and warm."""

from __future__ import annotations

from dataclasses import dataclass

from harness.suites import Figure, Output, Table, frame_lines


@dataclass
class Config:
    object: str = "kuka_link_1"  # dataset name or mesh path
    r: float = 0.005  # m: STP-BV small radius
    R_values: list[float] | None = None  # m: big radii; None: harness.suites.support.stp_scaling's factors of the smallest admissible
    directions: int = 20000
    seed: int = 0
    repeats: int = 3
    progress: bool = False


def run(config: Config) -> Output:
    from datasets import load_object
    from harness.report.meta import run_metadata
    from harness.suites.support import stp_scaling as sc

    cfg = sc.ScalingConfig(object_name=config.object, r=config.r, R_values=tuple(config.R_values or ()) or None,
                           directions=config.directions, seed=config.seed, repeats=config.repeats)
    table = sc.run(cfg, lambda name: load_object(name).vertices, progress=config.progress)
    slopes = sc.loglog_slopes(table)
    meta = run_metadata(command="spq bench support", seed=config.seed, directions=config.directions, r=config.r)
    notes = (f"Time per STP-BV support call on {config.object} ({table.points.iloc[0]} hull points), r = {config.r} m, "
             "R varied to vary the feature count. cold: random directions, no warm start; warm: a smooth path "
             "of directions, each search starting from the previous patch. Slopes of log(time) against "
             "log(features): 1 is linear, 0.5 is the paper's O(sqrt n).")
    out = Output(meta=meta, tables=[
        Table("support_scaling", "STP-BV support scaling (paper Fig. 6 and 7)", table, notes),
        Table("support_scaling_slopes", "Support scaling: log-log slopes", slopes)],
        figures=[Figure("support_scaling.png", lambda path: sc.plot(table, path))])
    out.lines = [*frame_lines(table[["R", "features", "method", "mode", "ns_per_call", "mean_steps"]]), "",
                 *frame_lines(slopes)]
    return out
