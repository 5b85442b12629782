"""The benchmarks' blocked timing (harness.suites.bench.timing): order of the calls, the sum of each
block's least time, and a slow spell on every round that it sees through. A fake clock stands in for
the machine's, so nothing here depends on this machine's speed."""

from __future__ import annotations

import numpy as np
import pytest

from harness.suites.bench.timing import block_bounds, blocked_calls, blocked_times


class FakeClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def poses(n: int) -> np.ndarray:
    """(n, 4, 4) poses whose [i, 0, 3] is i, so a job can tell which ones it was given."""
    p = np.tile(np.eye(4), (n, 1, 1))
    p[:, 0, 3] = np.arange(n)
    return p


def fake_job(clock: FakeClock, name: str, seconds_per_pose: float, log: list, slow=lambda call: False):
    """A distances call that costs seconds_per_pose a pose on the fake clock, three times that on the
    calls where slow(call index) holds, and logs (name, first pose, poses)."""
    def fn(pa, pb):
        factor = 3.0 if slow(len(log)) else 1.0
        log.append((name, int(pa[0, 0, 3]), len(pa)))
        clock.t += factor * seconds_per_pose * len(pa)
        return pa[:, 0, 3].copy()
    return fn


def test_block_bounds_cover_the_poses_in_near_equal_contiguous_blocks():
    for n, block in [(1, 2000), (2000, 2000), (2001, 2000), (20000, 2000), (2036, 2000), (10, 3), (7, 1)]:
        bounds = block_bounds(n, block)
        assert len(bounds) == -(-n // block)
        assert bounds[0][0] == 0 and bounds[-1][1] == n
        assert all(stop == start for (_, stop), (start, _) in zip(bounds, bounds[1:]))
        sizes = [stop - start for start, stop in bounds]
        assert max(sizes) - min(sizes) <= 1 and max(sizes) <= block
    with pytest.raises(ValueError, match="block must be at least 1"):
        block_bounds(10, 0)


def test_every_job_runs_a_block_before_any_runs_the_next_and_the_results_come_in_order():
    clock, log = FakeClock(), []
    jobs = {"ten": (fake_job(clock, "ten", 1.0, log), poses(10), poses(10)),
            "four": (fake_job(clock, "four", 1.0, log), poses(4), poses(4))}
    timed = blocked_times(jobs, repeats=2, block=3, clock=clock, before_round=lambda: log.append("round"), warm=False)
    one_round = ["round", ("ten", 0, 2), ("four", 0, 2), ("ten", 2, 3), ("four", 2, 2), ("ten", 5, 3), ("ten", 8, 2)]
    assert log == one_round * 2
    log[:] = [entry for entry in log if entry != "round"]
    assert blocked_calls(jobs, 2, 3) == len(log)
    for key, n in (("ten", 10), ("four", 4)):
        seconds, results = timed[key]
        assert seconds == n
        np.testing.assert_array_equal(np.concatenate(results), np.arange(n))


def test_a_slow_spell_in_every_round_is_not_counted_where_the_block_ran_fast_once():
    # job a's block r is three times slower in round r: each of its whole runs holds a slow spell, so
    # the best whole run would count one slow block (a ratio to b of 40/30, not 2); each block ran
    # fast in some round, so the blocked time is the undisturbed one
    clock, log = FakeClock(), []
    calls_per_round = 8  # 4 blocks of 5 poses, two jobs

    def slow(call):
        rnd, k = divmod(call, calls_per_round)
        return k == 2 * rnd  # job a's block `rnd` (a runs first in each block)

    jobs = {"a": (fake_job(clock, "a", 1.0, log, slow), poses(20), poses(20)),
            "b": (fake_job(clock, "b", 2.0, log), poses(20), poses(20))}
    timed = blocked_times(jobs, repeats=3, block=5, clock=clock, warm=False)
    assert [name for name, _, _ in log[:calls_per_round]] == ["a", "b"] * 4
    assert timed["a"][0] == 20.0 and timed["b"][0] == 40.0
    # one round is not enough: its slow block stays
    clock, log = FakeClock(), []
    jobs["a"] = (fake_job(clock, "a", 1.0, log, slow), poses(20), poses(20))
    jobs["b"] = (fake_job(clock, "b", 2.0, log), poses(20), poses(20))
    assert blocked_times(jobs, repeats=1, block=5, clock=clock, warm=False)["a"][0] == 30.0


def cache_job(clock: FakeClock, name: str, seconds_per_pose: float, log: list):
    """A distances call that costs seconds_per_pose a pose on the fake clock, twice that when another
    job ran last (its data evicted, as on a real machine's caches), and logs (name, first pose)."""
    def fn(pa, pb):
        evicted = bool(log) and log[-1][0] != name
        log.append((name, int(pa[0, 0, 3])))
        clock.t += (2.0 if evicted else 1.0) * seconds_per_pose * len(pa)
        return pa[:, 0, 3].copy()
    return fn


def test_warm_times_each_call_after_an_untimed_one_on_its_own_block():
    clock, log = FakeClock(), []
    jobs = {"a": (cache_job(clock, "a", 1.0, log), poses(6), poses(6)),
            "b": (cache_job(clock, "b", 3.0, log), poses(6), poses(6))}
    timed = blocked_times(jobs, repeats=2, block=3, clock=clock)
    one_round = [("a", 0), ("a", 0), ("b", 0), ("b", 0), ("a", 3), ("a", 3), ("b", 3), ("b", 3)]
    assert log == one_round * 2
    assert blocked_calls(jobs, 2, 3) == len(log) // 2  # the untimed calls advance no progress bar
    assert timed["a"][0] == 6.0 and timed["b"][0] == 18.0  # undisturbed: the ratio is 3
    np.testing.assert_array_equal(np.concatenate(timed["b"][1]), np.arange(6))
    # interleaved, every call but the very first finds the other job's data and pays for reloading it:
    # the ratio reads 4
    clock, log = FakeClock(), []
    jobs = {"a": (cache_job(clock, "a", 1.0, log), poses(6), poses(6)),
            "b": (cache_job(clock, "b", 3.0, log), poses(6), poses(6))}
    timed = blocked_times(jobs, repeats=2, block=3, clock=clock, warm=False)
    assert timed["a"][0] == 9.0 and timed["b"][0] == 36.0


def test_bad_rounds_are_refused():
    clock = FakeClock()
    with pytest.raises(ValueError, match="repeats must be at least 1"):
        blocked_times({"a": (fake_job(clock, "a", 1.0, []), poses(3), poses(3))}, repeats=0, clock=clock)
