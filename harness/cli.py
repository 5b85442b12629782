"""The ``spq`` command line: ``spq crosscheck``, ``spq bench pch``, ``spq continuity``."""

from __future__ import annotations

import argparse
from dataclasses import asdict
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from harness.check import SECTIONS, SPEED_FLOOR, CheckConfig
from spq.query import DEFAULT_TOL_ABS, DEFAULT_TOL_REL
from spq.shapes.superellipsoid import INNER_DIRECTIONS

DEFAULT_OUT = Path("reports")


def _print(df: pd.DataFrame) -> None:
    from harness.suites import frame_lines

    print("\n".join(frame_lines(df)))


def _with_plugins(names: list[str] | None, specs: list[str] | None) -> list[str] | None:
    """Engine names to run: those named plus the plugins of --engine (registered here), or None
    (every registered engine that imports, the plugins included) when none is named."""
    from harness.engines import register_plugin

    plugins = [register_plugin(spec) for spec in specs or []]
    return list(dict.fromkeys(names + plugins)) if names else None


def cmd_crosscheck(args) -> int:
    from harness.suites import write_output
    from harness.suites import crosscheck as suite

    start = time.perf_counter()
    config = suite.Config(objects=args.objects, per_bucket=args.per_bucket, seed=args.seed,
                          engines=_with_plugins(args.engines, args.engine), buckets=args.buckets,
                          agreement_poses=args.agreement_poses, progress=not args.quiet)
    output = suite.run(config)
    write_output(output, Path(args.out))
    print("\n".join(output.lines))
    print(f"\nwrote {args.out}/crosscheck.csv.gz, crosscheck_summary.*, crosscheck_engines.*, crosscheck_worst.* "
          f"in {time.perf_counter() - start:.0f} s")
    return 0


def cmd_table1(args) -> int:
    from datasets import load_object
    from harness import table1 as t1
    from harness.report.meta import run_metadata
    from harness.report.tables import markdown_table

    start = time.perf_counter()
    config = t1.Table1Config(object_name=args.object, r=args.r, R=args.R, poses=args.poses, seed=args.seed,
                             translation_range=args.range, repeats=args.repeats)
    table, bodies, coal_qps = t1.run(config, load_object, progress=not args.quiet)
    pch_volume = bodies["PCH"].volume
    volumes = pd.DataFrame([{"BV": b.name, "features": b.features, "volume_m3": b.volume,
                             "volume_ratio_to_pch": b.volume / pch_volume} for b in bodies.values()])
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    table.to_csv(out / "table1.csv", index=False)
    volumes.to_csv(out / "table1_volumes.csv", index=False)
    get = lambda a, b, col: float(table.loc[(table.row == a) & (table.column == b), col].iloc[0])  # noqa: E731
    stp_ratio, cse_ratio = get("STP", "STP", "time_vs_pch"), get("CSE", "CSE", "time_vs_pch")
    meta = run_metadata(command="spq bench table1", object=args.object, r=args.r, R=args.R, poses=args.poses,
                        seed=args.seed, translation_range_m=args.range, repeats=args.repeats,
                        spq_tol_abs=DEFAULT_TOL_ABS, spq_tol_rel=DEFAULT_TOL_REL,
                        seconds=round(time.perf_counter() - start, 1))
    reading = (
        f"STP-STP takes {stp_ratio:.2f}x the time of PCH-PCH here ({100 * (stp_ratio - 1):+.0f}%; the paper: "
        f"+39%), and CSE-CSE {cse_ratio:.2f}x ({100 * (cse_ratio - 1):+.0f}%; the paper: +145%). "
        "An STP-BV query first runs the PCH search on the underlying hulls grown by r, which settles every "
        "overlap, then finishes exactly on the facing sphere or torus patches with a certificate; so it "
        "costs a PCH query plus the finishing (a few closed-form ball steps, or a ball centre against a "
        "polytope). A superellipsoid is smooth everywhere, so GJK would converge on it only linearly; between "
        f"two of them, spq runs GJK on polytopes inscribed in them ({INNER_DIRECTIONS} support points each; an overlap there is "
        "theirs), then Newton's method on the contact normal with the supports' analytic derivatives, which "
        "closes the 1e-10 m certificate in a few steps. Against a PCH or an STP-BV, the plain GJK runs.")
    md = [f"# Table I: proximity queries per second ({args.object})", "",
          f"Two copies of {args.object} ({bodies['PCH'].features} hull vertices) covered by a PCH-BV, an STP-BV "
          f"(r = {args.r} m, R = {args.R} m) and the covering CSE-BV fit. {args.poses} pose pairs: uniformly random "
          f"rotations, translations uniform in ±{args.range} m (seed {args.seed}); spq batched, tolerance "
          f"{DEFAULT_TOL_ABS:g} m + {DEFAULT_TOL_REL:g} relative, best of {args.repeats} runs. coal PCH-PCH in the same "
          f"run: {coal_qps:,.0f} queries/s.", "",
          "## spq, queries per second (all poses)", "", markdown_table(t1.lower_triangle(table, "queries_per_s")), "",
          "## spq, queries per second on the separated poses only", "",
          markdown_table(t1.lower_triangle(table, "separated_queries_per_s")), "",
          "## spq, signed queries per second (all poses; overlaps get their penetration depth)", "",
          markdown_table(t1.lower_triangle(table, "signed_queries_per_s")), "",
          "## The paper's Table I (HRP-2 link, 300 vertices, Pentium 4, C++)", "",
          markdown_table(t1.lower_triangle(table, "paper_queries_per_s")), "",
          "## Time relative to PCH-PCH (spq here / the paper)", "",
          markdown_table(t1.lower_triangle(table, "time_vs_pch", "{:.2f}")), "",
          markdown_table(t1.lower_triangle(table, "paper_time_vs_pch", "{:.2f}")), "",
          "## Per pair", "", markdown_table(table), "",
          "## Bounding volumes", "", markdown_table(volumes), "",
          "Volumes: PCH exact (qhull); STP by Monte Carlo over its bounding box "
          f"({config.volume_samples} samples, membership by spq's distance); CSE by its closed form.", "",
          "## Reading", "", reading, "", "Run: `" + __import__("json").dumps(meta, sort_keys=True) + "`", ""]
    (out / "table1.md").write_text("\n".join(md))
    print(t1.lower_triangle(table, "queries_per_s").to_string(index=False))
    print()
    _print(table[["row", "column", "queries_per_s", "separated_queries_per_s", "signed_queries_per_s", "overlapping",
                  "signed_failed", "mean_iterations", "time_vs_pch", "paper_time_vs_pch"]])
    print()
    _print(volumes)
    print(f"\ncoal PCH-PCH in the same run: {coal_qps:,.0f} queries/s; spq PCH-PCH / coal = "
          f"{get('PCH', 'PCH', 'queries_per_s') / coal_qps:.2f}")
    print(reading)
    print(f"wrote {out}/table1.md, table1.csv, table1_volumes.csv in {time.perf_counter() - start:.0f} s")
    return 0


