"""The paper's Table I: proximity queries per second between two copies of one link covered by each
bounding volume (PCH, STP, CSE), all six pairs, measured in one run beside coal's PCH-PCH figure.
The CSE is the link's covering fit unless the config gives one (Table1Config.cse).

Pose distribution: the same as ``spq bench pch`` (uniformly random rotations, translations uniform
in a cube of +-range metres for both bodies, seeded), so that separated and overlapping poses both
occur; they are counted apart. Each figure is timed in blocks of poses, every pair and coal on one
block before the next, ``repeats`` rounds, the least time of each block summed
(harness.suites.bench.timing.blocked_times).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

import spq
from harness.suites.bench.timing import BLOCK, blocked_calls, blocked_times
from harness.workloads.poses import random_poses

PAPER_QPS = {  # ICRA 2009 Table I, HRP-2 link of 300 vertices, Pentium 4 3.8 GHz, C++
    ("PCH", "PCH"): 795123, ("STP", "PCH"): 584567, ("STP", "STP"): 525394,
    ("CSE", "PCH"): 319216, ("CSE", "STP"): 286368, ("CSE", "CSE"): 187429,
}
PAIRS = [("PCH", "PCH"), ("STP", "PCH"), ("STP", "STP"), ("CSE", "PCH"), ("CSE", "STP"), ("CSE", "CSE")]


@dataclass
class Table1Config:
    object_name: str = "kuka_link_4"
    r: float = 0.005  # m: STP small radius (a 5 mm safety margin)
    R: float = 2.0  # m: STP big radius (about 10x the link's size: close to the hull, yet C1)
    poses: int = 20000
    seed: int = 0
    translation_range: float = 0.3
    repeats: int = 3  # rounds: each block of poses timed this many times, its least time kept
    block: int = BLOCK  # poses per block
    volume_samples: int = 200_000
    cse: tuple[float, float, float, float, float] | None = None  # (a, b, c, e1, e2) (m, m, m, -, -); None: the fit


@dataclass
class Body:
    """A bounding volume and the fixed transform from its frame to the link's frame."""

    name: str
    shape: object
    offset: np.ndarray  # (4, 4)
    features: int
    volume: float


def monte_carlo_volume(shape, samples: int, seed: int) -> float:
    """Volume (m^3) of a convex shape by sampling its bounding box; a point is inside when spq's
    distance from it (a 1e-12 m sphere) is zero. Standard error about sqrt(p(1-p)/n) of the box."""
    rng = np.random.default_rng(seed)
    rad = shape.bounding_radius()
    pts = rng.uniform(-rad, rad, size=(samples, 3))
    poses = np.tile(np.eye(4), (samples, 1, 1))
    poses[:, :3, 3] = pts
    res = spq.distances(shape, spq.Sphere(1e-12), np.eye(4), poses)
    inside = np.isin(res.status, ["overlapping", "touching"])
    return float(inside.mean() * (2 * rad) ** 3)


def build_bodies(config: Table1Config, load_object) -> dict[str, Body]:
    from scipy.spatial import ConvexHull

    pch = load_object(config.object_name)
    stp = spq.STPBV.from_points(pch.vertices, config.r, config.R)
    if config.cse is None:
        cse, cse_offset = spq.Superellipsoid.fit(pch.vertices)
    else:  # a given CSE need not cover the link: centred on its bounding box, axes along its axes
        cse = spq.Superellipsoid(*config.cse)
        cse_offset = np.eye(4)
        cse_offset[:3, 3] = 0.5 * (pch.vertices.min(axis=0) + pch.vertices.max(axis=0))
    hull_volume = float(ConvexHull(pch.vertices).volume)
    return {
        "PCH": Body("PCH", pch, np.eye(4), len(pch.vertices), hull_volume),
        "STP": Body("STP", stp, np.eye(4), stp.n_patches, monte_carlo_volume(stp, config.volume_samples, config.seed)),
        "CSE": Body("CSE", cse, cse_offset, 1, float(cse.volume())),
    }


