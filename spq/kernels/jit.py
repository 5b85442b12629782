"""The one decorator every compiled kernel uses.

cache=True keeps compiled code between runs; error_model="numpy" makes a float division by zero
give inf/nan instead of a Python exception check on every division in the hot loops (the kernels
test their denominators themselves).
"""

from numba import njit


def kernel(fn=None, **options):
    """``numba.njit`` with the project's options; use as ``@kernel`` or ``@kernel(inline="always")``."""
    opts = {"cache": True, "error_model": "numpy", **options}
    if fn is None:
        return njit(**opts)
    return njit(**opts)(fn)
