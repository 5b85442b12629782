"""The velocity damper's rows from one configuration's scene result, in one compiled pass.

spq.control.damper documents the rows. Built in numpy they took about 45 us a step on JVRC-1's 561
pairs (ten array calls of 1.5 to 3.5 us each), as long as the pruned scene query they come from;
here they take a few microseconds.
"""

from __future__ import annotations

import math

import numpy as np

from spq.kernels.gjk import FAILED, OUT_DISTANCE, OUT_STATUS
from spq.kernels.jit import kernel


@kernel(allocates=True)
def damper_rows(out, jac, di, ds, xi):
    """(G, h, pairs, distances, jacobian, failed) of the pairs closer than di.

    out (n, OUT_SIZE): the pairs' result rows as the scene's sweep wrote them (distance in m, status
    code as a float, spq.kernels.gjk's OUT_*); read here rather than through the result's ``distance``
    and ``status_code`` fields, whose conversion took a fifth of a small arm's damper call inside a
    control loop. jac (n, nv): their rows ∂d/∂q. A pair gives a
    row when d < di (inf for a pruned pair and NaN never are), its status is not FAILED and its row is
    finite; the rows come by increasing distance (ties in pair order). failed: the pairs whose status
    is FAILED or whose close row is not finite, in pair order. G = -jacobian, h = xi (d - ds) / (di - ds)."""
    n, nv = jac.shape
    close = np.empty(n, np.int64)
    failed = np.empty(n, np.int64)
    k = 0
    nf = 0
    for p in range(n):
        if out[p, OUT_STATUS] == FAILED:
            failed[nf] = p
            nf += 1
        elif out[p, OUT_DISTANCE] < di:
            finite = True
            for c in range(nv):
                if not math.isfinite(jac[p, c]):
                    finite = False
                    break
            if finite:
                close[k] = p
                k += 1
            else:
                failed[nf] = p
                nf += 1
    dist = np.empty(k)
    for i in range(k):
        dist[i] = out[close[i], OUT_DISTANCE]
    order = np.argsort(dist, kind="mergesort")  # stable: equal distances keep the pairs' order
    pairs = np.empty(k, np.int64)
    d = np.empty(k)
    h = np.empty(k)
    rows = np.empty((k, nv))
    G = np.empty((k, nv))
    for i in range(k):
        p = close[order[i]]
        pairs[i] = p
        d[i] = dist[order[i]]
        h[i] = xi * (d[i] - ds) / (di - ds)
        for c in range(nv):
            rows[i, c] = jac[p, c]
            G[i, c] = -jac[p, c]
    return G, h, pairs, d, rows, failed[:nf].copy()
