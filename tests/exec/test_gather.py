"""Windows copied a block at a time (``pyramid_cli.exec.gather``): the same values as the fancy index. The CPU
executor's folded windows: tests/exec/cpu/test_executor.py; the scheduler's: tests/exec/test_tiles.py."""

import numpy as np
import pytest

from pyramid_cli.exec.gather import MAX_BLOCKS, gather, runs
from pyramid_cli.exec.tiles import _fold


@pytest.mark.parametrize("border", ["mirror", "wrap", "clamp", "zero"])
def test_a_folded_window_is_gathered_as_the_fancy_index_gathers_it(border):
    """Folds reaching past either edge, and windows wider than the image (a mirror bouncing: past
    MAX_BLOCKS copies, the fancy index itself)."""
    rng = np.random.default_rng(11)
    buf = rng.random((50, 60, 3)).astype(np.float32)
    for _ in range(200):
        a, c = int(rng.integers(-70, 60)), int(rng.integers(-80, 70))
        ri = np.maximum(_fold(np.arange(a, a + int(rng.integers(1, 130))), (0, 50), border), 0)
        ci = np.maximum(_fold(np.arange(c, c + int(rng.integers(1, 150))), (0, 60), border), 0)
        np.testing.assert_array_equal(gather(buf, ri, ci), buf[np.ix_(ri, ci)])


def test_any_indices_and_the_runs_they_make():
    rng = np.random.default_rng(12)
    buf = rng.random((50, 60)).astype(np.float32)
    for _ in range(200):
        ri, ci = rng.integers(0, 50, int(rng.integers(1, 12))), rng.integers(0, 60, int(rng.integers(1, 12)))
        np.testing.assert_array_equal(gather(buf, ri, ci), buf[np.ix_(ri, ci)])
    assert runs(np.array([1, 0, 0, 1, 2, 3, 3, 2, 5])) == [(0, 2, 1, -1), (2, 3, 0, 0), (3, 6, 1, 1), (6, 7, 3, 0),
                                                            (7, 8, 2, 0), (8, 9, 5, 0)]
    assert runs(np.array([-1, -1, 0, 1, 2])) == [(0, 2, -1, 0), (2, 5, 0, 1)]
    assert MAX_BLOCKS >= 9  # a window folded at all four edges: three runs each way
