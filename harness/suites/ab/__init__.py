"""The A/B suite: two versions of spq timed against each other in one process, on the same poses.

Every hot-path change is judged by a same-process A/B (see the project's guide): the old and the new
kernels on one link's random pose pairs, batched and per call, the overlapping poses also alone, and
optionally a robot scene's cold all-pairs sweep over random configurations and its coherent one along a
smooth trajectory (each version's own Scene, as
``spq bench robot`` times it); blocks of poses (or configurations) timed in turn
(harness.suites.bench.timing, the two versions' order alternating), each version's least time per block
summed. It also says whether the two versions' result rows
(distance, witness points, normal, bounds, iterations, status) are bit-identical, and how many differ.
The versions are copies of the package at git revisions, or the working tree (harness.suites.ab.packages).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from harness.suites import Output, Table, frame_lines
from harness.suites.bench.timing import BLOCK, blocked_times

PAIR_TYPES = ("PCH-PCH", "STP-PCH", "STP-STP", "CSE-PCH", "CSE-STP", "CSE-CSE")
DEFAULT_PAIRS = PAIR_TYPES[:3]
BOUNDS_SLACK = 1e-10  # m, and relative: how far one version's distance may lie outside the other's certified bounds


@dataclass
class Config:
    old: str = "HEAD"  # git revision, or "working-tree"
    new: str = "working-tree"
    pairs: list[str] = field(default_factory=lambda: list(DEFAULT_PAIRS))
    object: str = "kuka_link_4"  # dataset name or mesh path
    poses: int = 20000
    seed: int = 0
    range: float = 0.3  # m: translations uniform in ±range
    repeats: int = 7  # rounds
    block: int = BLOCK
    per_call: int = 4000  # poses timed per call (Pair.cold_distance in a Python loop); 0: none
    signed: bool = True
    r: float = 0.005  # m: STP-BV small radius
    R: float = 2.0  # m: STP-BV big radius
    cse: str = "fit"  # the CSE-BV of the CSE pairs, as spq bench table1's --cse (harness.suites.table1.cse_spec)
    repo: str = "."  # the git checkout the revisions are read from
    robot: str | None = None  # a robot of datasets.robots: its cold and coherent all-pairs sweeps, per policy
    policies: list[str] = field(default_factory=lambda: ["pch", "auto"])  # the robot's scene policies
    configs: int = 1000  # random configurations of the robot's sweep (seed: ``seed``)
    robot_block: int = 50  # configurations per timed block (as spq bench robot)
    progress: bool = False


def _check(config: Config) -> None:
    from spq.scene import SCENE_POLICIES

    from harness.suites.table1 import cse_spec

    cse_spec(config.cse)  # its ValueError names the bad value
    unknown = [p for p in config.pairs if p not in PAIR_TYPES]
    if unknown or not (config.pairs or config.robot):
        raise ValueError(f"pairs must be some of {list(PAIR_TYPES)} (none only with a robot); got {config.pairs}")
    for name in ("poses", "repeats", "block", "configs", "robot_block"):
        if getattr(config, name) < 1:
            raise ValueError(f"{name} must be at least 1; got {getattr(config, name)}")
    if config.per_call < 0:
        raise ValueError(f"per_call must be 0 or more; got {config.per_call}")
    if config.robot is not None:
        from datasets.robots import robot_urdf

        robot_urdf(config.robot)  # an unknown robot or missing files, before any copy compiles
        bad = [p for p in config.policies if p not in SCENE_POLICIES]
        if bad or not config.policies:
            raise ValueError(f"policies must be some of {list(SCENE_POLICIES)}; got {config.policies}")


def rows_differing(a: np.ndarray, b: np.ndarray) -> int:
    """Result rows of two (N, OUT_SIZE) arrays that are not equal bit for bit (NaN equal to NaN)."""
    same = (a == b) | (np.isnan(a) & np.isnan(b))
    return int((~same.all(axis=1)).sum())


STATUS_COLUMN = 13  # result_rows' column of the status code
LOWER_COLUMN, UPPER_COLUMN = 10, 11  # its columns of the certified bounds


def result_rows(batch) -> np.ndarray:
    """(N, 14) rows of a BatchDistances, from its public fields (the same in every version): distance,
    point_a (3), point_b (3), normal (3), lower and upper bounds, iterations, status code (STATUS_COLUMN)."""
    return np.column_stack([batch.distance, batch.point_a, batch.point_b, batch.normal, batch.lower_bound,
                            batch.upper_bound, batch.iterations, batch.status_code]).astype(np.float64)


def _pairs(package, object_name: str, kinds: list[str], signed: bool, r: float, R: float, cse: str) -> dict:
    """{kind: (one version's Pair, A's offset, B's offset)}: each side's shape built by that version, with the
    fixed transform from its frame to the link's (identity but for the CSE-BV, as spq bench table1 places it)."""
    from datasets import load_object
    from harness.suites.table1 import cse_spec

    pch = load_object(object_name)
    shapes = {"PCH": (package.Polyhedron(pch.vertices, pch.faces), np.eye(4))}
    if any("STP" in k for k in kinds):
        shapes["STP"] = (package.STPBV.from_points(pch.vertices, r, R), np.eye(4))
    if any("CSE" in k for k in kinds):
        params = cse_spec(cse)[1]
        if params is None:
            shapes["CSE"] = package.Superellipsoid.fit(pch.vertices)
        else:  # centred on the link's bounding box, axes along its axes (as table1's bodies)
            offset = np.eye(4)
            offset[:3, 3] = 0.5 * (pch.vertices.min(axis=0) + pch.vertices.max(axis=0))
            shapes["CSE"] = (package.Superellipsoid(*params), offset)
    pairs = {}
    for kind in kinds:
        (a, offset_a), (b, offset_b) = (shapes[side] for side in kind.split("-"))
        pairs[kind] = (package.Pair(a, b, signed=signed), offset_a, offset_b)
    return pairs


def outside_bounds(a: np.ndarray, b: np.ndarray) -> int:
    """Rows of two versions' result rows (result_rows) where either version's distance lies outside the other's
    certified bounds by more than BOUNDS_SLACK (absolute plus relative): both cannot be right there."""
    def outside(x, y):
        slack = BOUNDS_SLACK * (1.0 + np.abs(y[:, 0]))
        return (x[:, 0] < y[:, LOWER_COLUMN] - slack) | (x[:, 0] > y[:, UPPER_COLUMN] + slack)

    return int((outside(a, b) | outside(b, a)).sum())


def run(config: Config) -> Output:
    from harness.report.meta import run_metadata
    from harness.suites.ab import packages
    from harness.workloads.poses import random_poses
    from spq.kernels.gjk import OVERLAPPING

    _check(config)
    prepared = [packages.prepare(config.repo, rev) for rev in (config.old, config.new)]
    if prepared[0][0] == prepared[1][0]:
        raise ValueError(f"{config.old} and {config.new} hold the same spq sources: nothing to compare")
    versions = [packages.load(name, folder) for name, _, folder in prepared]
    pairs = [_pairs(v, config.object, config.pairs, config.signed, config.r, config.R, config.cse)
             if config.pairs else {} for v in versions]
    poses_a, poses_b = random_poses(config.poses, config.seed, config.range)
    rows = []
    bar = None
    if config.progress:
        from tqdm import tqdm

        print(f"spq ab: the first calls compile each version's kernels unless its cache ({prepared[0][2].parent}) "
              "holds them (minutes each)", flush=True)
        bar = tqdm(desc="ab", unit="run", leave=False)
    for kind in config.pairs:
        (old, offset_a, offset_b), (new, _, _) = pairs[0][kind], pairs[1][kind]
        kind_a, kind_b = poses_a @ offset_a, poses_b @ offset_b
        first = [result_rows(p.distances(kind_a, kind_b, coherent=False)) for p in (old, new)]  # compiles
        differing = (rows_differing(first[0], first[1]), outside_bounds(first[0], first[1]))
        overlapping = first[0][:, STATUS_COLUMN] == OVERLAPPING
        sets = {"all": np.arange(config.poses), "overlapping": np.flatnonzero(overlapping)}
        for label, index in sets.items():
            if len(index) == 0:
                continue
            pa, pb = np.ascontiguousarray(kind_a[index]), np.ascontiguousarray(kind_b[index])
            jobs = {side: (lambda a, b, p=p: p.distances(a, b, coherent=False), pa, pb)
                    for side, p in (("old", old), ("new", new))}
            times = _times(jobs, config, bar)
            rows.append(_row(kind, "batched", label, len(index), times, differing))
        if config.per_call:
            n = min(config.per_call, config.poses)

            def loop(a, b, p):
                call = p.cold_distance
                for i in range(len(a)):
                    call(a[i], b[i])

            for p in (old, new):  # compiles
                loop(kind_a[:2], kind_b[:2], p)
            jobs = {side: (lambda a, b, p=p: loop(a, b, p), kind_a[:n], kind_b[:n])
                    for side, p in (("old", old), ("new", new))}
            rows.append(_row(kind, "per call", "all", n, _times(jobs, config, bar), None))
    if config.robot is not None:
        qs = trajectory = None
        for policy in config.policies:
            scenes = [_scene(v, config.robot, policy, config.r, config.R) for v in versions]
            if qs is None:
                from harness.workloads.robot_poses import random_configurations, smooth_trajectory

                qs = random_configurations(scenes[0].model, config.configs, config.seed)
                trajectory = smooth_trajectory(scenes[0].model, config.configs, config.seed)
            rows.append(sweep_row(versions, scenes, qs, f"{config.robot} {policy}", config, bar))
            rows.append(sweep_row(versions, scenes, trajectory, f"{config.robot} {policy}", config, bar, coherent=True))
    if bar is not None:
        bar.close()
    table = pd.DataFrame(rows)
    meta = run_metadata(command="spq ab", old=config.old, old_commit=prepared[0][1], new=config.new,
                        new_commit=prepared[1][1], packages=[p[0] for p in prepared], seed=config.seed,
                        poses=config.poses, translation_range_m=config.range, repeats=config.repeats,
                        block=config.block, signed=config.signed, object=config.object, stp_r=config.r,
                        cse=config.cse if any("CSE" in k for k in config.pairs) else None,
                        stp_R=config.R, robot=config.robot, policies=config.policies if config.robot else None,
                        configurations=config.configs if config.robot else None,
                        robot_block=config.robot_block if config.robot else None)
    notes = f"spq at {config.old} (old) against spq at {config.new} (new), in one process."
    if config.pairs:
        notes += (f" Two copies of {config.object} (its hull, its STP-BV with r = {config.r} m, R = {config.R} m, and "
                  f"its CSE-BV '{config.cse}' placed as spq bench table1 places it), "
                  f"{config.poses} random pose pairs (seed {config.seed}, translations within ±{config.range} m), "
                  f"{'signed' if config.signed else 'unsigned'}, cold, in blocks of {config.block} poses. "
                  "overlapping: the poses the old version finds overlapping (status), timed alone. rows_differing: "
                  "result rows (distance, witness points, normal, bounds, iterations, status) not equal bit for bit, "
                  f"over all poses; outside_bounds: rows where one version's distance lies more than {BOUNDS_SLACK:g} m "
                  "(plus as much relative) outside the other's certified bounds, which cannot both be right. per call: Pair.cold_distance in a Python loop (the copies' Python path: they "
                  "leave the C extension out).")
    if config.robot:
        notes += (f" {config.robot} <policy>: the robot scene's cold sweep over all its pairs (each version's "
                  f"Scene.distances_many, unsigned, coherent=False) at {config.configs} random configurations "
                  f"(seed {config.seed}), and its coherent sweep (warm starts) along a {config.configs}-step smooth "
                  f"trajectory (seed {config.seed}), in blocks of {config.robot_block}; queries: configurations x pairs, "
                  "us per query: per pair; rows_differing: the pairs' raw result rows not equal bit for bit.")
    notes += (f" Each block timed {config.repeats} times, old and new in turn (their order alternating by block "
              "and round), each timed run just after an untimed one of the same version on the same block; a version's "
              "time is the sum of its least time on each block. old_over_new > 1: the new "
              "version is faster.")
    out = Output(meta=meta, tables=[Table("ab", f"A/B: {config.old} against {config.new}", table, notes)])
    out.lines = frame_lines(table)
    return out


def _times(jobs: dict, config: Config, bar, block: int | None = None) -> dict:
    """{job: seconds}: blocked_times with the two versions' order alternating."""
    return {key: seconds for key, (seconds, _) in
            blocked_times(jobs, config.repeats, block or config.block, progress=bar, alternate=True).items()}


def _scene(package, robot: str, policy: str, r: float, R: float):
    """Robot ``robot``'s scene built by one version of spq (its own Scene class), as spq bench robot builds it."""
    from harness.suites.robot.robot_bench import RobotBenchConfig, load_scene

    return load_scene(RobotBenchConfig(robot=robot, r=r, R=R), policy, package.Scene)


def sweep_rows_differing(versions, outs) -> int:
    """Pair results of two versions' sweeps (N, npairs, OUT_SIZE each) not equal bit for bit: whole raw
    rows where both versions lay them out alike (the same OUT_SIZE), else the distances alone."""
    size = [v.kernels.gjk.OUT_SIZE for v in versions]
    if size[0] == size[1]:
        return rows_differing(outs[0].reshape(-1, size[0]), outs[1].reshape(-1, size[1]))
    column = [o[..., v.kernels.gjk.OUT_DISTANCE].reshape(-1, 1) for v, o in zip(versions, outs)]
    return rows_differing(column[0], column[1])


def sweep_row(versions, scenes, qs: np.ndarray, label: str, config: Config, bar, coherent: bool = False) -> dict:
    """The row of two versions' scenes (the same robot and policy) swept over configurations qs (cold, or
    coherent: each pair warm-started from its last query, as along a trajectory), each into its own result
    array, allocated and touched before the timing (as spq bench robot's)."""
    from harness.suites.robot.robot_bench import result_array

    outs = []
    for version, scene in zip(versions, scenes):
        scene.reset()
        scene.distances_many(qs[:2], coherent=coherent)  # compiles, or loads the copy's cache
        outs.append(result_array(len(qs), len(scene.pairs), version.kernels.gjk.OUT_SIZE))
    jobs = {side: (lambda q, o, s=scene: s.distances_many(q, coherent=coherent, out=o), qs, out)
            for side, scene, out in zip(("old", "new"), scenes, outs)}
    times = _times(jobs, config, bar, config.robot_block)
    pairs = len(scenes[0].pairs)
    return _row(f"{label} ({pairs} pairs)", "coherent sweep" if coherent else "cold sweep", "configurations",
                len(qs) * pairs, times, (sweep_rows_differing(versions, outs), None))


def _row(kind: str, mode: str, poses: str, n: int, times: dict, differing) -> dict:
    """differing: (rows not bit-identical, rows outside the other version's bounds or None), or None."""
    old, new = times["old"], times["new"]
    rows, outside = differing if differing is not None else ("", "")
    return {"pair": kind, "mode": mode, "poses": poses, "queries": n, "old_s": old, "new_s": new,
            "old_over_new": old / new, "rows_differing": rows, "outside_bounds": "" if outside is None else outside,
            "old_us_per_query": 1e6 * old / n, "new_us_per_query": 1e6 * new / n}
