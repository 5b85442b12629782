"""`spq report`: run the suites, then assemble index.html and REPORT.md from what they wrote.

Each suite of harness/suites runs with the report's config, its output is written into the output
folder, and its section is built from the files written, with readings computed from the numbers.
The run's size (:data:`SIZES`) sets every suite's samples: "standard" (`spq report`) answers every question of
"full" (`spq report --full`, the committed report) on fewer samples, in about ten minutes on a fresh
2-core install; "quick" shrinks every suite so that the whole report takes a minute or two.

The suites that time nothing (accuracy, stability, pictures: ``timed=False``) run first, side by side
on ``workers`` processes, longest first; then the benchmarks run one at a time in this process, on an
otherwise idle machine, so that their figures mean what a serial run's do. Each suite's content is
the same either way (its seed fixes it); only the run's metadata (seconds, peak memory) differ.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from harness.report.html import Chart, Section, render
from harness.report.meta import run_metadata


@dataclass
class Suite:
    name: str
    module: str  # the suite's module in harness.suites (run(config) -> Output)
    config: Callable[[str, int, Path], object]  # (size, seed, output folder) -> the suite's config
    section: Callable[[Path], Section]
    timed: bool = True  # whether it measures speed (then it runs alone); False: it may share the machine


CHECK_BASELINE = Path(__file__).resolve().parent.parent / ".ci" / "check-baseline.json"


def check_config(size: str, seed: int, out: Path):
    """spq check against the committed baseline (if this is a source checkout), speed advisory, the
    run appended to the report's history."""
    from harness.suites import check
    from harness.suites.check.gate import CheckConfig

    history = str(out / "check_history.jsonl")
    if size == "quick":  # smaller than the baseline's run: nothing to compare with
        return check.Config(CheckConfig(seed=seed, per_bucket=26, oracle_per_bucket=1, speed_poses=500, fuzz_cases=1,
                                        fuzz_poses=200),
                            history=history)
    return check.Config(CheckConfig(seed=seed), speed="advisory", history=history,
                        baseline=str(CHECK_BASELINE) if CHECK_BASELINE.exists() else None)


def check_section(out: Path) -> Section:
    from harness.suites.check import gate as ck

    doc = ck.load_results(out / "check.json")
    metrics = pd.DataFrame(doc["metrics"])
    judged = (out / "check_diff.csv").exists()
    paragraphs = [
        f"spq check is the gate a CI runs (docs/commands/check.md): {len(metrics)} metrics over "
        f"{metrics.engine.nunique()} engines at fixed seeds, in {doc['meta']['seconds']:.0f} s"
        + (", judged against the committed baseline (.ci/check-baseline.json): accuracy regressions fail, speed "
           "ratios are advisory here." if judged else "; no baseline compared in this run.")]
    tables = []
    per = []
    for engine, g in metrics.groupby("engine", sort=False):
        acc = g[(g.kind == "error") & g.check.str.startswith("accuracy")]
        speed = g[(g.kind == "ratio") & g.metric.str.startswith("PCH-PCH per-call")]
        per.append({"engine": engine, "checks": g.check.nunique(),
                    "wrong_failed_missed": int(g[g.kind.isin(["count", "zero"])].value.sum()),
                    "max_pch_error_m": acc.value.max() if len(acc) else float("nan"),
                    "per_call_speed_ratio": speed.value.iloc[0] if len(speed) else float("nan")})
    tables.append(("Per engine: counts of wrong, failed and missed-bound cases over all checks; the largest "
                   "PCH-PCH error; the per-call speed ratio to coal", pd.DataFrame(per)))
    if judged:
        diff = _read(out, "check_diff.csv")
        counts = diff.verdict.value_counts()
        paragraphs.append("Against the baseline: " + ", ".join(f"{k} {v}" for k, v in counts.items()) + ".")
        changed = diff[~diff.verdict.isin(["ok", "info"])]
        if len(changed):
            tables.append(("Metrics that changed against the baseline", changed))
    charts = []
    history = out / "check_history.jsonl"
    if history.exists():
        table = ck.load_history(history)
        path = ck.history_chart(table, out / "check_history.png")
        charts.append(Chart(path, f"Check history, {table.run.nunique()} runs (x: the commit of each run). Left: the "
                                  "largest PCH-PCH error per engine; middle: wrong, failed and missed-bound cases; "
                                  "right: speed ratios to coal. Look for a step up (left, middle) or down (right) at "
                                  "a commit."))
    return Section("The gate: spq check", paragraphs, tables, charts)


def _read(out: Path, name: str) -> pd.DataFrame:
    return pd.read_csv(out / name)


