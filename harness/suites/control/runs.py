"""The control benchmark's computation: every task of every robot with every method, then the runs'
measures (harness.suites.control.metrics), a per-method summary, the charts' data and the closing note."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from harness.suites.control.controller import ControlParams, Controller, SpqSource
from harness.suites.control.metrics import CAUSES, DS_TOL_M, SPIKE_RAD_S2, run_metrics, series
from harness.suites.control.peers import DAMPER_PEERS, PEERS, damper_source, run_peer
from harness.suites.control.scenes import SPQ_POLICIES, check_start, robot_scenes
from harness.suites.control.tasks import ROBOTS, frozen_mask, make_tasks, setup, start_posture

METHODS = tuple(f"spq-{p}" for p in SPQ_POLICIES) + PEERS + DAMPER_PEERS
FALLBACK = {"pink": "pin-damper", "mink": "mujoco-damper"}  # a peer that cannot run a robot: its distances in spq's QP
DEFAULT_ROBOTS = ("jvrc1", "talos_reduced", "panda", "ur5_robot")


def check_methods(methods) -> list[str]:
    methods = list(methods or METHODS)
    out = []
    for m in methods:
        name = m if m in METHODS else f"spq-{m}"
        if name not in METHODS:
            raise ValueError(f"unknown control method {m!r}; choose from {list(METHODS)} (or pch, stp, cse, auto)")
        out.append(name)
    return list(dict.fromkeys(out))


def check_robots(robots) -> list[str]:
    robots = list(robots or DEFAULT_ROBOTS)
    for r in robots:
        if r not in ROBOTS:
            raise ValueError(f"unknown control robot {r!r}; choose from {sorted(ROBOTS)}")
    return robots


@dataclass
class BenchResult:
    runs: pd.DataFrame
    robots: pd.DataFrame  # per robot: pairs, how pruned, start distance, status
    acc: dict = field(default_factory=dict)  # method -> all steps' accelerations (rad/s²)
    traces: dict = field(default_factory=dict)  # (robot, task) -> {method: (qdot (T, n) active joints, joint names)}
    trace_choice: str = ""


def run_method(method, task, scenes, params, steps, frozen):
    if method.startswith("spq-"):
        scene = scenes.by_policy[method[4:]]
        return Controller(scene, SpqSource(scene, params, method), params, frozen).run(task, steps)
    if method in DAMPER_PEERS:
        source = damper_source(method, task, scenes.base, scenes.urdf, params, frozen)
        return Controller(scenes.base, source, params, frozen).run(task, steps)
    return run_peer(method, task, scenes.base, scenes.urdf, params, steps, frozen)


SLOW_PEERS = ("pink",)  # pink's barrier computes every pair's rows in Python: 50 to 120 ms a step on the humanoids


def run(robots, tasks: int, steps: int, seed: int, methods, params: ControlParams, progress: bool = False,
        slow_peer_tasks: int | None = None) -> BenchResult:
    """Every task (``tasks`` per robot, seeded) for ``steps`` steps with every method; the SLOW_PEERS on
    the first ``slow_peer_tasks`` tasks of each robot only (None: all)."""
    from tqdm import tqdm

    robots, methods = check_robots(robots), check_methods(methods)
    if steps < 2:
        raise ValueError(f"steps must be >= 2; got {steps}")
    rows, robot_rows, acc, logs = [], [], {m: [] for m in methods}, {}
    with tqdm(total=len(robots) * tasks * len(methods), desc="control", unit="run", disable=not progress) as bar:
        for robot in robots:
            start = time.perf_counter()
            try:
                policies = [m[4:] for m in methods if m.startswith("spq-")] or ["pch"]
                scenes = robot_scenes(robot, policies=list(dict.fromkeys(["pch", *policies])))
            except (ValueError, FileNotFoundError, ImportError, RuntimeError) as exc:
                robot_rows.append({"robot": robot, "status": "failed", "reason": f"{type(exc).__name__}: {exc}"})
                bar.update(tasks * len(methods))
                continue
            s = setup(robot)
            model = scenes.base.model
            frozen = frozen_mask(model, s)
            q0 = start_posture(model, s)
            robot_rows.append({"robot": robot, "status": "ran", "reason": "", "dof": model.ndof,
                               "active_joints": int((~frozen).sum()), "bodies": len(scenes.base.bodies),
                               "obstacles": len(scenes.obstacles), "pairs": len(scenes.base.pairs),
                               "pairs_from": scenes.pairs_note, "start_min_distance_m": check_start(scenes.base, q0, params.ds),
                               "build_s": round(time.perf_counter() - start, 1)})
            for index, task in enumerate(make_tasks(scenes.base, robot, tasks, seed)):
                for method in methods:
                    if method in SLOW_PEERS and slow_peer_tasks is not None and index >= slow_peer_tasks:
                        bar.update()
                        continue
                    try:
                        log = run_method(method, task, scenes, params, steps, frozen)
                    except (ImportError, ValueError, RuntimeError, AttributeError) as exc:  # cannot run this robot
                        reason = f"{type(exc).__name__}: {exc}"
                        rows.append({"method": method, "robot": robot, "task": task.name, "note": f"did not run: {reason}"})
                        fallback = FALLBACK.get(method)
                        if fallback is None or fallback in methods:
                            bar.update()
                            continue
                        try:
                            log = run_method(fallback, task, scenes, params, steps, frozen)
                            log.note = f"ran in place of {method} ({reason})"
                        except (ImportError, ValueError, RuntimeError, AttributeError) as exc2:
                            rows.append({"method": fallback, "robot": robot, "task": task.name,
                                         "note": f"did not run: {type(exc2).__name__}: {exc2}"})
                            bar.update()
                            continue
                    row = run_metrics(log, params, scenes.base)
                    row["kind"] = task.kind
                    rows.append(row)
                    acc.setdefault(log.method, []).append(series(log, params)["acc"])
                    logs[(robot, task.name, log.method)] = (log.qdot[:, ~frozen], [n for n, f in zip(model.joint_names, frozen) if not f])
                    bar.update()
    runs = pd.DataFrame(rows)
    result = BenchResult(runs, pd.DataFrame(robot_rows), {m: np.concatenate(v) if v else np.zeros(0) for m, v in acc.items()})
    _choose_trace(result, logs)
    return result


def _choose_trace(result: BenchResult, logs) -> None:
    """The task shown in the joint-velocity chart: among those run with both spq-pch and spq-stp, the one
    where pch's steps at closest-feature switches reach the highest acceleration."""
    r = result.runs
    if r.empty or "acc_peak_feature_switch" not in r:
        return
    pch = r[(r.method == "spq-pch") & r.acc_peak_feature_switch.notna()]
    best = None
    for row in pch.sort_values("acc_peak_feature_switch", ascending=False).itertuples():
        if (row.robot, row.task, "spq-stp") in logs:
            best = row
            break
    if best is None:
        return
    key = (best.robot, best.task)
    result.traces[key] = {m: logs[(best.robot, best.task, m)] for m in ("spq-pch", "spq-stp")}
    result.trace_choice = (f"{best.task} ({best.robot}): the task where spq-pch's steps at closest-feature switches "
                           f"reach the highest acceleration ({best.acc_peak_feature_switch:.0f} rad/s²)")


