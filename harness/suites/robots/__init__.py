"""The robots suite: every robot of example-robot-data, one row each (spq pch and auto, cold and
coherent, beside pinocchio.computeDistances and coal; gradient jumps), and time against pair count."""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from harness.suites import Figure, Output, Table, frame_lines

FULL = {"configs": 100, "steps": 200, "engine_configs": 5}  # None in the Config means these (or QUICK)
QUICK = {"configs": 10, "steps": 30, "engine_configs": 2}
ALL_VARIANTS = ("default", "cached-guess", "nesterov", "nesterov-cached")  # harness.engines.pinocchio_peer.VARIANTS


@dataclass
class Config:
    robots: list[str] | None = None  # robot names (datasets.example_robots.robot_names()); None: all (quick: a few)
    configs: int | None = None  # random configurations, cold (None: 100; quick 10)
    steps: int | None = None  # trajectory steps, coherent, and steps of the gradient track (None: 200; quick 30)
    engine_configs: int | None = None  # configurations coal runs from Python (None: 5; quick 2)
    repeats: int = 3
    seed: int = 0
    r: float = 0.005  # m: STP-BV small radius
    R: float = 2.0  # m: STP-BV big radius
    pin_variants: tuple[str, ...] = ALL_VARIANTS
    quick: bool = False  # a few small robots, few configurations
    progress: bool = False


def resolved(config: Config) -> Config:
    """config with the None sizes set for its mode (FULL or QUICK); ValueError for sizes below 1."""
    sizes = QUICK if config.quick else FULL
    out = dataclasses.replace(config, **{k: v for k, v in sizes.items() if getattr(config, k) is None})
    for name in ("configs", "steps", "engine_configs", "repeats"):
        if int(getattr(out, name)) < 1:
            raise ValueError(f"robots suite: {name} must be >= 1; got {getattr(out, name)}")
    if out.steps < 2:
        raise ValueError(f"robots suite: steps must be >= 2 (a trajectory); got {out.steps}")
    return out


def run(config: Config) -> Output:
    from harness.report.charts import pyplot  # noqa: F401  (headless backend before any figure)
    from harness.report.meta import run_metadata
    from harness.suites.robot import robot_bench as rb
    from harness.suites.robots import robots_bench as rsb
    from spq.query import DEFAULT_TOL_ABS, DEFAULT_TOL_REL

    config = resolved(config)
    start = time.perf_counter()
    result = rsb.run(config, progress=config.progress)
    table = result["table"]
    ran = table[table.status == rsb.STATUS_RAN]
    meta = run_metadata(command="spq bench robots", robots=len(table), ran=len(ran), seed=config.seed,
                        configurations=config.configs, trajectory_steps=config.steps,
                        coal_configurations=config.engine_configs, repeats=config.repeats, stp_r=config.r,
                        stp_R=config.R, spq_tol_abs=DEFAULT_TOL_ABS, spq_tol_rel=DEFAULT_TOL_REL,
                        coal_tolerance=rsb.COAL_TOLERANCE, pinocchio_variants=list(config.pin_variants),
                        quick=bool(config.quick), seconds=round(time.perf_counter() - start, 1))
    notes = (
        f"Every robot (URDF file) of the pip package example-robot-data{' (quick: a few of them)' if config.quick else ''}, "
        "read in place (datasets/example_robots.py). Bodies: each collision mesh's convex hull (a link without "
        "collision elements: its visual ones); boxes, spheres and capsules as spq's exact Box, Sphere and Capsule; "
        "cylinders as the hull of a circumscribing 64-sided prism (at most 0.12% of the radius too large). Pairs: every "
        "pair of bodies except those on one link or on adjacent links (a link and its nearest ancestor with a body). "
        "The root link is fixed (a floating base does not move the links relative to each other); pinocchio is read "
        "the same way. "
        f"*_cold_ms: all pairs per configuration, cold, on {config.configs} random configurations within the joint "
        f"limits (seed {config.seed}); *_coherent_ms: warm-started along a {config.steps}-step smooth trajectory; both "
        f"the sum over blocks of {rb.TIMING_BLOCK} configurations of each block's best of {config.repeats} runs, forward "
        "kinematics included. pinocchio_ms: pinocchio.computeDistances (its own URDF parser; the same bodies as "
        "coal.Convex, coal.Sphere/Box/Capsule; the same pairs; coal's gjk_tolerance 1e-6) in the GJK variant "
        f"(of {', '.join(config.pin_variants)}) fastest on the first {rsb.PROBE_CONFIGURATIONS} configurations, timed "
        f"beside spq's cold runs in blocks of {rb.TIMING_BLOCK} configurations, {config.repeats} rounds, each "
        "timed run just after an untimed one of the same side on the same block, each side's least time per "
        "block summed; pinocchio_over_*: its time / spq's. pinocchio_max_diff_m, "
        "coal_max_diff_m: the largest difference from "
        "spq's pch distances over the pair results spq calls separated (pinocchio on every configuration, coal from "
        f"Python with gjk_tolerance {rsb.COAL_TOLERANCE:g} m on the first {config.engine_configs}); "
        f"*_overlap_disagreements: one side overlapping, the other farther than {rsb.OVERLAP_BAND_M:g} m. "
        "overlapping_pct: share of pair results overlapping (collision meshes often interpenetrate at random "
        "configurations). *_jumps: gradient jumps of the closest pair (among jump_pairs pairs separated at every step "
        f"and moving by over {rb.MOVING_PAIR_M:g} m) along the first {config.steps} steps of a trajectory sampled "
        f"{rb.CONTINUITY_ZOOM}x finer, the {rb.JUMP_CANDIDATES} largest changes bisected {rb.BISECTIONS} times. "
        "srdf: the MoveIt SRDF example-robot-data ships for the robot (datasets.example_robots.robot_srdf; "
        f"'{rsb.SRDF_NONE}' where there is none), srdf_disabled: its disable_collisions link pairs, pairs_srdf: the "
        "pairs left once they are skipped as well (links the URDF lacks passed over, as pinocchio does); the timings "
        "above use every pair (pairs). "
        "status: ran, failed (reason: why it did not load), no pairs, no joints; reason also says what did not run.")
    out = Output(meta=meta, figures=[Figure(name, draw) for name, draw in result["figures"]])
    out.tables = [Table("robots", "example-robot-data: all pairs per configuration, per robot", table, notes)]
    shown = ["robot", "status", "bodies", "pairs", "pairs_srdf", "srdf", "pch_cold_ms", "auto_cold_ms",
             "pch_coherent_ms", "auto_coherent_ms", "pinocchio_ms", "pinocchio_over_pch", "pinocchio_over_auto",
             "coal_max_diff_m", "pch_jumps", "auto_jumps"]
    out.lines = [*frame_lines(table[shown]), "", *summary_lines(table)]
    return out


