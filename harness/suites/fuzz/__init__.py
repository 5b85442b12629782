"""The fuzz suite (``spq fuzz``): a seeded, resumable campaign over adversarial shape and pose families,
where each engine fails, and every wrong or failed spq case shrunk to a reproducer.

This module is the suite's entry (config, run, tables); beside it: the families (families.py), every
query judged against independent support functions, two or more peers and, on every disagreement and
a random sample, the exact reference or the depth oracle (oracle.py, judge.py); every wrong or failed
spq case shrunk to a small reproducer (shrink.py) saved for the test suite; the campaign's state
checkpointed (campaign.py); planted bugs that show the campaign finds one (plant.py); and STP-BV
construction as a fuzz family of its own (construction.py, ``python -m harness.suites.fuzz.construction``)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from harness.suites import Figure, Output, frame_lines

FIXTURES = Path("tests/fixtures/fuzz")  # where the test suite replays reproducers from


@dataclass
class Config:
    seed: int = 0
    families: list | None = None  # None: all of harness.suites.fuzz.families.FAMILIES
    poses: int = 2000  # pose pairs per case (each queried unsigned and signed by spq)
    sample: float = 2e-4  # share of spq's queries referenced whatever the cheap checks say
    peers: list | None = None  # None: coal, mujoco, bullet (those that import)
    budget: float | None = None  # seconds of this run
    queries: int | None = None  # stop once the campaign holds this many spq queries
    workers: int = 1
    scheduler: str | None = None
    state: str | None = None  # campaign state file (resumed when it exists)
    shrink: bool = True
    shrink_limit: int = 5  # reproducers shrunk per run (one per family, mode and verdict first)
    fixtures: str | None = None  # folder for the reproducers (default tests/fixtures/fuzz if it exists)
    plant: str | None = None  # a planted bug (harness.suites.fuzz.plant)
    progress: bool = False


def run(config: Config) -> Output:
    from harness.parallel.cluster import check_scheduler, describe
    from harness.report.meta import run_metadata
    from harness.report.tables import markdown_table
    from harness.suites.fuzz import campaign as cp
    from harness.suites.fuzz.families import FAMILY_NOTES
    from harness.suites.fuzz.judge import BAND, PEER_TOL, SLACK_ULPS
    from harness.suites.fuzz.plant import planted
    from harness.suites.fuzz.shrink import case_of, points_count, save, shrink
    from spq.workers import check_workers

    check_workers(config.workers)
    check_scheduler(config.scheduler)
    if config.budget is None and config.queries is None:
        raise ValueError("spq fuzz needs --budget SECONDS or --queries N (or both)")
    if config.poses < 1 or not 0.0 <= config.sample <= 1.0:
        raise ValueError(f"poses must be >= 1 and sample within [0, 1]; got {config.poses} and {config.sample}")
    planted(config.plant)  # a bad name fails before the campaign starts
    cc = cp.CampaignConfig(seed=config.seed, families=config.families, poses=config.poses, sample=config.sample,
                           peers=config.peers, plant=config.plant)
    start = time.perf_counter()
    state = cp.run(cc, config.state, config.budget, config.queries, config.workers, config.scheduler,
                   progress=config.progress)
    seconds = time.perf_counter() - start
    table = cp.table(state)
    reproducers = []
    if config.shrink and state.bad:
        # a planted bug's reproducers are no regression cases: saved only where --fixtures says
        default = FIXTURES if FIXTURES.parent.is_dir() and config.plant is None else None
        folder = Path(config.fixtures) if config.fixtures else default
        plant = planted(config.plant)
        seen = set()
        ordered = sorted(state.bad, key=lambda b: ((b["family"], b["mode"], b["verdict"]) in seen,
                                                   points_count(b)))
        for bad in ordered:
            key = (bad["family"], bad["mode"], bad["verdict"])
            if key in seen or len(reproducers) >= config.shrink_limit:
                continue
            seen.add(key)
            before = points_count(bad)
            small = shrink(case_of(bad), plant=plant)
            small["found"] = {"seed": config.seed, "case": bad.get("case"), "points_before": before,
                              "plant": config.plant}
            path = save(small, folder) if folder is not None else None
            reproducers.append({"family": bad["family"], "mode": bad["mode"], "verdict": bad["verdict"],
                                "points_before": before, "points_after": points_count(small),
                                "shrink_calls": small["shrink_calls"], "file": str(path) if path else ""})
    meta = run_metadata(command="spq fuzz", seed=config.seed, families=cc.family_names(), poses_per_case=config.poses,
                        sample=config.sample, peers=cp.available_peers(config.peers), plant=config.plant,
                        run=describe(config.workers, config.scheduler), cases=state.next_case,
                        spq_queries=state.spq_queries(), campaign_seconds=round(state.seconds, 1),
                        this_run_seconds=round(seconds, 1), contact_band_m=BAND, slack_ulps=SLACK_ULPS,
                        peer_tolerances={k: list(v) for k, v in PEER_TOL.items()})
    out = Output(meta=meta)
    out.raw["fuzz.csv"] = table
    spq_rows = table[table.engine == "spq"]
    totals = {k: int(spq_rows[k].sum()) for k in ("queries", "wrong", "failed", "disputed")} if len(table) else {}
    lines = [f"spq fuzz: {state.spq_queries():,} spq queries over {state.next_case} cases ({describe(config.workers, config.scheduler)}, "
             f"{state.seconds:.0f} s in all)"]
    if totals:
        raised = sum(b["verdict"] == "raised" for b in state.bad)
        lines.append(f"spq: {totals['wrong']} wrong, {totals['failed']} failed, {totals['disputed']} disputed"
                     + (f" ({raised} cases kept that raised: each of their queries counted failed)" if raised else ""))
    doc = ["# Where each engine fails: the fuzz campaign", "",
           _notes(config, state, cc), "", "## Families", "",
           *[f"- **{f}**: {FAMILY_NOTES[f]}" for f in cc.family_names()], "",
           "## Per family, engine and mode", "", markdown_table(table) if len(table) else "no case ran", ""]
    if reproducers:
        import pandas as pd

        rep = pd.DataFrame(reproducers)
        out.raw["fuzz_reproducers.csv"] = rep
        doc += ["## Reproducers (shrunk)", "", markdown_table(rep), ""]
        lines += ["", "reproducers:", *frame_lines(rep)]
    doc += ["Run: `" + str(meta) + "`", ""]
    out.documents["fuzz.md"] = "\n".join(doc)
    out.figures = [Figure("fuzz_heatmap.png", lambda p: heatmap(table, p))]
    out.lines = lines + ["", *frame_lines(table)]
    return out


def _notes(config, state, cc) -> str:
    return (f"{state.spq_queries():,} spq queries (each pose pair unsigned and signed) over {state.next_case} cases of "
            f"{config.poses} pose pairs, seed {config.seed}, {state.rounds} rounds, {state.seconds:.0f} s of campaign. "
            "Every spq query is judged by its certified interval against the separation bounds at its own normal "
            "(independent support functions), its unsigned and signed answers against each other, and on polytope "
            "pairs the peers' answers against the interval; every disagreement, every failed query and a random "
            f"{config.sample:g} share go to the exact Minkowski reference (two polytopes) or the depth oracle. "
            "wrong: outside the reference beyond rounding; failed: status failed, or every query of a case on which "
            "spq raised (kept as a 'raised' reproducer with its message) (spq), a failed or crashed query "
            "(peers); disputed: spq's lower bound above every value the oracle certified, even after a denser run "
            "(spq), or a peer's disagreement with spq's interval beyond its tolerance not referenced (a peer's "
            "referenced disagreements are capped per case). Peers take the polytope pairs only (meshes).")


def heatmap(table, path) -> None:
    """Families x engines, colour: share of queries wrong, failed or disputed (log scale), counts written."""
    from harness.report.charts import failure_heatmap, pyplot

    if not len(table):
        plt = pyplot()
        fig, ax = plt.subplots(figsize=(4, 2))
        ax.text(0.5, 0.5, "no case ran", ha="center")
        fig.savefig(path, dpi=110)
        plt.close(fig)
        return
    t = table.assign(col=table.engine + " " + table["mode"], bad=table.wrong + table.failed + table.disputed)
    grid = t.pivot_table(index="family", columns="col", values=["bad", "queries"], aggfunc="sum")
    failure_heatmap(grid["bad"], grid["queries"], path, "Where each engine fails (fuzz campaign)",
                    "log10 share of queries wrong, failed or disputed", floor=-7.0)