def crosscheck_section(out: Path) -> Section:
    engines = _read(out, "crosscheck_engines.csv")
    worst = _read(out, "crosscheck_worst.csv")
    spq_row = engines[engines.engine == "spq"].iloc[0]
    paragraphs = [
        f"Every engine answered the same {int(spq_row.n)} distance-controlled poses (13 buckets from 5 body sizes "
        "apart to 10% overlap), scored against an exact reference that shares no code with spq's GJK (the "
        "closest point of the Minkowski-difference hull).",
        f"spq: largest absolute error {spq_row.max_abs_error:.2g} m, witness points off their surfaces by at most "
        f"{spq_row.max_witness_off_surface:.2g} m, {int(spq_row.false_overlaps)} false and "
        f"{int(spq_row.missed_overlaps)} missed overlaps, {int(spq_row.failures)} failures.",
    ]
    for _, r in engines[engines.engine != "spq"].iterrows():
        paragraphs.append(
            f"{r.engine}: largest error {r.max_abs_error:.2g} m, mean signed error {r.mean_signed_error:.2g} m, "
            f"{int(r.false_overlaps)} false and {int(r.missed_overlaps)} missed overlaps, {int(r.failures)} failures.")
    tables = []
    if (out / "crosscheck_agreement.csv").exists():
        agree = _read(out, "crosscheck_agreement.csv")
        paragraphs.append(
            f"spq against coal on {int(agree.poses.sum()):,} random poses ({int(agree.results.sum()):,} results): "
            f"largest difference {agree.max_abs_difference.max():.2g} m on poses both call separated, "
            f"{int(agree.over_tolerance.sum())} beyond 1e-7 m, {int(agree.status_disagreements.sum())} status "
            f"disagreements outside the contact band, {int(agree.spq_failed.sum())} spq failures.")
        tables.append(("spq against coal on random poses", agree))
    if (out / "crosscheck_depth.csv").exists():
        depth = _read(out, "crosscheck_depth.csv")
        scored = depth[depth.depth == "yes"]
        per = scored.groupby("engine", sort=False).agg(err=("max_abs_depth_error", "max"),
                                                       sign=("sign_errors", "sum"), failed=("failures", "sum"))
        spq_hold = scored[scored.engine == "spq"].certificate_holds_pct.min()
        paragraphs.append(
            "Penetration depth (touching and overlap buckets, each engine's signed distance against the reference's): "
            + "; ".join(f"{e} largest error {r.err:.2g} m, {int(r.sign)} sign errors, {int(r.failed)} failures"
                        for e, r in per.iterrows())
            + (f"; spq's certified interval holds the reference in {spq_hold:.4g}% of the poses of its worst bucket"
               if scored.engine.eq("spq").any() else "")
            + "".join(f"; {e}: no depth" for e in depth[depth.depth == "no depth"].engine) + ".")
        tables += [("Penetration depth per engine and bucket (m)", depth),
                   ("Worst depth errors", _read(out, "crosscheck_depth_worst.csv"))]
    cols = ["engine", "n", "max_abs_error", "median_abs_error", "max_rel_error", "mean_signed_error",
            "max_witness_off_surface", "false_overlaps", "missed_overlaps", "failures"]
    return Section("Cross-check against the exact reference", paragraphs,
                   [("Per engine (errors in m)", engines[cols]), ("Worst cases", worst), *tables])


def bench_section(out: Path, suite: str, title: str) -> Section:
    table = _read(out, f"bench_{suite}.csv")
    if "poses" not in table:
        table["poses"] = "all"
    rows = [f"{r.pair} {r.engine} {r['mode']} ({r.poses} poses): {r.queries_per_s:,.0f} queries/s, "
            f"{r.ratio_to_coal_pch:.2f}x coal's PCH-PCH" for _, r in table.iterrows() if r.engine == "spq"]
    return Section(title, ["Same link, same poses, every engine in one run (best of the repeats). coal runs with "
                           "signed distance on (EPA on overlaps); spq's 'signed' modes give the penetration depth too. "
                           "The overlapping rows time the poses coal finds overlapping, alone. " + "; ".join(rows) + "."],
                   [("Queries per second", table[["pair", "engine", "mode", "poses", "queries_per_s",
                                                  "ratio_to_coal_pch", "features", "overlapping"]]),
                    *_mesh_table(out, suite)])


def _mesh_table(out: Path, suite: str) -> list:
    """The peers on the STP-BV's own meshes (spq bench stp), when the run made that table."""
    if not (out / f"bench_{suite}_meshes.csv").exists():
        return []
    return [("The peers on the STP-BV's own meshes: spq's speed-up over them and their largest difference from "
             "spq's exact signed distance", _read(out, f"bench_{suite}_meshes.csv"))]


def support_section(out: Path) -> Section:
    slopes = _read(out, "support_scaling_slopes.csv")
    s = {(r.method, r["mode"]): r.loglog_slope for _, r in slopes.iterrows()}
    caption = ("Time per STP-BV support call (ns, log scale) against the feature count (log scale), varied by R on one "
               f"link. Log-log slopes: naive {s.get(('naive', 'cold'), float('nan')):.2f}, guided march "
               f"{s.get(('march', 'cold'), float('nan')):.2f}, hull-accelerated {s.get(('hull', 'cold'), float('nan')):.2f} "
               "(cold); warm searches along a smooth path stay flat. A slope of 1 is linear, 0.5 the paper's sqrt(n).")
    return Section("STP-BV support scaling (paper Fig. 6 and 7)", [],
                   [("Slopes", slopes)], [Chart(out / "support_scaling.png", caption)])


def table1_section(out: Path) -> Section:
    table = _read(out, "table1.csv")
    volumes = _read(out, "table1_volumes.csv")
    text = (out / "table1.md").read_text()
    reading = text.split("## Reading", 1)[1].split("Run:", 1)[0].strip() if "## Reading" in text else ""
    anchor = [ln for ln in text.splitlines() if "coal PCH-PCH in the same run" in ln]
    return Section("Table I: PCH, STP and CSE on one link", [*(a.strip() for a in anchor[:1]), reading],
                   [("Queries per second per pair (paper's figures beside)", table), ("Bounding volumes", volumes)])


