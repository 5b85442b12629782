"""Compiled entry points around gjk_query: pose checks, frames, single and batched queries.

Packing: ``ints = [kind_a, kind_b, max_iter, warm state (gjk.WARM_SIZE), signed]`` and
``floats = [margin_a, margin_b, tol_abs, tol_rel, centre_a (3), centre_b (3), dx, dy, dz, R (9), t (3)]``
(centre_a, centre_b: a point inside each core, in its own frame, that aims a cold start, zero for
the frame origins; dx, dy, dz: the warm-start search direction in A's frame; R, t: B's pose in A's
frame at the previous query). Few arguments keep the Python-to-compiled call cheap for per-call use.
"""

from __future__ import annotations

import math

import numpy as np
from spq.kernels.jit import kernel

from spq.kernels.gjk import (
    IWORK_SIZE,
    OUT_DISTANCE,
    OUT_LOWER,
    OUT_NORMAL,
    OUT_POINT_A,
    OUT_POINT_B,
    OUT_STATUS,
    OUT_UPPER,
    WARM_COUNT,
    WARM_SIZE,
    WORK_ROWS,
    clear_warm,
)
from spq.kernels.kinds import IDATA_DTYPE, SHAPE_HEAD
from spq.kernels.query import gjk_query

POSE_OK = 0
POSE_NOT_FINITE = 1
POSE_BAD_BOTTOM_ROW = 2
POSE_NOT_ROTATION = 3
POSE_LAYOUT = 4  # query_one only: not a C-ordered 4x4 array; the caller converts it and asks again
ROTATION_TOL = 1e-6  # same admissible error as spq.validation.ROTATION_TOL

I_KIND_A, I_KIND_B, I_MAX_ITER, I_WARM = 0, 1, 2, 3
I_SIGNED = I_WARM + WARM_SIZE  # 1: overlaps get their penetration depth (spq.kernels.signed)
INTS_SIZE = I_SIGNED + 1
F_MARGIN_A, F_MARGIN_B, F_TOL_ABS, F_TOL_REL, F_CENTRES, F_DIR, F_PREV_R, F_PREV_T = 0, 1, 2, 3, 4, 10, 13, 22
FLOATS_SIZE = 25
COHERENT_ROTATION = 0.2  # max |R - R_prev| entry for the previous simplex to be re-used
COHERENT_TRANSLATION = 0.2  # max |t - t_prev| / |t_prev| for the same


@kernel(inline="always")
def keep_simplex_if_coherent(R, t, floats, warm):
    """Drop the warm-start simplex and direction unless B moved little relative to A since the last query.

    Along a trajectory the previous simplex, re-evaluated, is nearly optimal; after a jump it is a
    poor start that costs more iterations than a cold one. The pose is then remembered."""
    near = True
    for r in range(3):
        for c in range(3):
            if abs(R[r, c] - floats[F_PREV_R + 3 * r + c]) > COHERENT_ROTATION:
                near = False
    dt = 0.0
    tt = 0.0
    for r in range(3):
        dt += (t[r] - floats[F_PREV_T + r]) ** 2
        tt += floats[F_PREV_T + r] ** 2
    if dt > COHERENT_TRANSLATION * COHERENT_TRANSLATION * tt:
        near = False
    if not near:
        warm[WARM_COUNT] = 0
        floats[F_DIR] = floats[F_DIR + 1] = floats[F_DIR + 2] = 0.0
    for r in range(3):
        for c in range(3):
            floats[F_PREV_R + 3 * r + c] = R[r, c]
        floats[F_PREV_T + r] = t[r]


@kernel(inline="always")
def _c_4x4(T):
    return T.shape[0] == 4 and T.shape[1] == 4 and T.strides[0] == 32 and T.strides[1] == 8


@kernel
def check_pose(T):
    """POSE_OK, or the code of the first problem found in a 4x4 pose."""
    for r in range(4):
        for c in range(4):
            if not math.isfinite(T[r, c]):
                return POSE_NOT_FINITE
    if T[3, 0] != 0.0 or T[3, 1] != 0.0 or T[3, 2] != 0.0 or T[3, 3] != 1.0:
        return POSE_BAD_BOTTOM_ROW
    for a in range(3):
        for b in range(3):
            s = T[0, a] * T[0, b] + T[1, a] * T[1, b] + T[2, a] * T[2, b]
            if abs(s - (1.0 if a == b else 0.0)) > ROTATION_TOL:
                return POSE_NOT_ROTATION
    det = (
        T[0, 0] * (T[1, 1] * T[2, 2] - T[1, 2] * T[2, 1])
        - T[0, 1] * (T[1, 0] * T[2, 2] - T[1, 2] * T[2, 0])
        + T[0, 2] * (T[1, 0] * T[2, 1] - T[1, 1] * T[2, 0])
    )
    if abs(det - 1.0) > ROTATION_TOL:
        return POSE_NOT_ROTATION
    return POSE_OK


