"""The demo's pictures (pyramid_cli.demo); the whole demo from the wheel: tests/system/test_wheel.py."""

import numpy as np

from pyramid_cli import demo


def test_apple_orange_is_two_pictures_and_a_half_mask():
    a, b, mask = demo.apple_orange(32)
    assert a.shape[:2] == b.shape[:2] == mask.shape[:2] == (32, 32)
    assert np.all((mask == 0) | (mask == 1)) and 0 < mask.mean() < 1
