"""Running a suite's independent tasks on several processes or on a Dask cluster, with the serial
run's results.

A suite that can spread its work (crosscheck, stability) cuts it into tasks that each carry their
own seed or their own pre-drawn poses (a crosscheck object pair with its seed ``seed + k``, a
stability case), runs ``fn(task)`` for each, and reassembles the results in task order: the output
is the serial run's whatever ran where. Three ways to run them:

- ``workers=1`` and no scheduler: in this process, one after the other (the serial run itself);
- ``workers=N`` and no scheduler: N processes on this machine, this one and N - 1 spawned ones (the
  external engines hold the GIL, so threads would not help); this process, whose modules are loaded
  already, starts on the first task while the others start up. Each runs its linear algebra on one
  thread (threadpoolctl), so that N workers keep N cores busy, as Dask's workers do by default;
- ``scheduler="local"``: a Dask ``LocalCluster`` of ``workers`` processes on this machine;
  ``scheduler="tcp://HOST:8786"``: the workers of an existing Dask cluster (see the README).

Dask is optional (``pip install "dask[distributed]"``) and imported only for a scheduler. Timing
benchmarks never come here: a time measured on another machine or beside other tasks means nothing.
"""

from __future__ import annotations

import atexit
import multiprocessing as mp
import os
from collections.abc import Callable, Sequence
from contextlib import contextmanager

from spq.workers import check_workers

DASK_HINT = 'pip install "dask[distributed]"'
LOCAL = "local"  # scheduler value that starts a Dask LocalCluster on this machine


def check_scheduler(scheduler) -> str | None:
    """None, "local" or a scheduler address ("tcp://host:port", "host:port"); ValueError otherwise."""
    if scheduler is None:
        return None
    if not isinstance(scheduler, str) or not scheduler.strip() or any(c.isspace() for c in scheduler.strip()):
        raise ValueError(f"scheduler must be None, {LOCAL!r} or a Dask scheduler address such as "
                         f"'tcp://10.0.0.5:8786'; got {scheduler!r}")
    return scheduler.strip()


def describe(workers: int = 1, scheduler: str | None = None) -> str:
    """How tasks run, in words (for a run's metadata)."""
    if scheduler is None:
        return "serial" if workers == 1 else f"{workers} local processes"
    return f"Dask LocalCluster of {workers} processes" if scheduler == LOCAL else f"Dask cluster at {scheduler}"


def run_tasks(fn: Callable, tasks: Sequence, workers: int = 1, scheduler: str | None = None,
              order: Sequence[int] | None = None, done: Callable | None = None) -> list:
    """[fn(task) for task in tasks], run as the module docstring says; results in task order.

    fn: a module-level function (it is pickled by name). order: the order in which to hand the
    tasks out (longest first balances the workers); default as given. done(index, result): called
    in this process as each task finishes (progress). An exception in a task is raised here."""
    workers = check_workers(workers)
    scheduler = check_scheduler(scheduler)
    order = list(range(len(tasks))) if order is None else list(order)
    if sorted(order) != list(range(len(tasks))):
        raise ValueError("order must be a permutation of the task indices")
    results = [None] * len(tasks)
    if scheduler is None and (workers == 1 or len(tasks) <= 1):
        for i in order:
            results[i] = fn(tasks[i])
            if done:
                done(i, results[i])
        return results
    if scheduler is None:
        return _run_here_and_in_children(fn, tasks, min(workers, len(tasks)), order, done)
    with dask_client(scheduler, workers) as (client, as_completed):
        futures = [client.submit(fn, tasks[i], key=f"spq-task-{os.getpid()}-{id(tasks)}-{i}", pure=False)
                   for i in order]
        index = {f.key: i for f, i in zip(futures, order)}
        for future in as_completed(futures):
            i = index[future.key]
            results[i] = future.result()
            if done:
                done(i, results[i])
    return results


