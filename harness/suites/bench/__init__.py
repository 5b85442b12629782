"""The throughput suite: queries per second of every engine on one link's random pose pairs, PCH-PCH
(kind "pch") or spq's STP-PCH and STP-STP beside it (kind "stp")."""

from __future__ import annotations

from dataclasses import dataclass

from harness.engines.mujoco_engine import PIPELINE_NOTE as MUJOCO_PIPELINE
from harness.suites import Output, Table, frame_lines
from harness.suites.bench.timing import BLOCK

PAIRS = {"pch": ["PCH-PCH"], "stp": ["PCH-PCH", "STP-PCH", "STP-STP"]}


@dataclass
class Config:
    kind: str = "pch"  # "pch" or "stp"
    object: str = "kuka_link_4"  # dataset name or mesh path
    poses: int = 20000
    seed: int = 0
    range: float = 0.3  # m: translations uniform in ±range
    repeats: int = 3  # rounds: each block of poses timed this many times, its least time kept
    block: int = BLOCK  # poses per block (harness.suites.bench.timing)
    engines: list[str] | None = None  # None: every registered engine that imports
    r: float = 0.005  # m: STP-BV small radius (kind "stp")
    R: float = 2.0  # m: STP-BV big radius (kind "stp")
    progress: bool = False
    workers: int = 1  # > 1: spq's batched rows also on this many threads (rows "batched N workers")


def run(config: Config) -> Output:
    from datasets import load_object
    from harness.report.meta import run_metadata
    from harness.suites.bench import throughput as bench
    from spq.query import DEFAULT_TOL_ABS, DEFAULT_TOL_REL

    from spq.workers import check_workers

    check_workers(config.workers)
    if config.kind not in PAIRS:
        raise ValueError(f"kind must be one of {sorted(PAIRS)}, not {config.kind!r}")
    cfg = bench.BenchConfig(object_name=config.object, poses=config.poses, seed=config.seed,
                            translation_range=config.range, repeats=config.repeats, block=config.block,
                            engines=config.engines, r=config.r, R=config.R, pairs=PAIRS[config.kind],
                            workers=config.workers)
    table = bench.throughput(cfg, load_object, progress=config.progress)
    meta = run_metadata(command=f"spq bench {config.kind}", seed=config.seed, poses=config.poses,
                        translation_range_m=config.range, repeats=config.repeats, block=config.block,
                        spq_tol_abs=DEFAULT_TOL_ABS, spq_tol_rel=DEFAULT_TOL_REL, coal_gjk_tolerance=1e-8,
                        **({"stp_r": config.r, "stp_R": config.R} if config.kind == "stp" else {}),
                        **({"workers": config.workers} if config.workers > 1 else {}))
    notes = (f"Two copies of {config.object}, {config.poses} pose pairs with uniformly random rotations and "
             f"translations uniform in ±{config.range} m, seed {config.seed}. Timed in blocks of {config.block} "
             f"poses: every engine runs a block before any runs the next, {config.repeats} rounds, each timed run just "
             "after an untimed one of the same engine on the same block (its data in the caches), and an engine's "
             "time is the sum over the blocks of its least time on each; every engine in the same run. per-call: "
             "one Python call per query; batched: one compiled call per block; signed: spq with signed=True "
             "(penetration depth on overlaps; coal always runs with signed distance on). poses: all, or only "
             "those coal finds overlapping, timed alone. features: vertices (PCH) or patches (STP) of each side. "
             + MUJOCO_PIPELINE)
    if config.workers > 1:
        notes += (f" batched {config.workers} workers: the batched call split over {config.workers} threads "
                  "(spq.workers), its results equal one thread's bit for bit; every other row runs on one thread.")
    if config.kind == "stp":
        notes += f" STP-BV built from the link's hull vertices with r = {config.r} m, R = {config.R} m."
    out = Output(meta=meta, tables=[Table(f"bench_{config.kind}", f"Throughput ({config.kind})", table, notes)])
    out.lines = frame_lines(table[["pair", "engine", "mode", "poses", "queries_per_s", "ratio_to_coal_pch",
                                   "features", "overlapping"]])
    meshes = bench.mesh_summary(table)
    if len(meshes):
        out.tables.append(Table(f"bench_{config.kind}_meshes", "The peers on the STP-BV's own meshes", meshes,
                                MESH_NOTES))
        out.lines += ["", *frame_lines(meshes[["pair", "poses", "engine", "mode", "features", "queries_per_s",
                                               "spq_batched_signed_speedup", "spq_per_call_signed_speedup",
                                               "diff_min_m", "diff_max_m"]])]
    return out


MESH_NOTES = ("The peers have no STP-BV. Given the same smooth volume, their users mesh it: here the STP-BV's "
              "certified mesh (STPBV.to_mesh: every vertex on the true surface, the mesh inside the STP-BV, "
              "their Hausdorff distance at most mesh_error_m), at spq's default tolerance (1e-3 of the "
              "bounding radius) and ten times finer, against the other side's hull (STP-PCH) or the same "
              "mesh (STP-STP). Each peer per call, with signed distance on, timed in the same blocks as spq. "
              "spq_*_speedup: spq's signed rate on the exact STP-BVs (batched, per call) over the peer's. "
              "diff_min_m, diff_max_m: the least and largest of the peer's signed distance less spq's on the same "
              "poses. The mesh lies inside the STP-BV, so an exact answer on it lies 0 to 1 (STP-PCH) or 2 "
              "(STP-STP) times mesh_error_m above spq's; outside that range is the peer's own error (spq's is "
              "within its 1e-10 m tolerance).")