def cmd_bench(args) -> int:
    from datasets import load_object
    from harness import bench
    from harness.report.meta import run_metadata
    from harness.report.tables import write_table

    if args.suite == "table1":
        return cmd_table1(args)
    if args.suite == "robot":
        return cmd_bench_robot(args)
    pairs = {"pch": ["PCH-PCH"], "stp": ["PCH-PCH", "STP-PCH", "STP-STP"]}[args.suite]
    config = bench.BenchConfig(object_name=args.object, poses=args.poses, seed=args.seed,
                               translation_range=args.range, repeats=args.repeats, engines=args.engines,
                               r=args.r, R=args.R, pairs=pairs)
    table = bench.throughput(config, load_object, progress=not args.quiet)
    meta = run_metadata(command=f"spq bench {args.suite}", seed=args.seed, poses=args.poses,
                        translation_range_m=args.range, repeats=args.repeats, spq_tol_abs=DEFAULT_TOL_ABS,
                        spq_tol_rel=DEFAULT_TOL_REL, coal_gjk_tolerance=1e-8,
                        **({"stp_r": args.r, "stp_R": args.R} if args.suite == "stp" else {}))
    notes = (f"Two copies of {args.object}, {args.poses} pose pairs with uniformly random rotations and "
             f"translations uniform in ±{args.range} m, seed {args.seed}. Best of {args.repeats} repeats; every "
             "engine in the same run. per-call: one Python call per query; batched: one compiled call for all "
             "poses; signed: spq with signed=True (penetration depth on overlaps; coal always runs with signed "
             "distance on). poses: all, or only those coal finds overlapping, timed alone. features: vertices (PCH) or patches (STP) of each side.")
    if args.suite == "stp":
        notes += f" STP-BV built from the link's hull vertices with r = {args.r} m, R = {args.R} m."
    write_table(table, Path(args.out), f"bench_{args.suite}", f"Throughput ({args.suite})", meta, notes)
    _print(table[["pair", "engine", "mode", "poses", "queries_per_s", "ratio_to_coal_pch", "features", "overlapping"]])
    return 0


def cmd_bench_robot(args) -> int:
    from harness import robot_bench as rb
    from harness.report.charts import pyplot  # noqa: F401  (headless backend before any figure)
    from harness.report.meta import run_metadata
    from harness.report.tables import write_table

    config = rb.RobotBenchConfig(robot=args.robot, configurations=args.configs, steps=args.steps, seed=args.seed,
                                 prune=args.prune, repeats=args.repeats, r=args.r, R=args.R,
                                 engines=args.engines or ["coal", "fcl"], engine_configurations=args.engine_configs)
    out = Path(args.out)
    start = time.perf_counter()
    tables = rb.run(config, out, progress=not args.quiet)
    meta = run_metadata(command="spq bench robot", robot=args.robot, seed=args.seed, configurations=args.configs,
                        trajectory_steps=args.steps, prune_m=args.prune, repeats=args.repeats, stp_r=args.r,
                        stp_R=args.R, spq_tol_abs=DEFAULT_TOL_ABS, spq_tol_rel=DEFAULT_TOL_REL,
                        engine_configurations=args.engine_configs or args.configs,
                        seconds=round(time.perf_counter() - start, 1))
    where = (f"{tables['robot']}: {tables['bodies']} bodies, {tables['pairs']} pairs (adjacent bodies skipped). "
             f"{args.configs} random configurations within the joint limits (seed {args.seed}) and a {args.steps}-step "
             "smooth trajectory. ")
    write_table(tables["scene"], out, "robot_scene", "Robot scene: all pairs per configuration", meta,
                where + f"Per configuration: {args.repeats} runs through all configurations in order, one compiled call "
                f"per block of {rb.TIMING_BLOCK}; each block's fastest run counts (the sum over blocks, divided by the "
                "number of configurations); forward kinematics included; the results go into one array allocated "
                "beforehand, as a control loop "
                "would keep. cold: every pair starts cold; coherent: per-pair warm starts along the "
                f"trajectory. pruning_m > 0: pairs whose bounding spheres are farther apart are skipped.")
    write_table(tables["engines"], out, "robot_engines", "Robot scene: spq against coal and python-fcl", meta,
                where + "Same PCH pairs at the same random configurations; the engines run one Python call per "
                f"query, with the body poses computed beforehand (not timed); each pair's loop over the configurations "
                f"is the fastest of {args.repeats}. speedup_of_spq_auto: engine time / spq "
                "auto cold time. max_abs_diff_vs_spq_m and results_off_by_over_0.1mm: over the pair results spq calls "
                "separated (coal agrees with spq to about 1e-8 m; python-fcl's GJK stops early on some, as in the "
                "stability suite, and overestimates).")
    write_table(tables["continuity"], out, "robot_continuity", "Robot scene: gradient continuity along the trajectory",
                meta, where + f"Closest pair among the pairs separated along the whole trajectory; the {rb.JUMP_CANDIDATES} steps "
                f"with the largest relative gradient change (closest pair unchanged) are bisected {rb.BISECTIONS} times; "
                f"a jump keeps over {rb.JUMP_RESIDUAL:g} of its change. "
                f"pairs whose distance varies by less than {rb.MOVING_PAIR_M:g} m along the trajectory are left out.")
    write_table(tables["kinematics"], out, "robot_kinematics", "Robot scene: forward kinematics against pybullet",
                meta, where + "Every link's world pose from spq (URDF read by yourdfpy, compiled kinematics) against "
                "pybullet's (its own URDF parser), composed in double precision from its centre-of-mass frames.")
    write_table(tables["signed"], out, "robot_signed", "Robot scene: signed distances (penetration depth)", meta,
                where + "Every pair cold at the random configurations, unsigned (an overlap is distance 0) and with "
                "signed=True (an overlap gets minus its penetration depth), the two timed in turn within each "
                f"round, best of {args.repeats} per block of {rb.TIMING_BLOCK}. deepest overlap: the least signed "
                "distance of a configuration, over those with an overlap.")
    _print(tables["kinematics"])
    _print(tables["signed"])
    _print(tables["scene"][["policy", "configurations", "mode", "pruning_m", "ms_per_config", "pairs_per_s",
                            "mean_iterations", "median_min_distance_m", "median_min_separated_m",
                            "configs_with_overlap"]])
    _print(tables["engines"])
    _print(tables["continuity"])
    return 0