def continuity_section(out: Path) -> Section:
    summary = _read(out, "continuity_summary.csv")
    caption = ("Empirical Lipschitz ratio of the witness point, max |p(s+h) - p(s)| / h (log scale), against the step h "
               "(log scale) along three trajectories. Polyhedral pairs grow like 1/h where the witness point jumps "
               "(parallel faces); pairs with an STP-BV or a superellipsoid stay bounded: their gradient is continuous.")
    paths = ("Witness point of B along the parallel-face rotation: PCH-PCH jumps across the face as the faces pass "
             "parallel; the strictly convex covers move it continuously.")
    tables, charts = [("Summary", summary)], [Chart(out / "continuity_lipschitz.png", caption),
                                              Chart(out / "continuity_witness_paths.png", paths)]
    paragraphs = []
    if (out / "contact_continuity_summary.csv").exists():
        contact = _read(out, "contact_continuity_summary.csv")
        paragraphs.append(
            "Through contact (signed distance): largest jump of the signed distance left at a sign change after "
            "bisection " + ", ".join(f"{r.pair} {r.max_crossing_jump_m:.2g} m" for r in contact.itertuples())
            + "; gradient jumps " + ", ".join(f"{r.pair} {int(r.gradient_jumps)} ({int(r.gradient_jumps_in_contact)} "
                                               f"in contact, {int(r.gradient_jumps_deeper_than_r)} deeper than r)"
                                               for r in contact.itertuples())
            + ". Deeper than the STP-BV's small radius r the penetration depth's gradient may jump for any bodies "
              "(the nearest boundary point of the Minkowski difference switches); down to that depth, with an STP-BV on a side, it may not.")
        tables.append(("Through contact", contact))
        charts.append(Chart(out / "contact_continuity.png",
                            "Signed distance (top) and the norm of its gradient in B's rotation (bottom) along one path per pair that "
                            "enters and leaves contact; dotted lines mark gradient jumps confirmed by bisection. The "
                            "signed distance passes zero without a step; in shallow contact only PCH-PCH's gradient jumps."))
    return Section("Gradient continuity", paragraphs, tables, charts)


def tradeoff_section(out: Path) -> Section:
    table = _read(out, "tradeoff.csv")
    caption = ("Queries per second (log scale) against the largest and the median absolute error (m, log scale; exact "
               "zeros drawn at 1e-17) on one suite of separated poses with exact reference distances. spq, coal and MuJoCo "
               "are swept over their tolerance (one curve each); python-fcl and pybullet expose none and are single "
               "points. The Pareto front marks the settings no other setting beats in both speed and accuracy.")
    return Section("Speed against accuracy", [], [("Per engine and setting", table)],
                   [Chart(out / "tradeoff.png", caption)])


def rtradeoff_section(out: Path) -> Section:
    table = _read(out, "rtradeoff.csv")
    text = (out / "rtradeoff.md").read_text()
    recommendation = [p.strip() for p in text.split("\n\n") if "recommend" in p.lower() or "pick" in p.lower()]
    caption = ("Against R (m, log scale) at fixed r: the STP-BV's feature count, its volume excess over the hull, "
               "STP-PCH queries per second, and the witness-point Lipschitz ratio (m/rad) on the parallel-face "
               "rotation. A larger R hugs the hull more closely but lets the witness point move faster.")
    return Section("Choosing R", recommendation[:1], [("R sweep", table)], [Chart(out / "rtradeoff.png", caption)])


def stability_section(out: Path) -> Section:
    summary = _read(out, "stability_summary.csv")
    spq_row = summary[summary.engine == "spq"].iloc[0]
    paragraphs = [
        "Every engine on the cases where distance solvers are known to fail: near contact (1e-4 to 1e-12 m), shallow "
        "and deep overlap, scales from 1e-3 m to 1e3 m, bodies 1e4 m from the origin, flat and needle-like bodies, "
        "near-parallel faces, FCL's 3.0-gap boxes, and coal's duality-gap criterion at several tolerances.",
        f"spq: {int(spq_row.ok)} ok, {int(spq_row.wrong)} wrong, {int(spq_row.failed)} failed (a failed status is spq "
        "declining to certify, never a wrong number). Details per family and the coal tolerance sweep: "
        "stability_summary.md and stability_coal_dualitygap.md beside this page."]
    if "depth_n" in summary:
        paragraphs.append(
            "Penetration depth where the reference overlaps or touches (every family, the pen_* ones included: "
            "shallow 1e-12 to 1e-3 m, containment, parallel faces, scales, 1e4 m from the origin, degenerate GJK "
            "simplices, long faces): " + "; ".join(
                f"{r.engine} {int(r.depth_ok)} ok, {int(r.depth_wrong)} wrong, {int(r.depth_failed)} failed"
                + (f", {int(r.no_depth)} without depth" if r.no_depth else "")
                + f" (largest error {r.max_abs_depth_error:.2g} m)" for r in summary.itertuples()) + ".")
    tables = [("Verdicts per engine", summary)]
    if (out / "stability_generated.csv").exists():
        generated = _read(out, "stability_generated.csv")
        gen_cases = int(generated.loc[generated.engine == "spq", "n"].sum()) if "spq" in set(generated.engine) else 0
        paragraphs.insert(1, (
            f"Beside the {int(spq_row.n) - gen_cases:,} hand-built cases, {gen_cases:,} cases generated from the fuzz "
            "campaign's families (seeded: case k is a pure function of the seed and k), a case being one shape pair at "
            "one pose judged by every engine that takes its shapes: polytope pairs by every engine against the exact "
            "reference, pairs with an STP-BV, a superellipsoid, a sphere or a capsule by spq alone against the fuzz "
            "campaign's independent oracle. The heat map shows, per family, the share of cases each engine answers "
            "wrong or not at all; stability_generated.md holds the counts."))
        tables.append(("Generated cases: verdicts per family and engine", generated))
    if (out / "stability_depth_worst.csv").exists():
        tables.append(("Largest depth errors per engine and family", _read(out, "stability_depth_worst.csv")))
    charts = [Chart(out / "stability_heatmap.png", "Share of each engine's cases wrong or failed (distance or depth "
                    "verdict) per family, hand-built families above the line, generated ones below; each cell reads "
                    "bad/judged (log colour scale, white: none; n/a: the engine takes no such shapes).")]
    return Section("Stability where methods fail", paragraphs, tables, [c for c in charts if c.path.is_file()])


