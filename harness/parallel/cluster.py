"""Running a suite's independent tasks on several processes or on a Dask cluster, with the serial
run's results.

A suite that can spread its work (crosscheck, stability, the fuzz campaign, scene sweeps) cuts it
into tasks that each carry their own seed or their own pre-drawn poses (a crosscheck object pair
with its seed ``seed + k``, a stability case, a few fuzz cases by index), runs ``fn(task)`` for
each, and reassembles the results in task order: the output is the serial run's whatever ran
where. A task carries a small spec; what is heavy to build (engines and their child processes,
compiled kernels) is built once per worker process (:func:`process_cache`) and kept while the
workers live: for one call of :func:`run_tasks`, or for as long as a :class:`TaskRunner` is open (a
campaign's rounds). Three ways to run them:

- ``workers=1`` and no scheduler: in this process, one after the other (the serial run itself);
- ``workers=N`` and no scheduler: N processes on this machine, this one and N - 1 spawned ones (the
  external engines hold the GIL, so threads would not help); this process, whose modules are loaded
  already, starts on the first task while the others start up. Each runs its linear algebra on one
  thread (threadpoolctl), so that N workers keep N cores busy, as Dask's workers do by default;
- ``scheduler="local"``: a Dask ``LocalCluster`` of ``workers`` single-threaded processes on this
  machine, set up as LOCAL_CLUSTER_CONFIG says; ``scheduler="tcp://HOST:8786"``: the workers of an
  existing Dask cluster (see docs/clusters.md). Tasks are submitted in order, two per worker thread at
  most, so that a longest-first order holds.

Dask is optional (``pip install "dask[distributed]"``) and imported only for a scheduler. Timing
benchmarks never come here: a time measured on another machine or beside other tasks means nothing.
"""

from __future__ import annotations

import atexit
import itertools
import multiprocessing as mp
import os
import uuid
from collections.abc import Callable, Iterable, Sequence
from contextlib import ExitStack, contextmanager

from spq.workers import check_workers

