"""An engine run in a child process, so that a native crash costs the queries it hit, not the run.

Some engines end the interpreter on rare inputs: python-fcl's libccd EPA throws a C++ exception that
nothing catches ("The origin is outside of the polytope", std::terminate) on some touching poses.
:class:`IsolatedEngine` serves a registered engine from a child process (multiprocessing, spawn).
When the child dies during a batch, or stays silent past a time limit that grows with the batch (a
hang), a fresh one takes over and the batch is split in halves until the poses that kill it are found; those come back as status "failed" with the reason, the others
with the engine's own answers. Results are the engine's, bit for bit (arrays cross the pipe as they
are); only the time per query grows (one round trip per call), so timing suites use the engine
in-process.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from contextlib import contextmanager

import numpy as np

from harness.engines.base import (
    BatchResult,
    Engine,
    EngineResult,
    PreparedPair,
    as_mesh,
    failed_result,
)

CRASHED = "the engine's process died on this query (a native crash) or did not answer in time (a hang)"
HANG_BASE_S = 2.0  # a child silent for longer than this plus HANG_PER_QUERY_S per query is hung: it is
HANG_PER_QUERY_S = 0.002  # killed and the batch split as after a crash (seen: python-fcl looping on one pose
MAX_HANGS_PER_PAIR = 16  # of a 1e-3 m hull); enough to bisect a batch of 2000 down to one hanging pose, after
# which a pair's unanswered rows stay "failed" (an engine hanging on every pose of a pair would cost hours)
PREPARE_QUERIES = 10_000  # loading two bodies may take as long as this many queries (a BVH over a big mesh)
NATIVE = ("fcl", "coal", "bullet", "bullet-margin", "mujoco")  # the built-in engines of native code, judged in children


def _serve(conn, name: str, plugin: str | None) -> None:
    """The child: build engine ``name`` (registered from ``plugin``, "module:Class", if given) and
    answer requests until told to stop or the pipe closes."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)  # a native abort's message would only clutter the parent's output
    from harness.engines import available_engines, register_plugin

    if plugin:
        register_plugin(plugin, name)

    engine = available_engines([name])[name]
    engine.warm_up()  # before the info is sent: the parent's time limits apply to queries only
    pair = None
    conn.send((engine.tolerance, bool(getattr(engine, "gives_depth", False)), engine.version()))
    while True:
        try:
            op, payload = conn.recv()
        except EOFError:
            break
        if op == "stop":
            break
        try:
            if op == "prepare":
                if pair is not None:
                    pair.close()
                pair = engine.prepare(*payload)
                conn.send(("ok", None))
            elif op == "query_many":
                # a built-in engine's batch was checked by the parent (IsolatedPair.query_many), which
                # spares the child spq's import; a plugin's own query_many is its API
                r = (pair.query_many if plugin else pair.query_checked)(*payload)
                conn.send(("ok", (r.distance, r.point_a, r.point_b, r.status, r.raw_distance)))
            elif op == "query":
                r = pair.query(*payload)
                conn.send(("ok", (r.distance, r.point_a, r.point_b, r.status, r.raw_distance, r.message)))
            else:
                conn.send(("error", f"unknown request {op!r}"))
        except Exception as exc:  # reported to the parent, which raises it there
            conn.send(("error", f"{type(exc).__name__}: {exc}"))
    if pair is not None:
        pair.close()
    engine.close()


_BLAS_THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


@contextmanager
def _one_blas_thread_env():
    """The environment a child is started in: one BLAS thread. It serves one query at a time, and
    OpenBLAS's pool, started on every core when the child imports numpy, doubled each child's
    start-up CPU (measured: 5 engine children 1.86 s, 1.16 s with one thread)."""
    saved = {k: os.environ.get(k) for k in _BLAS_THREAD_VARS}
    os.environ.update({k: "1" for k in _BLAS_THREAD_VARS})
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


class WorkerDied(Exception):
    """The child process ended while answering (hung: it was killed for not answering in time)."""

    def __init__(self, hung: bool = False):
        super().__init__("hung" if hung else "died")
        self.hung = hung