def _run_here_and_in_children(fn: Callable, tasks: Sequence, workers: int, order: list, done) -> list:
    """run_tasks on this process and workers - 1 spawned ones: each takes the next task in ``order``
    as it becomes free (a thread here hands the children theirs). What this process built for its
    tasks (process_cache) is closed at the end."""
    import threading
    from concurrent.futures import ProcessPoolExecutor

    results = [None] * len(tasks)
    pending = iter(order)
    lock = threading.Lock()
    failures: list[BaseException] = []
    cached_before = set(_CACHE)

    def take():
        with lock:
            return None if failures else next(pending, None)

    def finish(i: int, result) -> None:
        results[i] = result
        if done:
            with lock:
                done(i, result)

    def feed(pool) -> None:  # a thread per child process: its next task, until none is left
        try:
            while (i := take()) is not None:
                finish(i, pool.submit(fn, tasks[i]).result())
        except BaseException as exc:
            failures.append(exc)

    from threadpoolctl import threadpool_limits

    with ProcessPoolExecutor(max_workers=workers - 1, mp_context=mp.get_context("spawn"),
                             initializer=one_blas_thread) as pool, threadpool_limits(limits=1):
        feeders = [threading.Thread(target=feed, args=(pool,), daemon=True) for _ in range(workers - 1)]
        for t in feeders:
            t.start()
        try:
            while (i := take()) is not None:
                finish(i, fn(tasks[i]))
        except BaseException as exc:
            failures.append(exc)
        finally:
            for t in feeders:
                t.join()
            _close_cached(set(_CACHE) - cached_before)
    if failures:
        raise failures[0]
    return results


def one_blas_thread() -> None:
    """Limit this process's BLAS and OpenMP pools to one thread (a worker is one core): OpenBLAS's
    threads on the reference's small matrices cost more than they gain, and beside another worker
    they oversubscribe the cores."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1)


def import_dask():
    """(dask.config, distributed.Client, distributed.LocalCluster, distributed.as_completed), or a
    ValueError naming the install command when Dask is missing."""
    try:
        import dask.config
        from distributed import Client, LocalCluster, as_completed
    except ImportError as exc:
        raise ValueError(f"running on a Dask cluster (--scheduler) needs Dask's distributed scheduler, which is "
                         f"not installed ({exc}); install it with: {DASK_HINT}") from None
    return dask.config, Client, LocalCluster, as_completed


@contextmanager
def dask_client(scheduler: str, workers: int):
    """A Dask client on a LocalCluster of ``workers`` single-threaded processes (scheduler "local")
    or on the cluster at ``scheduler``; closed on exit. Local workers are not daemonic processes, so
    that a task may start the child processes the native engines are judged in."""
    config, Client, LocalCluster, as_completed = import_dask()
    if scheduler == LOCAL:
        with config.set({"distributed.worker.daemon": False}):
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None)
            client = Client(cluster)
            try:
                yield client, as_completed
            finally:
                client.close()
                cluster.close()
        return
    try:
        client = Client(scheduler, timeout="30s")
    except OSError as exc:
        raise ValueError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}") from None
    try:
        yield client, as_completed
    finally:
        client.close()


def check_may_start_children(what: str) -> None:
    """RuntimeError, naming the fix, if this process may not start child processes (a Dask worker
    started as a daemon): the native engines run in children."""
    if mp.current_process().daemon:
        raise RuntimeError(f"{what} starts child processes for the native engines, which a daemonic process "
                           "cannot: start the Dask workers with DASK_DISTRIBUTED__WORKER__DAEMON=False "
                           "(see the README, 'On a cluster')")


_CACHE: dict = {}  # key -> (value, close or None)


def process_cache(key, build: Callable, close: Callable | None = None):
    """build() once per process and key, kept for the process's later tasks (engines, whose child
    processes take seconds to start), and closed with close(value) when the process exits (or, in the
    process that hands out the tasks, when they are done)."""
    if key not in _CACHE:
        value = build()
        _CACHE[key] = (value, close)
        if close is not None:
            atexit.register(close, value)
    return _CACHE[key][0]


def _close_cached(keys) -> None:
    for key in keys:
        value, close = _CACHE.pop(key)
        if close is not None:
            atexit.unregister(close)
            close(value)
