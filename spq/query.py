"""distance(), distances() and Pair: the public face of the compiled GJK (and EPA).

Frames and units: shapes live in their local frames; poses are 4x4 homogeneous matrices mapping
local to world coordinates (batches N x 4 x 4); every returned point and normal is in the world
frame, in metres.

Signed distance (``signed=True``): an overlapping pair gets distance = -depth, the depth being the
length of the shortest translation of B that separates the bodies. For both signs, ``normal`` is
the unit vector from A to B (for an overlap: the direction B must move to separate), point_a lies
on A's surface and point_b on B's, and point_b - point_a = distance * normal. The bounds are
certified: lower_bound <= true signed distance <= upper_bound, and ``distance`` is the upper bound.
Without it (the default) an overlap gives distance 0, NaN witness points, and the bounds bound the
unsigned distance.

Per-call entry points: where spq's C extension was built (spq._entry, setup.py), distance,
Pair.distance and Pair.cold_distance are its compiled entries, which call the kernel directly and
hand anything unusual (another pair, a pose of another type or layout, a rejected pose, unknown
keywords) to the Python functions below, kept as their ``__wrapped__``: the same answers, bit for bit,
and the same errors.
"""

from __future__ import annotations

import functools
import math
import threading
import warnings

import numpy as np

from spq.kernels import batch as kb
from spq.kernels.gjk import (
    OUT_DISTANCE,
    OUT_UPPER,
    OUT_ITERATIONS,
    OUT_LOWER,
    OUT_NORMAL,
    OUT_POINT_A,
    OUT_POINT_B,
    OUT_SIZE,
    OUT_STATUS,
    STATUS_NAMES,
)
from spq.shapes.base import Shape
from spq.validation import as_poses
from spq.workers import MIN_PAIR_QUERIES, check_workers, chunk_bounds, map_chunks

try:  # the per-call entry points in C (setup.py); without them, the Python ones below
    from spq import _entry
except ImportError:
    _entry = None

DEFAULT_TOL_ABS = 1e-10  # m: stop when upper - lower bound <= TOL_ABS + TOL_REL * distance
DEFAULT_TOL_REL = 1e-10  # m/m
DEFAULT_MAX_ITER = 128  # GJK iterations; polytope queries here converge in about 5 to 20

_STATUS_ARRAY = np.array(STATUS_NAMES)
_POSE_PROBLEM = {
    kb.POSE_NOT_FINITE: "contains NaN or inf",
    kb.POSE_BAD_BOTTOM_ROW: "has a bottom row other than (0, 0, 0, 1)",
    kb.POSE_NOT_ROTATION: f"has a rotation block that is not a rotation (tolerance {kb.ROTATION_TOL})",
}


class _ResultFields:
    """DistanceResult's fields, read from its result array (spq._entry.result_type's has them in C)."""

    # no __init__: a class with one of its own costs about 30 ns more to make, and object.__new__ 25 ns
    # more, of a 2 us call; the queries fill both slots (_result)
    __slots__ = ("_out", "distance")

    point_a = property(lambda self: self._out[OUT_POINT_A:OUT_POINT_A + 3].copy())
    point_b = property(lambda self: self._out[OUT_POINT_B:OUT_POINT_B + 3].copy())
    normal = property(lambda self: self._out[OUT_NORMAL:OUT_NORMAL + 3].copy())
    status = property(lambda self: STATUS_NAMES[int(self._out[OUT_STATUS])])
    iterations = property(lambda self: int(self._out[OUT_ITERATIONS]))
    lower_bound = property(lambda self: float(self._out[OUT_LOWER]))
    upper_bound = property(lambda self: float(self._out[OUT_UPPER]))


