"""The one decorator every compiled kernel uses.

cache=True keeps compiled code between runs; error_model="numpy" makes a float division by zero
give inf/nan instead of a Python exception check on every division in the hot loops (the kernels
test their denominators themselves).

Kernels run without numba's reference counting (NRT) unless they allocate. With it, every array
passed to a non-inlined call, and every view taken, costs an increment and a decrement call: in a
scene's all-pairs call, where a query is a chain of small calls with a dozen array arguments each,
those calls took about a fifth of the time (measured with perf). A kernel without NRT cannot
allocate, so the hot paths take scratch arrays from their callers; a kernel that does allocate (an
entry point that returns new arrays) says so with ``allocates=True`` and may call the others, but
not the other way round. Nor may code with NRT (a kernel with ``allocates=True``, or a user's own
``njit``) keep an array that a kernel without it returns (hull_core's views): it would release a
reference it never took.
"""

from numba import njit


def kernel(fn=None, *, allocates: bool = False, **options):
    """``numba.njit`` with the project's options; use as ``@kernel``, ``@kernel(inline="always")`` or
    ``@kernel(allocates=True)`` (for a kernel that creates arrays)."""
    opts = {"cache": True, "error_model": "numpy", "_nrt": bool(allocates), **options}
    if fn is None:
        return njit(**opts)
    return njit(**opts)(fn)
