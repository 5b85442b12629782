"""Batched queries and scene sweeps on several threads (spq.workers): the oracle is the same call on
one thread, whose results the threaded run must reproduce bit for bit (every field, NaNs included),
leaving the same warm-start state behind."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import spq
from datasets import load_object
from datasets.robots import ROBOTS
from harness.workloads.poses import random_poses
from spq.workers import CHUNKS_PER_WORKER, MAX_WORKERS, chunk_bounds

N_POSES = 2048  # 4 chunks on 2 threads (MIN_PAIR_QUERIES = 512)
FIELDS = ("distance", "point_a", "point_b", "normal", "status_code", "iterations", "lower_bound", "upper_bound")


def assert_bitwise_equal(a: np.ndarray, b: np.ndarray, what: str) -> None:
    a, b = np.asarray(a), np.asarray(b)
    assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), what
    assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), f"{what}: not equal bit for bit"


@pytest.fixture(scope="module")
def link():
    return load_object("kuka_link_4")


@pytest.fixture(scope="module")
def poses(link):
    return random_poses(N_POSES, seed=3, translation_range=1.2 * link.bounding_radius())


def shapes(kind: str, link):
    if kind == "pch":
        return link, link
    if kind == "stp":
        return spq.STPBV.from_points(link.vertices, r=0.005, R=2.0), link
    return spq.Superellipsoid.fit(link.vertices).shape, spq.Superellipsoid(0.05, 0.08, 0.12, 0.5, 0.8)


@pytest.mark.parametrize("signed", [False, True])
@pytest.mark.parametrize("kind", ["pch", "stp", "cse"])
def test_two_workers_give_the_one_worker_results_bit_for_bit(kind, signed, link, poses):
    a, b = shapes(kind, link)
    one = spq.distances(a, b, *poses, signed=signed)
    two = spq.distances(a, b, *poses, signed=signed, workers=2)
    assert (one.status_code == 2).any() and (one.status_code == 0).any()  # both overlaps and separations
    for name in FIELDS:
        assert_bitwise_equal(getattr(one, name), getattr(two, name), f"{kind} signed={signed}: {name}")
    assert list(one.status) == list(two.status)


def test_a_broadcast_pose_and_the_pair_state_after_a_threaded_batch(link, poses):
    pa, pb = poses
    p1, p2 = spq.Pair(link, link), spq.Pair(link, link)
    one = p1.distances(pa[0], pb, coherent=False)
    two = p2.distances(pa[0], pb, coherent=False, workers=3)
    assert_bitwise_equal(one.distance, two.distance, "distance")
    assert_bitwise_equal(p1._ints, p2._ints, "warm-start ints")  # the state the last query left
    assert_bitwise_equal(p1._floats, p2._floats, "warm-start floats")
    after1, after2 = p1.distances(pa[:50], pb[:50]), p2.distances(pa[:50], pb[:50])  # coherent: uses that state
    assert_bitwise_equal(after1.distance, after2.distance, "coherent batch after")


def test_a_coherent_batch_runs_on_one_thread_and_equals_it(link, poses):
    pa, pb = poses
    one = spq.distances(link, link, pa, pb, coherent=True)
    two = spq.distances(link, link, pa, pb, coherent=True, workers=2)
    assert_bitwise_equal(one.distance, two.distance, "distance")


def test_a_bad_pose_is_named_by_its_index_with_threads(link, poses):
    pa, pb = (p.copy() for p in poses)
    pb[1500, 0, 0] = np.nan
    with pytest.raises(ValueError) as one:
        spq.distances(link, link, pa, pb)
    with pytest.raises(ValueError) as two:
        spq.distances(link, link, pa, pb, workers=2)
    assert "1500 contains NaN" in str(two.value) and str(one.value) == str(two.value)


@pytest.mark.parametrize("bad", [0, -1, 1.5, "2", None, True, MAX_WORKERS + 1])
def test_bad_workers_raise_naming_the_admissible_range(bad, link, poses):
    with pytest.raises(ValueError, match=f"workers must be an integer from 1 to {MAX_WORKERS}"):
        spq.distances(link, link, *poses, workers=bad)


def test_chunks_cover_the_batch_in_order():
    for n, workers, least in [(10, 2, 4), (2048, 2, 512), (1000, 3, 7), (5, 8, 1), (0, 2, 1)]:
        bounds = chunk_bounds(n, workers, least)
        assert bounds[0][0] == 0 and bounds[-1][1] == n
        assert all(b[1] == c[0] for b, c in zip(bounds, bounds[1:]))
        assert len(bounds) == 1 or min(b - a for a, b in bounds) >= least
    assert chunk_bounds(10_000, 1, 4) == [(0, 10_000)]
    assert chunk_bounds(2_000, 2, 512) == [(0, 1_000), (1_000, 2_000)]  # not three chunks on two threads


@settings(max_examples=300, deadline=None)
@given(n=st.integers(0, 100_000), workers=st.integers(1, 16), least=st.integers(1, 2_000))
def test_chunks_share_evenly_between_the_workers(n, workers, least):
    bounds = chunk_bounds(n, workers, least)
    sizes = [b - a for a, b in bounds]
    assert bounds[0][0] == 0 and bounds[-1][1] == n and sum(sizes) == n
    assert max(sizes) - min(sizes) <= 1
    assert len(bounds) <= max(1, workers * CHUNKS_PER_WORKER)
    if len(bounds) > 1:
        assert min(sizes) >= least
    if len(bounds) >= workers:  # no thread left idle for a whole chunk's time at the end
        assert len(bounds) % workers == 0


# ---------------------------------------------------------------- scenes


@pytest.fixture(scope="module")
def kuka():
    files = ROBOTS["kuka_iiwa"]
    return spq.Scene.from_urdf(files.urdf, mesh_root=files.mesh_root, policy="auto")


@pytest.fixture(scope="module")
def configurations(kuka):
    rng = np.random.default_rng(5)
    return np.array([kuka.random_configuration(rng) for _ in range(64)])


@pytest.mark.parametrize("prune, signed", [(None, False), (None, True), (0.05, False)])
def test_a_cold_scene_sweep_on_two_threads_equals_one_bit_for_bit(kuka, configurations, prune, signed):
    kuka.reset()
    one = kuka.distances_many(configurations, prune=prune, signed=signed)
    ints, floats = kuka._pair_ints.copy(), kuka._pair_floats.copy()
    kuka.reset()
    two = kuka.distances_many(configurations, prune=prune, signed=signed, workers=2)
    assert_bitwise_equal(one, two, "scene results (distance, points, normal, status, bounds, iterations)")
    assert_bitwise_equal(ints, kuka._pair_ints, "pairs' warm-start ints after the sweep")
    assert_bitwise_equal(floats, kuka._pair_floats, "pairs' warm-start floats after the sweep")


def test_a_coherent_scene_sweep_stays_serial(kuka, configurations):
    kuka.reset()
    one = kuka.distances_many(configurations, coherent=True)
    kuka.reset()
    two = kuka.distances_many(configurations, coherent=True, workers=2)
    assert_bitwise_equal(one, two, "coherent scene results")


def test_a_scene_sweep_rejects_bad_workers(kuka, configurations):
    with pytest.raises(ValueError, match="workers must be an integer from 1"):
        kuka.distances_many(configurations, workers=0)