_RESULT_DOC = """Result of one query (world frame, metres).

    distance: >= 0, 0 when overlapping; with ``signed=True``, -depth when overlapping (a float
    attribute, the others are read from the result vector on demand).
    point_a, point_b: witness points on A and B (NaN when overlapping, unless signed).
    normal: unit vector from A to B (for a signed overlap: the direction B must move).
    status: 'separated' | 'touching' (within tol of contact) | 'overlapping' | 'failed'.
    iterations: GJK (plus EPA) iterations. lower_bound, upper_bound: certified bounds on the
    distance (the signed distance when signed); distance == upper_bound.

    With spq's C extension (spq._entry) the result vector lives in the object and the fields are
    read in C (a vector field in about 80 ns instead of 300), and the type is made there
    (``_entry.result_type``); without it, the Python class below. Either way ``_out`` is the result
    vector (OUT_SIZE floats), set by the queries.
    """


def _result_repr(self) -> str:
    return (f"DistanceResult(distance={self.distance:.12g}, status={self.status!r}, "
            f"iterations={self.iterations}, lower_bound={self.lower_bound:.12g}, "
            f"upper_bound={self.upper_bound:.12g})")


def _result_reduce(self):
    return _result, (self._out,)


if _entry is not None:
    # made in C, not a Python subclass: a class statement's type takes part in the garbage collector,
    # whose bookkeeping and the subclass's deallocation a plain call paid for its result
    DistanceResult = _entry.result_type(_RESULT_DOC)
    DistanceResult.__repr__ = _result_repr
    DistanceResult.__reduce__ = _result_reduce
else:
    class DistanceResult(_ResultFields):
        __doc__ = _RESULT_DOC
        __slots__ = ()
        __repr__ = _result_repr
        __reduce__ = _result_reduce


def _result(out: np.ndarray) -> DistanceResult:
    """The DistanceResult of one query's result array."""
    result = DistanceResult()
    result._out = out
    result.distance = float(out[OUT_DISTANCE])
    return result


class BatchDistances:
    """Results of N queries as arrays (world frame, metres); fields as in DistanceResult.

    distance (N,), point_a (N, 3), point_b (N, 3), normal (N, 3), status (N,) str,
    status_code (N,) int8 (index into spq.STATUS_NAMES), iterations (N,) int, lower_bound (N,),
    upper_bound (N,).

    point_a, point_b and normal are views into the one (N, OUT_SIZE) array the kernel wrote (rows
    of OUT_SIZE floats, so not C-contiguous): copying them cost about 24 ns a query (1% to 4% of a
    batched query, by pair kind). Every field is made on first access: making them took 2 us of a
    one-pair robot's 12 us per-step call (:meth:`spq.Scene.distances`), and a velocity damper
    (spq.control) reads the kernel's rows directly, so inside a control loop even the distance's copy
    and the three views cost a tenth of a small arm's damper call.
    """

    def __init__(self, out: np.ndarray):
        self._rows = out  # the kernel's result rows (a fresh array of each call), which the fields read

    @functools.cached_property
    def distance(self) -> np.ndarray:
        """(N,) float64 m (a copy)."""
        return self._rows[:, OUT_DISTANCE].copy()

    @functools.cached_property
    def point_a(self) -> np.ndarray:
        """(N, 3) float64, a view of the result rows."""
        return self._rows[:, OUT_POINT_A:OUT_POINT_A + 3]

    @functools.cached_property
    def point_b(self) -> np.ndarray:
        """(N, 3) float64, a view of the result rows."""
        return self._rows[:, OUT_POINT_B:OUT_POINT_B + 3]

    @functools.cached_property
    def normal(self) -> np.ndarray:
        """(N, 3) float64, a view of the result rows."""
        return self._rows[:, OUT_NORMAL:OUT_NORMAL + 3]

    @functools.cached_property
    def status_code(self) -> np.ndarray:
        """(N,) int8: each query's index into spq.STATUS_NAMES."""
        return self._rows[:, OUT_STATUS].astype(np.int8)

    @functools.cached_property
    def iterations(self) -> np.ndarray:
        """(N,) int64: GJK (plus EPA) iterations of each query."""
        return self._rows[:, OUT_ITERATIONS].astype(np.int64)

    @functools.cached_property
    def lower_bound(self) -> np.ndarray:
        """(N,): certified lower bounds on the distances."""
        return self._rows[:, OUT_LOWER].copy()

    @functools.cached_property
    def upper_bound(self) -> np.ndarray:
        """(N,): certified upper bounds on the distances."""
        return self._rows[:, OUT_UPPER].copy()

    @functools.cached_property
    def status(self) -> np.ndarray:
        """(N,) str: each query's STATUS_NAMES entry."""
        return _STATUS_ARRAY[self.status_code]

    def __len__(self) -> int:
        return len(self.distance)


