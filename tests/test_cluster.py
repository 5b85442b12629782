"""Suites spread over processes or a Dask cluster (harness.parallel.cluster): the oracle is the serial run of
the same suite, whose tables the spread run must reproduce exactly (timing columns aside)."""

from __future__ import annotations

import json
import os
import time

import pandas as pd
import pytest

from harness.parallel import cluster
from harness.suites import crosscheck

TIMING = ("time_us", "median_time_us")  # wall times: never equal between two runs, serial or not


def tiny_crosscheck(**spread) -> crosscheck.Config:
    return crosscheck.Config(objects=["kuka_link_4", "panda_link_5", "random_hull_50"], per_bucket=3, seed=3,
                             engines=["spq", "coal"], buckets=["distant-2.5", "close-1e-3", "touching", "overlap-1e-2"],
                             agreement_poses=300, **spread)


def assert_same_tables(serial, spread) -> None:
    assert [t.stem for t in serial.tables] == [t.stem for t in spread.tables]
    frames = {**{t.stem: (t.frame, u.frame) for t, u in zip(serial.tables, spread.tables)},
              **{name: (serial.raw[name], spread.raw[name]) for name in serial.raw}}
    assert set(serial.raw) == set(spread.raw)
    for stem, (a, b) in frames.items():
        keep = [c for c in a.columns if c not in TIMING]
        pd.testing.assert_frame_equal(a[keep], b[keep], check_exact=True, obj=stem)


@pytest.fixture(scope="module")
def serial_crosscheck():
    pytest.importorskip("coal")
    return crosscheck.run(tiny_crosscheck())


@pytest.mark.engines
def test_a_crosscheck_on_two_processes_equals_the_serial_run(serial_crosscheck):
    assert_same_tables(serial_crosscheck, crosscheck.run(tiny_crosscheck(workers=2)))


def require_dask():
    try:
        cluster.import_dask()
    except ValueError as exc:
        if os.environ.get("CI"):
            pytest.fail(f"Dask is missing under CI (the README's set-up installs it): {exc}")
        pytest.skip(f"Dask is not installed ({cluster.DASK_HINT})")


@pytest.fixture(scope="module")
def dask_scheduler():
    """The address of a Dask LocalCluster of 2 processes (harness.parallel.cluster's, as --scheduler local starts
    it), shared by the tests that run on it: they reach it as a remote cluster, by address."""
    require_dask()
    with cluster.dask_client(cluster.LOCAL, 2) as (client, _):
        yield client.scheduler.address


@pytest.mark.engines
def test_a_crosscheck_on_a_dask_local_cluster_equals_the_serial_run(serial_crosscheck, dask_scheduler):
    assert_same_tables(serial_crosscheck, crosscheck.run(tiny_crosscheck(scheduler=dask_scheduler)))


@pytest.mark.parametrize("bad", [0, -1, 2.0, "2", None])
def test_bad_workers_raise_naming_the_admissible_range(bad):
    with pytest.raises(ValueError, match="workers must be an integer from 1 to"):
        crosscheck.run(tiny_crosscheck(workers=bad))


@pytest.mark.parametrize("bad", ["", "tcp://a b", 8786])
def test_a_bad_scheduler_is_named(bad):
    with pytest.raises(ValueError, match="scheduler must be None, 'local' or a Dask scheduler address"):
        cluster.check_scheduler(bad)


def test_missing_dask_gives_the_install_command(monkeypatch):
    import builtins

    real = builtins.__import__

    def no_dask(name, *args, **kwargs):
        if name.split(".")[0] in ("dask", "distributed"):
            raise ImportError(f"No module named {name!r}")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_dask)
    with pytest.raises(ValueError, match=r'pip install "dask\[distributed\]"'):
        cluster.run_tasks(abs, [1, 2], workers=2, scheduler="local")


def test_tasks_come_back_in_task_order_whatever_the_hand_out_order():
    assert cluster.run_tasks(abs, [-3, 1, -2], order=[2, 0, 1]) == [3, 1, 2]
    assert cluster.run_tasks(abs, list(range(-6, 0)), workers=2, order=[5, 4, 3, 2, 1, 0]) == [6, 5, 4, 3, 2, 1]


