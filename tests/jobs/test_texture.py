"""The MIP chain a renderer reads (pyramid_cli.jobs.texture.TextureLevels): maketx's settings, checked when made,
what the chain's name and level count say, and the mean every level keeps under every wrap mode (issue 26: the
levels are built inside the texture's domain). Its plans against the oracle: tests/plan/test_resample.py."""

import numpy as np
import pytest

import pyramid_cli as pyr
from pyramid_cli.core.errors import UsageError
from pyramid_cli.core.geometry import mip_sizes
from pyramid_cli.jobs.texture import TextureLevels

# The sizes (rows, columns): one texel, strips, odd, large odd, HD and a tall strip.
SIZES = [(1, 1), (1, 7), (7, 1), (5, 3), (37, 51), (777, 1001), (1080, 1920), (4097, 3)]
BORDERS = ["clamp", "zero", "wrap", "mirror"]  # maketx's clamp, black, periodic, mirror


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


def gradient(h: int, w: int, channels: int = 2) -> np.ndarray:
    """A ramp plus noise: where edge texels weigh too much or too little, the mean moves."""
    y, x = np.mgrid[0:h, 0:w]
    ramp = 0.2 + (x + 0.5) / w + 0.5 * (y + 0.5) / h
    noise = np.random.default_rng(h * 7919 + w).random((h, w, channels))
    return (ramp[..., None] * np.array([1.0, 0.5][:channels]) + 0.3 * noise).astype(np.float32)


@pytest.fixture(scope="module")
def cpu_means(cpu_executor):
    """Level means / level 0's mean − 1 of every level, CPU executor, float32 output: {(size, border): [...]}."""
    out = {}
    for size in SIZES:
        x = gradient(*size)
        mean = x.astype(np.float64).mean(axis=(0, 1))
        for border in BORDERS:
            plan = TextureLevels(levels=None, border=border).plan([size], "paper")
            levels = cpu_executor.run_outputs(plan, x) if plan is not None else []
            assert [lv.shape[:2] for lv in levels] == mip_sizes(size)[1:]
            out[size, border] = [np.abs(lv.astype(np.float64).mean(axis=(0, 1)) / mean - 1).max() for lv in levels]
    return out


@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("border", BORDERS)
def test_every_level_keeps_level_0s_mean_under_every_wrap(cpu_means, size, border):
    """clamp and black included: their levels are built by the filter folded back into the domain."""
    assert max(cpu_means[size, border], default=0) < 1e-6, cpu_means[size, border]


@pytest.mark.parametrize("border", BORDERS)
def test_the_float64_reference_keeps_the_mean_to_rounding(border):
    for size in [(1, 7), (7, 1), (5, 3), (37, 51), (2, 9)]:
        x = gradient(*size).astype(np.float64)
        for k, level in enumerate(TextureLevels(levels=None, border=border).reference([x])):
            np.testing.assert_allclose(level.mean(axis=(0, 1)), x.mean(axis=(0, 1)), rtol=1e-14, atol=0,
                                       err_msg=f"{size} {border} level {k + 1}")


@pytest.mark.parametrize("border", ["clamp", "zero"])
def test_the_api_builds_inside_the_domain_and_round_up_pads_as_documented(border):
    """pyr.mipmap follows the same rule on every backend; --round up keeps the border's padding (its mean moves)."""
    x = gradient(5, 3)
    mean = x.astype(np.float64).mean(axis=(0, 1))
    for backend in ("reference", "cpu"):
        for level in pyr.mipmap(x, border=border, backend=backend)[1:]:
            np.testing.assert_allclose(level.astype(np.float64).mean(axis=(0, 1)), mean, rtol=1e-6)
    up = pyr.mipmap(x, border=border, rounding="up", backend="reference")
    assert [lv.shape[:2] for lv in up] == [(5, 3), (3, 2), (2, 1), (1, 1)]
    assert np.abs(up[-1].astype(np.float64).mean(axis=(0, 1)) / mean - 1).max() > 1e-3
