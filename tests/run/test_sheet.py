"""Contact sheets of panels side by side (pyramid_cli.run.sheet)."""

import numpy as np

from pyramid_cli.run.sheet import contact_sheet


def test_panels_side_by_side_top_aligned_on_grey():
    grey = np.ones((4, 3))
    rgba = np.zeros((2, 5, 4), np.float32)
    out = contact_sheet([grey, rgba], gap=2)
    assert out.shape == (4, 3 + 2 + 5, 3) and out.dtype == np.float32
    np.testing.assert_array_equal(out[:, :3], 1.0)
    np.testing.assert_array_equal(out[:2, 5:], 0.0)
    np.testing.assert_array_equal(out[2:, 5:], np.float32(0.2))
    np.testing.assert_array_equal(out[:, 3:5], np.float32(0.2))
