"""sRGB curves and non-finite counts (pyramid_cli.imageio.colour)."""

import numpy as np

from pyramid_cli.imageio import colour


def test_srgb_curves_are_inverse_and_match_the_standard_at_known_points():
    x = np.linspace(0, 1, 1001)
    np.testing.assert_allclose(colour.srgb_to_linear(colour.linear_to_srgb(x)), x, rtol=0, atol=1e-6)
    np.testing.assert_allclose(colour.srgb_to_linear(np.array([0.0, 0.04045, 1.0])), [0, 0.04045 / 12.92, 1],
                               rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(colour.linear_to_srgb(np.array([0.5])), [0.7353569830524495], rtol=1e-6)


def test_count_nonfinite():
    assert colour.count_nonfinite(np.array([0.0, np.nan, np.inf, -np.inf, 1.0])) == 3
