"""The stability suite: every engine on the cases where distance methods are known to fail (touching,
shallow and deep overlaps, scales, far from the origin, flat and needle bodies...), scored against the
exact reference (harness.suites.stability.hard_cases), with coal's DualityGap + Relative tolerance sweep, and on cases
generated from the fuzz campaign's families (harness.suites.fuzz.families), scored against the exact
reference or the fuzz campaign's independent oracle; a heat map shows where each engine fails."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass

from harness.engines.mujoco_engine import PIPELINE_NOTE as MUJOCO_PIPELINE
from harness.suites import Figure, Output, Table, frame_lines


@dataclass
class Config:
    seed: int = 0
    engines: list[str] | None = None  # None: harness.suites.stability.hard_cases.ENGINES (those that import)
    quick: bool = False  # one pose per case and fewer sweeps
    fcl_gap: bool = True  # the fcl_box_gap_3 family
    coal_sweep: bool = True  # coal's DualityGap + Relative sweep (when coal runs)
    generated: bool = True  # the cases generated from the fuzz families (harness.suites.stability.hard_cases.generated_draw)
    generated_cases: int = 10_000  # how many in a full run (quick: the first pose of one draw per family)
    progress: bool = False
    workers: int = 1  # processes (> 1: a local pool, or the Dask LocalCluster's size with scheduler "local")
    scheduler: str | None = None  # None, "local" or a Dask scheduler address (harness.parallel.cluster)


def run(config: Config) -> Output:
    from datasets import load_object
    from harness.parallel.cluster import describe
    from harness.report.meta import run_metadata
    from harness.report.tables import markdown_table
    from harness.suites.stability import hard_cases as st

    start = time.perf_counter()
    cfg = st.StabilityConfig(seed=config.seed, quick=bool(config.quick), engines=config.engines,
                             fcl_gap=config.fcl_gap, coal_sweep=config.coal_sweep, generated=config.generated,
                             generated_cases=config.generated_cases)
    everything, sweep = st.run(cfg, load_object, progress=config.progress, workers=config.workers,
                               scheduler=config.scheduler)
    generated = everything[everything.source == "generated"].dropna(axis=1, how="all")
    table = everything[everything.source == "hand-built"].dropna(axis=1, how="all").drop(columns=["source"])
    cases = st.case_count(everything)
    summary = st.summarize(everything)
    families = st.summarize(everything, by=("family", "engine"))
    sweep_summary = st.coal_sweep_summary(sweep)
    fcl_gap = st.fcl_gap_summary(table)
    meta = run_metadata(command="spq stability", seed=config.seed, quick=bool(config.quick),
                        engine_tolerances={k: list(v) for k, v in st.ENGINE_TOL.items()},
                        engine_depth_tolerances={k: list(v) for k, v in st.ENGINE_DEPTH_TOL.items()},
                        ambiguous_band_m=st.AMBIGUOUS_BAND, links=list(cfg.links),
                        queries=len(everything) + len(sweep), cases=cases,
                        generated={"poses_per_draw": st.POSES_PER_DRAW, "family_draws": st.FAMILY_DRAWS,
                                   "stream": st.GENERATED_STREAM},
                        seconds=round(time.perf_counter() - start, 1),
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
    total = cases["hand-built"] + cases["generated"]
    case_note = (f"A case is one shape pair at one pose; each is judged by every engine that takes its shapes (a "
                 f"row of the detail tables: one case, one engine). This run: {total:,} cases, "
                 f"{cases['hand-built']:,} hand-built (stability.md) and {cases['generated']:,} generated from the "
                 "fuzz families (stability_generated_detail.csv.gz).")
    text = ["# Stability summary", "", case_note, "", "Counts of verdicts per engine over every case family (see "
            "stability.md for the detail). " + notes, "", markdown_table(summary), "",
            "![Where each engine fails](stability_heatmap.png)", "", HEATMAP_CAPTION, "", "## Per family", ""]
    for fam, para in st.FAMILY_NOTES.items():
        text += [f"### {fam}", "", para, ""]
        sub = families[families.family == fam]
        if len(sub):
            text += [markdown_table(sub.drop(columns=["family"])), ""]
    if len(generated):
        from harness.suites.fuzz.families import FAMILY_NOTES as FUZZ_NOTES

        gen_notes = generated_notes(generated)
        gen_summary = st.summarize(generated, by=("family", "engine"))
        refs = generated.groupby(["family", "engine"], sort=False).reference.value_counts().unstack(fill_value=0)
        gen_summary = gen_summary.merge(refs.add_prefix("ref_").reset_index(), on=["family", "engine"])
        out.raw["stability_generated_detail.csv.gz"] = generated
        out.tables.append(Table("stability_generated", "Generated stability cases: verdicts per family and engine",
                                gen_summary, gen_notes))
        text += ["## Generated cases", "", gen_notes, ""]
        for fam in FUZZ_NOTES:
            sub = gen_summary[gen_summary.family == fam]
            if len(sub):
                text += [f"### {fam} (generated)", "", FUZZ_NOTES[fam] + ".", "",
                         markdown_table(sub.drop(columns=["family"])), ""]
    out.figures.append(Figure("stability_heatmap.png", lambda path: heatmap(st.failure_grid(everything), path)))
    depth_worst = st.depth_worst_cases(everything)
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
    out.lines += ["", f"{total:,} cases ({cases['hand-built']:,} hand-built, {cases['generated']:,} generated); "
                  "per engine:", *frame_lines(summary)]
    if len(fcl_gap):
        out.lines += ["", "FCL 3.0 box gap (fcl rows):", *frame_lines(fcl_gap[fcl_gap.engine == "fcl"])]
    if not sweep.empty:
        out.lines += ["", "coal DualityGap + Relative sweep:", *frame_lines(sweep_summary)]
    return out


HEATMAP_CAPTION = ("Share of the cases each engine answers wrong or not at all, per family (hand-built above the "
                   "line, generated from the fuzz families below): a case counts when its distance verdict or its "
                   "depth verdict is wrong or failed; each cell reads bad/judged; n/a: the engine takes no such "
                   "shapes (the peers take meshes, so no STP-BV, superellipsoid, sphere or capsule). Log colour "
                   "scale, white: none.")


def generated_notes(generated) -> str:
    """What the generated cases are and how each verdict was reached, with this run's counts."""
    from harness.suites.stability import hard_cases as st

    spq_rows = generated[generated.engine == "spq"]
    kinds = spq_rows.reference.value_counts()
    draws = ", ".join(f"{f} {n}" for f, n in st.FAMILY_DRAWS.items())
    return (f"{generated.case_index.nunique():,} cases drawn from the fuzz campaign's families "
            f"(harness/suites/fuzz/families.py): case k is pose k mod {st.POSES_PER_DRAW} of draw k div {st.POSES_PER_DRAW}, "
            f"and draw j is entry j mod {len(st.GENERATED_SCHEDULE)} of a fixed schedule (every family once, then the "
            f"rest interleaved: {draws} draws a round) drawn with np.random.default_rng([seed, "
            f"{st.GENERATED_STREAM}, j]), so a case is a pure "
            "function of the seed and its index. Poses from far apart to deep overlap and containment (the "
            "family's regime: the target separation along a random direction, a lower bound of the signed "
            "distance, so many 'touching' and 'shallow' poses land apart). Polytope pairs (hulls, boxes): every "
            "engine against the exact Minkowski reference. Pairs with an STP-BV, a superellipsoid, a sphere or a "
            "capsule: spq only (the peers take meshes), unsigned (verdict) and signed (depth_verdict), against "
            "the fuzz campaign's independent support functions (harness/suites/fuzz/oracle.py, no spq code): the "
            "bracket [separation along spq's normal, distance of the support points] where it is narrower than "
            "the allowed error and gives one verdict at both ends, else the depth oracle's value, a lower bound "
            "of the signed distance (raised to the separation along spq's normals); a 'wrong' above that lower "
            "bound is checked by a denser oracle run and left 'disputed' if it stands (never ok, never wrong "
            f"unproven). spq's references here: {', '.join(f'{k} {int(v)}' for k, v in kinds.items())}. Same "
            "tolerances and verdicts as the hand-built cases; regime, reference and ref_uncertainty are in "
            "stability_generated_detail.csv.gz.")


def heatmap(grid, path) -> None:
    """Families (rows: hand-built, a line, generated) x engines, colour: log10 share of bad cases, each
    cell's bad/judged written in it (harness.suites.stability.hard_cases.failure_grid)."""
    from harness.report.charts import failure_heatmap

    families = list(dict.fromkeys(grid.family))
    engines = list(dict.fromkeys(grid.engine))

    def count(column):
        return grid.pivot_table(index="family", columns="engine", values=column,
                                aggfunc="sum").reindex(index=families, columns=engines)

    sources = grid.drop_duplicates("family").set_index("family").source.reindex(families)
    failure_heatmap(count("bad"), count("n"), path,
                    "Where each engine fails: the stability suite, cases wrong or failed / judged",
                    "log10 share of cases wrong or failed", line_after=int((sources == "hand-built").sum()))
