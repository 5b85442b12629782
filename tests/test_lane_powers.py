"""spq.kernels.lane_powers: the vectorized power against the C library's (math.pow) over the range the
superellipsoid kernels use, and its special values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from numba import njit

from spq.kernels.jit import kernel
from spq.kernels.lane_powers import lanes_view, powers_in_place, rough_powers_in_place


def _powers(x, p, kernel=powers_in_place):
    out = np.array(x, dtype=float)
    kernel(out, np.array(p, dtype=float))
    return out


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.floats(1e-6, 1e3), st.floats(0.5, 40.0)), min_size=1, max_size=19))
def test_powers_agree_with_the_c_library_to_the_rounding_of_p_log_x(pairs):
    x = [a for a, _ in pairs]
    p = [b for _, b in pairs]
    got = _powers(x, p)
    for xi, pi, gi in zip(x, p, got):
        want = math.pow(xi, pi)
        if want < 1e-300 or want > 1e300:
            continue
        # y = p log x rounded: a relative error of a few |y| ulps, plus the series' own 1e-16
        assert abs(gi - want) <= (4.0 * abs(pi * math.log(xi)) + 8.0) * 2.2e-16 * want, (xi, pi, gi, want)


def test_powers_on_the_superellipsoid_kernels_range_are_within_1e_14():
    rng = np.random.default_rng(0)
    x = rng.uniform(1e-3, 1.5, 4096)
    p = rng.choice([2.0 / 0.3, 2.0 / 1.0218, 2.0 / 0.4196, 2.0, 10.0, 0.65], 4096)
    got = _powers(x, p)
    want = np.array([math.pow(a, b) for a, b in zip(x, p)])
    assert np.max(np.abs(got / want - 1.0)) < 1e-14


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.floats(1e-6, 1e3), st.floats(0.5, 40.0)), min_size=1, max_size=19))
def test_rough_powers_agree_with_the_c_library_to_their_series(pairs):
    x = [a for a, _ in pairs]
    p = [b for _, b in pairs]
    got = _powers(x, p, rough_powers_in_place)
    for xi, pi, gi in zip(x, p, got):
        want = math.pow(xi, pi)
        if want < 1e-300 or want > 1e300:
            continue
        # the logarithm's series to z^4 / 9 (7e-10 of log m at most, times p) and the exponential's to
        # r^7 (7.3e-9 at r = -ln 2 / 2), over the rounding of y = p log x
        bound = 1e-9 * pi + 8e-9 + (4.0 * abs(pi * math.log(xi)) + 8.0) * 2.2e-16
        assert abs(gi - want) <= bound * want, (xi, pi, gi, want)


def test_rough_powers_stay_within_2e_8_on_the_superellipsoid_kernels_range():
    rng = np.random.default_rng(0)
    x = rng.uniform(1e-3, 1.5, 4096)
    p = rng.choice([2.0 / 0.3, 2.0 / 1.0218, 2.0 / 0.4196, 2.0, 10.0, 0.65], 4096)
    got = _powers(x, p, rough_powers_in_place)
    want = np.array([math.pow(a, b) for a, b in zip(x, p)])
    error = np.max(np.abs(got / want - 1.0))
    assert 1e-12 < error < 2e-8  # rough indeed, and no rougher than its series


@pytest.mark.parametrize("kernel", [powers_in_place, rough_powers_in_place])
def test_special_values(kernel):
    x = [0.0, math.inf, math.nan, 5e-324, 1e-310, 1.0, 1e-200, 1e200, 2.0]
    p = [3.0, 2.0, 2.0, 1.0, 0.5, 7.3, 10.0, 10.0, 1.0]
    got = _powers(x, p, kernel)
    assert got[0] == 0.0
    assert got[1] == math.inf
    assert math.isnan(got[2])
    assert got[3] == 0.0  # a result below about 3e-308 is taken as 0
    # a subnormal base is scaled first
    assert abs(got[4] / math.sqrt(1e-310) - 1.0) < (1e-13 if kernel is powers_in_place else 2e-8)
    assert got[5] == 1.0
    assert got[6] == 0.0  # 1e-2000 underflows
    assert got[7] == math.inf  # 1e2000 overflows
    assert got[8] == 2.0


def _square_rows_in_place(scratch, row):
    x = lanes_view(scratch, row)
    p = lanes_view(scratch, row + 2)
    for i in range(x.shape[0]):
        p[i] = 2.0
    powers_in_place(x, p)


def test_lanes_view_is_two_rows_of_a_scratch_with_nrt_and_without():
    for compiled in (njit(_square_rows_in_place), kernel(cache=False)(_square_rows_in_place)):
        scratch = np.arange(1.0, 41.0).reshape(10, 4)
        want = scratch.copy()
        want[3:5] = want[3:5] ** 2
        want[5:7] = 2.0
        compiled(scratch, 3)
        np.testing.assert_allclose(scratch, want, rtol=1e-14)
