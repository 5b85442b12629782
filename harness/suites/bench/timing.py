"""How the benchmarks time their jobs: side by side in rounds, each job's least disturbed time kept.

A shared machine's speed swings: on one 2-core host (2026-11-30) a fixed batch of queries, timed
back to back for 8 s, took 1.8x its least time most of the time, with faster spells of 100 to 700 ms.
A whole run of a job either falls in a fast spell or it does not, so the best of a few whole runs
moved one job's rate against another's by up to that swing: the signed plain call's ratio to MuJoCo
read 1.27x to 1.67x over four runs of the same code (docs/notes/speed-45.md, stop 76).

- :func:`best_times` times each job whole, all jobs in turn within each round, and keeps each
  job's least time over the rounds: for jobs that take no poses.
- :func:`blocked_times` cuts the poses into blocks and, in each round, runs every job on the first
  block, then every job on the second, and so on. A job's time is the sum over the blocks of its
  least time on that block. Each block is timed ``repeats`` times, a few milliseconds apart from the
  other jobs' same block, so a slow spell falls on every job alike and a fast one is taken by each
  block separately, not by one job's whole run.

  By default each timed call follows an untimed call of the same job on the same block (``warm``):
  without it a job found its data (hulls, cube maps, a peer's own structures) evicted by the other
  jobs' runs of the block, and paid for reloading it, more the more data it has. That was not
  neutral: on Table I's pairs it slowed coal's and spq's PCH-PCH (a hull and a cube map) and hardly
  a superellipsoid, and moved CSE-CSE's speed ratio from 0.46 (warm) to 0.51 (interleaved), and spq's
  JVRC-1 cold sweep against pinocchio's from 2.18x to 1.98x (docs/notes/speed-45.md, stop 120).
  A user's loop that calls one engine over and over keeps that engine's data in the caches, and
  that is what the benchmarks measure.
"""

from __future__ import annotations

import math
import time

import numpy as np

BLOCK = 2000  # poses per block: a few milliseconds of any engine's loop, long against the timer's resolution


def best_time(fn, repeats: int, setup=None) -> tuple[float, object]:
    """(best seconds, last result) of ``repeats`` timed calls of fn; setup(), if given, runs untimed
    before each."""
    return best_times({None: fn}, repeats, setups={None: setup} if setup is not None else None)[None]


def best_times(jobs: dict, repeats: int, setups: dict | None = None, progress=None) -> dict:
    """{key: (best seconds, last result)} of ``repeats`` rounds over the zero-argument calls in
    ``jobs``, timed in turn within each round, so that a slow spell of a shared machine falls on
    every job alike and the ratios between them stay fair. setups: {key: untimed call before each
    timed one}; progress: a tqdm bar to advance once per timed call."""
    best = {key: (np.inf, None) for key in jobs}
    for _ in range(repeats):
        for key, fn in jobs.items():
            if setups and key in setups:
                setups[key]()
            t0 = time.perf_counter()
            out = fn()
            best[key] = (min(best[key][0], time.perf_counter() - t0), out)
            if progress is not None:
                progress.update(1)
    return best


def block_bounds(n: int, block: int) -> list[tuple[int, int]]:
    """Contiguous (start, stop) ranges covering 0..n, ceil(n / block) of them, of near-equal size."""
    if block < 1:
        raise ValueError(f"block must be at least 1 pose, got {block}")
    count = max(1, math.ceil(n / block))
    edges = [round(i * n / count) for i in range(count + 1)]
    return list(zip(edges[:-1], edges[1:]))


def blocked_times(jobs: dict, repeats: int, block: int = BLOCK, progress=None, clock=time.perf_counter,
                  before_round=None, alternate: bool = False, warm: bool = True) -> dict:
    """{key: (seconds, [result of each block])} for jobs {key: (fn, array, ...)}: fn takes the arrays
    (poses, configurations, an output to fill), all of one length, sliced alike along their first axis.
    In each of ``repeats`` rounds, block k of every job runs before block k + 1 of any (a job on
    fewer rows has fewer blocks); seconds is the sum over a job's blocks of its least time on each.
    The results are the last round's, in block order. progress: a tqdm bar advanced once per timed
    call; clock: the timer (seconds); before_round: an untimed call at the start of each round (a
    scene's reset, so that warm starts carried from block to block start alike in every round);
    alternate: the jobs' order reversed on every other block and round (an A/B of two versions, where
    the job that runs second on a block may find the caches and predictors as the first left them);
    warm: each timed call preceded by an untimed one of the same job on the same block, so that it
    finds its own data in the caches, not the other jobs' (turn it off where a call carries state into
    the next, such as a scene's warm starts, which the untimed call would advance)."""
    if repeats < 1:
        raise ValueError(f"repeats must be at least 1, got {repeats}")
    bounds = {key: block_bounds(len(job[1]), block) for key, job in jobs.items()}
    least = {key: [math.inf] * len(b) for key, b in bounds.items()}
    results = {key: [None] * len(b) for key, b in bounds.items()}
    for r in range(repeats):
        if before_round is not None:
            before_round()
        for k in range(max((len(b) for b in bounds.values()), default=0)):
            keys = list(jobs)
            if alternate and (r + k) % 2 == 1:
                keys.reverse()
            for key in keys:
                fn, *arrays = jobs[key]
                if k >= len(bounds[key]):
                    continue
                start, stop = bounds[key][k]
                parts = [a[start:stop] for a in arrays]
                if warm:
                    fn(*parts)
                t0 = clock()
                out = fn(*parts)
                least[key][k] = min(least[key][k], clock() - t0)
                results[key][k] = out
                if progress is not None:
                    progress.update(1)
    return {key: (math.fsum(least[key]), results[key]) for key in jobs}


def blocked_calls(jobs: dict, repeats: int, block: int = BLOCK) -> int:
    """The timed calls blocked_times makes (for a progress bar's total)."""
    return repeats * sum(len(block_bounds(len(job[1]), block)) for job in jobs.values())