DASK_HINT = 'pip install "dask[distributed]"'
LOCAL = "local"  # scheduler value that starts a Dask LocalCluster on this machine
DASK_IN_FLIGHT = 2  # tasks submitted per Dask worker thread at most: one running, one ready to start


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
    in this process as each task finishes (progress). An exception in a task is raised here. The
    workers live for this call only: a caller with several batches (a campaign's rounds) keeps one
    :class:`TaskRunner` open instead."""
    with TaskRunner(workers, scheduler) as runner:
        return runner.run(fn, tasks, order, done)


class TaskRunner:
    """The workers of the module docstring, started once and kept for any number of batches, so that
    what they built for their first tasks (process_cache: engines and their child processes, compiled
    kernels, loaded objects) serves every later one; a context manager, closed on exit.

    workers: processes (scheduler None: this one and workers - 1 spawned ones, started with the first
    batch that needs them; scheduler "local": the Dask LocalCluster's size); scheduler: None, "local"
    or a Dask scheduler address. What this process built for its tasks is closed on exit."""

    def __init__(self, workers: int = 1, scheduler: str | None = None):
        self.workers = check_workers(workers)
        self.scheduler = check_scheduler(scheduler)
        self._stack = ExitStack()
        self._pool = None
        self._client = None
        self._as_completed = None
        self._keys = itertools.count()
        self._tag = uuid.uuid4().hex[:12]
        self._cached_before: set = set()

    def __enter__(self) -> "TaskRunner":
        self._cached_before = set(_CACHE)
        if self.scheduler is not None:
            self._client, self._as_completed = self._stack.enter_context(dask_client(self.scheduler, self.workers))
        return self

    def __exit__(self, *exc) -> None:
        try:
            self._stack.close()
        finally:
            _close_cached(set(_CACHE) - self._cached_before)

    def describe(self) -> str:
        return describe(self.workers, self.scheduler)

    def run(self, fn: Callable, tasks: Sequence, order: Sequence[int] | None = None,
            done: Callable | None = None) -> list:
        """[fn(task) for task in tasks], handed out in ``order`` (default as given), results in task
        order; done(index, result) in this process as each finishes; a task's exception raised here."""
        order = list(range(len(tasks))) if order is None else list(order)
        if sorted(order) != list(range(len(tasks))):
            raise ValueError("order must be a permutation of the task indices")
        results = [None] * len(tasks)

        def finish(i: int, result) -> None:
            results[i] = result
            if done:
                done(i, result)

        keyed = ((i, tasks[i]) for i in order)
        if self.scheduler is None and len(tasks) <= 1:
            for i, task in keyed:
                finish(i, fn(task))
        else:
            self.stream(fn, keyed, finish)
        return results

    def stream(self, fn: Callable, tasks: Iterable, done: Callable) -> None:
        """fn(task) for each (key, task) of the iterable ``tasks``, which is drawn from lazily, one
        item each time a worker is free (so it may decide on the way when to stop: a time budget),
        and done(key, result) called in this process as each task ends, one call at a time. A
        task's exception is raised here, after the tasks under way have ended (local processes)."""
        if self.scheduler is not None:
            self._stream_dask(fn, tasks, done)
        elif self.workers == 1:
            for key, task in tasks:
                done(key, fn(task))
        else:
            self._stream_here_and_in_children(fn, tasks, done)

    def on_each_worker(self, fn: Callable, *args) -> dict:
        """{worker address: fn(*args)} run as a task on every worker of the Dask cluster (warming it
        up: imports, compiled kernels, process_cache); tasks, not client.run, so that a long warm-up
        (kernels compiled anew) does not stall the worker's heartbeats."""
        if self._client is None:
            raise ValueError("on_each_worker needs a Dask scheduler (local processes start with their first batch)")
        addresses = list(self._client.scheduler_info()["workers"])
        futures = {a: self._client.submit(fn, *args, key=self._key(), workers=[a], allow_other_workers=False,
                                          pure=False) for a in addresses}
        return {a: f.result() for a, f in futures.items()}

    def _key(self) -> str:
        return f"spq-task-{self._tag}-{next(self._keys)}"

    def _stream_dask(self, fn: Callable, tasks: Iterable, done: Callable) -> None:
        """Tasks submitted in order, DASK_IN_FLIGHT per worker thread at most (the scheduler starts
        them in submission order, so a longest-first order holds), the next one submitted as each ends."""
        client = self._client
        window = DASK_IN_FLIGHT * max(1, sum(client.nthreads().values()))
        source = iter(tasks)
        keys: dict = {}

        def submit():
            item = next(source, None)
            if item is None:
                return None
            key, task = item
            future = client.submit(fn, task, key=self._key(), pure=False)
            keys[future.key] = key
            return future

        first = []
        while len(first) < window and (future := submit()) is not None:
            first.append(future)
        queue = self._as_completed(first)
        for future in queue:
            done(keys.pop(future.key), future.result())
            if (following := submit()) is not None:
                queue.add(following)

    def _children(self):
        """The workers - 1 spawned processes (started on first use, kept until exit)."""
        if self._pool is None:
            from concurrent.futures import ProcessPoolExecutor

            self._pool = self._stack.enter_context(ProcessPoolExecutor(
                max_workers=self.workers - 1, mp_context=mp.get_context("spawn"), initializer=one_blas_thread))
        return self._pool

    def _stream_here_and_in_children(self, fn: Callable, tasks: Iterable, done: Callable) -> None:
        """stream on this process and the workers - 1 spawned ones: each takes the next task as it
        becomes free (a thread here hands the children theirs)."""
        import threading

        from threadpoolctl import threadpool_limits

        source = iter(tasks)
        lock = threading.Lock()
        failures: list[BaseException] = []
        pool = self._children()

        def take():
            with lock:
                if failures:
                    return None
                try:
                    return next(source, None)
                except BaseException as exc:
                    failures.append(exc)
                    return None

        def finish(key, result) -> None:
            with lock:
                done(key, result)

        def feed() -> None:  # a thread per child process: its next task, until none is left
            try:
                while (item := take()) is not None:
                    finish(item[0], pool.submit(fn, item[1]).result())
            except BaseException as exc:
                failures.append(exc)

        with threadpool_limits(limits=1):
            feeders = [threading.Thread(target=feed, daemon=True) for _ in range(self.workers - 1)]
            for t in feeders:
                t.start()
            try:
                while (item := take()) is not None:
                    finish(item[0], fn(item[1]))
            except BaseException as exc:
                failures.append(exc)
            finally:
                for t in feeders:
                    t.join()
        if failures:
            raise failures[0]


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


# The LocalCluster's Dask settings, each against a loss measured on the crosscheck (issue 44):
LOCAL_CLUSTER_CONFIG = {
    # a task starts the native engines' child processes, which a daemonic worker may not
    "distributed.worker.daemon": False,
    # Dask's default (65536) for its workers fixes glibc's mmap threshold at 128 KiB: every array of
    # 128 KiB or more is then mapped and unmapped, page by page, at each allocation; the reference's
    # hulls took some 40 % more CPU so (2.5x the page faults) than in a plain process. Unset, a
    # worker allocates as the serial run does.
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
}
MALLOC_HINT = ("DASK_DISTRIBUTED__NANNY__PRE_SPAWN_ENVIRON='{\"MALLOC_TRIM_THRESHOLD_\": None}' dask worker ...")


@contextmanager
def dask_client(scheduler: str, workers: int):
    """A Dask client on a LocalCluster of ``workers`` single-threaded processes (scheduler "local",
    set as LOCAL_CLUSTER_CONFIG says) or on the cluster at ``scheduler``; closed on exit. The
    environment variables the LocalCluster's nannies set in this process for their workers (one
    BLAS thread, the hash seed) are undone on exit."""
    config, Client, LocalCluster, as_completed = import_dask()
    if scheduler == LOCAL:
        environ = dict(os.environ)
        with config.set(LOCAL_CLUSTER_CONFIG):
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None)
            client = Client(cluster)
            try:
                yield client, as_completed
            finally:
                client.close()
                cluster.close()
                _restore_environ(environ)
        return
    try:
        client = Client(scheduler, timeout="30s")
    except OSError as exc:
        raise ValueError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}") from None
    try:
        warn_about_malloc_trim(client)
        yield client, as_completed
    finally:
        client.close()


