"""The package's re-exports as a whole (pyramid_cli.imageio) and the colour tables behind reading and writing:
sRGB helpers, the 8-bit encoding table and integer decoding, checked against the float64 formulas.

The per-module tests mirror the package: tests/imageio/test_read.py, test_encode.py, test_write.py, ...
"""

from __future__ import annotations

import numpy as np
import pytest

from helpers.stored import srgb_eotf, srgb_oetf
from pyramid_cli import imageio as pio
from pyramid_cli.core.errors import DataError
from pyramid_cli.imageio import colour as pio_colour


def test_check_size():
    pio.check_size(4096, 4096, 4096)
    with pytest.raises(DataError) as err:
        pio.check_size(5000, 300, 4096, where="big.exr")
    assert "5000x300" in str(err.value) and "4096" in str(err.value)
    assert "big.exr" in str(err.value)
    with pytest.raises(DataError):
        pio.check_size(10, 4097, 4096)


def test_count_nonfinite():
    a = np.array([0.0, np.nan, np.inf, -np.inf, 1.0], dtype=np.float32)
    assert pio.count_nonfinite(a) == 3
    assert pio.count_nonfinite(np.zeros((3, 3), np.float32)) == 0


def test_count_nonfinite_of_half_values_agrees_with_isfinite():
    """Every float16 bit pattern (NaNs of every payload and sign, ±inf, the largest finite, subnormals), in a
    contiguous array and in a strided view, counted as numpy's isfinite counts."""
    every = np.arange(1 << 16, dtype=np.uint32).astype(np.uint16).view(np.float16).reshape(256, 64, 4)
    for a in (every, every[::3, 1::2, :3], every[0, 0, :1]):
        assert pio.count_nonfinite(a) == a.size - np.count_nonzero(np.isfinite(a))
    assert pio.count_nonfinite(every) == 2 * 1024  # 2 signs × (inf + 1023 NaN payloads)
    assert pio.count_nonfinite(np.float16([65504.0, -65504.0, 6e-8])) == 0


def test_srgb_helpers_match_formula():
    v = np.linspace(0, 1, 1001)
    np.testing.assert_allclose(pio.srgb_to_linear(v), srgb_eotf(v), rtol=1e-12)
    np.testing.assert_allclose(pio.linear_to_srgb(v), srgb_oetf(v), rtol=1e-12)


def _srgb8_by_formula(x: np.ndarray) -> np.ndarray:
    """The float64 route the table replaces (linear_to_srgb, ×255, round half up, clamp; NaN → 0)."""
    v = np.nan_to_num(pio.linear_to_srgb(x.astype(np.float64)), nan=0.0, posinf=1.0, neginf=0.0) * 255.0
    return np.clip(np.floor(v + 0.5), 0, 255).astype(np.uint8)


@pytest.mark.slow
def test_srgb8_table_equals_the_float64_formula_everywhere_it_matters():
    thresholds, _ = pio_colour.srgb8_tables()
    t = thresholds.view(np.uint32)
    edges = np.concatenate([t - 2, t - 1, t, t + 1]).view(np.float32)  # around every code boundary
    rng = np.random.default_rng(8)
    x = np.concatenate([
        edges, -edges, rng.random(200_000, dtype=np.float32), rng.random(50_000, dtype=np.float32) * 1e-2,
        rng.standard_normal(50_000).astype(np.float32) * 3,
        np.array([0.0, -0.0, 1.0, 1.0000001, 1e30, np.inf, -np.inf, np.nan, 1e-45, 0.0031308], np.float32),
    ])
    with np.errstate(over="ignore", invalid="ignore"):
        np.testing.assert_array_equal(pio_colour.srgb8(x), _srgb8_by_formula(x))
    # every float32 pattern of [0, 1] in steps of 97 ulps, too
    grid = np.arange(0, 0x3F800001, 97, dtype=np.uint32).view(np.float32)
    np.testing.assert_array_equal(pio_colour.srgb8(grid), _srgb8_by_formula(grid))


@pytest.mark.parametrize("bits", [8, 16])
@pytest.mark.parametrize("alpha", ["straight", "premultiplied", "none", "no alpha"])
def test_integer_decoding_by_table_equals_float64_decoding(bits, alpha):
    dtype = np.uint8 if bits == 8 else np.uint16
    codes = np.random.default_rng(bits).integers(0, np.iinfo(dtype).max + 1, (17, 19, 4), dtype=dtype)
    colour = np.array([True, True, True, alpha == "no alpha"])
    a = -1 if alpha in ("none", "no alpha") else 3
    got = pio_colour.decode_integer(codes, True, colour, a, alpha == "straight")
    v = codes.astype(np.float64) / np.iinfo(dtype).max  # the old route, whole image in float64
    if alpha == "premultiplied":
        pio_colour.unpremultiply(v, 3, colour)
    v[..., colour] = srgb_eotf(v[..., colour])
    if a >= 0:
        pio_colour.premultiply(v, 3, colour)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, v.astype(np.float32))