def cmd_support_scaling(args) -> int:
    from datasets import load_object
    from harness import stp_scaling as sc
    from harness.report.meta import run_metadata
    from harness.report.tables import write_table

    config = sc.ScalingConfig(object_name=args.object, r=args.r, R_values=tuple(args.R_values or ()) or None,
                              directions=args.directions, seed=args.seed, repeats=args.repeats)
    table = sc.run(config, lambda name: load_object(name).vertices, progress=not args.quiet)
    slopes = sc.loglog_slopes(table)
    out = Path(args.out)
    meta = run_metadata(command="spq bench support", seed=args.seed, directions=args.directions, r=args.r)
    notes = (f"Time per STP-BV support call on {args.object} ({table.points.iloc[0]} hull points), r = {args.r} m, "
             "R varied to vary the feature count. cold: random directions, no warm start; warm: a smooth path "
             "of directions, each search starting from the previous patch. Slopes of log(time) against "
             "log(features): 1 is linear, 0.5 is the paper's O(sqrt n).")
    write_table(table, out, "support_scaling", "STP-BV support scaling (paper Fig. 6 and 7)", meta, notes)
    write_table(slopes, out, "support_scaling_slopes", "Support scaling: log-log slopes", meta)
    sc.plot(table, out / "support_scaling.png")
    _print(table[["R", "features", "method", "mode", "ns_per_call", "mean_steps"]])
    print()
    _print(slopes)
    print(f"\nwrote {out}/support_scaling.csv, .md, .png and support_scaling_slopes.*")
    return 0


