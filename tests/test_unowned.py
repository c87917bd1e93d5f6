"""The engines' views that numba does not reference-count (rubcosim.reference.unowned)."""

from __future__ import annotations

import numba as nb
import numpy as np

from rubcosim.reference.unowned import keep_alive, unowned


@nb.njit
def _write_through_views(a, b):
    va, vb = unowned(a), unowned(b)
    for i in range(va.shape[0]):
        va[i] = 2.0 * i
    for i in range(vb.shape[0]):
        for j in range(vb.shape[1]):
            vb[i, j] = va[j] + i
    keep_alive((a, b))
    return va.shape[0], vb.shape, vb.strides


def test_a_view_is_the_same_memory_with_the_same_shape():
    a = np.zeros(5)
    b = np.zeros((3, 5))[:, ::1]
    n, shape, strides = _write_through_views(a, b)
    assert (n, shape, strides) == (5, b.shape, b.strides)
    assert a.tolist() == [0.0, 2.0, 4.0, 6.0, 8.0]
    assert np.array_equal(b, a[None, :] + np.arange(3)[:, None])
