"""The rate model's compiled kernel that is called with several array types
is compiled for all of them at import, in one fixed order.

Compiled on demand instead, two processes starting from an empty numba cache
(the parallel test workers of a fresh checkout) met its float32 and float64
callers in different orders and their concurrent saves filed one variant's
machine code under another's types: every later process failed with "can't
unbox array from PyObject". Such a race cannot be provoked reliably in a
test, so this checks the property that rules it out."""

import numpy as np
import pytest

from snn_fg.models.rate import _sparse_kernels as nbk


def test_pool_add_is_compiled_for_its_types_at_import_and_never_on_demand():
    assert len(nbk.pool_add.signatures) == len(nbk.POOL_ADD_SIGNATURES) == 4
    assert not nbk.pool_add._can_compile  # a new type is refused, not compiled and cached


@pytest.mark.parametrize("acc_t", (np.float64, np.float32))
@pytest.mark.parametrize("x_t", (np.float64, np.float32))
@pytest.mark.parametrize("strided", (False, True))
def test_every_type_it_is_called_with_gives_the_resize(acc_t, x_t, strided):
    """One target pixel, 4 x 4 taps of weight 1/4 each way over a map of ones
    times its column index: the result is the mean column index times ``scale``."""
    x = np.tile(np.arange(8, dtype=x_t), (1, 8, 1))
    x = x[:, :, ::2] if strided else np.ascontiguousarray(x[:, :, :4])  # columns 0,2,4,6 or 0,1,2,3
    i, w = np.zeros(1, np.int64), np.full((1, 4), 0.25)
    acc = np.zeros(1, acc_t)
    nbk.pool_add(acc, i, i, i, x, i, w, i, w, 2.0)
    assert acc[0] == pytest.approx(2.0 * (3.0 if strided else 1.5))