def cmd_continuity(args) -> int:
    from datasets import load_object
    from harness import continuity as ct
    from harness.report.meta import run_metadata
    from harness.report.tables import write_table

    start = time.perf_counter()
    config = ct.quick_config(args.object, args.seed) if args.quick else ct.ContinuityConfig(object_name=args.object,
                                                                                             seed=args.seed)
    table, paths = ct.run(config, load_object)
    summary = ct.growth(table)
    out = Path(args.out)
    meta = run_metadata(command="spq continuity", object=args.object, seed=args.seed, quick=bool(args.quick),
                        stp_r=config.r, stp_R=config.R, spq_tol_abs=ct.TOL["tol"], spq_tol_rel=ct.TOL["rel_tol"],
                        steps_s=list(config.steps), grid=config.grid, fd_step_s=config.fd_step,
                        theta_max_rad=config.theta_max, gap_m=config.gap,
                        seconds=round(time.perf_counter() - start, 1))
    notes = (f"Two copies of {args.object}; A fixed, B moving along a trajectory s in [0, 1] "
             "(see harness/continuity.py). "
             "witness_lipschitz = max |p(s+h) - p(s)| / step over the witness points of A and B (world frame), "
             "normal_lipschitz the same for the unit normal; step = h converted to rad (parallel_faces: B rotates "
             f"about an in-plane axis through a face-to-face parallel configuration, ±{config.theta_max} rad), "
             "m (edge_slide: B translates parallel to A's longest hull edge) or kept in s (random_path: Fourier modes "
             "in translation and rotation). Sample points: a uniform grid plus points straddling the largest witness "
             "jumps (located by bisection). grad_abs_error / grad_rel_error: analytic dd/ds (spq.distance_gradients "
             "along B's twist) against a central difference of the distance (step "
             f"{config.fd_step:g} in s, spq tolerance 1e-13), max over {config.gradient_samples} s values, in m per "
             "unit s and relative to max(|dd/ds|, 1); NaN for external engines (their tolerance is too loose). "
             f"STP-BV r = {config.r} m, R = {config.R} m; CSE-BV by Superellipsoid.fit; B is shifted by shift_m along "
             "the separation direction so each pair keeps the gap of the hulls.")
    write_table(table, out, "continuity", "Continuity of witness points and gradients", meta, notes)
    write_table(summary, out, "continuity_summary", "Continuity: witness Lipschitz ratio at the largest and "
                "smallest steps", meta, "growth = ratio at the smallest step / ratio at the largest step "
                "(~ largest/smallest step for a jump, ~1 for a Lipschitz witness).")
    ct.plot_lipschitz(table, out / "continuity_lipschitz.png",
                      f"Witness-point Lipschitz ratio vs step ({args.object}, STP r={config.r} m, R={config.R} m)")
    ct.plot_paths(paths, out / "continuity_witness_paths.png",
                  f"parallel_faces ({args.object}): witness point on B along the sweep")
    _print(summary)
    from harness import contact_continuity as cc

    contact_config = cc.ContactConfig(object_name=args.object, r=config.r, R=config.R, seed=args.seed,
                                      grid=201 if args.quick else 401)
    contact, curves = cc.run(contact_config, load_object, progress=True)
    contact_summary = cc.summary(contact)
    contact_notes = (f"Signed distance (spq, signed=True, tolerance {cc.TOL['tol']:g}) along {contact_config.paths} "
                     f"seeded paths per pair that enter and leave contact (B turns {contact_config.turn} rad while "
                     f"crossing A, from {contact_config.gap} m apart to about {contact_config.depth} m deep and out; "
                     "harness/contact_continuity.py), on a grid of "
                     f"{contact_config.grid} points. max_crossing_jump_m: |sd| difference left after {cc.BISECTIONS} "
                     "bisections of each sign change (a jump at contact would stay). gradient_jumps: of B's 6-vector "
                     f"gradient, the {cc.JUMP_CANDIDATES} largest relative changes per path bisected "
                     f"{contact_config.gradient_bisections} times; a jump keeps over {cc.JUMP_RESIDUAL} of its change; "
                     "in_contact: at a step where sd < 0; deeper_than_r: where the depth exceeds the STP-BV's "
                     f"small radius r = {config.r} m (below it the depth of a pair with an STP-BV is C1; deeper, the "
                     "nearest boundary point of the Minkowski difference can switch, for any bodies).")
    write_table(contact, out, "contact_continuity", "Continuity through contact, per path", meta, contact_notes)
    write_table(contact_summary, out, "contact_continuity_summary", "Continuity through contact", meta, contact_notes)
    cc.plot(curves, out / "contact_continuity.png",
            f"Through contact ({args.object}): signed distance and gradient along one path per pair")
    _print(contact_summary)
    print(f"\nwrote {out}/continuity.csv, .md, continuity_summary.*, continuity_lipschitz.png, "
          f"continuity_witness_paths.png, contact_continuity* in {time.perf_counter() - start:.0f} s")
    return 0


def cmd_stability(args) -> int:
    from datasets import load_object
    from harness import stability as st
    from harness.report.meta import run_metadata
    from harness.report.tables import markdown_table, write_table

    start = time.perf_counter()
    config = st.StabilityConfig(seed=args.seed, quick=bool(args.quick), engines=args.engines)
    table, sweep = st.run(config, load_object, progress=not args.quiet)
    summary = st.summarize(table)
    families = st.summarize(table, by=("family", "engine"))
    sweep_summary = st.coal_sweep_summary(sweep)
    fcl_gap = st.fcl_gap_summary(table)
    meta = run_metadata(command="spq stability", seed=args.seed, quick=bool(args.quick),
                        engine_tolerances={k: list(v) for k, v in st.ENGINE_TOL.items()},
                        engine_depth_tolerances={k: list(v) for k, v in st.ENGINE_DEPTH_TOL.items()},
                        ambiguous_band_m=st.AMBIGUOUS_BAND, links=list(config.links),
                        queries=len(table) + len(sweep), seconds=round(time.perf_counter() - start, 1))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    notes = ("One row per case, pose and engine. error = distance - exact reference distance (m); rel_error on "
             "separated poses. verdict: ok (|error| <= allowed_error = tol_abs + tol_rel * d_ref + 64 eps * extent, "
             "and a status consistent with the reference outside the contact band max(1e-9 m, tol_abs)), wrong, "
             "failed (status failed). Tolerances (abs m, rel): " +
             ", ".join(f"{k} {a:g}/{r:g}" for k, (a, r) in st.ENGINE_TOL.items()) + ". depth_verdict, where the "
             "reference overlaps or touches: the engine's raw signed distance against the reference's within its "
             "depth tolerance (" + ", ".join(f"{k} {a:g}/{r:g}" for k, (a, r) in st.ENGINE_DEPTH_TOL.items())
             + ") and on the right side of the 1e-9 m band; 'no depth' for an engine that gives none.")
    write_table(table, out, "stability", "Stability cases (detail)", meta, notes)
    if not sweep.empty:
        sweep.to_csv(out / "stability_coal_dualitygap_detail.csv", index=False)
        write_table(sweep_summary, out, "stability_coal_dualitygap",
                    "coal with DualityGap + Relative: false overlaps against gjk_tolerance", meta,
                    "Separated link poses (gaps 1e-6, 1e-4, 1e-2 m). false_overlaps: reference separated by more "
                    "than 1e-9 m, coal reports a collision. 'coal' is the adapter's default criterion at 1e-8.")
    text = ["# Stability summary", "", "Counts of verdicts per engine over every case family (see stability.md for "
            "the detail). " + notes, "", markdown_table(summary), "", "## Per family", ""]
    for fam, para in st.FAMILY_NOTES.items():
        text += [f"### {fam}", "", para, ""]
        sub = families[families.family == fam]
        if len(sub):
            text += [markdown_table(sub.drop(columns=["family"])), ""]
    depth_worst = st.depth_worst_cases(table)
    write_table(depth_worst, out, "stability_depth_worst", "Largest depth errors per engine and family", meta, notes)
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
    text += ["Run: `" + __import__("json").dumps(meta, sort_keys=True) + "`", ""]
    summary.to_csv(out / "stability_summary.csv", index=False)
    (out / "stability_summary.md").write_text("\n".join(text))
    print("\nPer engine:")
    _print(summary)
    if len(fcl_gap):
        print("\nFCL 3.0 box gap (fcl rows):")
        _print(fcl_gap[fcl_gap.engine == "fcl"])
    if not sweep.empty:
        print("\ncoal DualityGap + Relative sweep:")
        _print(sweep_summary)
    print(f"\nwrote {out}/stability.csv, .md, stability_summary.*, stability_coal_dualitygap* "
          f"in {time.perf_counter() - start:.0f} s")
    return 0


