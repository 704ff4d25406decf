"""The Python API's dtype rules (pyramid_cli.imageio.dtypes): what a result is stored as and computed at."""

from __future__ import annotations

import numpy as np
import pytest

from pyramid_cli.core.errors import UsageError
from pyramid_cli.imageio import dtypes


@pytest.mark.parametrize("source, asked, result, wide", [
    (np.float16, None, np.float16, False), (np.float32, None, np.float32, False), (np.float64, None, np.float64, True),
    (np.uint8, None, np.uint8, False), (np.uint16, None, np.uint16, False), (np.int16, None, np.int16, False),
    (np.uint32, None, np.uint32, True), (np.bool_, None, np.float32, False), (np.uint8, np.float64, np.float64, True),
    (np.float64, np.float32, np.float32, False), (np.float32, "uint16", np.uint16, False),
    (np.uint32, np.float32, np.float32, False), (np.float16, np.float64, np.float64, True),
])
def test_result_dtype_and_width(source, asked, result, wide):
    got = dtypes.result_dtype(np.dtype(source), asked)
    assert got == result and dtypes.is_wide(np.dtype(source), got) is wide


def test_codes_round_trip_and_clip():
    for t in (np.uint8, np.uint16, np.int8, np.int16):
        info = np.iinfo(t)
        codes = np.arange(-info.max if info.min < 0 else 0, info.max + 1, max(1, info.max // 997)).astype(t)[None, :]
        np.testing.assert_array_equal(dtypes.to_dtype(dtypes.as_pixels(codes), t), codes)
    np.testing.assert_array_equal(dtypes.to_dtype(np.array([-0.5, np.nan, 0.5, 1.7]), np.uint8), [0, 0, 128, 255])
    np.testing.assert_array_equal(dtypes.to_dtype(np.array([-2.0, -1.0]), np.int8), [-127, -127])


def test_level_zero_is_a_copy_of_the_callers_array():
    a = np.arange(6, dtype=np.float32).reshape(2, 3)
    z = dtypes.level_zero(a, dtypes.as_pixels(a), np.dtype(np.float32))
    assert not np.shares_memory(z, a) and np.array_equal(z, a)
    assert dtypes.level_zero(a, dtypes.as_pixels(a), np.dtype(np.float16)).dtype == np.float16


@pytest.mark.parametrize("asked", [bool, "complex64", "U4", "not a type"])
def test_a_dtype_that_is_no_real_number_is_refused(asked):
    with pytest.raises(UsageError, match="dtype"):
        dtypes.result_dtype(np.dtype(np.float32), asked)