def summary_lines(table) -> list[str]:
    """The run in a few sentences: how many robots ran, ranges of ms and ratios, what failed and why."""
    from harness.suites.robots import robots_bench as rsb

    ran = table[table.status == rsb.STATUS_RAN]
    lines = [f"{len(ran)} of {len(table)} robots ran ({int(ran.pairs.sum()) if len(ran) else 0} pairs in all)."]
    with_srdf = table[table.srdf.astype(str).str.endswith(".srdf")]
    if len(with_srdf):
        lines.append(f"{len(with_srdf)} of {len(table)} robots ship an SRDF: their {int(with_srdf.pairs.sum())} pairs "
                     f"are {int(with_srdf.pairs_srdf.sum())} once its disable_collisions are skipped.")

    def span(column, unit=""):
        v = ran[column].astype(float)
        v = v[np.isfinite(v)]
        return f"{v.min():.3g}{unit} .. {v.max():.3g}{unit} (median {v.median():.3g}{unit})" if len(v) else "none"

    if len(ran):
        lines += [f"ms per configuration, cold: pch {span('pch_cold_ms')}, auto {span('auto_cold_ms')}, "
                  f"pinocchio {span('pinocchio_ms')}",
                  f"coherent: pch {span('pch_coherent_ms')}, auto {span('auto_coherent_ms')}",
                  f"pinocchio / spq: pch {span('pinocchio_over_pch', 'x')}, auto {span('pinocchio_over_auto', 'x')}",
                  f"largest difference from spq pch: coal {ran.coal_max_diff_m.max():.2g} m, pinocchio "
                  f"{ran.pinocchio_max_diff_m.max():.2g} m",
                  f"gradient jumps (closest pair): pch {int(np.nansum(ran.pch_jumps))} in all, auto "
                  f"{int(np.nansum(ran.auto_jumps))} in all"]
    for r in table[table.status != rsb.STATUS_RAN].itertuples():
        lines.append(f"{r.robot}: {r.status}: {r.reason}")
    for r in ran[ran.reason.astype(str).str.len() > 0].itertuples():
        lines.append(f"{r.robot}: {r.reason}")
    return lines
