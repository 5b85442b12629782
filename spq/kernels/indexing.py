"""Unsigned array indices for the hot kernels.

numba lets a negative index count from the end of the array, as Python does, so every read with a
signed index it cannot prove non-negative (a vertex id, a patch, an offset read from the data) first
adds the array's length where the index is negative: two or three more instructions per read. The
kernels never index from the end, so their data-dependent reads in the hot loops take the index as
unsigned, for which numba emits no such fix-up. On JVRC-1's all-pairs loop, cold, that is 4% of the
time from the polytope support's reads alone, and 5 to 6% (auto) and 4% (pch) from the reads that
use it (same-process A/B, bit-identical results). Compute the index as a signed int, then convert
at the read: arithmetic that mixes numba's unsigned and signed ints gives a float.
"""

from __future__ import annotations

import numpy as np

from spq.kernels.jit import kernel


@kernel(inline="always")
def at(i):
    """i (a signed int, >= 0) as an unsigned index: ``a[at(i)]`` reads a[i] without the wrap of negatives."""
    return np.uint64(i)