@pytest.mark.engines
def test_stability_cases_on_a_dask_local_cluster_equal_the_serial_run(dask_scheduler):
    pytest.importorskip("coal")
    from datasets import load_object
    from harness.engines import available_engines
    from harness.engines.isolated import isolated
    from harness.suites.stability import hard_cases as st

    cases = st.build_cases(st.StabilityConfig(quick=True), load_object)[::8]
    plain = available_engines(["spq", "coal"])
    judged = isolated(plain)
    try:
        serial = st.run_cases(cases, judged)
    finally:
        for engine in [*plain.values(), *judged.values()]:
            engine.close()
    spread = st._run_spread(cases, st.CaseTask(None, ("spq", "coal")), 1, dask_scheduler, progress=False)
    keep = [c for c in serial.columns if c not in TIMING]
    assert len(serial) >= 20
    pd.testing.assert_frame_equal(serial[keep], spread[keep], check_exact=True)


@pytest.fixture(scope="module")
def arm_sweep():
    import numpy as np

    import spq
    from datasets.robots import ROBOTS
    from harness.workloads import scene_run as sr

    files = ROBOTS["kuka_iiwa"]
    scene = spq.Scene.from_urdf(files.urdf, mesh_root=files.mesh_root, policy="pch")
    rng = np.random.default_rng(11)
    qs = np.array([scene.random_configuration(rng) for _ in range(sr.SPREAD_BLOCK + 44)])  # two blocks
    return scene, qs, sr.run_scene(scene, qs, coherent=False, prune=0.05)


def assert_same_sweep(serial, spread) -> None:
    import numpy as np

    for name in ("min_distance", "min_pair", "min_status", "overlapping"):
        assert np.array_equal(getattr(serial, name), getattr(spread, name)), name
    assert serial.status_counts == spread.status_counts and serial.closest == spread.closest
    for name in ("distance", "point_a", "point_b", "normal", "lower_bound", "upper_bound", "iterations"):
        a, b = getattr(serial.closest_result, name), getattr(spread.closest_result, name)
        assert a.tobytes() == b.tobytes(), name


def test_a_cold_scene_sweep_on_threads_equals_the_serial_run(arm_sweep):
    from harness.workloads import scene_run as sr

    scene, qs, serial = arm_sweep
    assert_same_sweep(serial, sr.run_scene_spread(scene, qs, prune=0.05, workers=2))


def test_a_cold_scene_sweep_on_a_dask_local_cluster_equals_the_serial_run(arm_sweep, dask_scheduler):
    from harness.workloads import scene_run as sr

    scene, qs, serial = arm_sweep
    assert_same_sweep(serial, sr.run_scene_spread(scene, qs, prune=0.05, scheduler=dask_scheduler))


def tiny_campaign(**where):
    """A small fuzz campaign (harness.suites.fuzz.campaign): three families, 12 cases of 40 pose pairs, coal as
    the peer, rounds of 3 one-case tasks; its state after the run."""
    from harness.suites.fuzz.campaign import CampaignConfig, run

    config = CampaignConfig(seed=7, families=["primitives", "hull-needle", "cse"], poses=40,
                            peers=["coal"], cases_per_task=1)
    return run(config, None, max_queries=12 * 2 * 40, tasks_per_round=3, **where)


def assert_same_campaign(serial, spread) -> None:
    from harness.suites.fuzz.campaign import table

    assert (spread.next_case, spread.rounds) == (serial.next_case, serial.rounds) == (12, 4)
    pd.testing.assert_frame_equal(table(serial), table(spread), check_exact=True)
    assert json.dumps(spread.bad) == json.dumps(serial.bad)


@pytest.fixture(scope="module")
def serial_campaign():
    pytest.importorskip("coal")
    return tiny_campaign()


@pytest.mark.engines
def test_a_fuzz_campaign_on_a_dask_local_cluster_equals_the_serial_run(serial_campaign, dask_scheduler):
    assert_same_campaign(serial_campaign, tiny_campaign(scheduler=dask_scheduler))


@pytest.mark.engines
def test_a_fuzz_campaign_on_two_processes_equals_the_serial_run(serial_campaign):
    assert_same_campaign(serial_campaign, tiny_campaign(workers=2))


def pid_after(seconds: float) -> int:
    """The id of the process that ran this task, after ``seconds`` of sleep (so that every worker takes some)."""
    time.sleep(seconds)
    return os.getpid()


def test_a_runner_keeps_its_worker_processes_from_batch_to_batch():
    with cluster.TaskRunner(2) as runner:
        first = set(runner.run(pid_after, [0.2] * 6))
        second = set(runner.run(pid_after, [0.2] * 6))
    assert os.getpid() in first and len(first) == 2 and second == first


def test_a_failing_task_raises_its_error_here():
    with pytest.raises(ValueError, match="invalid literal"):
        cluster.run_tasks(int, ["1", "x", "3", "4"], workers=2)
