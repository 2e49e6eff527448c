"""`rhi.jit.stack_empty`: arrays on a compiled function's stack, freed when it returns, without an owner."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")


def _kernels():
    from numba import njit

    from rhi.jit import stack_empty

    @njit(error_model="numpy")  # not cached: a test's own kernels
    def shapes(n):
        a = stack_empty((n, 3), np.float64)
        b = stack_empty(n, np.bool_)
        c = stack_empty((2, n, 2), np.int64)
        for i in range(n):
            b[i] = i % 2 == 0
            for j in range(3):
                a[i, j] = 10.0 * i + j
            for k in range(2):
                c[0, i, k], c[1, i, k] = i + k, -(i + k)
        return a.copy(), b.copy(), c.copy(), a.strides, c.strides

    @njit(error_model="numpy")
    def local_sum(n):
        w = stack_empty(n, np.float64)  # 8 KiB each call: a leak would overflow the stack within the loop below
        for i in range(n):
            w[i] = i
        return w[1:].sum()

    @njit(error_model="numpy")
    def many(calls, n):
        s = 0.0
        for _ in range(calls):
            s += local_sum(n)
        return s

    return shapes, many


def test_stack_arrays_hold_their_values_in_c_order_and_are_freed_at_return():
    shapes, many = _kernels()
    a, b, c, sa, sc = shapes(4)
    np.testing.assert_array_equal(a, 10.0 * np.arange(4)[:, None] + np.arange(3))
    np.testing.assert_array_equal(b, [True, False, True, False])
    np.testing.assert_array_equal(c[0], np.arange(4)[:, None] + np.arange(2))
    np.testing.assert_array_equal(c[1], -c[0])
    assert sa == (24, 8) and sc == (64, 16, 8)
    assert many(100_000, 1024) == 100_000 * (1023 * 1024 / 2)  # 800 MB of stack if calls kept theirs
