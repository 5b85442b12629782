"""The control benchmark (harness/control, ``spq bench control``) on a small robot (example-robot-data's
ur5_robot with the shelf and the wall) and few steps: the damper rows hold along the commanded motion
(checked by finite differences of the scene's own distance, not by the rows), the joint limits are
never crossed, a target out of reach, a start below d_s and a contradictory QP give stated results, and
the suite runs end to end and writes its files."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("qpsolvers")


def _robots_installed() -> bool:
    from datasets.example_robots import package_root

    try:
        package_root()
    except ValueError:
        return False
    return True


pytestmark = pytest.mark.skipif(not _robots_installed(), reason="example-robot-data (pip) ships the test robot")

from harness.suites.control.controller import STATUS_SOLVED, ControlParams, Controller, SpqSource, solve_qp  # noqa: E402
from harness.suites.control.tasks import frozen_mask, make_tasks, setup  # noqa: E402

ROBOT = "ur5_robot"
FD_STEP_S = 1e-6  # s: the finite difference of d along the commanded q̇
RATE_TOL = 2e-4  # m/s: solver tolerance and finite-difference error on ḋ


@pytest.fixture(scope="module")
def scenes():
    from harness.suites.control.scenes import robot_scenes

    return robot_scenes(ROBOT, policies=["pch", "stp"])


@pytest.fixture(scope="module")
def frozen(scenes):
    return frozen_mask(scenes.base.model, setup(ROBOT))


def _run(scenes, policy, task, steps, frozen, params=ControlParams()):
    scene = scenes.by_policy[policy]
    return Controller(scene, SpqSource(scene, params), params, frozen).run(task, steps)


def _distances(scene, q):
    return scene.distances(q, coherent=False, signed=True).distance


def test_commanded_motion_keeps_every_damper_row_by_finite_differences(scenes, frozen):
    """ḋ along the commanded q̇ (central differences of the STP-BV scene's distances, an oracle
    independent of the rows) is at least -ξ (d - ds)/(di - ds) for every pair within di."""
    params = ControlParams()
    scene = scenes.by_policy["stp"]
    task = make_tasks(scenes.base, ROBOT, 1, seed=3)[0]  # the shelf: the hand goes under the board
    log = _run(scenes, "stp", task, 220, frozen, params)
    checked = 0
    for k in range(0, len(log.rows), 4):
        rows = log.rows[k]
        if not len(rows.pairs) or log.status[k] != STATUS_SOLVED:
            continue
        q, qdot = log.q[k], log.qdot[k]
        rate = (_distances(scene, q + FD_STEP_S * qdot) - _distances(scene, q - FD_STEP_S * qdot)) / (2 * FD_STEP_S)
        bound = -params.xi * (rows.distance - params.ds) / (params.di - params.ds)
        assert np.all(rate[rows.pairs] >= bound - RATE_TOL), (k, rate[rows.pairs], bound)
        checked += len(rows.pairs)
    assert checked >= 20, f"only {checked} active (step, pair) rows were checked: the task did not bring pairs near"


def test_joint_limits_are_never_crossed_when_the_target_pulls_past_them(scenes, frozen):
    """A target far beyond the reach pulls the joints to their limits (narrowed here to ±0.3 rad around
    the start, so that the ur5's ±2π are reached): the joint-limit dampers stop every joint short of its
    limits (by joint_ds less the solver tolerance), and q is never clipped."""
    params = ControlParams()
    base = make_tasks(scenes.base, ROBOT, 1, seed=0)[0]
    far = np.array([[[2.0, 0.0, 1.0]], [[2.0, 0.0, 1.0]]])
    task = dataclasses.replace(base, name="far", waypoints=far, durations=np.array([0.3, 0.3]))
    scene = scenes.by_policy["pch"]
    controller = Controller(scene, SpqSource(scene, params), params, frozen)
    controller.lower = np.maximum(controller.lower, task.q0 - 0.3)
    controller.upper = np.minimum(controller.upper, task.q0 + 0.3)
    log = controller.run(task, 300)
    assert log.clipped == 0
    assert np.all(log.q >= controller.lower + params.joint_ds - 1e-6)
    assert np.all(log.q <= controller.upper - params.joint_ds + 1e-6)
    near_limit = np.minimum(log.q - controller.lower, controller.upper - log.q)[:, ~frozen].min()
    assert near_limit < params.joint_di, "the task never brought a joint near its limit"


def test_a_target_out_of_reach_gives_a_stated_task_error(scenes, frozen):
    """A target 3 m above the base: the run ends with its statuses and a final task error, no exception."""
    from harness.suites.control.metrics import run_metrics

    params = ControlParams()
    base = make_tasks(scenes.base, ROBOT, 1, seed=0)[0]
    task = dataclasses.replace(base, name="unreachable", waypoints=np.array([[[0.0, 0.0, 3.0]]]),
                               durations=np.array([0.2]))
    log = _run(scenes, "stp", task, 60, frozen, params)
    row = run_metrics(log, params, scenes.base)
    assert row["final_task_error_m"] > 1.5
    assert all(isinstance(s, str) for s in log.status)
    assert row["qp_failures"] == sum(s != STATUS_SOLVED for s in log.status)


def test_a_singular_task_gives_finite_commands_and_a_stated_error(scenes, frozen):
    """A hand point fixed to the base link (no active joint moves it: its Jacobian is zero) with a target
    away from it: the task is singular, the damping and the posture keep the QP well posed, so every step
    solves with finite commands, the hand cannot move and the task error says so."""
    from harness.suites.control.metrics import run_metrics

    params = ControlParams()
    base = make_tasks(scenes.base, ROBOT, 1, seed=0)[0]
    hand = [(0, np.zeros(3))]  # link 0: the root, moved by no joint
    task = dataclasses.replace(base, name="singular", hands=hand, waypoints=np.array([[[0.3, 0.0, 0.0]]]),
                               durations=np.array([0.1]))
    log = _run(scenes, "pch", task, 40, frozen, params)
    assert all(s == STATUS_SOLVED for s in log.status)
    assert np.isfinite(log.qdot).all() and np.abs(log.qdot).max() < 1e-6
    assert run_metrics(log, params, scenes.base)["final_task_error_m"] == pytest.approx(0.3, abs=1e-9)


def test_a_start_below_ds_gives_a_stated_status(scenes, frozen):
    """An obstacle put through the tool at the start (a pair below ds, overlapping): every step has a
    stated QP status (solved, pushing the pair apart, or failed with q̇ = 0), never an exception, and
    the rows ask for separation (h < 0)."""
    from harness.suites.control.scenes import obstacle_objects
    from spq.scene import Scene

    base = scenes.base
    task = make_tasks(base, ROBOT, 1, seed=0)[0]
    tool = task.hand_points(base, task.q0)[0]
    pose = np.eye(4)
    pose[:3, 3] = tool
    robot_bodies = [b for b in base.bodies if b.link >= 0]
    scene = Scene(base.model, robot_bodies, policy="pch", obstacles=obstacle_objects(
        [("block", np.array([0.03, 0.03, 0.03]), pose)]))
    params = ControlParams()
    log = Controller(scene, SpqSource(scene, params), params, frozen).run(task, 20)
    first = log.rows[0]
    assert len(first.pairs) and first.distance.min() < params.ds
    assert all(s == STATUS_SOLVED or s.startswith("failed") for s in log.status)
    solved = [k for k, s in enumerate(log.status) if s == STATUS_SOLVED]
    for k in solved:  # a solved step moves the deepest pair apart (its row asks for ḋ > 0)
        rows = log.rows[k]
        i = int(np.argmin(rows.distance))
        if rows.distance[i] < params.ds:
            assert rows.jacobian[i] @ log.qdot[k] >= params.xi * (params.ds - rows.distance[i]) / (params.di - params.ds) - RATE_TOL


def test_the_same_qp_fed_by_pinocchio_or_mujoco_commands_what_spq_pch_commands(scenes, frozen):
    """The damper QP fed by pinocchio + coal (computeDistances, joint Jacobians at the witness points) and by
    MuJoCo (mj_geomDistance, mj_jac) on the same hulls commands the same q̇ as fed by spq's PCH scene."""
    pytest.importorskip("pinocchio")
    pytest.importorskip("mujoco")
    from harness.suites.control.runs import run_method

    params = ControlParams()
    task = make_tasks(scenes.base, ROBOT, 1, seed=3)[0]
    runs = {m: run_method(m, task, scenes, params, 120, frozen) for m in ("spq-pch", "pin-damper", "mujoco-damper")}
    assert sum(len(r.pairs) for r in runs["spq-pch"].rows) > 0
    for m in ("pin-damper", "mujoco-damper"):
        np.testing.assert_allclose(runs[m].qdot, runs["spq-pch"].qdot, atol=1e-5, err_msg=m)


def test_contradictory_rows_give_a_failed_status_not_an_exception():
    """Two rows asking q̇_0 >= 1 and q̇_0 <= -1: proxqp finds no solution; the status says so."""
    x, status = solve_qp(np.eye(2), np.zeros(2), np.array([[-1.0, 0.0], [1.0, 0.0]]), np.array([-1.0, -1.0]),
                         -np.ones(2) * 5, np.ones(2) * 5, np.zeros(2))
    assert x is None and status.startswith("failed")


def test_bad_parameters_are_refused_with_the_admissible_range():
    with pytest.raises(ValueError, match="ds < di"):
        ControlParams(di=0.01, ds=0.02)
    with pytest.raises(ValueError, match="tasks must be >= 1"):
        make_tasks(None, ROBOT, 0, 0)


def test_the_suite_runs_end_to_end_and_writes_its_files(tmp_path):
    """spq bench control with tiny settings: every method ran (or says why not), the files are written."""
    from harness.cli import main

    code = main(["bench", "control", "--robots", ROBOT, "--tasks", "1", "--steps", "12", "--quiet",
                 "--out", str(tmp_path)])
    assert code == 0
    for name in ("control.csv", "control.md", "control_runs.csv", "control_robots.csv", "control_qdot_traces.png",
                 "control_acceleration.png", "control_time.png"):
        assert (tmp_path / name).is_file(), name
    import pandas as pd

    runs = pd.read_csv(tmp_path / "control_runs.csv")
    assert set(runs.method) == {"spq-pch", "spq-stp", "spq-cse", "spq-auto", "pink", "mink", "pin-damper", "mujoco-damper"}
    assert not runs.note.astype(str).str.startswith("did not run").any(), runs.note.tolist()
    text = (tmp_path / "control.md").read_text()
    assert "What continuity buys a controller" in text and '"xi": 0.5' in text


def test_the_time_chart_shows_every_bar_above_its_axis_floor(tmp_path, monkeypatch):
    """The log axis's floor lies below the shortest distance bar (autoscale had put it above ur5's spq
    bars, which then did not show): each bar's top, read back from the drawn patches, is above it."""
    import pandas as pd

    import harness.report.charts as charts
    from harness.suites.control import _time_chart

    table = pd.DataFrame({"robot": ["big", "big", "arm", "arm"], "method": ["spq-auto", "mink"] * 2,
                          "ms_distance": [0.09, 0.23, 0.054, 0.096], "ms_qp": [0.41, 0.31, 0.28, 0.19]})
    drawn = {}
    real_save = charts.save_figure
    monkeypatch.setattr(charts, "save_figure", lambda fig, path, title="": (drawn.setdefault("fig", fig),
                                                                            real_save(fig, path, title)))
    _time_chart(table, tmp_path / "t.png")
    ax = drawn["fig"].axes[0]
    floor = ax.get_ylim()[0]
    tops = [bar.get_y() + bar.get_height() for bar in ax.patches]
    assert len(tops) == 2 * len(table) and min(tops) > floor, (floor, min(tops))
    assert (tmp_path / "t.png").stat().st_size > 0
