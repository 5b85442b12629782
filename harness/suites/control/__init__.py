"""The control suite (``spq bench control``): a collision-avoiding differential-IK controller run on seeded
tasks with spq's pch, stp, cse and auto scenes and with pink and mink, and what each bounding volume does
to the commands.

This module is the suite's entry (config, run, tables); beside it:

- controller.py: the QP at a fixed step (hand targets, damped joint limits, joint velocity limits, one
  velocity-damper row per pair closer than d_i), fed by a distance source.
- tasks.py: seeded tasks that drive bodies near each other, per robot.
- scenes.py: one robot read once, one scene per bounding-volume policy.
- peers.py: pink's SelfCollisionBarrier and mink's CollisionAvoidanceLimit in their own solvers, and the
  same damper QP fed by pinocchio's or MuJoCo's distances.
- metrics.py: per run, the smallest distance on a common geometry, how far the active rows turn, the
  commands' jumps by cause, time per step.
- runs.py: every task of every robot with every method, and the runs' summary.
- speed.py: what a control step costs, side by side in one process.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from harness.suites import Figure, Output, frame_lines


@dataclass
class Config:
    robots: list[str] | None = None  # None: jvrc1, talos_reduced, panda, ur5_robot
    tasks: int = 20  # seeded tasks per robot
    steps: int = 600  # 5 ms steps per task (3 s)
    seed: int = 0
    methods: list[str] | None = None  # None: spq-pch, spq-stp, spq-cse, spq-auto, pink, mink, pin-damper, mujoco-damper
    progress: bool = False
    pink_tasks: int | None = 3  # pink on this many tasks per robot only (None: all): its barrier loops over every pair
    speed: bool = True  # also time a control step side by side (harness/suites/control/speed.py) on the first robot
    speed_steps: int = 400  # configurations of the timed replay
    speed_rounds: int = 5


SHOWN = ["robot", "method", "runs", "min_distance_m_worst", "steps_below_ds", "final_task_error_m_median",
         "row_turn_p99_median", "row_turn_peak_worst", "acc_peak_median", "acc_peak_worst",
         "acc_peak_feature_switch_worst", "acc_peak_row_switch_worst", "acc_peak_row_binding_worst", "spikes",
         "qp_failures", "ms_distance", "ms_qp"]


def run(config: Config) -> Output:
    from harness.report.charts import pyplot  # noqa: F401  (headless backend before any figure)
    from harness.report.meta import _version, run_metadata
    from harness.report.tables import markdown_table
    from harness.suites.control import runs
    from harness.suites.control.controller import QP_EPS_ABS, QP_SOLVER, ControlParams
    from harness.suites.control.metrics import FEATURE_JUMP_M, FEATURE_JUMP_RATIO, SPIKE_RAD_S2
    from harness.suites.control.peers import MINK_SOLVER
    from harness.suites.control.tasks import JITTER_M, SEGMENT_S

    if config.tasks < 1:
        raise ValueError(f"control suite: tasks must be >= 1; got {config.tasks}")
    params = ControlParams()
    start = time.perf_counter()
    result = runs.run(config.robots, config.tasks, config.steps, config.seed, config.methods, params,
                       progress=config.progress, slow_peer_tasks=config.pink_tasks)
    table = runs.summary(result.runs)
    meta = run_metadata(command="spq bench control", robots=runs.check_robots(config.robots), tasks=config.tasks,
                        steps=config.steps, seed=config.seed, methods=runs.check_methods(config.methods),
                        pink_tasks=config.pink_tasks,
                        params=params.describe(), qp_solver=f"{QP_SOLVER} via qpsolvers (eps_abs {QP_EPS_ABS:g}), "
                        f"warm-started", mink_solver=MINK_SOLVER, feature_jump_m=FEATURE_JUMP_M, feature_jump_ratio=FEATURE_JUMP_RATIO,
                        spike_rad_s2=SPIKE_RAD_S2, target_jitter_m=JITTER_M, segment_s=list(SEGMENT_S),
                        peer_versions={p: _version(p) for p in ("pin-pink", "mink", "pin", "mujoco", "qpsolvers",
                                                                 "proxsuite", "daqp")},
                        seconds=round(time.perf_counter() - start, 1))
    notes = _notes(config, params, result)
    out = Output(meta=meta)
    out.raw["control_runs.csv"] = result.runs
    out.raw["control_robots.csv"] = result.robots
    text = [f"# Control: what each bounding volume does to a collision-avoiding controller", "", notes, "",
            "## Robots", "", markdown_table(result.robots) if not result.robots.empty else "none", "",
            "## What ran", "", *[f"- {line}" for line in runs.which_ran(result.runs)], "",
            "## Per robot and method (medians and worst over the tasks)", "",
            markdown_table(table) if not table.empty else "no run finished", "",
            *runs.continuity_note(table), "Run: `" + _json(meta) + "`", ""]
    out.documents["control.md"] = "\n".join(text)
    out.raw["control.csv"] = table
    out.figures = [Figure("control_qdot_traces.png", lambda p: _traces_chart(result, p)),
                   Figure("control_acceleration.png", lambda p: _acceleration_chart(result, p)),
                   Figure("control_time.png", lambda p: _time_chart(table, p))]
    shown = [c for c in SHOWN if c in table.columns]
    out.lines = [*frame_lines(result.robots), "", *runs.which_ran(result.runs), "",
                 *(frame_lines(table[shown]) if not table.empty else ["no run finished"]),
                 "", *[l for l in runs.continuity_note(table) if l]]
    if config.speed:
        _add_speed(out, config, params)
    return out


def _add_speed(out: Output, config: Config, params) -> None:
    """control_speed.md/.csv: a control step timed side by side on one robot (harness/suites/control/speed.py)."""
    from harness.report.tables import markdown_table
    from harness.suites.control import runs
    from harness.suites.control.speed import step_timing

    robot = runs.check_robots(config.robots)[0]
    timing = step_timing(robot, steps=config.speed_steps, rounds=config.speed_rounds, seed=config.seed,
                         params=params, progress=config.progress)
    out.raw["control_speed.csv"] = timing.table
    out.documents["control_speed.md"] = "\n".join([
        "# Time per control step, side by side", "", timing.note, "",
        "ratio: for a distances+jacobians mode, its time over the same mode without Jacobians; for a whole spq "
        "step, the pinocchio + coal step's time over it.", "", markdown_table(timing.table), ""])
    out.lines += ["", f"step timing ({robot}):", *frame_lines(timing.table)]


def _json(meta) -> str:
    import json

    return json.dumps(meta, sort_keys=True, default=str)


def _notes(config, params, result) -> str:
    from harness.suites.control.controller import QP_SOLVER
    from harness.suites.control.metrics import FEATURE_JUMP_M, FEATURE_JUMP_RATIO, SPIKE_RAD_S2
    from harness.suites.control.peers import MINK_SOLVER

    p = params
    return (
        f"A differential-IK controller as a QP at dt = {p.dt * 1e3:g} ms on the joint velocities (harness/suites/control/"
        f"controller.py): hand points tracked (gain {p.position_gain:g} 1/s with the reference's velocity fed forward, "
        f"weight {p.position_weight:g}; hand orientations held, gain {p.orientation_gain:g} 1/s, weight "
        f"{p.orientation_weight:g}), a posture pull (gain {p.posture_gain:g} 1/s, weight {p.posture_weight:g}), "
        f"damping {p.damping:g}; joint speeds within min(URDF, {p.velocity_limit:g} rad/s); joint limits damped "
        f"(|q̇| <= v_max (s - {p.joint_ds:g})/({p.joint_di:g} - {p.joint_ds:g}) within {p.joint_di:g} rad of a limit, "
        f"continuous where it turns on); one velocity-damper row per pair closer than d_i = {p.di:g} m: ḋ >= -ξ (d - "
        f"d_s)/(d_i - d_s), d_s = {p.ds:g} m, ξ = {p.xi:g} m/s"
        + (" or, as mc_rtc computes it, the gain that allows the pair's rate when its row turns on (so that a row "
           "turns on without a jump)" if p.xi_auto else "") + " (spq.control.VelocityDamper: one compiled call gives "
        f"every distance and row ∂d/∂q). {QP_SOLVER} (proxsuite) through qpsolvers, warm-started; a failed solve "
        "is counted and q̇ = 0 held that step. Every task starts from rest; its hand references are minimum-jerk "
        f"segments through seeded waypoints (seed {config.seed}), so the reference is smooth. "
        "Methods: spq-pch, spq-stp, spq-cse, spq-auto: the same QP on spq scenes of each policy (the same pairs); "
        + (f"pink on the first {config.pink_tasks} tasks of each robot only (its barrier computes every pair's row "
           "in Python, 50 to 120 ms a step on the humanoids); " if config.pink_tasks is not None else "") +
        "pink: pink.solve_ik with FrameTasks, PostureTask, ConfigurationLimit, VelocityLimit and SelfCollisionBarrier "
        f"over every pair (gain ξ/(d_i - d_s), d_min = d_s) on pinocchio + coal hulls; mink: mink.solve_ik "
        f"({MINK_SOLVER}) with FrameTasks, PostureTask, ConfigurationLimit, VelocityLimit and CollisionAvoidanceLimit "
        "(detection d_i, minimum d_s, gain set to the same damper) on a MuJoCo model of the same hulls (harness/suites/control/"
        "peers.py); pin-damper and mujoco-damper: spq's QP fed by pinocchio + coal (computeDistances, joint Jacobians "
        "shifted to the witness points) and by MuJoCo (mj_geomDistance, mj_jac) on the same hulls, which also stand in "
        "for pink or mink on a robot they cannot run (a run's note says so). Pairs: the robot's SRDF-pruned set "
        "(example-robot-data's shipped SRDF; JVRC-1's sampled one in datasets/srdf/), less the pairs no active joint "
        "moves apart (rigid), those whose distance hardly varies over random configurations of the active joints "
        "(static) and those within d_s at the start posture under some volume: the same for every method "
        "(control_robots.csv counts them). "
        "Measures (harness/suites/control/metrics.py): a closest-feature switch is a witness point jumping in its body's "
        f"frame: over {FEATURE_JUMP_M * 1e3:g} mm in one step and over {FEATURE_JUMP_RATIO:g} times its move at the "
        f"steps before and after; a spike is ‖Δq̇‖/dt over {SPIKE_RAD_S2:g} "
        "rad/s²; the smallest distance is every trajectory's on the same PCH scene. Time: distances + Jacobians "
        "(spq: the VelocityDamper call; pink: Configuration.update and the barrier's rows; mink: "
        "Configuration.update and the collision limit's rows; pin-damper, mujoco-damper: the distances and rows) "
        "and QP (the rest of the step: task Jacobians, QP build and solve). "
        + (f"Joint-velocity chart: {result.trace_choice}." if result.trace_choice else ""))


def _traces_chart(result, path):
    from harness.report.charts import pyplot, save_figure

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2), sharey=True)
    if not result.traces:
        for ax in axes:
            ax.text(0.5, 0.5, "no task ran with both spq-pch and spq-stp", ha="center", va="center")
        save_figure(fig, path)
        return
    (robot, task), traces = next(iter(result.traces.items()))
    for ax, method in zip(axes, ("spq-pch", "spq-stp")):
        qdot, names = traces[method]
        t = np.arange(len(qdot)) * 5e-3
        for j in range(qdot.shape[1]):
            ax.plot(t, qdot[:, j], lw=0.9)
        ax.set_title(f"{method}")
        ax.set_xlabel("time (s)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("joint velocity (rad/s)")
    save_figure(fig, path, f"Commanded joint velocities, {task} ({robot}): PCH beside STP-BV")


ACC_CHART_FLOOR = 0.1  # rad/s²: the acceleration chart starts here (steps at rest lie below)


def _acceleration_chart(result, path):
    from harness.report.charts import pyplot, save_figure
    from harness.suites.control.metrics import SPIKE_RAD_S2

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for method, acc in result.acc.items():
        if not len(acc):
            continue
        a = np.sort(acc[acc > 0])
        if not len(a):
            continue
        frac = 1.0 - np.arange(len(a)) / len(acc)
        ax.loglog(a, frac, label=f"{method} (peak {a[-1]:.0f})", lw=1.2)
    ax.axvline(SPIKE_RAD_S2, color="0.5", ls="--", lw=0.8)
    ax.set_xlim(left=ACC_CHART_FLOOR)
    ax.set_xlabel("joint acceleration ‖Δq̇‖/dt (rad/s²)")
    ax.set_ylabel("fraction of steps at or above")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    save_figure(fig, path, "Command accelerations over every step of every task, per method")


def _time_chart(table, path):
    from harness.report.charts import pyplot, save_figure

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 4.5))
    if table.empty:
        ax.text(0.5, 0.5, "no run finished", ha="center")
        save_figure(fig, path)
        return
    robots = list(dict.fromkeys(table.robot))
    methods = list(dict.fromkeys(table.method))
    width = 0.8 / len(methods)
    for i, m in enumerate(methods):
        sub = table[table.method == m].set_index("robot").reindex(robots)
        x = np.arange(len(robots)) + (i - (len(methods) - 1) / 2) * width
        ax.bar(x, sub.ms_distance, width, color=f"C{i}", label=f"{m}")
        ax.bar(x, sub.ms_qp, width, bottom=sub.ms_distance, color=f"C{i}", alpha=0.45)
    ax.set_xticks(np.arange(len(robots)), robots)
    ax.set_yscale("log")
    shortest = table.ms_distance[table.ms_distance > 0].min()
    if np.isfinite(shortest):  # log autoscale put its floor above the shortest bar (ur5's spq bars were cut off)
        ax.set_ylim(bottom=shortest / 2)
    ax.set_ylabel("ms per step (median): solid distances + Jacobians, light QP")
    ax.grid(alpha=0.3, axis="y", which="both")
    ax.legend(fontsize=8, ncol=2)
    save_figure(fig, path, "Time per control step, per method")


