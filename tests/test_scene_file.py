"""Scene files (harness.workloads.scene_file) and ``spq scene``: the examples in scenes/ parse and run, the CSV
pose source reads back what was written, and mistakes in a file are ValueErrors that say what is wrong."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from harness.workloads import scene_file as sf
from harness.cli import main
from harness.workloads.robot_poses import random_configurations, read_configurations
from tests.conftest import REPO_ROOT, require_shared_datasets

SCENES = REPO_ROOT / "scenes"
KUKA = 'robot = "kuka_iiwa"\n'
RANDOM_POSES = '[poses]\nkind = "random"\ncount = 4\n'


def _write(tmp_path: Path, text: str, name: str = "scene.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _fewer_poses(example: str, tmp_path: Path, key: str, n: int) -> Path:
    """A copy of scenes/<example>.toml in tmp_path with ``key = n`` in [poses]."""
    text, found = re.subn(rf"^{key} = \d+", f"{key} = {n}", (SCENES / f"{example}.toml").read_text(), flags=re.M)
    assert found == 1
    return _write(tmp_path, text, f"{example}.toml")


def _write_configurations(path: Path, names, qs: np.ndarray, order) -> None:
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow([names[k] for k in order])
        writer.writerows([[repr(float(q[k])) for k in order] for q in qs])


def test_every_example_scene_file_parses_to_what_its_comments_say():
    specs = {p.stem: sf.read_scene_file(p) for p in sorted(SCENES.glob("*.toml"))}
    assert set(specs) == {"jvrc1", "kuka_iiwa", "panda"}
    jvrc1 = specs["jvrc1"]
    assert (jvrc1.robot, jvrc1.policy, jvrc1.r, jvrc1.R) == ("jvrc1", "auto", 0.005, 2.0)
    assert (jvrc1.poses.kind, jvrc1.poses.steps, jvrc1.poses.coherent) == ("trajectory", 1000, True)
    for name in ("kuka_iiwa", "panda"):
        spec = specs[name]
        assert spec.robot == name and spec.skip_adjacent
        assert (spec.poses.kind, spec.poses.count, spec.poses.coherent) == ("random", 200, False)


@pytest.mark.parametrize("example", ["kuka_iiwa", "panda"])
def test_pybullet_example_scenes_run_through_the_cli(example, tmp_path, capsys):
    path = _fewer_poses(example, tmp_path, "count", 5)
    assert main(["scene", str(path), "--quiet", "--out", str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out
    assert "pairs per BV" in printed and "configurations  5" in printed and "min distance" in printed
    configs = pd.read_csv(tmp_path / "out" / f"{example}_configurations.csv")
    posture = pd.read_csv(tmp_path / "out" / f"{example}_closest_posture.csv")
    assert len(configs) == 5 and (configs.time_ms > 0).all()
    assert posture.distance_m.min() == configs.min_distance_m.min()
    assert (posture.configuration == configs.min_distance_m.idxmin()).all()
    assert len(posture) == int(re.search(r"^pairs +(\d+)", printed, flags=re.M).group(1))


def test_jvrc1_example_scene_runs_through_the_cli(tmp_path, capsys):
    require_shared_datasets()
    path = _fewer_poses("jvrc1", tmp_path, "steps", 20)
    assert main(["scene", str(path), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "bodies          35" in printed and "configurations  20" in printed


def test_csv_pose_source_gives_the_results_of_the_same_configurations_passed_directly(tmp_path):
    # oracle: the configurations written to the CSV, handed to the same scene without the file
    path = _write(tmp_path, KUKA + '[poses]\nkind = "file"\npath = "poses/q.csv"\n')
    spec = sf.read_scene_file(path)
    scene = sf.build_scene(spec)
    qs = random_configurations(scene.model, 6, seed=3)
    (tmp_path / "poses").mkdir()
    order = np.random.default_rng(0).permutation(scene.model.ndof)
    assert (order != np.arange(scene.model.ndof)).any()
    _write_configurations(tmp_path / "poses" / "q.csv", scene.model.joint_names, qs, order)
    read = sf.scene_configurations(spec, scene.model)
    np.testing.assert_array_equal(read, qs)
    np.testing.assert_array_equal(scene.distances_many(read, spec.poses.coherent),
                                  scene.distances_many(qs, spec.poses.coherent))


@pytest.mark.parametrize("text, expected", [
    (KUKA + "polcy = 'auto'\n" + RANDOM_POSES, ["unknown key ['polcy']", "'policy'"]),
    (KUKA + RANDOM_POSES + "cout = 4\n", ["unknown key ['cout']", "[poses] of kind 'random'", "'count'"]),
    (KUKA + "[skip]\nadjacnt = false\n" + RANDOM_POSES, ["'adjacnt'", "'adjacent'"]),
    ('robot = "kuka"\n' + RANDOM_POSES, ["unknown robot 'kuka'", "'kuka_iiwa'", "'panda'"]),
    (KUKA + 'urdf = "x.urdf"\n' + RANDOM_POSES, ["exactly one robot source"]),
    (KUKA + 'policy = "stp-pch"\n' + RANDOM_POSES, ["unknown policy 'stp-pch'", "'stp-both'"]),
    (KUKA + '[policies]\nlbr_iiwa_link_7 = "stp-both"\n' + RANDOM_POSES, ["policies.lbr_iiwa_link_7", "'cse'"]),
    (KUKA + 'r = "0.005"\n' + RANDOM_POSES, ["r must be a finite number"]),
    (KUKA + "r = 0.5\nR = 0.1\n" + RANDOM_POSES, ["R must be larger than r"]),
    (KUKA + '[poses]\nkind = "random"\ncount = 0\n', ["poses.count must be at least 1"]),
    (KUKA + '[poses]\nkind = "trajectory"\n', ["needs steps"]),
    (KUKA + '[poses]\nkind = "grid"\n', ["poses.kind = 'grid'", "'trajectory'"]),
    (KUKA, ["missing [poses]"]),
], ids=["unknown-key", "unknown-pose-key", "unknown-skip-key", "unknown-robot", "two-robot-sources", "bad-policy",
        "bad-body-policy", "r-not-a-number", "R-below-r", "zero-count", "missing-steps", "unknown-pose-kind",
        "no-poses"])
def test_mistakes_in_a_scene_file_are_value_errors_that_name_them(tmp_path, text, expected):
    path = _write(tmp_path, text)
    with pytest.raises(ValueError) as info:
        sf.read_scene_file(path)
    message = str(info.value)
    assert message.startswith(str(path))
    for part in expected:
        assert part in message


def test_skip_pair_naming_no_body_is_a_value_error_listing_the_bodies(tmp_path):
    path = _write(tmp_path, KUKA + '[skip]\npairs = [["lbr_iiwa_link_1", "link_9"], ["hand", "lbr_iiwa_link_3"]]\n'
                  + RANDOM_POSES)
    spec = sf.read_scene_file(path)
    with pytest.raises(ValueError, match=r"skip.pairs names \['hand', 'link_9'\] not in the scene; bodies: "
                                         r"\['lbr_iiwa_link_0', .*'lbr_iiwa_link_7'\]"):
        sf.build_scene(spec)


def test_policy_for_no_body_is_a_value_error(tmp_path):
    spec = sf.read_scene_file(_write(tmp_path, KUKA + '[policies]\ngripper = "pch"\n' + RANDOM_POSES))
    with pytest.raises(ValueError, match=r"policies name \['gripper'\] not in the scene"):
        sf.build_scene(spec)


def test_csv_with_a_missing_or_unknown_joint_column_is_a_value_error(tmp_path):
    from spq.io.urdf import read_urdf

    from datasets.robots import robot_urdf

    model = read_urdf(robot_urdf("kuka_iiwa"))
    qs = random_configurations(model, 2, seed=0)
    names = list(model.joint_names)
    path = tmp_path / "q.csv"
    _write_configurations(path, names, qs, range(1, len(names)))  # no first joint
    with pytest.raises(ValueError, match=rf"missing joint columns \['{names[0]}'\]"):
        read_configurations(model, path)
    _write_configurations(path, names + ["gripper"], np.hstack([qs, qs[:, :1]]), range(len(names) + 1))
    with pytest.raises(ValueError, match=r"unknown columns \['gripper'\]"):
        read_configurations(model, path)


def test_cli_reports_a_bad_scene_file_as_an_error_not_a_traceback(tmp_path, capsys):
    path = _write(tmp_path, KUKA + 'policy = "fast"\n' + RANDOM_POSES)
    assert main(["scene", str(path)]) == 2
    assert "unknown policy 'fast'" in capsys.readouterr().err
    assert main(["scene", str(tmp_path / "absent.toml")]) == 2


def test_urdf_path_is_relative_to_the_scene_file(tmp_path):
    from datasets.robots import robot_urdf

    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "iiwa").symlink_to(robot_urdf("kuka_iiwa").parent, target_is_directory=True)
    spec = sf.read_scene_file(_write(tmp_path, 'urdf = "robots/iiwa/model.urdf"\npolicy = "pch"\n' + RANDOM_POSES))
    assert spec.urdf == (tmp_path / "robots" / "iiwa" / "model.urdf").resolve() and spec.name == "model"
    assert len(sf.build_scene(spec).pairs) == 21  # 8 links in a chain: 28 pairs less 7 adjacent ones
