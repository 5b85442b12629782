"""kb.query_one as a C function (a numba cfunc), for spq._entry's compiled entry points.

spq._entry calls it through its address with raw pointers and sizes, as arrays it has checked: the
state and packed shapes of a Pair (1-D float64), poses that are C-ordered 4x4 float64, the result
vector of OUT_SIZE doubles (inside the result object) and the module's work array (kb.query_work's).
Compiled when this module is imported (spq.query imports it on a pair's first call), from numba's
cache after the first time.
"""

from numba import carray, cfunc, config, types

from spq.kernels.batch import PAIR_R, WORK_ROWS, query_shaped
from spq.kernels.gjk import OUT_SIZE

_F64P = types.CPointer(types.float64)
SIGNATURE = types.float64(_F64P, types.int64, _F64P, types.int64, _F64P, types.int64, _F64P, _F64P, types.int64,
                          _F64P, _F64P, types.int64)


@cfunc(SIGNATURE, cache=True, error_model="numpy")
def query_c(state, n_state, packed_a, n_a, packed_b, n_b, pose_a, pose_b, coherent, out, work, n_work):
    """kb.query_one on the arrays at these addresses; coherent is 0 or 1. Its 2-D views are carrays of
    the same pointers (the state begins with R: PAIR_R is 0), not numba's reshape, a call."""
    return query_shaped(carray(state, n_state), carray(state, (3, 3)), carray(packed_a, n_a), carray(packed_b, n_b),
                        carray(pose_a, (4, 4)), carray(pose_b, (4, 4)), coherent != 0, carray(out, OUT_SIZE),
                        carray(work, n_work), carray(work, (WORK_ROWS, 4)))


if PAIR_R != 0:  # query_c's R is the state's first nine slots
    raise ImportError("spq.kernels.batch.PAIR_R must be 0 for query_cfunc")


ADDRESS = None if config.DISABLE_JIT else query_c.address  # no machine code without the compiler