def cmd_depth(args) -> int:
    from datasets import load_object
    from harness import depth_oracle as do
    from harness.report.meta import run_metadata
    from harness.report.tables import write_table

    start = time.perf_counter()
    config = do.DepthConfig(object_name=args.object, per_bucket=args.per_bucket,
                            stp_per_bucket=args.stp_per_bucket or args.per_bucket, seed=args.seed,
                            pairs=tuple(args.pairs))
    table = do.run(config, load_object, progress=not args.quiet)
    summary = do.summarize(table)
    meta = run_metadata(command="spq depth", object=args.object, seed=args.seed, per_bucket=config.per_bucket,
                        stp_per_bucket=config.stp_per_bucket, pairs=list(config.pairs), r=config.r, R=config.R,
                        stp_points=do.STP_POINTS, tol=DEFAULT_TOL_ABS, rel_tol=DEFAULT_TOL_REL,
                        seconds=round(time.perf_counter() - start, 1))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    notes = ("spq's signed distance (batched, default tolerances) against an independent oracle that shares no code "
             "with spq's kernels (harness/depth_oracle.py: min over unit n of h_B(n) + h_A(-n) from closed-form "
             "superellipsoid supports, brute-force STP-BV supports from the generating points, and hull vertices; "
             f"{do.STARTS} starts, SLSQP from the {do.POLISH} best). Poses: per overlap bucket, depth = bucket x "
             "L, L = mean bounding radius; B moved along the oracle's normal to the target depth. contains: spq's "
             "[lower, upper] holds the oracle's value (widened by its spread). The STP-BV is built from "
             f"{do.STP_POINTS} of the link's hull vertices (r = {config.r} m, R = {config.R} m).")
    write_table(table, out, "depth_oracle", "Penetration depth against the independent oracle, per pose", meta, notes)
    write_table(summary, out, "depth_oracle_summary", "Penetration depth against the independent oracle", meta, notes)
    _print(summary)
    print(f"\nwrote {out}/depth_oracle*.csv/.md in {time.perf_counter() - start:.0f} s")
    return 0