def fuzz_section(out: Path) -> Section:
    """The fuzz campaign's counts per family, engine and mode, and its heat map."""
    table = _read(out, "fuzz.csv")
    document = (out / "fuzz.md").read_text() if (out / "fuzz.md").is_file() else ""
    notes = [p for p in document.split("\n\n")[1:2] if p.strip()]
    spq_rows = table[table.engine == "spq"]
    lines = notes + [f"spq: {int(spq_rows.wrong.sum())} wrong, {int(spq_rows.failed.sum())} failed, "
                     f"{int(spq_rows.disputed.sum())} disputed in {int(spq_rows.queries.sum()):,} queries; "
                     "`spq fuzz` runs larger campaigns (reports/fuzz.md holds the last one)."]
    charts = [Chart(out / "fuzz_heatmap.png", "Share of each engine's queries wrong, failed or disputed per family "
                    "(log colour scale; each cell's count written in it; n/a: the engine takes no such shapes).")]
    return Section("Where each engine fails", lines, [("Per family, engine and mode", table)],
                   [c for c in charts if c.path.is_file()])


def depth_section(out: Path) -> Section:
    summary = _read(out, "depth_oracle_summary.csv")
    worst = summary.sort_values("max_abs_error_m", ascending=False).iloc[0]
    paragraphs = [
        "Penetration depth of pairs with an STP-BV or a superellipsoid, where no exact reference exists: spq's signed "
        "distance against an independent oracle (min over unit n of h_B(n) + h_A(-n), from closed-form superellipsoid "
        "supports, brute-force STP-BV supports from the generating points and hull vertices; many starts, SLSQP "
        "polish; harness/references/depth_oracle.py), on overlaps of 1e-4 to 1e-1 times the body size.",
        f"Largest |spq - oracle| over {int(summary.poses.sum())} poses: {worst.max_abs_error_m:.2g} m ({worst.pair}, "
        f"{worst.bucket}); spq's certified interval holds the oracle's value in {summary.contained_pct.min():.4g}% "
        f"of the poses of the worst bucket; spq failed {int(summary.spq_failed.sum())} times."]
    return Section("Penetration depth against an independent oracle", paragraphs, [("Per pair and bucket", summary)])


def pictures_section(out: Path) -> Section:
    table = _read(out, "pictures.csv")
    facts = dict(zip(table.picture, table.facts))
    subject = dict(zip(table.picture, table.subject))
    captions = {
        "pictures_link_covers.png": "One link's three covers, the same view: " + facts.get("pictures_link_covers.png", ""),
        "pictures_r_tradeoff.png": (f"STP-BVs of {subject.get('pictures_r_tradeoff.png', 'the link')} at growing R (r fixed): "
                                    + facts.get("pictures_r_tradeoff.png", "")),
        "pictures_robot.png": (f"{subject.get('pictures_robot.png', 'The robot')}: " + facts.get("pictures_robot.png", "")
                               + ". Left: every body's bounding volume, the closest pairs' witness segments numbered "
                                 "from the closest; right: the closest pair, each side with the volume its query used."),
        "pictures_penetration.png": (f"{subject.get('pictures_penetration.png', '')}: "
                                     + facts.get("pictures_penetration.png", "")
                                     + ". Left: overlapping, see-through; right: B moved by the vector."),
    }
    charts = [Chart(out / name, text, LOOK.get(name, "")) for name, text in captions.items()]
    notes = ["Meshes from spq's to_mesh: every vertex on the true surface, each mesh within the stated tolerance of "
             "it (certified). STP-BV patches: orange small spheres (radius r, at the hull's vertices), gold big spheres "
             "(radius R, on its faces), purple tori (along its edges)."]
    return Section("Pictures: bounding volumes, a robot, a penetration", notes,
                   [("The closest pairs at the pictured posture", _read(out, "pictures_closest_pairs.csv"))], charts,
                   gallery=True)


# the one line above each chart's caption: what to look at (by file name)
LOOK = {
    "pictures_link_covers.png": "Look at how tightly each cover hugs the link: the STP-BV is the hull rounded, the CSE "
                                "one smooth shape around it.",
    "pictures_r_tradeoff.png": "Look at the shape as R grows: from a ball-like hull to the link's own hull rounded by r.",
    "pictures_robot.png": "Look at the red witness segments: where the robot comes closest to itself.",
    "pictures_penetration.png": "Look at the red arrow: the shortest translation of B that separates the two bodies.",
    "fuzz_heatmap.png": "Look for red cells: the families where an engine answers wrong or not at all.",
    "stability_heatmap.png": "Look for red cells: the families where an engine answers wrong or not at all.",
    "check_history.png": "Look for a step up (left, middle) or down (right) at a commit.",
    "support_scaling.png": "Look at the slopes: the hull-accelerated search grows slowest with the feature count.",
    "continuity_lipschitz.png": "Look at which lines rise as the step shrinks: only polyhedral pairs' witness points jump.",
    "continuity_witness_paths.png": "Look at the PCH-PCH path: it jumps across the face where the covers' paths glide.",
    "contact_continuity.png": "Look for steps at zero: none in the signed distance; gradient jumps only for PCH-PCH.",
    "tradeoff.png": "Look at the upper left: faster and more accurate at once.",
    "rtradeoff.png": "Look at the recommended R: little volume excess left, witness speed still low.",
    "robot_engines.png": "Look at the bar lengths: time per configuration, shorter is faster.",
    "robot_trajectory.png": "Look at the x marks: gradient jumps of PCH-PCH that auto does not have.",
    "robot_distance_matrix.png": "Look for the darkest cells: the pairs that come closest at this posture.",
    "robots_time_vs_pairs.png": "Look at the gap between the circles and the grey squares: spq's time and "
                                "pinocchio's on the same robot.",
    "control_qdot_traces.png": "Look for the kinks: steps where a joint's commanded velocity changes direction at once.",
    "control_acceleration.png": "Look at the tails right of the dashed line: how often, and how hard, each method's "
                                "commands jump.",
    "control_time.png": "Look at the bar heights: the time a control step spends on distances and on the QP.",
}


