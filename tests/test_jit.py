"""spq.kernels.jit: inline="hot" kernels are inlined into hot entry points and called from the others."""

import re

from spq.kernels.jit import kernel


# cache off: a kernel loaded from numba's cache has no LLVM text to inspect
@kernel(inline="hot", cache=False)
def _scaled(x):
    return 2.0 * x


@kernel(hot=True, cache=False)
def _hot_entry(x):
    return _scaled(x) + 1.0


@kernel(cache=False)
def _plain_entry(x):
    return _scaled(x) + 1.0


def _refers_to_scaled(dispatcher) -> bool:
    (llvm,) = dispatcher.inspect_llvm().values()
    return re.search(r"@\"?_ZN[^\s(]*7_scaled", llvm) is not None


def test_a_hot_kernel_is_inlined_only_into_hot_entry_points():
    assert _hot_entry(3.0) == _plain_entry(3.0) == 7.0
    assert not _refers_to_scaled(_hot_entry)
    assert _refers_to_scaled(_plain_entry)