def _check_tolerances(tol, rel_tol, max_iter) -> tuple[float, float, int]:
    tol, rel_tol = float(tol), float(rel_tol)
    for name, val in (("tol", tol), ("rel_tol", rel_tol)):
        if not math.isfinite(val) or val < 0.0:
            raise ValueError(f"{name} must be finite and >= 0; got {val}")
    if tol == 0.0 and rel_tol == 0.0:
        raise ValueError("tol and rel_tol cannot both be 0: GJK on curved shapes would never stop")
    if int(max_iter) < 1:
        raise ValueError(f"max_iter must be >= 1; got {max_iter}")
    return tol, rel_tol, int(max_iter)


def _check_shape(shape, name: str) -> None:
    if not isinstance(shape, Shape):
        raise ValueError(f"{name} must be an spq shape (Polyhedron, Sphere, Box, Capsule, ...); got {type(shape).__name__}")


def check_signed(signed) -> bool:
    if not isinstance(signed, (bool, np.bool_)):
        raise ValueError(f"signed must be True or False; got {signed!r}")
    return bool(signed)


def _pack(A: Shape, B: Shape, tol, rel_tol, max_iter, signed) -> tuple[np.ndarray, np.ndarray]:
    _check_shape(A, "A")
    _check_shape(B, "B")
    tol, rel_tol, max_iter = _check_tolerances(tol, rel_tol, max_iter)
    ka, kb_ = A.kernel_data(), B.kernel_data()
    # one element at a time: a fancy-indexed write of the four took about 4 us, a third of a Pair's making
    ints = np.zeros(kb.INTS_SIZE, dtype=np.int64)
    ints[kb.I_KIND_A], ints[kb.I_KIND_B], ints[kb.I_MAX_ITER] = ka.kind, kb_.kind, max_iter
    ints[kb.I_SIGNED] = check_signed(signed)
    floats = np.zeros(kb.FLOATS_SIZE)
    floats[kb.F_MARGIN_A], floats[kb.F_MARGIN_B], floats[kb.F_TOL_ABS], floats[kb.F_TOL_REL] = (
        ka.margin, kb_.margin, tol, rel_tol)
    floats[kb.F_CENTRES:kb.F_CENTRES + 3], floats[kb.F_CENTRES + 3:kb.F_DIR] = A.aim_point(), B.aim_point()
    return ints, floats


def _raise_pose_error(code: int, index: int | None = None) -> None:
    which = "pose_b" if code >= 10 else "pose_a"
    if index is not None:
        which += "s"
    where = f" {index}" if index is not None else ""
    raise ValueError(f"{which}{where} {_POSE_PROBLEM[code % 10]}")


_F64 = np.dtype(np.float64)
# one global lookup each on the per-call paths (np.empty is two: np, then its attribute)
_NDARRAY = np.ndarray
_empty = np.empty


_SCRATCH = threading.local()


def _thread_work() -> np.ndarray:
    """This thread's work array for one query (kb.query_work's), made once: a call then allocates
    only its result."""
    work = getattr(_SCRATCH, "work", None)
    if work is None:
        work = _SCRATCH.work = kb.query_work()
    return work


def _as_matrix(pose) -> np.ndarray:
    """A 4x4 float64 pose, C-contiguous, aligned and writeable (numba's plain array type, the one
    :func:`_machine_code` was taken for); validity is checked in the kernel. Cheap when it already is.
    Raises ValueError for any other shape."""
    if type(pose) is np.ndarray and pose.shape == (4, 4) and pose.dtype is _F64 and pose.flags.carray:
        return pose
    arr = np.asarray(pose)
    if arr.shape != (4, 4):
        raise ValueError(f"a pose must be a 4x4 homogeneous matrix; got shape {arr.shape}")
    return as_poses(arr)[0]  # a fresh copy