def report_robot() -> str:
    """JVRC-1 (the issue's robot, from the shared datasets) if present, else the KUKA iiwa of pybullet_data."""
    from datasets.robots import robot_files

    return "jvrc1" if robot_files("jvrc1").urdf.is_file() else "kuka_iiwa"


def robot_section(out: Path) -> Section:
    scene = _read(out, "robot_scene.csv")
    engines = _read(out, "robot_engines.csv")
    cont = _read(out, "robot_continuity.csv")

    def ms(policy, source, prune=False):
        rows = scene[(scene.policy == policy) & (scene.configurations == source) & ((scene.pruning_m > 0) == prune)]
        return float(rows.ms_per_config.iloc[0]) if len(rows) else float("nan")

    fk = _read(out, "robot_kinematics.csv").iloc[0]
    auto = scene[scene.policy == "auto"].iloc[0]
    coal = engines[engines.engine == "coal"]
    coal_ms = float(coal.ms_per_config.iloc[0]) if len(coal) else float("nan")
    jumps = {(r.policy, r.track): int(r.gradient_jumps_same_pair) for r in cont.itertuples()}
    residual = {(r.policy, r.track): r.largest_residual_after_bisection for r in cont.itertuples()}
    closest = [(p, t) for p, t in jumps if t == "closest pair"]
    through = [r for r in cont.itertuples() if str(r.track).startswith("through contact")]
    paragraphs = [
        f"Every non-adjacent pair of {fk.robot} ({int(auto.pairs)} pairs; auto policy: {auto.pairs_by_bv}) per "
        "configuration, in one compiled call (forward kinematics included). Forward kinematics against pybullet's "
        f"on {int(fk.configurations)} configurations ({int(fk.links)} links, {int(fk.dof)} joints): largest position "
        f"difference {fk.max_position_error_m:.2g} m, rotation entry {fk.max_rotation_entry_error:.2g}.",
        f"auto (STP-BV on the side with fewer patches, PCH on the other): {ms('auto', 'random'):.3g} ms cold, "
        f"{ms('auto', 'trajectory'):.3g} ms with warm starts along the trajectory; the targets are 0.5 ms and 0.15 ms. "
        f"PCH-PCH: {ms('pch', 'random'):.3g} ms cold, {ms('pch', 'trajectory'):.3g} ms coherent. With pruning of pairs "
        f"whose bounding spheres are over {scene[scene.pruning_m > 0].pruning_m.iloc[0]:g} m apart: auto "
        f"{ms('auto', 'random', True):.3g} ms cold, {ms('auto', 'trajectory', True):.3g} ms coherent.",
        f"coal on the same PCH pairs, one Python call per pair: {coal_ms:.3g} ms per configuration, "
        f"{coal_ms / ms('pch', 'random'):.2g}x spq's PCH-PCH time and {coal_ms / ms('auto', 'random'):.2g}x spq's auto "
        f"time (target: 2x); largest difference from spq's PCH distances "
        f"{float(coal.max_abs_diff_vs_spq_m.iloc[0]) if len(coal) else float('nan'):.2g} m."
        + "".join(f" {r.engine}: {r.ms_per_config:.3g} ms, {int(r['results_off_by_over_0.1mm'])} results off spq's by "
                  f"over 0.1 mm (largest {r.max_abs_diff_vs_spq_m:.2g} m)." for _, r in engines.iterrows()
                  if r.engine not in ("coal",) and not r.engine.startswith("spq")),
        "Gradient jumps along the trajectory (closest pair unchanged, confirmed by bisection to 1/1024 of a step): "
        + "; ".join(f"{p} {jumps[(p, t)]} (largest residual {residual[(p, t)]:.2g})" for p, t in closest) + ".",
    ]
    if through:
        paragraphs.append(
            "Through contact (signed distances along the coarser trajectory; per policy the pair that enters and "
            "leaves contact most often, with an STP-BV never deeper than r): "
            + "; ".join(f"{r.policy} {r.track[len('through contact: '):]}: {int(r.contact_crossings)} contact "
                        f"crossings, deepest {r.deepest_m:.2g} m, {int(r.gradient_jumps_same_pair)} gradient jumps"
                        for r in through) + ".")
    charts = [
        Chart(out / "robot_engines.png", "All-pairs time per configuration (ms, log scale): spq for each policy, cold "
              "on random configurations and warm-started along the trajectory, beside coal and python-fcl on the same "
              "PCH pairs (one Python call per pair, poses computed beforehand). Lower is faster."),
        Chart(out / "robot_trajectory.png", "Along a smooth joint trajectory (steps of about 0.01 rad per joint): the "
              "minimum distance over the moving, separated pairs, the norm of its gradient with respect to the joints "
              "(m/rad; grey lines where the closest pair changes), one pair's gradient norm, and that pair's gradient "
              "change per step relative to its norm (x: jumps that stay the same size when the step is bisected ten "
              "times). PCH-PCH gradients jump where witness points jump across a face; auto's change steeply but "
              "continuously. Bottom two panels: one pair's signed distance and its gradient norm through contact "
              "(below zero: penetration depth)."),
        Chart(out / "robot_distance_matrix.png", "Distance (m) of every pair at one random posture, auto policy; "
              "white: skipped (adjacent bodies, and the diagonal); black squares: overlapping hulls."),
    ]
    tables = [("Forward kinematics against pybullet", _read(out, "robot_kinematics.csv")),
              ("All pairs per configuration", scene), ("Against coal and python-fcl", engines),
              ("Gradient continuity", cont)]
    if (out / "robot_pinocchio.csv").exists():
        from harness.suites.robot.robot_bench import ON_AUTO_VOLUMES

        pin = _read(out, "robot_pinocchio.csv")
        ran = pin[pin.status == "ran"] if "status" in pin else pin.iloc[0:0]
        same_job = ran.engine.str.endswith(f"{ON_AUTO_VOLUMES})")
        hulls, meshes = ran[~same_job], ran[same_job]
        if len(hulls):
            fastest = hulls.sort_values("ms_per_config").iloc[0]
            paragraphs.append(
                f"pinocchio.computeDistances, the peer in its own best form (one C++ call per configuration over "
                f"the same {int(fastest.pairs)} pairs with coal.Convex hulls, forward kinematics included): fastest "
                f"variant {fastest.engine[len('pinocchio ('):-1]} at {fastest.ms_per_config:.3g} ms per configuration "
                f"against spq pch {fastest.spq_pch_ms:.3g} ms ({fastest.spq_pch_speedup:.2f}x) and auto "
                f"{fastest.spq_auto_ms:.3g} ms ({fastest.spq_auto_speedup:.2f}x; target 2.5x), timed in turn. Its "
                f"distances agree with spq's PCH results to {hulls.max_abs_diff_vs_spq_m.max():.2g} m on separated "
                f"pairs, with {int(hulls.overlap_disagreements.max())} overlap disagreements.")
        if len(meshes):
            quickest = meshes.sort_values("ms_per_config").iloc[0]
            paragraphs.append(
                f"The same job as spq's auto (each pair's STP side given to pinocchio as that STP-BV's certified "
                f"mesh, within {meshes.stp_mesh_error_m.max():.2g} m of it): fastest variant "
                f"{quickest.engine[len('pinocchio ('):-len(ON_AUTO_VOLUMES) - 1]} at {quickest.ms_per_config:.3g} ms, "
                f"{quickest.spq_auto_speedup:.2f}x spq auto's time; on separated pairs its distances lie "
                f"{meshes.diff_min_m.min():.2g} to {meshes.diff_max_m.max():.2g} m from spq's.")
        if not len(ran):
            paragraphs.append(f"pinocchio: {pin.status.iloc[0]}.")
        tables.append(("Against pinocchio.computeDistances", pin))
    if (out / "robot_signed.csv").exists():
        signed = _read(out, "robot_signed.csv")
        paragraphs.append("Signed distances (every pair cold; overlaps get minus their penetration depth), timed in "
                          "turn with the unsigned run: " + "; ".join(
                              f"{r.policy} {r.signed_ms_per_config:.3g} ms, {r.signed_over_unsigned:.2f}x unsigned, "
                              f"{int(r.configs_with_overlap)} of {int(r.configurations)} configurations with an overlap, "
                              f"median deepest {r.median_deepest_overlap_m:.2g} m, {int(r.signed_failed)} failed"
                              for r in signed.itertuples()) + " (target for auto: at most 1.15x).")
        tables.append(("Signed distances", signed))
    return Section("Robot scene: whole-body self-distance", paragraphs, tables, charts)


