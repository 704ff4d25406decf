"""The float64 oracle of pull-push filling and multiresolution blending (pyramid_cli.reference.methods).

Every executor is held to it in tests/workflows/test_methods.py; here, what the papers' equations promise.
"""

import numpy as np

from pyramid_cli.reference import methods


def test_fill_keeps_known_pixels_and_fills_a_constant_with_the_constant():
    colour = np.full((17, 13, 3), 0.25)
    weight = np.zeros((17, 13, 3))
    weight[3, 4] = weight[10, 9] = 1
    out = methods.fill(colour * weight, weight)
    np.testing.assert_allclose(out, colour, rtol=0, atol=1e-12)


def test_blend_with_a_mask_of_ones_is_the_first_picture():
    rng = np.random.default_rng(0)
    a, b = rng.random((16, 20)), rng.random((16, 20))
    np.testing.assert_allclose(methods.blend(a, b, np.ones((16, 20)), 3), a, rtol=0, atol=1e-12)
    np.testing.assert_allclose(methods.blend(a, b, np.zeros((16, 20)), 3), b, rtol=0, atol=1e-12)