try:  # numba's own key of an argument's type, in C: what its dispatcher looks a call's types up by
    from numba._dispatcher import compute_fingerprint as _fingerprint
except ImportError:  # a numba without it (or NUMBA_DISABLE_JIT's stand-ins): no cache, numba's typeof each time
    _fingerprint = None

_MACHINE_CODES: dict = {}  # (dispatcher, the arguments' fingerprints) -> its machine code, for every Pair


def _machine_code(dispatcher, args):
    """The machine code numba compiled for these arguments' types, called without numba's per-call
    dispatch on them (the type of every argument, then a lookup: about 0.6 us of a 3 us query). Only
    for arguments whose types cannot change between calls (a Pair's own arrays) or that the kernel
    checks (poses: any float64 2-D array, whose shape and strides kb.query_one checks): the machine
    code does not check them. The dispatcher itself where numba has none (NUMBA_DISABLE_JIT).

    Kept per the arguments' type fingerprints, which every Pair shares: numba's typeof in Python took
    about 180 us of a new pair's first call, so a plain distance() over more shape pairs than its
    cache holds (PLAIN_PAIRS) cost 190 us a call."""
    try:
        key = (dispatcher, *map(_fingerprint, args))
    except (TypeError, ValueError):  # no fingerprint (_fingerprint None, or an argument numba keys otherwise)
        key = None
    code = _MACHINE_CODES.get(key) if key is not None else None
    if code is None:
        try:
            code = dispatcher.overloads[tuple(dispatcher.typeof_pyval(a) for a in args)].entry_point
        except (AttributeError, KeyError):
            code = dispatcher
        if key is not None:
            _MACHINE_CODES[key] = code
    return code


def _as_pose_batch(poses, name: str) -> np.ndarray:
    """(N, 4, 4) float64 C-contiguous view of poses; their validity is checked in the kernel."""
    arr = np.asarray(poses, dtype=np.float64)
    if arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[1:] != (4, 4):
        raise ValueError(f"{name} must have shape (4, 4) or (N, 4, 4); got {arr.shape}")
    return np.ascontiguousarray(arr)


def _per_call(coherent: bool, doc: str):
    """Pair.distance (coherent) or Pair.cold_distance, each a method of its own rather than a call
    into a shared one (that call and _thread_work's were about 0.1 us of a 3 us query)."""

    def query(self, pose_a, pose_b) -> DistanceResult:
        call = self._call
        # Any float64 2-D arrays go straight to the machine code, which answers POSE_LAYOUT for one
        # that is not a C-ordered 4x4 (checking that here took about 0.2 us of a 2.2 us plain call)
        if call is not None and type(pose_a) is _NDARRAY and type(pose_b) is _NDARRAY \
                and pose_a.dtype is _F64 and pose_b.dtype is _F64 and pose_a.ndim == 2 and pose_b.ndim == 2:
            work = getattr(_SCRATCH, "work", None)
            if work is None:
                work = _thread_work()
            machine, state, packed_a, packed_b = call
            out = _empty(OUT_SIZE)
            d = machine(state, packed_a, packed_b, pose_a, pose_b, coherent, out, work)
            if d == d:  # not NaN: a result
                result = DistanceResult()  # _result(out) inlined, the distance at hand
                result._out = out
                result.distance = d
                return result
            code = kb.rejected_pose(out)
            if code == kb.POSE_OK:  # the kernel's own NaN
                return _result(out)
            if code % 10 != kb.POSE_LAYOUT:
                _raise_pose_error(code)
        return self._plain_poses(_as_matrix(pose_a), _as_matrix(pose_b), coherent)

    query.__name__ = "distance" if coherent else "cold_distance"
    query.__qualname__ = "Pair." + query.__name__
    query.__doc__ = doc
    return query


