"""Borrowed array views: the same data, with no reference count.

Every view numba makes (``a[i]``, ``a[i:j]``) increments and later decrements its parent's reference
count with a locked instruction, and across the many small non-inlined calls of a GJK query these
atomic operations took about a third of the time of a scene's all-pairs call (measured with perf).
A view of a borrowed array carries no reference count, so those operations become a null test.

Safety rule: borrow only arrays that a caller keeps alive for the whole call, i.e. the arguments of
a kernel called from Python, and never return or store a borrowed array.
"""

from __future__ import annotations

from numba import types
from numba.extending import intrinsic


@intrinsic
def borrowed(typingctx, arr):
    """A view of ``arr`` (same type, data, shape and strides) without a reference count."""
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, signature, args):
        src = context.make_array(arr)(context, builder, value=args[0])
        dst = context.make_array(arr)(context, builder)
        context.populate_array(dst, data=src.data, shape=src.shape, strides=src.strides,
                               itemsize=src.itemsize, meminfo=None, parent=None)
        return dst._getvalue()

    return arr(arr), codegen