def run(config: Table1Config, load_object, progress: bool = True) -> tuple[pd.DataFrame, dict, float]:
    """(one row per pair, bodies, coal PCH-PCH queries per second from the same run)."""
    from tqdm import tqdm

    from harness.engines.coal_engine import CoalEngine

    bodies = build_bodies(config, load_object)
    poses_a, poses_b = random_poses(config.poses, config.seed, config.translation_range)
    jobs, statuses = {}, {}
    for a_name, b_name in tqdm(PAIRS, desc="table1 (compile)", unit="pair", disable=not progress):
        a, b = bodies[a_name], bodies[b_name]
        pa = poses_a @ a.offset
        pb = poses_b @ b.offset
        res = spq.distances(a.shape, b.shape, pa, pb)  # compile, warm and sort out the overlapping poses
        sep = res.status != "overlapping"
        statuses[a_name, b_name] = res
        pa_sep, pb_sep = np.ascontiguousarray(pa[sep]), np.ascontiguousarray(pb[sep])
        unsigned = lambda pa, pb, a=a, b=b: spq.distances(a.shape, b.shape, pa, pb)  # noqa: E731
        jobs[a_name, b_name, "all"] = (unsigned, pa, pb)
        jobs[a_name, b_name, "separated"] = (unsigned, pa_sep, pb_sep)
        signed = spq.distances(a.shape, b.shape, pa, pb, signed=True)  # compile and warm the signed path
        statuses[a_name, b_name, "signed"] = signed
        signed_call = lambda pa, pb, a=a, b=b: spq.distances(a.shape, b.shape, pa, pb, signed=True)  # noqa: E731
        jobs[a_name, b_name, "signed"] = (signed_call, pa, pb)
    coal_pair = CoalEngine().prepare(bodies["PCH"].shape, bodies["PCH"].shape)
    coal_pair.distance_loop(poses_a[:8], poses_b[:8])
    jobs["coal"] = (coal_pair.distance_loop, poses_a, poses_b)
    with tqdm(total=blocked_calls(jobs, config.repeats, config.block), desc="table1", unit="run",
              disable=not progress) as bar:
        timed = blocked_times(jobs, config.repeats, config.block, progress=bar)
    coal_seconds = timed["coal"][0]
    rows = []
    for a_name, b_name in PAIRS:
        res = statuses[a_name, b_name]
        sep = res.status != "overlapping"
        rows.append({"row": a_name, "column": b_name, "queries_per_s": len(res.status) / timed[a_name, b_name, "all"][0],
                     "separated_queries_per_s": sep.sum() / timed[a_name, b_name, "separated"][0],
                     "overlapping": int((~sep).sum()), "failed": int((res.status == "failed").sum()),
                     "mean_iterations": float(res.iterations.mean()),
                     "mean_iterations_separated": float(res.iterations[sep].mean()),
                     "signed_queries_per_s": len(res.status) / timed[a_name, b_name, "signed"][0],
                     "signed_failed": int((statuses[a_name, b_name, "signed"].status == "failed").sum()),
                     "paper_queries_per_s": PAPER_QPS[(a_name, b_name)]})
    table = pd.DataFrame(rows)
    pch = table.loc[(table.row == "PCH") & (table.column == "PCH"), "queries_per_s"].iloc[0]
    table["time_vs_pch"] = pch / table.queries_per_s  # > 1: slower than PCH-PCH
    paper_pch = PAPER_QPS[("PCH", "PCH")]
    table["paper_time_vs_pch"] = paper_pch / table.paper_queries_per_s
    return table, bodies, config.poses / coal_seconds


def lower_triangle(table: pd.DataFrame, column: str, fmt="{:,.0f}") -> pd.DataFrame:
    """The paper's layout: rows PCH, STP, CSE; columns PCH, STP, CSE; lower triangle filled."""
    names = ["PCH", "STP", "CSE"]
    grid = pd.DataFrame("", index=names, columns=names)
    for _, row in table.iterrows():
        grid.loc[row["row"], row["column"]] = fmt.format(row[column])
    grid.index.name = "BV"
    return grid.reset_index()
