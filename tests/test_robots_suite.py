"""`spq bench robots` on a tiny setting: one row per robot with the table's columns, a robot that
cannot load listed with its reason, spq against coal and pinocchio on the rows that ran, and the
command line's sizes (the robot suite keeps its own)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from harness.cli import build_parser, main
from harness.suites.robots import robots_bench as rsb

pytest.importorskip("pinocchio", reason="pin not installed (pip install pin)")
try:
    from datasets.example_robots import package_root

    package_root()
except ValueError as exc:
    pytest.skip(str(exc), allow_module_level=True)

pytestmark = pytest.mark.engines


@pytest.fixture(scope="module")
def robots_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("robots")
    code = main(["bench", "robots", "--robots", "double_pendulum_simple", "ur3", "ur5_robot", "quadrotor_base",
                 "--configs", "4", "--steps", "6", "--engine-configs", "2", "--repeats", "1", "--quiet",
                 "--out", str(out)])
    return code, out


def test_one_row_per_robot_with_the_table_columns(robots_run):
    code, out = robots_run
    assert code == 0
    table = pd.read_csv(out / "robots.csv")
    assert list(table.columns) == rsb.COLUMNS
    assert list(table.robot) == ["double_pendulum_simple", "ur3", "ur5_robot", "quadrotor_base"]
    assert (out / "robots.md").read_text().startswith("# example-robot-data")
    assert (out / "robots_time_vs_pairs.png").stat().st_size > 10_000


def test_a_robot_that_fails_is_listed_with_its_reason(robots_run):
    table = pd.read_csv(robots_run[1] / "robots.csv").set_index("robot")
    assert table.loc["ur3", "status"] == "failed"
    assert "not a readable URDF" in table.loc["ur3", "reason"] and "site-packages" not in table.loc["ur3", "reason"]
    assert table.loc["quadrotor_base", "status"] == "no pairs"
    assert "no pair to query" in table.loc["quadrotor_base", "reason"]


def test_the_rows_that_ran_agree_with_coal_and_pinocchio(robots_run):
    table = pd.read_csv(robots_run[1] / "robots.csv").set_index("robot")
    ran = table[table.status == "ran"]
    assert list(ran.index) == ["double_pendulum_simple", "ur5_robot"]
    assert (ran.pairs == [1, 21]).all() and (ran.bodies == [3, 8]).all()
    for column in ("pch_cold_ms", "auto_cold_ms", "pch_coherent_ms", "auto_coherent_ms", "pinocchio_ms"):
        assert (ran[column] > 0).all() and np.isfinite(ran[column]).all(), column
    assert np.allclose(ran.pinocchio_over_pch, ran.pinocchio_ms / ran.pch_cold_ms)
    # coal (1e-8 m) and pinocchio (coal's 1e-6 m) against spq's PCH distances on separated pairs
    assert (ran.coal_max_diff_m.fillna(0) < 1e-7).all() and (ran.pinocchio_max_diff_m.fillna(0) < 1e-5).all()
    assert (ran.coal_overlap_disagreements == 0).all() and (ran.pinocchio_overlap_disagreements == 0).all()
    assert ran.loc["ur5_robot", "pinocchio_variant"] in ("default", "cached-guess", "nesterov", "nesterov-cached")


def test_unknown_robots_are_refused_by_name():
    from harness.suites import robots

    with pytest.raises(ValueError, match="unknown robots \\['nope'\\]"):
        robots.run(robots.Config(robots=["nope"]))


def test_sizes_default_per_suite_and_mode(monkeypatch):
    import harness.cli as cli
    from harness.suites import robots

    seen = {}

    def capture(name, config, out):
        seen[name] = config
        return 0

    monkeypatch.setattr(cli, "run_suite", capture)
    for argv in (["bench", "robot"], ["bench", "robots"]):
        args = build_parser().parse_args(argv)
        args.func(args)
    assert (seen["robot"].configs, seen["robot"].steps) == (1000, 1000)
    assert (seen["robots"].configs, seen["robots"].steps) == (None, None)
    full, quick = robots.resolved(robots.Config()), robots.resolved(robots.Config(quick=True))
    assert (full.configs, full.steps, full.engine_configs) == tuple(robots.FULL.values())
    assert (quick.configs, quick.steps, quick.engine_configs) == tuple(robots.QUICK.values())
    with pytest.raises(ValueError, match="configs must be >= 1"):
        robots.resolved(robots.Config(configs=0))
