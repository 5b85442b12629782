"""The robot suite: whole-body self-distance of a robot per configuration (spq's bounding-volume policies
against coal and python-fcl), its forward kinematics against pybullet's, and gradient continuity."""

from __future__ import annotations

import time
from dataclasses import dataclass

from harness.suites import Figure, Output, Table, frame_lines


@dataclass
class Config:
    robot: str = "jvrc1"  # jvrc1, kuka_iiwa, panda
    configs: int = 1000  # random configurations
    steps: int = 1000  # trajectory steps
    seed: int = 0
    prune: float = 0.05  # m: bounding-sphere pruning threshold of the pruned rows
    repeats: int = 3
    passes: int = 2  # times the scene table goes through its rows, each row keeping its least time
    r: float = 0.005  # m: STP-BV small radius
    R: float = 2.0  # m: STP-BV big radius
    engines: list[str] | None = None  # None: coal and fcl
    engine_configs: int | None = None  # configurations coal and fcl run (None: all)
    progress: bool = False
    workers: int = 1  # > 1: the cold scene rows also on this many threads (mode "cold N workers")


def run(config: Config) -> Output:
    from harness.report.charts import pyplot  # noqa: F401  (headless backend before any figure)
    from harness.report.meta import run_metadata
    from harness.suites.robot import robot_bench as rb
    from spq.query import DEFAULT_TOL_ABS, DEFAULT_TOL_REL
    from spq.workers import check_workers

    cfg = rb.RobotBenchConfig(robot=config.robot, configurations=config.configs, steps=config.steps,
                              seed=config.seed, prune=config.prune, repeats=config.repeats, passes=config.passes,
                              r=config.r, R=config.R,
                              engines=config.engines or ["coal", "fcl"], engine_configurations=config.engine_configs,
                              workers=check_workers(config.workers))
    start = time.perf_counter()
    tables = rb.run(cfg, progress=config.progress)
    meta = run_metadata(command="spq bench robot", robot=config.robot, seed=config.seed, configurations=config.configs,
                        trajectory_steps=config.steps, prune_m=config.prune, repeats=config.repeats,
                        passes=config.passes, stp_r=config.r, stp_R=config.R, spq_tol_abs=DEFAULT_TOL_ABS,
                        spq_tol_rel=DEFAULT_TOL_REL,
                        engine_configurations=config.engine_configs or config.configs,
                        seconds=round(time.perf_counter() - start, 1),
                        **({"workers": config.workers} if config.workers > 1 else {}))
    where = (f"{tables['robot']}: {tables['bodies']} bodies, {tables['pairs']} pairs (adjacent bodies skipped). "
             f"{config.configs} random configurations within the joint limits (seed {config.seed}) and a "
             f"{config.steps}-step smooth trajectory. ")
    out = Output(meta=meta, figures=[Figure(name, draw) for name, draw in tables["figures"]])
    out.tables = [
        Table("robot_scene", "Robot scene: all pairs per configuration", tables["scene"],
              where + f"Per configuration: {config.repeats} runs through all configurations in order, one compiled call "
              f"per block of {rb.TIMING_BLOCK}; each block's fastest run counts (the sum over blocks, divided by the "
              f"number of configurations); the table goes through all its rows {config.passes} times and each row "
              "keeps its least time (a slow spell of the machine can outlast one row's runs); forward kinematics "
              "included; the results go into one array allocated beforehand, as a control loop would keep. cold: "
              "every pair starts cold; coherent: per-pair warm starts along the "
              f"trajectory. pruning_m > 0: pairs whose bounding spheres are farther apart are skipped."
              + (f" cold {config.workers} workers: the cold runs with each call's configurations split over "
                 f"{config.workers} threads (spq.workers), results equal one thread's bit for bit."
                 if config.workers > 1 else "")),
        Table("robot_engines", "Robot scene: spq against coal and python-fcl", tables["engines"],
              where + "Same PCH pairs at the same random configurations; the engines run one Python call per "
              f"query, with the body poses computed beforehand (not timed); each pair's loop over the configurations "
              f"is the fastest of {config.repeats}. speedup_of_spq_auto: engine time / spq "
              "auto cold time. max_abs_diff_vs_spq_m and results_off_by_over_0.1mm: over the pair results spq calls "
              "separated (coal agrees with spq to about 1e-8 m; python-fcl's GJK stops early on some, as in the "
              "stability suite, and overestimates)."),
        Table("robot_continuity", "Robot scene: gradient continuity along the trajectory", tables["continuity"],
              where + f"Closest pair among the pairs separated along the whole trajectory; the {rb.JUMP_CANDIDATES} "
              f"steps with the largest relative gradient change (closest pair unchanged) are bisected {rb.BISECTIONS} "
              f"times; a jump keeps over {rb.JUMP_RESIDUAL:g} of its change. "
              f"pairs whose distance varies by less than {rb.MOVING_PAIR_M:g} m along the trajectory are left out."),
        Table("robot_kinematics", "Robot scene: forward kinematics against pybullet", tables["kinematics"],
              where + "Every link's world pose from spq (URDF read by yourdfpy, compiled kinematics) against "
              "pybullet's (its own URDF parser), composed in double precision from its centre-of-mass frames."),
        Table("robot_signed", "Robot scene: signed distances (penetration depth)", tables["signed"],
              where + "Every pair cold at the random configurations, unsigned (an overlap is distance 0) and with "
              "signed=True (an overlap gets minus its penetration depth), the two timed in turn within each "
              f"round, best of {config.repeats} per block of {rb.TIMING_BLOCK}. deepest overlap: the least signed "
              "distance of a configuration, over those with an overlap."),
        Table("robot_pinocchio", "Robot scene: spq against pinocchio.computeDistances", tables["pinocchio"],
              where + "pinocchio (its own URDF parser, fixed base) with the scene's PCH hulls as coal.Convex on the same "
              "links and the same pairs; one pinocchio.computeDistances call per configuration (forward kinematics, "
              "geometry placements and every pair's coal distance in C++), coal's gjk_tolerance 1e-6 and each GJK "
              "variant: default, cached-guess (the previous result's guess), nesterov (Nesterov acceleration) and "
              "both. Timed beside spq's cold pch and auto runs in blocks of "
              f"{rb.TIMING_BLOCK} configurations, every side on a block before any runs the next, each timed run just "
              f"after an untimed one of the same side on the same block, {config.repeats} "
              "rounds, each side's least time per block summed. spq_*_speedup: pinocchio's time / spq's. max_abs_diff_vs_spq_m: over the "
              "pair results spq's PCH run calls separated; overlap_disagreements: one side below -1e-6 m, the "
              "other above 1e-6 m. The variants 'on auto's volumes' run the same job as spq's auto: each pair's "
              "STP side as that body's certified STP-BV mesh (STPBV.to_mesh at "
              f"{rb.STP_MESH_REL_TOLERANCE:g} of its bounding radius; inside the STP-BV, within stp_mesh_error_m of "
              "it at most), compared with spq's auto results: on separated pairs an exact answer lies 0 to "
              "stp_mesh_error_m above spq's (diff_min_m, diff_max_m: pinocchio less spq).")]
    out.lines = [*frame_lines(tables["kinematics"]), *frame_lines(tables["signed"]),
                 *frame_lines(tables["scene"][["policy", "configurations", "mode", "pruning_m", "ms_per_config",
                                               "pairs_per_s", "mean_iterations", "median_min_distance_m",
                                               "median_min_separated_m", "configs_with_overlap"]]),
                 *frame_lines(tables["engines"]), *frame_lines(tables["pinocchio"]), *frame_lines(tables["continuity"])]
    return out