def cmd_tradeoff(args) -> int:
    from datasets import load_object
    from harness import tradeoff as tr
    from harness.report.meta import run_metadata
    from harness.report.tables import write_table

    start = time.perf_counter()
    overrides = {k: v for k, v in (("per_bucket", args.per_bucket), ("repeats", args.repeats)) if v is not None}
    config = (tr.quick_tradeoff_config(args.seed, **overrides) if args.quick
              else tr.TradeoffConfig(seed=args.seed, **overrides))
    table, suite = tr.run_tradeoff(config, load_object, progress=not args.quiet)
    out = Path(args.out)
    meta = run_metadata(command="spq tradeoff", quick=bool(args.quick), seed=args.seed, objects=[config.object_a,
                        config.object_b], buckets=list(config.buckets), per_bucket=config.per_bucket,
                        queries=len(suite), repeats=config.repeats, spq_tols=list(config.spq_tols),
                        coal_tols=list(config.coal_tols), seconds=round(time.perf_counter() - start, 1))
    notes = (f"{config.object_a} against {config.object_b}, {len(suite)} separated distance-controlled poses "
             f"(harness.poses.bucket_suite, buckets {', '.join(config.buckets)}, {config.per_bucket} each, seed "
             f"{args.seed}; reference distances {suite.ref_distance.min():.3g} to {suite.ref_distance.max():.3g} m). "
             "All engines on the same poses in the same run, best of "
             f"{config.repeats} timed runs after a warm-up on 8 poses. spq: tol = rel_tol = tolerance (stops when "
             "upper - lower bound <= tol + rel_tol * distance); coal: gjk_tolerance = tolerance; fcl, bullet "
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
    write_table(table, out, "tradeoff", "Speed against accuracy", meta, notes)
    tr.plot_tradeoff(table, out / "tradeoff.png",
                     f"Speed vs accuracy, {config.object_a} | {config.object_b}, {len(suite)} separated poses")
    _print(table[["engine", "mode", "tolerance", "queries_per_s", "max_abs_error", "median_abs_error",
                  "zero_error_fraction", "failures", "pareto_max", "pareto_median"]])
    print(f"\nwrote {out}/tradeoff.csv, .md, .png in {time.perf_counter() - start:.0f} s")
    return 0


def cmd_rtradeoff(args) -> int:
    from datasets import load_object
    from harness import tradeoff as tr
    from harness.report.meta import run_metadata
    from harness.report.tables import write_table

    start = time.perf_counter()
    overrides = dict(r=args.r, R_max=args.R_max, threshold_factor=args.threshold_factor)
    if args.R_values:
        overrides["R_values"] = tuple(args.R_values)
    config = (tr.quick_rtradeoff_config(args.object, args.seed, **overrides) if args.quick
              else tr.RTradeoffConfig(object_name=args.object, seed=args.seed, **overrides))
    table, facts = tr.run_rtradeoff(config, load_object, progress=not args.quiet)
    pick, text = tr.recommend(table, config.threshold_factor)
    table["recommended"] = table.R == (pick.R if pick is not None else np.nan)
    out = Path(args.out)
    meta = run_metadata(command="spq rtradeoff", quick=bool(args.quick), object=args.object, seed=args.seed,
                        r=config.r, R_min=facts["R_min"], poses=config.poses,
                        translation_range_m=config.translation_range, volume_samples=config.volume_samples,
                        repeats=config.repeats, step_s=config.step, threshold_factor=config.threshold_factor,
                        spq_tol_abs=DEFAULT_TOL_ABS, spq_tol_rel=DEFAULT_TOL_REL,
                        seconds=round(time.perf_counter() - start, 1))
    notes = (f"STP-BVs of {args.object}'s {facts['points']} hull vertices, r = {config.r} m, R swept from just above "
             f"the smallest admissible R = r + enclosing radius = {facts['R_min']:.6g} m (log-spaced in R - R_min). "
             "features: patches (stp.n_patches). volume_excess: Monte Carlo volume (harness.table1.monte_carlo_volume, "
             f"{config.volume_samples} samples, seed {args.seed}, the same box and points for every R) / hull volume "
             f"({facts['hull_volume']:.6g} m^3, qhull) - 1. queries_per_s: spq.distances STP-PCH (the STP-BV against "
             f"the link's hull) on {config.poses} random poses (harness.poses.random_poses, ±{config.translation_range} m), "
             f"default tolerance, best of {config.repeats}. witness_lipschitz: max |Δp| / step of the witness points "
             "(m/rad) for STP-PCH on harness.continuity's parallel_faces trajectory at one step (step_rad), on a "
             f"{config.grid}-point grid plus points straddling the {config.jumps} largest witness jumps.")
    write_table(table, out, "rtradeoff", "STP-BV big radius R: features, volume, speed, smoothness", meta,
                notes + "\n\n## Recommendation\n\n" + text)
    tr.plot_rtradeoff(table, out / "rtradeoff.png", facts, pick,
                      f"STP-BV of {args.object}, r = {config.r} m: what R trades")
    _print(table[["R", "R_minus_R_min", "features", "volume_excess", "queries_per_s", "witness_lipschitz",
                  "recommended"]])
    print("\n" + text)
    print(f"\nwrote {out}/rtradeoff.csv, .md, .png in {time.perf_counter() - start:.0f} s")
    return 0


def cmd_report(args) -> int:
    from harness.report_suite import run_report

    start = time.perf_counter()
    paths = run_report(Path(args.out), quick=args.quick, seed=args.seed)
    print(f"wrote {', '.join(str(p) for p in paths)} in {time.perf_counter() - start:.0f} s")
    return 0


def cmd_scene(args) -> int:
    from harness import scene_file as sf
    from harness import scene_run as sr

    start = time.perf_counter()
    try:
        spec = sf.read_scene_file(args.scene)
        scene = sf.build_scene(spec)
        qs = sf.scene_configurations(spec, scene.model)
    except FileNotFoundError as exc:
        print(f"spq scene: error: {exc}", file=sys.stderr)
        return 2
    urdf = scene.model.source or spec.urdf
    overrides = "; per body: " + ", ".join(f"{k} = {v}" for k, v in spec.policies.items()) if spec.policies else ""
    skipped = ("adjacent bodies skipped" if spec.skip_adjacent else "adjacent bodies queried") + (
        f", {len(spec.skip_pairs)} more pair{'s' if len(spec.skip_pairs) != 1 else ''} skipped")
    print(f"scene           {args.scene}")
    print(f"robot           {spec.name} ({urdf}), {scene.model.ndof} joints")
    print(f"bodies          {len(scene.bodies)}")
    print(f"pairs           {len(scene.pairs)} ({skipped})")
    print(f"pairs per BV    {', '.join(f'{k} {v}' for k, v in scene.kind_counts().items())}")
    print(f"policy          {spec.policy}{overrides}; r = {spec.r:g} m, R = {spec.R:g} m")
    print(f"poses           {spec.poses.describe()}")
    print(f"built in {time.perf_counter() - start:.1f} s")

    run = sr.run_scene(scene, qs, spec.poses.coherent, spec.poses.prune, progress=not args.quiet)
    ms = run.seconds * 1e3
    a, b = scene.pair_names[run.min_pair[run.closest]]
    print(f"\nconfigurations  {run.configurations}")
    print(f"time per config mean {ms.mean():.3g} ms, median {np.median(ms):.3g} ms (one call each)")
    print(f"pairs per s     {run.configurations * len(scene.pairs) / run.seconds.sum():,.0f}")
    print(f"min distance    {run.min_distance[run.closest]:.6g} m, {a} - {b} "
          f"({run.min_status[run.closest]}), configuration {run.closest}")
    print(f"overlaps        in {int(np.count_nonzero(run.overlapping))} of {run.configurations} configurations")
    print(f"statuses        {', '.join(f'{k} {v}' for k, v in run.status_counts.items())}")
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        stem = Path(args.scene).stem
        paths = (out / f"{stem}_configurations.csv", out / f"{stem}_closest_posture.csv")
        sr.configurations_table(scene, run).to_csv(paths[0], index=False)
        sr.closest_posture_table(scene, run).to_csv(paths[1], index=False)
        print(f"wrote {paths[0]}, {paths[1]}")
    print(f"done in {time.perf_counter() - start:.1f} s")
    return 0


def cmd_check(args) -> int:
    from datasets import load_object
    from harness import check as ck
    from harness.engines import available_engines

    start = time.perf_counter()
    names = _with_plugins(args.engines, args.engine)
    try:
        engines = available_engines(names)
    except ImportError as exc:
        print(f"spq check: error: an engine asked for cannot be built: {exc}", file=sys.stderr)
        return 2
    baseline = ck.load_results(args.baseline) if args.baseline else None
    config = ck.CheckConfig(seed=args.seed, per_bucket=args.per_bucket, oracle_per_bucket=args.oracle_per_bucket,
                            speed_poses=args.speed_poses, speed_rounds=args.speed_rounds, peer=args.peer,
                            sections=tuple(args.sections))
    if baseline is not None:
        before = baseline["meta"].get("config", {})
        differ = {k: (before.get(k), v) for k, v in asdict(config).items()
                  if k != "sections" and before.get(k) != (list(v) if isinstance(v, tuple) else v)}
        if differ:
            print(f"spq check: note: the baseline ran with other settings {differ} (baseline, now); its figures "
                  "are not comparable one for one", file=sys.stderr)
    if "speed" in config.sections and config.peer not in engines:
        print(f"spq check: error: the speed check times against {config.peer!r}, which is not running "
              f"(engines: {list(engines)}); add it or choose --peer", file=sys.stderr)
        return 2
    try:
        metrics, _ = ck.run_check(config, engines, load_object, progress=not args.quiet)
    finally:
        for e in engines.values():
            e.close()
    seconds = time.perf_counter() - start
    doc = ck.results_document(metrics, config, engines, seconds, args.speed_floor)
    ck.save_results(doc, Path(args.out) / "check.json")
    (Path(args.out) / "check_diff.csv").unlink(missing_ok=True)  # a diff of an earlier run must not linger
    diff = None
    if baseline is not None:
        diff = ck.compare(metrics, ck.metrics_of(baseline), set(engines), args.speed, args.speed_floor,
                          config.sections)
        diff.to_csv(Path(args.out) / "check_diff.csv", index=False)
        shown = diff[~diff.verdict.isin([ck.OK, ck.INFO])]
        if len(shown):
            print("\nChanges against the baseline (metric, baseline, now, verdict):")
            _print(shown[["engine", "check", "metric", "baseline", "now", "verdict", "rule"]])
    if args.junit:
        Path(args.junit).parent.mkdir(parents=True, exist_ok=True)
        Path(args.junit).write_text(ck.junit_xml(metrics, diff, seconds))
    if args.history:
        ck.append_history(doc, args.history)
    if args.update_baseline:
        ck.save_results(doc, args.update_baseline)
    print()
    for line in ck.summary_lines(metrics, diff):
        print(line)
    code = ck.exit_code(diff)
    verdict = "no baseline given" if diff is None else ("REGRESSION" if code else "pass")
    print(f"spq check: {verdict} ({len(metrics)} metrics, {len(engines)} engines, {seconds:.0f} s)")
    return code


def cmd_history(args) -> int:
    from harness import check as ck

    table = ck.load_history(args.history)
    if table.empty or table.run.nunique() < 1:
        raise ValueError(f"history {args.history!r} holds no runs")
    path = ck.history_chart(table, Path(args.out))
    print(f"{table.run.nunique()} runs, {table.commit.nunique()} commits; chart: {path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="spq", description="Smooth Proximity Queries: measurements.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("report", help="run every suite and write reports/index.html and REPORT.md")
    p.add_argument("--quick", action="store_true", help="small settings (a few minutes; what CI runs)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("crosscheck", help="every engine on distance-controlled poses vs the exact reference")
    p.add_argument("--objects", nargs="+", help="dataset names or mesh/qhull paths (default: the built-in set)")
    p.add_argument("--per-bucket", type=int, default=1000, help="poses per distance bucket, over all pairs")
    p.add_argument("--agreement-poses", type=int, default=500_000,
                   help="random poses on which spq is also compared with coal (0: none)")
    p.add_argument("--buckets", nargs="+", help="bucket names (default: all)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--engines", nargs="+", help="engine names (default: all that import)")
    p.add_argument("--engine", action="append", metavar="[NAME=]MODULE:CLASS",
                   help="a plugin engine adapter to add (repeatable); see harness/engines/base.py")
    p.add_argument("--out", default=str(DEFAULT_OUT), help="output folder (default: reports)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_crosscheck)

    p = sub.add_parser("bench-support", help="STP-BV support time against feature count (paper Fig. 6/7)")
    p.add_argument("--object", default="kuka_link_1", help="dataset name or mesh path (default: kuka_link_1, 574 points)")
    p.add_argument("--r", type=float, default=0.005)
    p.add_argument("--R-values", type=float, nargs="+", dest="R_values",
                   help="big radii (m); default: 1.0001 to 300 times the smallest admissible R - r, plus r")
    p.add_argument("--directions", type=int, default=20000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_support_scaling)

    p = sub.add_parser("bench", help="throughput benchmarks")
    p.add_argument("suite", choices=["pch", "stp", "table1", "robot"],
                   help="pch: PCH-PCH, every engine; stp: STP-PCH and STP-STP (spq) beside PCH-PCH; "
                        "table1: the paper's Table I, PCH/STP/CSE pairs with coal's PCH-PCH beside; "
                        "robot: all pairs of a robot per configuration, spq policies beside coal and fcl")
    p.add_argument("--object", default="kuka_link_4", help="dataset name or mesh path (default: kuka_link_4)")
    p.add_argument("--poses", type=int, default=20000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--range", type=float, default=0.3, help="translation range (m), uniform in ±range")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--engines", nargs="+", help="engine names (default: all that import)")
    p.add_argument("--r", type=float, default=0.005, help="STP-BV small radius (m), stp suite")
    p.add_argument("--R", type=float, default=2.0, help="STP-BV big radius (m), stp suite")
    p.add_argument("--robot", default="jvrc1", help="robot suite: a robot name (jvrc1, kuka_iiwa, panda)")
    p.add_argument("--configs", type=int, default=1000, help="robot suite: random configurations")
    p.add_argument("--steps", type=int, default=1000, help="robot suite: trajectory steps")
    p.add_argument("--prune", type=float, default=0.05, help="robot suite: pruning threshold (m) of the pruned rows")
    p.add_argument("--engine-configs", type=int, help="robot suite: configurations coal and fcl run (default: all)")
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("continuity", help="witness-point / normal continuity and gradient check along trajectories")
    p.add_argument("--object", default="kuka_link_4", help="dataset name or mesh path (default: kuka_link_4)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quick", action="store_true", help="fewer steps and samples (a few seconds)")
    p.set_defaults(func=cmd_continuity)

    p = sub.add_parser("stability", help="every engine on cases where distance methods are known to fail")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--engines", nargs="+", help="engine names (default: spq fcl coal bullet bullet-margin)")
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quick", action="store_true", help="one pose per case and fewer sweeps (seconds)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_stability)

    p = sub.add_parser("depth", help="spq's penetration depth against an independent oracle (STP-BV and CSE pairs)")
    p.add_argument("--object", default="kuka_link_4", help="dataset name or mesh path (default: kuka_link_4)")
    p.add_argument("--per-bucket", type=int, default=300, help="poses per overlap bucket (default 300)")
    p.add_argument("--stp-per-bucket", type=int, default=None,
                   help="poses per bucket for pairs with an STP-BV (default: --per-bucket; ~1 s a pose)")
    p.add_argument("--pairs", nargs="+", default=["STP-STP", "STP-PCH", "CSE-CSE", "CSE-PCH"])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_depth)

    p = sub.add_parser("tradeoff", help="speed against accuracy: engines' tolerances swept on one pose suite")
    p.add_argument("--per-bucket", type=int, default=None, help="poses per separated bucket (default 200; quick 10)")
    p.add_argument("--repeats", type=int, default=None, help="timed runs per setting, best kept (default 5; quick 2)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quick", action="store_true", help="small run (a few seconds)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_tradeoff)

    p = sub.add_parser("rtradeoff", help="STP-BV big radius R: features, volume excess, speed, witness smoothness")
    p.add_argument("--object", default="kuka_link_4", help="dataset name or mesh path (default: kuka_link_4)")
    p.add_argument("--r", type=float, default=0.005, help="small radius (m)")
    p.add_argument("--R-max", type=float, default=100.0, dest="R_max", help="largest R (m)")
    p.add_argument("--R-values", type=float, nargs="+", dest="R_values", help="explicit R values (m)")
    p.add_argument("--threshold-factor", type=float, default=10.0, dest="threshold_factor",
                   help="recommendation: Lipschitz ratio at most this times the smallest seen")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(DEFAULT_OUT))
    p.add_argument("--quick", action="store_true", help="small run (a few seconds)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_rtradeoff)

    p = sub.add_parser("scene", help="a robot scene from a TOML file (scenes/*.toml): every pair over its configurations")
    p.add_argument("scene", help="scene file (TOML; see scenes/ and harness/scene_file.py)")
    p.add_argument("--out", help="folder for the per-configuration and closest-posture CSVs (default: none written)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_scene)

    p = sub.add_parser("check", help="the gate: a fixed-seed run of every engine judged against a baseline (exit 0/1/2)")
    p.add_argument("--baseline", help="results file of an earlier run to compare with (regressions: exit 1)")
    p.add_argument("--update-baseline", metavar="FILE", help="write this run's results as the new baseline")
    p.add_argument("--out", default=str(DEFAULT_OUT), help="folder for the results file check.json (default reports)")
    p.add_argument("--junit", metavar="FILE", help="write JUnit XML: one test case per engine and check")
    p.add_argument("--history", metavar="FILE", help="append this run (commit, date, machine, metrics) to FILE")
    p.add_argument("--engines", nargs="+", help="registered engine names (default: all that import)")
    p.add_argument("--engine", action="append", metavar="[NAME=]MODULE:CLASS",
                   help="a plugin engine adapter to add (repeatable); see harness/engines/base.py")
    p.add_argument("--speed", choices=["strict", "advisory"], default="strict",
                   help="advisory: report slower speed ratios without failing")
    p.add_argument("--speed-floor", type=float, default=SPEED_FLOOR, dest="speed_floor",
                   help=f"least relative drop of a speed ratio that fails (default {SPEED_FLOOR}; noise may raise it)")
    p.add_argument("--sections", nargs="+", default=list(SECTIONS), choices=list(SECTIONS))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--per-bucket", type=int, default=CheckConfig.per_bucket, help="PCH-PCH poses per distance bucket")
    p.add_argument("--oracle-per-bucket", type=int, default=CheckConfig.oracle_per_bucket,
                   help="poses per overlap bucket and STP/CSE pair against the depth oracle")
    p.add_argument("--speed-poses", type=int, default=CheckConfig.speed_poses)
    p.add_argument("--speed-rounds", type=int, default=CheckConfig.speed_rounds)
    p.add_argument("--peer", default="coal", help="the engine speed ratios are taken against (default coal)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("history", help="chart accuracy and speed ratios over the runs of a check history file")
    p.add_argument("history", help="history file written by spq check --history")
    p.add_argument("--out", default=str(DEFAULT_OUT / "check_history.png"))
    p.set_defaults(func=cmd_history)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ValueError as exc:
        print(f"spq {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