class Pair:
    """A pair of shapes queried repeatedly, keeping the warm start between calls.

    The last support features and search direction of each call seed the next, so queries along a
    smooth trajectory take few iterations. ``reset()`` forgets them. signed: overlaps get their
    penetration depth as a negative distance (see the module docstring).
    """

    def __init__(self, A: Shape, B: Shape, tol: float = DEFAULT_TOL_ABS, rel_tol: float = DEFAULT_TOL_REL,
                 max_iter: int = DEFAULT_MAX_ITER, signed: bool = False):
        self.A, self.B = A, B
        self.signed = check_signed(signed)
        ints, floats = _pack(A, B, tol, rel_tol, max_iter, signed)
        ka, kb_ = A.kernel_data(), B.kernel_data()
        self._fa, self._ia, self._fb, self._ib = ka.fdata, ka.idata, kb_.fdata, kb_.idata
        # one call's arrays: the state, which both entry points share, and each shape's packed array
        self._state = kb.pair_state(floats, ints)
        self._floats, self._ints = kb.pair_floats(self._state), kb.pair_ints(self._state)
        self._packed_a, self._packed_b = ka.packed, kb_.packed
        # after the first call: kb.query_one's machine code for this pair and the pair's arrays it takes
        # (one attribute read instead of four: about 30 ns of a 2.5 us call), and spq._entry's Entry
        self._call = None
        self._entry = None

    def reset(self) -> None:
        """Forget the warm start."""
        self._ints[kb.I_WARM:kb.I_SIGNED] = 0
        self._floats[kb.F_DIR:] = 0.0

    distance = _per_call(True, """Distance between A at pose_a and B at pose_b (4x4 world poses).""")
    cold_distance = _per_call(False, """As :meth:`distance`, from a cold start: the answer a new Pair gives, bit for
        bit, whatever this pair was asked before; the warm start is left cleared.""")

    def _plain_poses(self, pose_a, pose_b, coherent: bool) -> DistanceResult:
        """A per-call query for poses that _as_matrix made C-ordered 4x4 float64 arrays. The first call compiles
        (or loads) the kernel, for these argument types, and keeps its machine code."""
        out = np.empty(OUT_SIZE)
        args = (self._state, self._packed_a, self._packed_b, pose_a, pose_b, coherent, out, _thread_work())
        if self._call is not None:
            d = self._call[0](*args)
        else:
            d = kb.query_one(*args)
            self._call = (_machine_code(kb.query_one, args), self._state, self._packed_a, self._packed_b)
            self._entry = _compiled_entry(self._state, self._packed_a, self._packed_b)
        if d != d:
            code = kb.rejected_pose(out)
            if code:
                _raise_pose_error(code)
        return _result(out)

    def distances(self, poses_a, poses_b, coherent: bool = True, workers: int = 1) -> BatchDistances:
        """Batched queries (see :func:`distances`), continuing this pair's warm start.

        workers: threads for a cold batch (coherent=False), split into contiguous chunks; results
        equal the one-thread call's bit for bit (see spq.workers). A coherent batch runs on one thread."""
        workers = check_workers(workers)
        pa = _as_pose_batch(poses_a, "poses_a")
        pb = _as_pose_batch(poses_b, "poses_b")
        n = max(len(pa), len(pb))
        if len(pa) not in (1, n) or len(pb) not in (1, n):
            raise ValueError(f"poses_a and poses_b must have the same length N (or 1); got {len(pa)} and {len(pb)}")
        out = np.empty((n, OUT_SIZE))
        bounds = [(0, n)] if coherent else chunk_bounds(n, workers, MIN_PAIR_QUERIES)
        if len(bounds) == 1:
            code = kb.query_batch(self._fa, self._ia, self._fb, self._ib, self._ints, self._floats, pa, pb,
                                  bool(coherent), out, kb.query_scratch())
            if code >= 0:
                _raise_pose_error(code % 100, code // 100)
            return BatchDistances(out)

        def chunk(start: int, stop: int):
            ints, floats = self._ints.copy(), self._floats.copy()
            code = kb.query_batch(self._fa, self._ia, self._fb, self._ib, ints, floats,
                                  pa[start:stop] if len(pa) > 1 else pa, pb[start:stop] if len(pb) > 1 else pb,
                                  False, out[start:stop], kb.query_scratch())
            return code, ints, floats

        results = map_chunks(chunk, bounds, workers)
        for (start, _), (code, _, _) in zip(bounds, results):
            if code >= 0:  # the first chunk with a bad pose holds the first bad pose
                _raise_pose_error(code % 100, start + code // 100)
        _, self._ints[:], self._floats[:] = results[-1]  # the state the last query left, as in one call
        return BatchDistances(out)


def distance(A: Shape, B: Shape, pose_a, pose_b, tol: float = DEFAULT_TOL_ABS, rel_tol: float = DEFAULT_TOL_REL,
             max_iter: int = DEFAULT_MAX_ITER, signed: bool = False) -> DistanceResult:
    """Distance between convex shape A at pose_a and B at pose_b (4x4 world poses, metres).

    The shapes come first, then their poses, as in :func:`distances` and ``Pair(A, B).distance(pose_a,
    pose_b)``. The order of spq 0.1, ``distance(A, pose_a, B, pose_b)``, still works for this release,
    with a DeprecationWarning (once per process), and after it as fast as the new order.

    GJK stops when the certified gap (upper_bound - lower_bound) is at most tol + rel_tol * |distance|.
    Overlapping shapes give distance 0 and status 'overlapping'; with signed=True, distance = -depth
    from the expanding polytope (EPA), with witness points and bounds certified the same way (see
    the module docstring). A query that cannot close its bounds within max_iter GJK steps (and
    32 * max_iter EPA expansions, at most 4072) returns status 'failed' with the bounds reached.
    Raises ValueError for bad poses or tolerances.
    """
    last = getattr(_SCRATCH, "last", None)  # a loop over poses asks for the same pair, with the same objects
    if last is not None and last[0] is A and last[1] is B and last[2] is tol and last[3] is rel_tol \
            and last[4] is max_iter and last[5] is signed:  # then B is a Shape: the new order
        # Pair.cold_distance inlined on the pair's machine code and arrays, kept flat in `last` (_plain_fast):
        # the calls and attribute reads it saves are about 0.6 us of a 2 us plain call. Any other
        # pose, and any error, takes Pair.cold_distance.
        if type(pose_a) is _NDARRAY and type(pose_b) is _NDARRAY and pose_a.dtype is _F64 and pose_b.dtype is _F64 \
                and pose_a.ndim == 2 and pose_b.ndim == 2:
            out = _empty(OUT_SIZE)
            d = last[6](last[7], last[8], last[9], pose_a, pose_b, False, out, last[10])
            if d == d:  # not NaN: a result (a rejected pose, or the kernel's own NaN, takes the way below)
                result = DistanceResult()  # _result(out) inlined, the distance at hand
                result._out = out
                result.distance = d
                return result
        return last[11].cold_distance(pose_a, pose_b)
    if isinstance(pose_a, Shape) and not isinstance(B, Shape):  # the old order: (A, pose_a, B, pose_b)
        _warn_old_order()
        B, pose_a = pose_a, B
        if last is not None and last[0] is A and last[1] is B and last[2] is tol and last[3] is rel_tol \
                and last[4] is max_iter and last[5] is signed:  # the last pair: the fast path, in the new order
            return distance(A, B, pose_a, pose_b, tol, rel_tol, max_iter, signed)
    pair = _plain_pair(A, B, tol, rel_tol, max_iter, signed)
    result = pair.cold_distance(pose_a, pose_b)
    _SCRATCH.last = _plain_fast(A, B, tol, rel_tol, max_iter, signed, pair)
    if pair._entry is not None:  # spq._entry's distance takes the next call on these objects
        _entry.remember((A, B, tol, rel_tol, max_iter, signed, pair._entry))
    return result


def _compiled_entry(state, packed_a, packed_b):
    """spq._entry's Entry for a pair's arrays: its per-call query in C. None without the extension, or
    without numba's compiler (NUMBA_DISABLE_JIT). The first one compiles kb.query_one as a C function
    (from numba's cache after the first time: about 0.2 s)."""
    if _entry is None:
        return None
    from spq.kernels.query_cfunc import ADDRESS
    return None if ADDRESS is None else _entry.Entry(ADDRESS, state, packed_a, packed_b)


def _plain_fast(A, B, tol, rel_tol, max_iter, signed, pair: "Pair"):
    """What distance()'s next call on the same objects reads, flat: its key (A, B and the options,
    compared by identity), then kb.query_one's machine code for the pair (which the pair's first
    call took) and the arrays it takes (this thread's work among them), then the pair."""
    return (A, B, tol, rel_tol, max_iter, signed, *pair._call,
            _thread_work(), pair)


PLAIN_PAIRS = 32  # shape pairs (with their options) whose packing each thread keeps for distance()


def _plain_pair(A: Shape, B: Shape, tol, rel_tol, max_iter, signed) -> "Pair":
    """The Pair a plain distance() call runs on (cold, see Pair.cold_distance): packed once per shape
    pair and options and kept per thread, as a loop over poses would otherwise spend half its time
    packing. The cache holds the last PLAIN_PAIRS pairs, and the shapes with them."""
    cache = getattr(_SCRATCH, "pairs", None)
    if cache is None:
        cache = _SCRATCH.pairs = {}
    # the options' types are in the key, so that a hit skips only the checks a miss made on equal input
    key = (id(A), id(B), tol, rel_tol, max_iter, signed, type(tol), type(rel_tol), type(max_iter), type(signed))
    try:
        pair = cache.get(key)
    except TypeError:  # an unhashable option (an array): Pair says what is wrong with it
        return Pair(A, B, tol, rel_tol, max_iter, signed)
    if pair is None or pair.A is not A or pair.B is not B:
        pair = Pair(A, B, tol, rel_tol, max_iter, signed)
        if len(cache) >= PLAIN_PAIRS:
            del cache[next(iter(cache))]
        cache[key] = pair
    return pair


_OLD_ORDER = {"warned": False}


def _warn_old_order() -> None:
    if not _OLD_ORDER["warned"]:
        _OLD_ORDER["warned"] = True
        warnings.warn("spq.distance(A, pose_a, B, pose_b) is deprecated: write spq.distance(A, B, pose_a, pose_b), "
                      "shapes first, as spq.distances and spq.Pair take them; the old order goes in the next release",
                      DeprecationWarning, stacklevel=3)


def distances(A: Shape, B: Shape, poses_a, poses_b, tol: float = DEFAULT_TOL_ABS, rel_tol: float = DEFAULT_TOL_REL,
              max_iter: int = DEFAULT_MAX_ITER, coherent: bool = False, signed: bool = False,
              workers: int = 1) -> BatchDistances:
    """Distances for N pose pairs in one compiled loop.

    poses_a, poses_b: (N, 4, 4) world poses (either may be a single 4x4, broadcast). coherent=True
    warm-starts each query from the previous one (for trajectories); False starts each cold.
    signed: as in :func:`distance`. workers: threads (1 to spq.workers.MAX_WORKERS) that share a cold
    batch in contiguous chunks, the compiled loop running without the GIL; the results equal one
    thread's bit for bit. A coherent batch depends on its order and runs on one thread whatever
    workers says. Returns a :class:`BatchDistances` of arrays.
    """
    return Pair(A, B, tol, rel_tol, max_iter, signed).distances(poses_a, poses_b, coherent=coherent, workers=workers)


def _with_compiled_entries() -> None:
    """spq._entry's distance and Pair methods in place of the Python ones (which they call for anything
    but a repeated pair with well-formed poses, and answer bit for bit as): a plain call costs about
    0.8 us less, and DistanceResult's fields are read in C. The Python ones stay as their ``__wrapped__``."""
    global distance
    layout = (OUT_SIZE, OUT_POINT_A, OUT_POINT_B, OUT_NORMAL, OUT_LOWER, OUT_UPPER, OUT_ITERATIONS, OUT_STATUS)
    _entry.configure(DistanceResult, layout, tuple(STATUS_NAMES), kb.query_work(), _OLD_ORDER)
    distance = functools.update_wrapper(_entry.PlainDistance(distance, distance.__defaults__), distance)
    for name, coherent in (("distance", True), ("cold_distance", False)):
        python = Pair.__dict__[name]
        setattr(Pair, name, functools.update_wrapper(_entry.PairQuery(python, coherent), python))


if _entry is not None:
    _with_compiled_entries()
