"""The robot benchmark's jump test, on gradients known in closed form, and a small run on the KUKA iiwa."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from harness.cli import main
from harness.suites.robot import robot_bench as rb


class _Result:
    pass


class _Scene:
    """A stand-in scene whose pair-0 distance gradient is a given function of q."""

    def __init__(self, gradient):
        self.gradient = gradient

    def distances(self, q, coherent=False, signed=False):
        return _Result()

    def distance_gradient(self, q, result, pair):
        return self.gradient(np.asarray(q, dtype=float))


@pytest.mark.parametrize("where", [0.1, 0.5, 0.937])
def test_bisection_keeps_a_jump_whole_wherever_it_lies(where):
    scene = _Scene(lambda q: np.array([1.0 if q[0] > where else -1.0, q[0]]))
    residual = rb.bisect_change(scene, np.array([0.0]), np.array([1.0]), 0)
    # the change is (2, 1): the step of 2 stays whole, the continuous part shrinks to 1/1024
    assert residual == pytest.approx(2.0 / np.sqrt(5.0), abs=1e-3)


@pytest.mark.parametrize("gradient", [lambda q: np.array([q[0], 2.0 * q[0]]),
                                      lambda q: np.array([np.sin(3.0 * q[0]), np.exp(q[0])]),
                                      lambda q: np.array([np.tanh(50.0 * (q[0] - 0.4)), 0.0])])
def test_bisection_shrinks_a_continuous_change(gradient):
    residual = rb.bisect_change(_Scene(gradient), np.array([0.0]), np.array([1.0]), 0)
    assert residual < 0.05 < rb.JUMP_RESIDUAL  # even the steep tanh (slope 50) shrinks to about 50/1024 of its change


def test_gradient_jumps_counts_only_confirmed_jumps_and_leaves_pair_changes_apart():
    qs = np.linspace(0.0, 1.0, 101)[:, None]
    scene = _Scene(lambda q: np.array([np.sign(q[0] - 0.3037), q[0]]))
    grads = np.array([scene.gradient(q) for q in qs])
    closest = np.zeros(101, dtype=int)
    closest[80:] = 1  # a pair change: not counted as a jump whatever the gradient does there
    grads[80:] += 5.0
    stats = rb.gradient_jumps(scene, qs, {"gradient": grads, "closest": closest})
    assert stats["closest_pair_switches"] == 1
    assert stats["gradient_jumps_same_pair"] == 1 and list(stats["jump_steps"]) == [31]


def test_bench_robot_on_the_kuka_writes_its_tables_and_figures_and_agrees_with_coal(tmp_path):
    code = main(["bench", "robot", "--robot", "kuka_iiwa", "--configs", "30", "--steps", "60", "--repeats", "1",
                 "--engines", "coal", "--quiet", "--out", str(tmp_path)])
    assert code == 0
    for name in ("robot_kinematics.csv", "robot_scene.csv", "robot_engines.csv", "robot_continuity.csv", "robot_engines.png",
                 "robot_trajectory.png", "robot_distance_matrix.png"):
        assert (tmp_path / name).stat().st_size > 0
    scene = pd.read_csv(tmp_path / "robot_scene.csv")
    assert len(scene) == 12 and (scene.pairs == 21).all() and (scene.failed == 0).all()
    fk = pd.read_csv(tmp_path / "robot_kinematics.csv").iloc[0]
    assert fk.configurations == 30 and fk.max_position_error_m <= 1e-9 and fk.max_rotation_entry_error <= 1e-9
    engines = pd.read_csv(tmp_path / "robot_engines.csv").set_index("engine")
    assert engines.loc["coal", "max_abs_diff_vs_spq_m"] <= 1e-7


@pytest.mark.parametrize("coherent", [False, True])
def test_blockwise_timing_gives_the_results_of_one_call(coherent):
    """best_run times blocks of configurations in separate calls; the warm starts carry across the
    blocks, so its results must be those of one call over all of them (the oracle), bit for bit."""
    from harness.workloads.robot_poses import random_configurations, smooth_trajectory

    config = rb.RobotBenchConfig(robot="kuka_iiwa")
    scene = rb.load_scene(config, "auto")
    qs = smooth_trajectory(scene.model, 37, 0) if coherent else random_configurations(scene.model, 37, 0)
    scene.reset()
    whole = scene.distances_many(qs, coherent=coherent).copy()
    seconds, out = rb.best_run(scene, qs, coherent, None, repeats=2, block=5)
    assert seconds > 0.0
    np.testing.assert_array_equal(out, whole)
    _, threaded = rb.best_run(scene, qs, coherent, None, repeats=1, block=20, workers=2)  # bench robot --workers 2
    assert threaded.tobytes() == whole.tobytes()
    with pytest.raises(ValueError, match="repeats and block"):
        rb.best_run(scene, qs, coherent, None, repeats=0)


def test_the_scene_table_keeps_each_rows_least_time_over_its_passes(monkeypatch):
    """A slow spell of the machine can outlast one row's runs, so the table goes through all its rows
    `passes` times and each row keeps its least time, whichever pass it came from, with the results of
    one call over the configurations (the oracle)."""
    from harness.workloads.robot_poses import random_configurations, smooth_trajectory

    config = rb.RobotBenchConfig(robot="kuka_iiwa", policies=("pch",), passes=3)
    model = rb.load_scene(config, "pch").model
    randoms, trajectory = random_configurations(model, 7, 0), smooth_trajectory(model, 7, 0)
    jobs = 4  # (random cold, trajectory coherent) x (all pairs, pruned)
    scripted = iter([4.0, 1.0, 6.0, 2.0, 3.0, 5.0, 1.5, 2.5, 2.0, 0.5, 7.0, 9.0])  # pass by pass, row by row
    real = rb.best_run
    monkeypatch.setattr(rb, "best_run", lambda *a, **k: (next(scripted), real(*a, **k)[1]))
    table, scenes, results = rb.scene_table(config, randoms, trajectory, progress=False)
    assert len(table) == jobs
    np.testing.assert_allclose(table.ms_per_config, np.array([2.0, 0.5, 1.5, 2.0]) * 1e3 / 7)
    whole = scenes["pch"]
    whole.reset()
    np.testing.assert_array_equal(results["pch"], whole.distances_many(randoms, coherent=False))
    with pytest.raises(ValueError, match="passes"):
        rb.scene_table(rb.RobotBenchConfig(robot="kuka_iiwa", passes=0), randoms, trajectory, progress=False)
