"""The MIP chain a renderer reads (pyramid_cli.jobs.texture.TextureLevels): maketx's settings, checked when made,
and what the chain's name and level count say. Its plans against the oracle: tests/plan/test_resample.py."""

import pytest

from pyramid_cli.core.errors import UsageError
from pyramid_cli.jobs.texture import TextureLevels


def test_round_down_refuses_what_it_cannot_resample():
    with pytest.raises(UsageError, match="one separable ⊗↓ step"):
        TextureLevels(analysis="box *v^2 g")
    TextureLevels(analysis="box *v^2 g", rounding="up")  # the pyramid's rule takes any ⊗↓


@pytest.mark.parametrize("kw, message", [
    ({"rounding": "sideways"}, "unknown rounding 'sideways'"),
    ({"rounding": "up", "resize": True}, "--resize makes maketx's power-of-two levels: it needs --round down"),
    ({"nchannels": 0}, "--nchannels 0: at least 1"),
])
def test_settings_maketx_refuses_are_refused(kw, message):
    with pytest.raises(UsageError, match=message):
        TextureLevels(levels=None, **kw)


def test_the_filter_name_says_everything_that_changes_the_texels():
    assert TextureLevels(levels=None).filter_name == TextureLevels(levels=None).analysis
    full = TextureLevels(levels=None, analysis="box", resize=True, nchannels=1, monochrome_detect=True, fill=True)
    assert full.filter_name == "box/resize/nchannels=1/monochrome-detect/fill"
    assert TextureLevels(levels=None, analysis="box", rounding="up").filter_name == "box/up"


def test_level_counts_follow_the_rounding_and_resize_makes_level_0():
    assert TextureLevels(levels=None).count((13, 6)) == 3           # 6×3, 3×1, 1×1
    assert TextureLevels(levels=None, rounding="up").count((13, 6)) == 4  # 7×3, 4×2, 2×1, 1×1
    assert TextureLevels(levels=None, resize=True).count((13, 6)) == 5  # 16×8 first, then down to 1×1
    assert TextureLevels(levels=None).keeps_input and not TextureLevels(levels=None, resize=True).keeps_input
    assert TextureLevels(levels=None).plan([(1, 1)]) is None  # nothing to make