def robots_section(out: Path) -> Section:
    table = _read(out, "robots.csv")
    ran = table[table.status == "ran"]
    others = table[table.status != "ran"]

    def span(column: str, unit: str = "") -> str:
        v = ran[column].dropna()
        return f"{v.min():.3g}{unit} to {v.max():.3g}{unit} (median {v.median():.3g}{unit})" if len(v) else "none"

    paragraphs = [
        f"Every robot of the pip package example-robot-data ({len(table)} URDF files; {len(ran)} ran): collision "
        "meshes as convex hulls, boxes, spheres and capsules as spq's exact shapes, cylinders as circumscribing "
        "64-gon prisms, adjacent links skipped, the root fixed. One row per robot: "
        f"{int(ran.pairs.min()) if len(ran) else 0} to {int(ran.pairs.max()) if len(ran) else 0} pairs.",
        f"All pairs per configuration, cold: spq pch {span('pch_cold_ms', ' ms')}, auto {span('auto_cold_ms', ' ms')}; "
        f"pinocchio.computeDistances (its fastest GJK variant per robot, timed in turn) {span('pinocchio_ms', ' ms')}. "
        f"pinocchio's time over spq's: pch {span('pinocchio_over_pch', 'x')}, auto {span('pinocchio_over_auto', 'x')}. "
        f"Warm-started along a trajectory: pch {span('pch_coherent_ms', ' ms')}, auto {span('auto_coherent_ms', ' ms')}.",
        f"Agreement with spq's pch distances on pairs spq finds separated: coal largest difference "
        f"{ran.coal_max_diff_m.max():.2g} m, pinocchio (coal's gjk_tolerance 1e-6) {ran.pinocchio_max_diff_m.max():.2g} m; "
        f"overlap verdicts that disagree: coal {int(ran.coal_overlap_disagreements.sum())}, pinocchio "
        f"{int(ran.pinocchio_overlap_disagreements.sum())}.",
        f"Gradient jumps of the closest pair along a smooth trajectory (confirmed by bisection): pch "
        f"{int(ran.pch_jumps.sum())} over {int((ran.pch_jumps > 0).sum())} robots, auto {int(ran.auto_jumps.sum())} "
        f"over {int((ran.auto_jumps > 0).sum())} robots.",
    ]
    if len(others):
        paragraphs.append("Not benchmarked: " + "; ".join(f"{r.robot} ({r.status}: {r.reason})"
                                                          for r in others.itertuples()) + ".")
    partial = ran[ran.reason.fillna("").astype(str).str.len() > 0]
    if len(partial):
        paragraphs.append("Ran in part: " + "; ".join(f"{r.robot}: {r.reason}" for r in partial.itertuples()) + ".")
    chart = Chart(out / "robots_time_vs_pairs.png",
                  "All-pairs time per configuration (ms, log scale) against the number of pairs queried (log scale), "
                  "one point per robot of example-robot-data: spq pch and auto cold (open circles) and warm-started "
                  "along a trajectory (crosses), pinocchio.computeDistances in its fastest GJK variant (grey squares).")
    return Section("The field's robots: example-robot-data", paragraphs, [("Per robot", table)], [chart])