class _Worker:
    """One child process serving one engine; ``call`` raises WorkerDied if the child died."""

    def __init__(self, name: str, plugin: str | None = None):
        ctx = mp.get_context("spawn")
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_serve, args=(child, name, plugin), daemon=True)
        with _one_blas_thread_env():
            self.proc.start()
        child.close()
        try:
            self.info = self.conn.recv()
        except EOFError:
            self.proc.join()
            raise ImportError(f"engine {name!r} could not be started in a child process") from None

    def call(self, op: str, payload, queries: int = 1):
        try:
            self.conn.send((op, payload))
            if not self.conn.poll(HANG_BASE_S + HANG_PER_QUERY_S * queries):
                self.proc.kill()
                self.proc.join(timeout=5)
                raise WorkerDied(hung=True)
            status, value = self.conn.recv()
        except (EOFError, BrokenPipeError, ConnectionResetError):
            self.proc.join(timeout=5)
            raise WorkerDied from None
        if status == "error":
            raise RuntimeError(value)
        return value

    def stop(self) -> None:
        try:
            self.conn.send(("stop", None))
        except (BrokenPipeError, OSError):
            pass
        self.proc.join(timeout=5)
        if self.proc.is_alive():
            self.proc.kill()
        self.conn.close()


class IsolatedPair(PreparedPair):
    def __init__(self, engine: "IsolatedEngine", a, b):
        self._engine = engine
        self._shapes = engine.sent(a), engine.sent(b)  # pickled across the pipe
        self._hangs = 0
        self._prepare()

    def _prepare(self) -> None:
        try:
            self._engine.worker().call("prepare", self._shapes, PREPARE_QUERIES)
        except WorkerDied:
            self._engine.restart()
            raise RuntimeError("the engine's process died while loading the bodies") from None

    def _run(self, op: str, payload, queries: int = 1):
        """The child's answer, or None if it died or hung (a fresh child then holds this pair again)."""
        try:
            return self._engine.worker().call(op, payload, queries)
        except WorkerDied as exc:
            self._hangs += exc.hung
            self._engine.restart()
            self._prepare()
            return None

    def _query(self, pose_a, pose_b) -> EngineResult:
        out = self._run("query", (pose_a, pose_b))
        if out is None:
            return failed_result(CRASHED)
        d, pa, pb, status, raw, message = out
        return EngineResult(d, pa, pb, status, raw, message)

    def query_many(self, poses_a, poses_b) -> BatchResult:
        poses_a, poses_b = self._check_batches(poses_a, poses_b)
        out = BatchResult.empty(len(poses_a))
        self._fill(out, poses_a, poses_b, np.arange(len(poses_a)))
        return out

    def _fill(self, out: BatchResult, poses_a, poses_b, rows: np.ndarray) -> None:
        """Answer ``rows`` in one call; if the child dies, in halves, down to the rows that kill it
        (left "failed", as BatchResult.empty made them)."""
        if len(rows) == 0:
            return
        if self._hangs >= MAX_HANGS_PER_PAIR:
            return
        got = self._run("query_many", (poses_a[rows], poses_b[rows]), len(rows))
        if got is not None:
            out.distance[rows], out.point_a[rows], out.point_b[rows], out.status[rows], out.raw_distance[rows] = got
            return
        if len(rows) == 1:
            return
        half = len(rows) // 2
        self._fill(out, poses_a, poses_b, rows[:half])
        self._fill(out, poses_a, poses_b, rows[half:])


class IsolatedEngine(Engine):
    """The registered engine ``name`` (or the plugin "module:Class" registered as ``name`` in the
    child), served from a child process (see the module docstring)."""

    def __init__(self, name: str, plugin: str | None = None):
        self.name = name
        self._plugin = plugin
        self._worker = None
        w = self.worker()
        self.tolerance, self.gives_depth, self._version = w.info

    def worker(self) -> _Worker:
        if self._worker is None:
            self._worker = _Worker(self.name, self._plugin)
        return self._worker

    def restart(self) -> None:
        if self._worker is not None:
            self._worker.stop()
        self._worker = None

    def sent(self, shape):
        """What goes to the child for ``shape``: for a built-in engine, which reads vertices and faces
        only, a :class:`~harness.engines.base.Mesh` (the child then need not import spq); for a
        plugin, the shape itself."""
        return shape if self._plugin else as_mesh(shape)

    def prepare(self, a, b) -> IsolatedPair:
        return IsolatedPair(self, a, b)

    def version(self) -> str:
        return self._version

    def close(self) -> None:
        self.restart()


def isolated(engines: dict) -> dict:
    """The engines to judge: the built-in native ones (NATIVE) served from child processes, so that a
    native crash fails its queries instead of ending the run; the others (spq, plugins) as they are.
    The caller closes both the given engines and the returned ones."""
    def builtin(e) -> bool:  # not a plugin registered under a built-in name
        return type(e).__module__.startswith("harness.engines.")

    return {name: IsolatedEngine(name) if name in NATIVE and builtin(e) else e for name, e in engines.items()}
