"""Support dispatch over shape kinds: the one entry point the solver calls.

Margins (sphere and capsule radii) are handled by the solver, not here, so that GJK runs on the
exact polyhedral/segment cores.
"""

from __future__ import annotations

import numpy as np

from spq.kernels.indexing import at
from spq.kernels.jit import kernel
from spq.kernels.kinds import BOX, POLYTOPE, SEGMENT, STP, STP_CORE, SUPERELLIPSOID
from spq.kernels.stp_support import F_R, IDX_METHOD, stp_support
from spq.kernels.superellipsoid_support import superellipsoid_support
from spq.kernels.support import polytope_support_index


@kernel(inline="always")
def _sign_half(h, d):
    return h if d >= 0.0 else -h


@kernel(inline="always")
def support_local(kind, f, ix, d0, d1, d2, warm, out):
    """Write the core support point along (d0, d1, d2) (local frame) into out[0:3].

    ``warm`` is the feature index the search starts from (a vertex for polytopes, a patch for
    STP-BVs, ignored otherwise); the feature found is returned so the caller can warm-start the
    next call.
    """
    if kind == POLYTOPE:
        i = polytope_support_index(f, ix, d0, d1, d2)
        out[0] = f[at(3 * i)]
        out[1] = f[at(3 * i + 1)]
        out[2] = f[at(3 * i + 2)]
        return i
    if kind == BOX:
        out[0] = _sign_half(f[0], d0)
        out[1] = _sign_half(f[1], d1)
        out[2] = _sign_half(f[2], d2)
        return 0
    if kind == STP:
        return stp_support(f, ix, ix[IDX_METHOD], d0, d1, d2, warm, 0.0, out)
    if kind == SUPERELLIPSOID:
        superellipsoid_support(f, d0, d1, d2, out)
        return 0
    if kind == STP_CORE:
        return stp_support(f, ix, ix[IDX_METHOD], d0, d1, d2, warm, f[F_R], out)
    if kind == SEGMENT:
        out[0] = 0.0
        out[1] = 0.0
        out[2] = _sign_half(f[0], d2)
        return 0
    # POINT
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    return 0


@kernel(allocates=True)
def support_many(kind, f, ix, directions):
    """Support points (m, 3) for an (m, 3) array of local directions (cold start each)."""
    m = directions.shape[0]
    out = np.empty((m, 3))
    tmp = np.empty(3)
    for k in range(m):
        support_local(kind, f, ix, directions[k, 0], directions[k, 1], directions[k, 2], 0, tmp)
        out[k, 0] = tmp[0]
        out[k, 1] = tmp[1]
        out[k, 2] = tmp[2]
    return out