CONTROL_SHOWN = ["robot", "method", "runs", "min_distance_m_worst", "steps_below_ds", "final_task_error_m_median",
                 "row_turn_p99_median", "row_turn_peak_worst", "acc_peak_median", "acc_peak_worst",
                 "acc_peak_feature_switch_worst", "acc_peak_row_switch_worst", "spikes", "qp_failures", "ms_step"]


def control_section(out: Path) -> Section:
    """The control benchmark: its notes, the per-method table, the step timing and the three charts; the
    paragraphs of "What continuity buys a controller" come from control.md, written from the measures."""
    table = _read(out, "control.csv")
    document = (out / "control.md").read_text() if (out / "control.md").is_file() else ""
    head, _, tail = document.partition("## What continuity buys a controller")
    notes = [line for line in head.split("\n\n")[1:2] if line.strip()]
    # the page's paragraphs are plain text: Markdown's bullets and bold markers would show as characters
    lessons = [line.lstrip("- ").replace("**", "").strip() for line in tail.split("\n")
               if line.strip() and not line.startswith("Run:")]
    tables = [("Per robot and method (medians, worst over the tasks)", table[[c for c in CONTROL_SHOWN
                                                                             if c in table.columns]])]
    if (out / "control_speed.csv").is_file():
        tables.append(("Time per control step, side by side on the same configurations", _read(out, "control_speed.csv")))
    charts = [Chart(out / "control_qdot_traces.png", "One task's joint velocities with spq-pch beside spq-stp."),
              Chart(out / "control_acceleration.png", "Peak joint accelerations ‖Δq̇‖/dt per step, every method."),
              Chart(out / "control_time.png", "Time per control step: distances and Jacobians, then the QP.")]
    return Section("What continuity buys a controller", notes + lessons, tables,
                   [c for c in charts if c.path.is_file()])


SIZES = ("quick", "standard", "full")


def _sized(value, size: str):
    """A field's setting for the run's size: a dict holds it per size ("standard" missing: the full
    run's); a callable is called; anything else is the setting."""
    if isinstance(value, dict):
        return value.get(size, value["full"]) if size == "standard" else value[size]
    return value() if callable(value) else value


def _config(module: str, **fixed) -> Callable[[str, int, Path], object]:
    """(size, seed, out) -> module's Config with the fixed fields, each set by :func:`_sized` (None:
    the suite's default)."""
    def make(size: str, seed: int, out: Path):
        import importlib

        cls = importlib.import_module(f"harness.suites.{module}").Config
        chosen = {k: _sized(v, size) for k, v in fixed.items()}
        return cls(seed=seed, **{k: v for k, v in chosen.items() if v is not None})
    return make


QUICK = {"quick": True, "full": False}
ONE = {"quick": 1, "full": None}  # a benchmark's repeats: one in a quick run

# The standard run (`spq report`) answers every question of the full one (`spq report --full`, the
# committed report) on fewer samples, so that a fresh install's first report takes about ten minutes on
# two cores (docs/commands/report.md gives both sets of sizes).
SUITES = [
    Suite("pictures", "pictures", _config("pictures", quick=QUICK, robot=report_robot), pictures_section,
          timed=False),
    Suite("crosscheck", "crosscheck", _config("crosscheck", per_bucket={"quick": 26, "standard": 200, "full": None},
                                              agreement_poses={"quick": 20000, "standard": 100_000, "full": None}),
          crosscheck_section, timed=False),
    Suite("bench pch", "bench", _config("bench", kind="pch", poses={"quick": 2000, "full": None}, repeats=ONE),
          lambda out: bench_section(out, "pch", "Throughput, PCH-PCH (every engine)")),
    Suite("bench stp", "bench", _config("bench", kind="stp", poses={"quick": 2000, "full": None}, repeats=ONE),
          lambda out: bench_section(out, "stp", "Throughput with STP-BVs")),
    Suite("bench-support", "support", _config("support", directions={"quick": 2000, "full": None}, repeats=ONE),
          support_section),
    Suite("table1", "table1", _config("table1", poses={"quick": 2000, "full": None}, repeats=ONE), table1_section),
    Suite("continuity", "continuity", _config("continuity", quick=QUICK), continuity_section, timed=False),
    Suite("tradeoff", "tradeoff", _config("tradeoff", quick=QUICK), tradeoff_section),
    Suite("rtradeoff", "rtradeoff", _config("rtradeoff", quick=QUICK), rtradeoff_section),
    # the full stability suite judges 10,000 generated cases: on two processes (its time is about halved)
    Suite("stability", "stability", _config("stability", quick=QUICK,
                                            generated_cases={"quick": None, "standard": 2000, "full": None},
                                            workers={"quick": 1, "standard": 1, "full": 2}),
          stability_section, timed=False),
    Suite("depth", "depth", _config("depth", per_bucket={"quick": 3, "standard": 12, "full": 50},
                                    stp_per_bucket={"quick": 1, "standard": 6, "full": None}),
          depth_section, timed=False),
    Suite("bench robot", "robot", _config("robot", robot=report_robot,
                                          configs={"quick": 40, "standard": 300, "full": None},
                                          steps={"quick": 200, "standard": 300, "full": None}, repeats=ONE,
                                          passes=ONE, engine_configs={"quick": 10, "standard": 50, "full": None}),
          robot_section),
    Suite("bench robots", "robots", _config("robots", quick=QUICK, configs={"quick": None, "standard": 20, "full": None},
                                            steps={"quick": None, "standard": 50, "full": None},
                                            engine_configs={"quick": None, "standard": 2, "full": None},
                                            repeats={"quick": None, "standard": 2, "full": None}),
          robots_section),
    # the report's controller run is smaller than `spq bench control`'s default (20 tasks, pink too: pink's
    # barrier over every pair takes 50 to 100 ms a step on the humanoids)
    Suite("bench control", "control", _config("control", robots={"quick": ["panda"], "full": None},
                                              tasks={"quick": 1, "standard": 1, "full": 4},
                                              steps={"quick": 150, "full": None},
                                              methods={"quick": ["spq-pch", "spq-stp", "pin-damper"],
                                                       "full": ["spq-pch", "spq-stp", "spq-cse", "spq-auto", "mink",
                                                                "pin-damper"]},
                                              speed={"quick": False, "full": True}),
          control_section),
    # a small campaign (the shrinking of failing cases is spq fuzz's, which writes into tests/)
    Suite("fuzz", "fuzz", _config("fuzz", queries={"quick": 4000, "standard": 50_000, "full": 200_000},
                                  poses={"quick": 200, "standard": 1000, "full": 2000}, shrink=False),
          fuzz_section, timed=False),
    Suite("check", "check", check_config, check_section),
]