@kernel(inline="always")
def relative_pose(TA, TB, R, t):
    """R = RA^T RB and t = RA^T (tB - tA): B's pose in A's frame."""
    for r in range(3):
        for c in range(3):
            R[r, c] = TA[0, r] * TB[0, c] + TA[1, r] * TB[1, c] + TA[2, r] * TB[2, c]
        t[r] = TA[0, r] * (TB[0, 3] - TA[0, 3]) + TA[1, r] * (TB[1, 3] - TA[1, 3]) + TA[2, r] * (TB[2, 3] - TA[2, 3])


@kernel(inline="always")
def _to_world(TA, out):
    """Witness points and normal of a gjk_query result, from A's frame to the world, in place."""
    for base in (OUT_POINT_A, OUT_POINT_B):
        x, y, z = out[base], out[base + 1], out[base + 2]
        for r in range(3):
            out[base + r] = TA[r, 0] * x + TA[r, 1] * y + TA[r, 2] * z + TA[r, 3]
    x, y, z = out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2]
    for r in range(3):
        out[OUT_NORMAL + r] = TA[r, 0] * x + TA[r, 1] * y + TA[r, 2] * z


# A Pair's state for query_one in one array, float64 slots: [R (9), t (3), floats (FLOATS_SIZE),
# ints (INTS_SIZE, read as int64)]; each shape comes as its packed array (kinds.pack_shape). Each
# array numba unboxes costs time per call (about 10 ns without NRT, 30 ns with it, on the 2-core
# test machine): three instead of eight. R comes first, so that a C caller's pointer to the state
# is R's too (spq.kernels.query_cfunc takes it as a 3x3 carray: numba's reshape is a call into its
# helper library, about 2% of a plain call).
PAIR_R = 0
PAIR_T = PAIR_R + 9
PAIR_FLOATS = PAIR_T + 3
PAIR_INTS = PAIR_FLOATS + FLOATS_SIZE
PAIR_SIZE = PAIR_INTS + INTS_SIZE


def pair_state(floats, ints) -> np.ndarray:
    """A pair's state for :func:`query_one`, laid out as PAIR_* says. The caller keeps
    ``pair_floats(state)`` as its floats and ``pair_ints(state)`` as its ints, so that both entry
    points share the warm start."""
    state = np.zeros(PAIR_SIZE)
    pair_floats(state)[:] = floats
    pair_ints(state)[:] = ints
    return state


def pair_floats(state):
    """The floats of a pair_state (a view)."""
    return state[PAIR_FLOATS:PAIR_INTS]


def pair_ints(state):
    """The int64 view of a pair_state's ints."""
    return state[PAIR_INTS:PAIR_SIZE].view(np.int64)


@kernel(inline="always")
def unpack_shape(packed):
    """(fdata, idata) of a packed shape (kinds.pack_shape), as views."""
    head = packed[:SHAPE_HEAD].view(np.int64)
    nf, ni = head[0], head[1]
    return packed[SHAPE_HEAD:SHAPE_HEAD + nf], packed[SHAPE_HEAD + nf:].view(IDATA_DTYPE)[:ni]


@kernel
def query_one(state, packed_a, packed_b, TA, TB, coherent, out, wbuf):
    """One query with world-frame results in out; warm-start state in state is updated. state:
    :func:`pair_state`'s; packed_a, packed_b: the shapes' ``KernelData.packed``. coherent: start from
    the last query's state if B moved little relative to A, else (and always when False, a cold
    query) from scratch. wbuf: :func:`query_work`'s, which the caller keeps: a signed query's
    polytope needs megabytes, too many to allocate per call.

    TA, TB: float64 2-D arrays of any shape and strides (their machine code is called without
    numba's type checks, see spq.query): POSE_LAYOUT unless each is C-ordered 4x4.

    Returns out[OUT_DISTANCE], so that the caller's result holds the distance without reading it
    back from out (a numpy element read costs about 80 ns of a 2 us call); NaN when a pose is
    rejected, nothing computed, and out[OUT_STATUS] = -(its POSE_* code, +10 for TB)."""
    return query_shaped(state, state[PAIR_R:PAIR_T].reshape((3, 3)), packed_a, packed_b, TA, TB, coherent, out, wbuf,
                        wbuf[:WORK_ROWS * 4].reshape((WORK_ROWS, 4)))


