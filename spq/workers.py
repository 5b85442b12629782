"""Worker threads for batched calls: the admissible ``workers`` argument, the split of a batch into
chunks, and the threads that run them.

The batched kernels (spq.kernels.batch.query_batch, spq.kernels.scene.scene_distances) release the
GIL (``nogil=True``), so several Python threads can run them at once. A batch of N cold queries is
split into contiguous chunks; each chunk is one call of the same kernel on its slice of the poses
(or configurations), with its own copy of the warm-start state and its own scratch, writing its
slice of the result array. A cold query depends only on its own poses (the kernel clears the warm
start before each one), so every query runs exactly the same operations as in a single call: the
results are equal bit for bit whatever the number of threads, and ``workers=1`` is the single call
itself. Warm-started (coherent) batches depend on the order of their queries and stay on one thread.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

MAX_WORKERS = 1024  # threads a call may ask for (more than any machine here has cores)
CHUNKS_PER_WORKER = 4  # chunks per thread: queries differ in cost (overlaps, STP patches), so a thread
                       # that finishes early takes another chunk instead of waiting
MIN_PAIR_QUERIES = 512  # queries per chunk at least (about 1 ms of PCH-PCH): a chunk's hand-off to a
                        # thread and its scratch cost some 20 microseconds
MIN_SCENE_CONFIGURATIONS = 4  # configurations per chunk at least (a robot scene: 0.1 to 1 ms each)

_pools: dict[int, ThreadPoolExecutor] = {}
_pools_lock = threading.Lock()


def check_workers(workers) -> int:
    """``workers`` as an int in 1..MAX_WORKERS, or ValueError naming the admissible range."""
    if type(workers) is int and 1 <= workers <= MAX_WORKERS:  # (not a bool, whose type is bool)
        return workers
    if isinstance(workers, (bool, np.bool_)) or not isinstance(workers, (int, np.integer)):
        raise ValueError(f"workers must be an integer from 1 to {MAX_WORKERS} (1: one thread); got {workers!r}")
    if not 1 <= int(workers) <= MAX_WORKERS:
        raise ValueError(f"workers must be an integer from 1 to {MAX_WORKERS} (1: one thread); got {workers}")
    return int(workers)


def chunk_bounds(n: int, workers: int, min_chunk: int) -> list[tuple[int, int]]:
    """Contiguous (start, stop) ranges covering range(n): up to CHUNKS_PER_WORKER per worker, each
    at least min_chunk long (one range when workers == 1 or n is small), sizes differing by at most 1.
    Where there are at least as many chunks as workers, their count is a multiple of the workers: three
    equal chunks on two threads keep one thread idle for a third of the call (2,000 queries on two
    threads over one: 1.32x to 1.44x in three chunks, 1.43x to 1.63x in two)."""
    if workers <= 1 or n <= min_chunk:
        return [(0, n)]
    count = max(1, min(workers * CHUNKS_PER_WORKER, n // min_chunk))
    if count >= workers:
        count -= count % workers
    base, extra = divmod(n, count)
    bounds, start = [], 0
    for k in range(count):
        stop = start + base + (1 if k < extra else 0)
        bounds.append((start, stop))
        start = stop
    return bounds


def _pool(workers: int) -> ThreadPoolExecutor:
    """A pool of ``workers`` threads, created on first use and kept for later calls."""
    with _pools_lock:
        pool = _pools.get(workers)
        if pool is None:
            pool = _pools[workers] = ThreadPoolExecutor(max_workers=workers, thread_name_prefix=f"spq-{workers}")
        return pool


def map_chunks(fn, bounds: list[tuple[int, int]], workers: int) -> list:
    """[fn(start, stop) for each range], on ``workers`` threads (in the calling thread when there is
    one range); results in the order of ``bounds``. An exception in any chunk is raised here."""
    if len(bounds) == 1 or workers <= 1:
        return [fn(start, stop) for start, stop in bounds]
    return list(_pool(workers).map(lambda b: fn(*b), bounds))
