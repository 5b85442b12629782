"""The pictures suite: 3-D pictures of the bounding volumes and of a robot scene, rendered offline to
PNG (harness.suites.pictures.paper_figures, drawn with matplotlib): one link's PCH, STP-BV and CSE cover; the R trade-off
as shapes; the robot at its closest posture with every body's bounding volume and the closest pairs'
witness segments; an overlapping pair with its penetration vector."""

from __future__ import annotations

import time
from dataclasses import dataclass

import pandas as pd

from harness.suites import Figure, Output, Table, frame_lines

FIGURES = ("pictures_link_covers.png", "pictures_r_tradeoff.png", "pictures_robot.png", "pictures_penetration.png")


@dataclass
class Config:
    object: str = "kuka_link_4"  # the link of the covers, the R trade-off and side A of the overlap (dataset name)
    other: str = "kuka_link_2"  # side B of the overlapping pair (its superellipsoid cover)
    r: float = 0.005  # m: STP-BV small radius
    R: float = 2.0  # m: STP-BV big radius of the covers and the overlap
    R_values: list[float] | None = None  # m: the R trade-off's values; None: 1.02, 2, 10, 200 x the smallest admissible R
    robot: str | None = None  # jvrc1 | kuka_iiwa | panda; None: JVRC-1 where the shared data is, else the KUKA iiwa
    steps: int = 1000  # configurations of the smooth trajectory searched for the closest posture
    closest_pairs: int = 5  # witness segments drawn
    depth: float = 0.02  # m: penetration depth of the overlapping pair
    tolerance: float = 1e-3  # m: largest distance between a drawn mesh and its true surface
    seed: int = 0
    quick: bool = False  # a shorter trajectory and coarser meshes
    progress: bool = False


def default_robot() -> str:
    """JVRC-1 (from the shared datasets) if present, else the KUKA iiwa of pybullet_data."""
    from datasets.robots import robot_files

    return "jvrc1" if robot_files("jvrc1").urdf.is_file() else "kuka_iiwa"


def run(config: Config) -> Output:
    from harness.report.meta import run_metadata
    from harness.suites.pictures import paper_figures as pic

    from spq.validation import as_positive

    start = time.perf_counter()
    for name in ("r", "R", "depth", "tolerance"):
        as_positive(getattr(config, name), name)
    if config.steps < 2 or config.closest_pairs < 1:
        raise ValueError(f"steps must be >= 2 and closest_pairs >= 1; got {config.steps} and {config.closest_pairs}")
    robot = config.robot or default_robot()
    steps = min(config.steps, 200) if config.quick else config.steps
    tol = max(config.tolerance, 3e-3) if config.quick else config.tolerance
    covers = pic.link_covers(config.object, config.r, config.R, tol)
    shapes = pic.r_tradeoff(config.object, config.r, config.R_values, tol)
    posture = pic.closest_posture(robot, steps, config.seed, config.closest_pairs, tol)
    overlap = pic.penetration(config.object, config.other, config.r, config.R, config.depth, config.seed, tol)
    a, b, d, *_ = posture.pairs[0]
    rows = [
        {"picture": FIGURES[0], "subject": config.object,
         "facts": (f"{covers.facts['hull_vertices']} hull vertices; STP-BV {covers.facts['stp_small_spheres']} small "
                   f"spheres, {covers.facts['stp_big_spheres']} big spheres, {covers.facts['stp_tori']} tori, volume "
                   f"{covers.facts['stp_volume_ratio']:.3f}x the hull; CSE volume {covers.facts['cse_volume_ratio']:.3f}x")},
        {"picture": FIGURES[1], "subject": config.object,
         "facts": "; ".join(f"R = {R:.3g} m: {n} patches, volume {v:.3f}x hull" for R, _, n, v in shapes.meshes)},
        {"picture": FIGURES[2], "subject": robot,
         "facts": (f"configuration {posture.configuration} of a {posture.configurations}-step trajectory; closest pair "
                   f"{a} - {b} at {d:.6g} m; BVs drawn: " + ", ".join(
                       f"{k} {sum(v == k for v in posture.kinds.values())}" for k in ("pch", "stp", "cse")))},
        {"picture": FIGURES[3], "subject": f"{config.object} (STP) - {config.other} (CSE)",
         "facts": (f"signed distance {-overlap.depth:.6g} m ({overlap.status}), certified in [{overlap.bounds[0]:.6g}, "
                   f"{overlap.bounds[1]:.6g}] m; normal {overlap.normal.round(4).tolist()}")},
    ]
    table = pd.DataFrame(rows)
    closest = pd.DataFrame([{"rank": k + 1, "body_a": pa, "body_b": pb, "bv_a": ka, "bv_b": kb, "distance_m": dist}
                            for k, (pa, pb, dist, _, _, ka, kb) in enumerate(posture.pairs)])
    meta = run_metadata(command="spq pictures", quick=bool(config.quick), object=config.object, other=config.other,
                        r=config.r, R=config.R, robot=robot, steps=steps, seed=config.seed, tolerance_m=tol,
                        depth_m=config.depth, seconds=round(time.perf_counter() - start, 1))
    notes = (f"Meshes from the shapes' to_mesh (every vertex on the true surface; at most {tol:g} m from it). "
             "The robot's bodies are drawn with the bounding volume of their policy (auto: the STP-BV; each of its "
             "pairs uses the STP-BV on the side with fewer patches and the hull on the other); the closest posture is "
             f"the configuration of a smooth {steps}-step trajectory (seed {config.seed}) where no pair overlaps and the "
             "smallest distance is least.")
    return Output(
        meta=meta,
        tables=[Table("pictures", "Pictures: what each shows", table, notes),
                Table("pictures_closest_pairs", f"{robot}: the closest pairs at the pictured posture", closest)],
        figures=[Figure(FIGURES[0], covers.draw), Figure(FIGURES[1], shapes.draw), Figure(FIGURES[2], posture.draw),
                 Figure(FIGURES[3], overlap.draw)],
        lines=[*frame_lines(table), "", *frame_lines(closest)])