# --- summary --------------------------------------------------------------------------------------
SUMMARY = [  # (column, aggregation over the robot's tasks, new name)
    ("min_distance_m", "min", "min_distance_m_worst"),
    ("min_distance_m", "median", "min_distance_m_median"),
    ("steps_below_ds", "sum", "steps_below_ds"),
    ("steps_below_0", "sum", "steps_below_0"),
    ("final_task_error_m", "median", "final_task_error_m_median"),
    ("row_turn_peak", "max", "row_turn_peak_worst"),
    ("row_turn_p99", "median", "row_turn_p99_median"),
    ("qdot_total_variation", "median", "qdot_tv_median"),
    ("acc_peak", "median", "acc_peak_median"),
    ("acc_peak", "max", "acc_peak_worst"),
    ("spikes", "sum", "spikes"),
    *[(f"acc_peak_{c}", "max", f"acc_peak_{c}_worst") for c in CAUSES],
    *[(f"spikes_{c}", "sum", f"spikes_{c}") for c in CAUSES],
    ("qp_failures", "sum", "qp_failures"),
    ("qp_fallbacks", "sum", "qp_fallbacks"),
    ("clipped_steps", "sum", "clipped_steps"),
    ("ms_distance_median", "median", "ms_distance"),
    ("ms_qp_median", "median", "ms_qp"),
    ("ms_step_median", "median", "ms_step"),
    ("ms_step_p99", "max", "ms_step_p99_worst"),
]


def summary(runs: pd.DataFrame) -> pd.DataFrame:
    """Per robot and method: medians and worst over the tasks (SUMMARY)."""
    if runs.empty or "min_distance_m" not in runs:
        return pd.DataFrame()
    ran = runs[runs.min_distance_m.notna()]
    out = []
    for (robot, method), g in ran.groupby(["robot", "method"], sort=False):
        row = {"robot": robot, "method": method, "runs": len(g)}
        for col, how, name in SUMMARY:
            row[name] = getattr(g[col], how)()
        out.append(row)
    return pd.DataFrame(out)


def _fmt(v, unit="") -> str:
    return "n/a" if v is None or not np.isfinite(v) else f"{v:.3g}{unit}"