def run_report(out: Path, size: str = "standard", seed: int = 0, only: list[str] | None = None,
               workers: int | None = None) -> list[Path]:
    """Run the suites into out at a size of :data:`SIZES` ("quick": small settings; "standard": every
    question on fewer samples, about ten minutes on two cores; "full": the committed report's) and
    render the report; each suite's terminal lines are printed as it finishes (a regression found by
    the check is shown in its section). workers: processes for the suites that time nothing (module
    docstring); None: every core."""
    from harness.report.verdict import verdict

    if size not in SIZES:
        raise ValueError(f"report size must be one of {', '.join(SIZES)}; got {size!r}")
    workers = os.cpu_count() or 1 if workers is None else int(workers)
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    chosen = [i for i, suite in enumerate(SUITES) if not only or suite.name in only]
    start = time.perf_counter()
    timings, memory, compiled = {}, {}, {}

    def report(i, lines, seconds, peak_mb):
        name = SUITES[i].name
        timings[name], memory[name] = seconds, peak_mb
        done = len(timings)
        print(f"\n== {name} == ({done}/{len(chosen)} suites, {time.perf_counter() - start:.0f} s)", *lines, sep="\n",
              flush=True)

    shared = [i for i in chosen if not SUITES[i].timed]
    if workers > 1 and len(shared) > 1:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor, as_completed

        from harness.report.compile import PARTS, compile_part

        # longest first (their last full run's order): the pool's makespan is then near its least
        shared.sort(key=lambda i: SHARED_ORDER.index(SUITES[i].name) if SUITES[i].name in SHARED_ORDER else 99)
        with ProcessPoolExecutor(min(workers, len(shared)), mp_context=mp.get_context("spawn")) as pool:
            # the kernels first, split between the processes (harness.report.compile): otherwise each
            # suite's process compiles the same kernels at the same time on a fresh install
            compiled.update(f.result() for f in [pool.submit(compile_part, part) for part in PARTS])
            print("compiled kernels (or loaded them from numba's cache): "
                  + ", ".join(f"{part} {seconds:.0f} s" for part, seconds in compiled.items()), flush=True)
            futures = {pool.submit(_run_suite, i, size, seed, out): i for i in shared}
            for future in as_completed(futures):
                report(futures[future], *future.result())
        serial = [i for i in chosen if SUITES[i].timed]
    else:
        serial = chosen
    for i in serial:
        report(i, *_run_suite(i, size, seed, out))
    sections = []
    for i in chosen:
        sections.append(SUITES[i].section(out))
        for chart in sections[-1].charts:
            chart.look = chart.look or LOOK.get(chart.path.name, "")
    meta = run_metadata(command="spq report" + ("" if size == "standard" else f" --{size}"), seed=seed, size=size,
                        workers=workers, compile_seconds=compiled, suite_seconds=timings, suite_peak_memory_mb=memory,
                        seconds=round(time.perf_counter() - start, 1))
    intro = ["spq against python-fcl, coal, pybullet, MuJoCo, pinocchio and an exact reference, on "
             "polyhedral hulls (PCH), sphere-torus-patch bounding volumes (STP-BV) and superellipsoids (CSE); every "
             "figure measured in this run, CSVs beside this page. "
             + {"quick": "Quick run: small settings, noisier figures.",
                "standard": "Standard run: every suite on fewer samples than the full run (`spq report --full`; "
                            "docs/commands/report.md gives both sizes).",
                "full": "Full run."}[size]]
    return render(out, "spq report", intro, sections, meta, lead=verdict(out))


# the suites that share the machine, longest first in a full run (seconds on 2 cores, 2026-11)
SHARED_ORDER = ["crosscheck", "depth", "stability", "fuzz", "pictures", "continuity"]


def _run_suite(index: int, size: str, seed: int, out: Path) -> tuple[list[str], float, float]:
    """Run SUITES[index] and write its output into out: (its terminal lines, seconds, this process's
    peak memory so far in MB). A top-level function, so that a pool's worker can run it."""
    import importlib
    import resource

    from harness.suites import write_output

    suite = SUITES[index]
    t0 = time.perf_counter()
    output = importlib.import_module(f"harness.suites.{suite.module}").run(suite.config(size, seed, out))
    write_output(output, out)
    peak_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # kB on Linux
    return list(output.lines), round(time.perf_counter() - t0, 1), round(peak_kb / 1024.0, 0)
