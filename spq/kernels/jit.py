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

Inlining a large kernel saves its call (a dozen arrays passed) but copies its code into every entry
point that reaches it, and each copy is compiled again. ``inline="hot"`` inlines a kernel only into
the entry points marked ``hot=True`` (a robot scene's all-pairs loop, where the calls' cost shows);
everywhere else it stays a call, which keeps the other entry points' compile time down.
"""

from numba import njit

_HOT = "_spq_hot_kernel"


def _into_hot_kernels(expr, caller_ir, callee_ir) -> bool:
    """numba's inlining cost model for ``inline="hot"``: caller_ir is the entry point being compiled
    (the whole chain of inlined kernels ends in it)."""
    return getattr(caller_ir.func_id.func, _HOT, False)


def kernel(fn=None, *, allocates: bool = False, hot: bool = False, **options):
    """``numba.njit`` with the project's options; use as ``@kernel``, ``@kernel(inline="always")``,
    ``@kernel(inline="hot")`` (inlined only into hot entry points), ``@kernel(hot=True)`` (an entry
    point that takes them inline) or ``@kernel(allocates=True)`` (for a kernel that creates arrays)."""
    if options.get("inline") == "hot":
        options["inline"] = _into_hot_kernels
    opts = {"cache": True, "error_model": "numpy", "_nrt": bool(allocates), **options}

    def compile_(f):
        if hot:
            setattr(f, _HOT, True)
        return njit(**opts)(f)

    return compile_ if fn is None else compile_(fn)