@kernel
def query_shaped(state, R, packed_a, packed_b, TA, TB, coherent, out, wbuf, work):
    """:func:`query_one` with its 2-D views made by the caller: R, the state's rotation slots as
    (3, 3), and work, wbuf's first WORK_ROWS * 4 slots as (WORK_ROWS, 4) (a C caller makes both as
    carrays of the same pointers, without numba's reshape)."""
    code = POSE_OK
    if not _c_4x4(TA):
        code = POSE_LAYOUT
    elif not _c_4x4(TB):
        code = POSE_LAYOUT + 10
    else:
        code = check_pose(TA)
        if code == POSE_OK:
            code = check_pose(TB)
            if code != POSE_OK:
                code += 10
    if code != POSE_OK:
        out[OUT_STATUS] = -code
        return math.nan
    fA, iA = unpack_shape(packed_a)
    fB, iB = unpack_shape(packed_b)
    scratch = (R, state[PAIR_T:PAIR_FLOATS], work, wbuf[WORK_ROWS * 4:].view(np.int64))
    posed_query(fA, iA, fB, iB, state[PAIR_INTS:PAIR_SIZE].view(np.int64), state[PAIR_FLOATS:PAIR_INTS], TA, TB,
                coherent, scratch, out)
    return out[OUT_DISTANCE]


def rejected_pose(out) -> int:
    """The POSE_* code (+10 for TB) that :func:`query_one` left in out when it returned NaN, or
    POSE_OK if it computed a result (a NaN distance of its own)."""
    status = out[OUT_STATUS]
    return int(-status) if status < 0 else POSE_OK


def query_work() -> np.ndarray:
    """A thread's scratch for :func:`query_one`, one float64 array: work (WORK_ROWS, 4), then iwork
    (IWORK_SIZE,) read as int64."""
    return np.empty(WORK_ROWS * 4 + IWORK_SIZE)


def query_scratch() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Scratch arrays for a batched kernel: R (3, 3), t (3,), work (WORK_ROWS, 4), iwork int64 (IWORK_SIZE,).

    Allocated by the Python caller: the kernels do not allocate (see spq.kernels.jit)."""
    return np.empty((3, 3)), np.empty(3), np.empty((WORK_ROWS, 4)), np.empty(IWORK_SIZE, dtype=np.int64)


@kernel(nogil=True)  # threads run chunks of one batch at once (spq.workers)
def query_batch(fA, iA, fB, iB, ints, floats, poses_a, poses_b, coherent, out, scratch):
    """Queries for N pose pairs into out (N, OUT_SIZE). poses_a/poses_b: (N or 1, 4, 4), broadcast.

    coherent: carry the warm start (features, direction) from each query to the next, as along a
    trajectory; otherwise every query starts cold. scratch: (R, t, work, iwork) from
    :func:`query_scratch`. Returns -1 if every pose is valid, else the index of the first bad pose
    times 100 plus its POSE_* code (+10 for B); nothing is computed then.
    """
    n = out.shape[0]
    na = poses_a.shape[0]
    nb = poses_b.shape[0]
    for q in range(n):
        ca = check_pose(poses_a[q if na > 1 else 0])
        if ca != POSE_OK:
            return q * 100 + ca
        cb = check_pose(poses_b[q if nb > 1 else 0])
        if cb != POSE_OK:
            return q * 100 + 10 + cb
    for q in range(n):
        posed_query(fA, iA, fB, iB, ints, floats, poses_a[q if na > 1 else 0], poses_b[q if nb > 1 else 0],
                    coherent, scratch, out[q])
    return -1


@kernel(inline="always")
def posed_query(fA, iA, fB, iB, ints, floats, TA, TB, coherent, scratch, row):
    """One query of a packed pair (ints, floats rows) at world poses TA, TB into row, world frame.

    coherent: keep the pair's warm start if B moved little relative to A; otherwise start cold.
    scratch: (R, t, work, iwork) from :func:`query_scratch`."""
    R, t, work, iwork = scratch
    warm = ints[I_WARM:I_WARM + WARM_SIZE]
    d = floats[F_DIR:F_DIR + 3]
    relative_pose(TA, TB, R, t)
    if coherent:
        keep_simplex_if_coherent(R, t, floats, warm)
    else:
        clear_warm(warm)
        d[0] = d[1] = d[2] = 0.0  # not d[:] = 0.0, a call to memset (see clear_warm)
    signed = ints[I_SIGNED] != 0
    gjk_query((ints[I_KIND_A], floats[F_MARGIN_A], fA, iA, ints[I_KIND_B], floats[F_MARGIN_B], fB, iB, R, t),
              (floats[F_TOL_ABS], floats[F_TOL_REL], ints[I_MAX_ITER]), d, floats[F_CENTRES:F_CENTRES + 6], warm, iwork,
              work, row, signed)
    row[OUT_UPPER] = row[OUT_DISTANCE]  # every path leaves its upper bound there
    if row[OUT_LOWER] > row[OUT_DISTANCE]:
        # a descent's bound and the gap between its witness points are different sums, which
        # rounding may cross by an ulp or two (7% to 49% of the separated queries between
        # polytopes, primitives and smooth bodies, by kind): the lesser is still a lower bound
        row[OUT_LOWER] = row[OUT_DISTANCE]
    _to_world(TA, row)
