"""spq.kernels.jit: inline="hot" kernels are inlined into hot entry points and called from the others;
spq.kernels.indexing: an unsigned index compiles without numba's wrap of negative indices."""

import re

import numpy as np

from spq.kernels.indexing import at
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



@kernel(cache=False)
def _read_signed(a, i):
    return a[3 * i + 1]


@kernel(cache=False)
def _read_unsigned(a, i):
    return a[at(3 * i + 1)]


def _shifts_sign(dispatcher) -> int:
    """Arithmetic right shifts in the compiled code: numba's wrap of a negative index is one
    (x >> 63 gives the mask that adds the array's length)."""
    (asm,) = dispatcher.inspect_asm().values()
    return len(re.findall(r"\n\s*sar[qx]?\s", asm))


def test_an_unsigned_index_reads_the_same_element_without_the_negative_index_wrap():
    a = np.arange(30.0) * 1.5
    for i in (0, 4, 9):
        assert _read_unsigned(a, i) == _read_signed(a, i) == a[3 * i + 1]
    assert _shifts_sign(_read_signed) > 0  # the control: a signed index is wrapped
    assert _shifts_sign(_read_unsigned) == 0
