"""The cross-check suite: every engine on the same distance-controlled poses, scored against the
exact reference (harness.suites.crosscheck.scoring), and spq against coal on random poses."""

from __future__ import annotations

import time
from dataclasses import dataclass

from harness.engines.mujoco_engine import PIPELINE_NOTE as MUJOCO_PIPELINE
from harness.suites import Output, Table, frame_lines
from harness.suites.crosscheck import scoring as cc

NOTES = ("Errors are reported distance minus the exact reference distance (closest point of the "
         "Minkowski-difference hull; 0 when overlapping), in metres; relative errors and witness checks on "
         "separated poses only (reference distance > 1e-9 m). false_overlaps: separated by more than "
         "1e-9 m but reported overlapping; missed_overlaps: overlapping by more than 1e-9 m but reported "
         "separated or touching. mean_signed_error shows a bias (pybullet's default margin: about -2 mm). "
         + MUJOCO_PIPELINE)
DEPTH_NOTES = ("Signed distance (minus the penetration depth when overlapping) against the exact reference's, on "
               "the touching and overlap buckets: depth error = the engine's raw signed distance - the "
               "reference's (m). sign_errors: on the wrong side of the +-1e-9 m band. Witness checks on the "
               "overlaps: | |p_B - p_A| - depth | and the points' distance from their hulls' surfaces. "
               "certificate_holds_pct: spq's [lower, upper] holds the reference. coal and python-fcl run with "
               "signed distance on, pybullet with margin 0 ('bullet') and its default 1 mm margin per shape "
               "('bullet-margin', a 2 mm bias); MuJoCo's mj_geomDistance is signed; spq with signed=True.")


@dataclass
class Config:
    objects: list[str] | None = None  # None: datasets.DEFAULT_OBJECTS
    per_bucket: int = 1000
    seed: int = 0
    engines: list[str] | None = None  # registered names; None: every one that imports
    buckets: list[str] | None = None
    agreement_poses: int = 500_000  # random poses on which spq is compared with coal (0: none)
    progress: bool = False
    workers: int = 1  # processes (> 1: a local pool, or the Dask LocalCluster's size with scheduler "local")
    scheduler: str | None = None  # None, "local" or a Dask scheduler address (harness.parallel.cluster)


def run(config: Config) -> Output:
    from datasets import DEFAULT_OBJECTS, load_object
    from harness.engines import available_engines
    from harness.engines.isolated import isolated
    from harness.report.meta import run_metadata
    from spq.query import DEFAULT_TOL_ABS, DEFAULT_TOL_REL

    from harness.parallel.cluster import check_scheduler, describe
    from spq.workers import check_workers

    start = time.perf_counter()
    workers, scheduler = check_workers(config.workers), check_scheduler(config.scheduler)
    objects = config.objects or DEFAULT_OBJECTS
    cfg = cc.CrosscheckConfig(objects=objects, per_bucket=config.per_bucket, seed=config.seed,
                              engines=config.engines, buckets=config.buckets)
    spread = workers > 1 or scheduler is not None
    plain = available_engines(cfg.engines)
    agree = None
    if spread:  # every pair's suite (and agreement) a task, engines built in the workers
        from harness.engines import PLUGIN_SPECS

        names = list(plain)
        for engine in plain.values():
            engine.close()
        table, agree = cc.run_spread(cfg, names, PLUGIN_SPECS, config.agreement_poses, workers, scheduler,
                                     progress=config.progress)
    else:
        engines = isolated(plain)  # a native engine's crash fails its queries, not the run
        try:
            table = cc.run(cfg, load_object, progress=config.progress, engines=engines)
        finally:
            for engine in {id(e): e for e in [*plain.values(), *engines.values()]}.values():
                engine.close()
    summary = cc.summarize(table)
    totals = cc.summarize(table, by=("engine",))
    worst = cc.worst_cases(table)
    meta = run_metadata(command="spq crosscheck", seed=config.seed, per_bucket=config.per_bucket,
                        objects=objects, spq_tol_abs=DEFAULT_TOL_ABS, spq_tol_rel=DEFAULT_TOL_REL,
                        coal_gjk_tolerance=1e-8, ambiguous_band_m=cc.AMBIGUOUS_BAND,
                        queries=len(table), seconds=round(time.perf_counter() - start, 1),
                        **({"runs_on": describe(workers, scheduler)} if spread else {}))
    depth = cc.depth_summary(table)
    out = Output(raw={"crosscheck.csv.gz": table}, meta=meta, tables=[
        Table("crosscheck_summary", "Cross-check per engine and bucket", summary, NOTES),
        Table("crosscheck_engines", "Cross-check per engine", totals, NOTES),
        Table("crosscheck_worst", "Worst cases per engine (largest absolute errors)", worst),
        Table("crosscheck_depth", "Penetration depth per engine and bucket", depth, DEPTH_NOTES),
        Table("crosscheck_depth_worst", "Worst depth errors per engine", cc.depth_worst_cases(table), DEPTH_NOTES)])
    lines = out.lines
    if config.agreement_poses > 0:
        if agree is None:
            agree = cc.agreement(objects, config.agreement_poses, config.seed, load_object, progress=config.progress)
        out.tables.append(Table(
            "crosscheck_agreement", "spq against coal on random poses", agree,
            f"spq batched and coal (gjk_tolerance 1e-8) on the same random poses; distances compared on "
            f"poses both call separated, statuses outside a {cc.AGREEMENT_TOL:g} m band around contact."))
        lines += ["", f"spq vs coal on {int(agree.poses.sum())} random poses ({int(agree.results.sum())} results): "
                  f"max |difference| {agree.max_abs_difference.max():.2g} m, {int(agree.over_tolerance.sum())} over "
                  f"{cc.AGREEMENT_TOL:g} m, {int(agree.status_disagreements.sum())} status disagreements, "
                  f"{int(agree.spq_failed.sum())} spq failures"]
    n_engines = max(len(table.engine.unique()), 1)
    lines += ["", f"{len(table)} query results, {len(table.engine.unique())} engines, {len(table) // n_engines} poses",
              "", "Per engine and bucket (errors in m; relative errors on separated poses):"]
    lines += frame_lines(summary[["engine", "bucket", "n", "max_abs_error", "median_abs_error", "max_rel_error",
                                  "median_rel_error", "mean_signed_error", "false_overlaps", "missed_overlaps",
                                  "failures"]])
    lines += ["", "Per engine:"]
    lines += frame_lines(totals[["engine", "n", "max_abs_error", "median_abs_error", "max_rel_error",
                                 "mean_signed_error", "max_witness_gap_error", "max_witness_off_surface",
                                 "false_overlaps", "missed_overlaps", "failures"]])
    lines += ["", "Worst cases:", *frame_lines(worst), "",
              "Penetration depth (signed distance against the reference's; touching and overlap buckets):",
              *frame_lines(depth)]
    return out