def _restore_environ(environ: dict) -> None:
    for name in set(os.environ) - set(environ):
        del os.environ[name]
    for name, value in environ.items():
        if os.environ.get(name) != value:
            os.environ[name] = value


def worker_malloc_trim() -> str | None:
    """This process's MALLOC_TRIM_THRESHOLD_ (a Dask worker's, run there), None when unset."""
    return os.environ.get("MALLOC_TRIM_THRESHOLD_")


def warn_about_malloc_trim(client) -> None:
    """A warning, naming the fix, when workers of the cluster run with MALLOC_TRIM_THRESHOLD_ set
    (Dask's default for the workers a nanny starts): their tasks take some 40 % more CPU."""
    import warnings

    try:
        set_on = [a for a, v in client.run(worker_malloc_trim).items() if v is not None]
    except Exception:  # a worker that cannot answer is no reason to stop the run
        return
    if set_on:
        warnings.warn(f"{len(set_on)} Dask worker(s) run with MALLOC_TRIM_THRESHOLD_ set (Dask's default), "
                      "which costs the crosscheck and the fuzz campaign some 40 % more CPU; start the workers "
                      f"with {MALLOC_HINT} (see docs/clusters.md)", stacklevel=3)


def check_may_start_children(what: str) -> None:
    """RuntimeError, naming the fix, if this process may not start child processes (a Dask worker
    started as a daemon): the native engines run in children."""
    if mp.current_process().daemon:
        raise RuntimeError(f"{what} starts child processes for the native engines, which a daemonic process "
                           "cannot: start the Dask workers with DASK_DISTRIBUTED__WORKER__DAEMON=False "
                           "(see docs/clusters.md)")


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
