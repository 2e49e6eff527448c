"""`rhi.devices._compiled.terms.shaped`: a contiguous 1-D array viewed in another shape, as reshape does."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")


def _kernels():
    from numba import njit

    from rhi.devices._compiled.terms import shaped

    @njit(error_model="numpy")  # not cached: a test's own kernels
    def views(w, m, n):
        a = shaped(w[2:2 + m * n], (m, n))
        b = shaped(w[1:1 + 2 * m * n], (2, m, n))
        c = shaped(w[:m], m)
        a[0, 1] = -1.0  # a view: written through to w
        return a.copy(), b.copy(), c.copy(), a.strides, b.strides, w[3]

    @njit(error_model="numpy")
    def wrong(w, m, n):
        return shaped(w, (m, n)).copy()

    @njit(error_model="numpy")
    def any_layout(w, step, m, n):
        v = w[::step]  # layout "A": contiguous only where step is 1
        return shaped(v, (m, n)).copy()

    return views, wrong, any_layout


def test_shaped_views_equal_reshape_and_write_through():
    views, wrong, any_layout = _kernels()
    w = np.arange(30.0)
    a, b, c, sa, sb, w3 = views(w, 3, 4)
    ref = np.arange(30.0)
    np.testing.assert_array_equal(a, np.where(np.arange(12).reshape(3, 4) == 1, -1.0, ref[2:14].reshape(3, 4)))
    np.testing.assert_array_equal(b, w[1:25].reshape(2, 3, 4))
    np.testing.assert_array_equal(c, ref[:3])
    assert sa == (32, 8) and sb == (96, 32, 8) and w3 == -1.0 == w[3]
    np.testing.assert_array_equal(any_layout(np.arange(6.0), 1, 2, 3), np.arange(6.0).reshape(2, 3))


def test_shaped_refuses_another_size_and_gaps():
    _, wrong, any_layout = _kernels()
    with pytest.raises(ValueError, match="reshape"):
        wrong(np.arange(6.0), 2, 2)
    with pytest.raises(ValueError, match="reshape"):
        any_layout(np.arange(12.0), 2, 2, 3)
