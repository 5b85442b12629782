"""The stability suite: every engine on the cases where distance methods are known to fail (touching,
shallow and deep overlaps, scales, far from the origin, flat and needle bodies...), scored against the
exact reference (harness.stability), with coal's DualityGap + Relative tolerance sweep."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass

from harness.engines.mujoco_engine import PIPELINE_NOTE as MUJOCO_PIPELINE
from harness.suites import Output, Table, frame_lines


@dataclass
class Config:
    seed: int = 0
    engines: list[str] | None = None  # None: harness.stability.ENGINES (those that import)
    quick: bool = False  # one pose per case and fewer sweeps
    fcl_gap: bool = True  # the fcl_box_gap_3 family
    coal_sweep: bool = True  # coal's DualityGap + Relative sweep (when coal runs)
    progress: bool = False
    workers: int = 1  # processes (> 1: a local pool, or the Dask LocalCluster's size with scheduler "local")
    scheduler: str | None = None  # None, "local" or a Dask scheduler address (harness.cluster)


def run(config: Config) -> Output:
    from datasets import load_object
    from harness import stability as st
    from harness.report.meta import run_metadata
    from harness.cluster import describe
    from harness.report.tables import markdown_table

    start = time.perf_counter()
    cfg = st.StabilityConfig(seed=config.seed, quick=bool(config.quick), engines=config.engines,
                             fcl_gap=config.fcl_gap, coal_sweep=config.coal_sweep)
    table, sweep = st.run(cfg, load_object, progress=config.progress, workers=config.workers,
                          scheduler=config.scheduler)
    summary = st.summarize(table)
    families = st.summarize(table, by=("family", "engine"))
    sweep_summary = st.coal_sweep_summary(sweep)
    fcl_gap = st.fcl_gap_summary(table)
    meta = run_metadata(command="spq stability", seed=config.seed, quick=bool(config.quick),
                        engine_tolerances={k: list(v) for k, v in st.ENGINE_TOL.items()},
                        engine_depth_tolerances={k: list(v) for k, v in st.ENGINE_DEPTH_TOL.items()},
                        ambiguous_band_m=st.AMBIGUOUS_BAND, links=list(cfg.links),
                        queries=len(table) + len(sweep), seconds=round(time.perf_counter() - start, 1),
                        **({"runs_on": describe(config.workers, config.scheduler)}
                           if config.workers != 1 or config.scheduler is not None else {}))
    notes = ("One row per case, pose and engine. error = distance - exact reference distance (m); rel_error on "
             "separated poses. verdict: ok (|error| <= allowed_error = tol_abs + tol_rel * d_ref + 64 eps * extent, "
             "and a status consistent with the reference outside the contact band max(1e-9 m, tol_abs)), wrong, "
             "failed (status failed). Tolerances (abs m, rel): " +
             ", ".join(f"{k} {a:g}/{r:g}" for k, (a, r) in st.ENGINE_TOL.items()) + ". depth_verdict, where the "
             "reference overlaps or touches: the engine's raw signed distance against the reference's within its "
             "depth tolerance (" + ", ".join(f"{k} {a:g}/{r:g}" for k, (a, r) in st.ENGINE_DEPTH_TOL.items())
             + ") and on the right side of the 1e-9 m band; 'no depth' for an engine that gives none. " + MUJOCO_PIPELINE)
    out = Output(meta=meta, tables=[Table("stability", "Stability cases (detail)", table, notes)])
    if not sweep.empty:
        out.raw["stability_coal_dualitygap_detail.csv"] = sweep
        out.tables.append(Table(
            "stability_coal_dualitygap", "coal with DualityGap + Relative: false overlaps against gjk_tolerance",
            sweep_summary, "Separated link poses (gaps 1e-6, 1e-4, 1e-2 m). false_overlaps: reference separated by "
            "more than 1e-9 m, coal reports a collision. 'coal' is the adapter's default criterion at 1e-8."))
    text = ["# Stability summary", "", "Counts of verdicts per engine over every case family (see stability.md for "
            "the detail). " + notes, "", markdown_table(summary), "", "## Per family", ""]
    for fam, para in st.FAMILY_NOTES.items():
        text += [f"### {fam}", "", para, ""]
        sub = families[families.family == fam]
        if len(sub):
            text += [markdown_table(sub.drop(columns=["family"])), ""]
    depth_worst = st.depth_worst_cases(table)
    out.tables.append(Table("stability_depth_worst", "Largest depth errors per engine and family", depth_worst, notes))
    text += ["## Penetration depth: worst cases per engine and family", "", markdown_table(depth_worst), ""]
    if len(fcl_gap):
        text += ["## FCL 3.0 box gap", "", markdown_table(fcl_gap), ""]
    if not sweep.empty:
        text += ["## coal DualityGap + Relative sweep", "",
                 "coal with gjk_convergence_criterion = DualityGap and gjk_convergence_criterion_type = Relative, "
                 "gjk_tolerance swept (engine name), on separated link poses (gaps 1e-6, 1e-4, 1e-2 m). "
                 "false_collisions: the reference is separated by more than 1e-9 m but coal answers a distance "
                 "<= 1e-9 m or a collision; false_overlaps: coal's raw distance is negative (min_raw_distance: "
                 "the most negative one). 'coal' is the adapter's default criterion at gjk_tolerance 1e-8.", "",
                 markdown_table(sweep_summary), ""]
    text += ["Run: `" + json.dumps(meta, sort_keys=True) + "`", ""]
    out.raw["stability_summary.csv"] = summary
    out.documents["stability_summary.md"] = "\n".join(text)
    out.lines += ["", "Per engine:", *frame_lines(summary)]
    if len(fcl_gap):
        out.lines += ["", "FCL 3.0 box gap (fcl rows):", *frame_lines(fcl_gap[fcl_gap.engine == "fcl"])]
    if not sweep.empty:
        out.lines += ["", "coal DualityGap + Relative sweep:", *frame_lines(sweep_summary)]
    return out