def which_ran(runs: pd.DataFrame) -> list[str]:
    """Per robot: the methods that ran (how many tasks) and those that did not (why)."""
    if runs.empty:
        return ["No run."]
    lines = []
    notes = runs.note.astype(str) if "note" in runs else pd.Series([""] * len(runs))
    failed = notes.str.startswith("did not run")
    for robot, g in runs.groupby("robot", sort=False):
        ok = g[~failed[g.index]]
        bad = g[failed[g.index]]
        ran = ", ".join(f"{m} {n}" for m, n in ok.groupby("method", sort=False).size().items())
        text = f"{robot}: ran {ran or 'nothing'}"
        for m, gm in bad.groupby("method", sort=False):
            text += f"; {m} did not run ({len(gm)} tasks): {notes[gm.index[0]][len('did not run: '):]}"
        instead = ok[notes[ok.index].str.startswith("ran in place of")]
        for m, gm in instead.groupby("method", sort=False):
            text += f"; {m} ran in place of a peer on {len(gm)} tasks"
        lines.append(text + ".")
    return lines


def continuity_note(table: pd.DataFrame) -> list[str]:
    """'What continuity buys a controller': sentences from the measured figures, per robot."""
    lines = ["## What continuity buys a controller", ""]
    if table.empty:
        return lines + ["No run finished.", ""]
    lines += [f"Spikes: steps whose ‖Δq̇‖/dt exceeds {SPIKE_RAD_S2:g} rad/s². Row turn: ‖Δ(∂d/∂q)‖ per 5 ms step of a "
              "pair that stays within d_i. Smallest distance: every method's trajectory on the same PCH bodies.", ""]
    for robot, g in table.groupby("robot", sort=False):
        by = g.set_index("method")
        lines.append(f"**{robot}** ({int(g.runs.max())} tasks):")

        def each(col, unit=""):
            return ", ".join(f"{m} {_fmt(by.loc[m, col], unit)}" for m in by.index)

        lines.append(f"- rows' turn, 99th percentile (median over tasks): {each('row_turn_p99_median')}; peak: "
                     f"{each('row_turn_peak_worst')}.")
        lines.append(f"- largest acceleration at a closest-feature switch: {each('acc_peak_feature_switch_worst', ' rad/s²')}; "
                     f"spikes there: {each('spikes_feature_switch')}.")
        lines.append(f"- at a row switching on/off: {each('acc_peak_row_switch_worst', ' rad/s²')}; at a row starting or "
                     f"stopping to hold the command: {each('acc_peak_row_binding_worst', ' rad/s²')}; at d_s reached: "
                     f"{each('acc_peak_ds_reached_worst', ' rad/s²')}; at a joint limit: "
                     f"{each('acc_peak_joint_limit_worst', ' rad/s²')}; at a velocity limit: "
                     f"{each('acc_peak_velocity_limit_worst', ' rad/s²')}; at steps with none of these events: "
                     f"{each('acc_peak_no_event_worst', ' rad/s²')}.")
        lines.append(f"- peak acceleration per task (median): {each('acc_peak_median', ' rad/s²')}; total variation of "
                     f"q̇ (median): {each('qdot_tv_median', ' rad/s')}.")
        lines.append(f"- smallest distance on the PCH bodies: {each('min_distance_m_worst', ' m')}; steps below d_s "
                     f"(by over {DS_TOL_M * 1e3:g} mm): "
                     f"{each('steps_below_ds')}; below 0: {each('steps_below_0')}.")
        lines.append(f"- final task error (median): {each('final_task_error_m_median', ' m')}; QP failures: "
                     f"{each('qp_failures')}; steps proxqp left to daqp: {each('qp_fallbacks')}; time per step (median, ms: distances + Jacobians / QP): "
                     + ", ".join(f"{m} {_fmt(by.loc[m, 'ms_distance'])} / {_fmt(by.loc[m, 'ms_qp'])}" for m in by.index)
                     + ".")
        steps = {m: by.loc[m, "ms_step"] for m in by.index}
        if "spq-pch" in steps:
            base = steps["spq-pch"]
            lines.append("- whole control step (median ms: distances, Jacobians, task and QP): " + ", ".join(
                f"{m} {_fmt(v)}" + (f" ({_fmt(v / base)}x spq-pch's)" if m != "spq-pch" and base > 0 else "")
                for m, v in steps.items()) + ".")
        if {"spq-pch", "spq-stp"} <= set(by.index):
            p, s = by.loc["spq-pch"], by.loc["spq-stp"]
            ratio = p.row_turn_p99_median / s.row_turn_p99_median if s.row_turn_p99_median > 0 else np.nan
            lines.append(f"- pch against stp: the rows turn {_fmt(ratio)}x as far per step with pch (99th percentile); "
                         f"feature-switch spikes {int(p.spikes_feature_switch)} with pch, {int(s.spikes_feature_switch)} "
                         f"with stp; all spikes {int(p.spikes)} against {int(s.spikes)}; the stp volume keeps "
                         f"{_fmt(s.min_distance_m_worst - p.min_distance_m_worst, ' m')} more clearance on the PCH "
                         "bodies (it is larger than the hull).")
        lines.append("")
    return lines
