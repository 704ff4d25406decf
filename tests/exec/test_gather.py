"""Windows copied a block at a time (``pyramid_cli.exec.gather``): the same values as the fancy index. The CPU
executor's folded windows (:func:`~pyramid_cli.exec.gather.window`) here; the scheduler's: tests/exec/test_tiles.py."""

import numpy as np
import pytest

from pyramid_cli.exec.gather import MAX_BLOCKS, fold_stored, gather, runs, window, window_index
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


@pytest.mark.parametrize("border", ["clamp", "mirror", "wrap", "zero"])
def test_a_window_is_the_folded_gather_of_its_texels(border):
    """``window`` (the CPU executor's border strips) copies slices of the source (each run of a folded index is
    one); it equals the plain gather of the folded indices for every border, window and extent, a fold that bounces
    too often for slices included."""
    rng = np.random.default_rng(3)
    blocks = gathers = 0
    for extent in [(1, 1), (1, 7), (5, 1), (3, 4), (9, 13)]:
        src = rng.standard_normal(extent + (2,)).astype(np.float32)
        for r0 in range(-12, extent[0] + 3, 3):
            for r1 in (r0, r0 + 1, r0 + 5, r0 + 30):
                for c0 in range(-9, extent[1] + 3, 4):
                    for c1 in (c0, c0 + 2, c0 + 17, c0 + 200):
                        ri = fold_stored(np.arange(r0, r1 + 1), extent[0], border)
                        ci = fold_stored(np.arange(c0, c1 + 1), extent[1], border)
                        want = src[np.ix_(np.maximum(ri, 0), np.maximum(ci, 0))]
                        want[ri < 0] = 0
                        want[:, ci < 0] = 0
                        np.testing.assert_array_equal(window(src, (r0, r1), (c0, c1), border), want)
                        sliced = window_index((r0, r1), (c0, c1), extent, border)[1] is not None
                        blocks += sliced
                        gathers += not sliced
    assert blocks > 0
    assert (gathers > 0) == (border in ("mirror", "wrap"))  # a 200-column window over 4 to 13 columns bounces
