"""Reading images (pyramid_cli.imageio.read): decoding to linear premultiplied light, input errors, NaN/Inf,
half kept as stored, headers.

Fixture files are written with OpenImageIO directly (helpers.images); expected values are computed here from
the formulas, never by the code under test.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from helpers.images import write as write_raw
from helpers.stored import make_png_bytes, read_raw, srgb_eotf
from pyramid_cli import imageio as pio
from pyramid_cli.core.errors import DataError, InputError

RNG = np.random.default_rng(12345)


# ---------------------------------------------------------------------------
# Decoding


def test_srgb_gradient_decodes_with_eotf(tmp_path):
    ramp = np.arange(256, dtype=np.uint8).reshape(1, 256, 1)
    path = tmp_path / "ramp.png"
    write_raw(path, ramp, "uint8")
    img = pio.read_image(path)
    expected = srgb_eotf(np.arange(256) / 255.0)
    np.testing.assert_allclose(img.pixels[0, :, 0], expected, rtol=1e-6, atol=1e-9)
    # Not a 2.2 gamma: the two differ by > 1e-3 in the dark end.
    assert abs(img.pixels[0, 10, 0] - (10 / 255) ** 2.2) > 1e-3


def test_wrong_extension_png_named_exr_reads(tmp_path):
    src = RNG.integers(0, 256, (4, 5, 3)).astype(np.uint8)
    real = tmp_path / "x.png"
    write_raw(real, src, "uint8")
    fake = tmp_path / "x.exr"
    fake.write_bytes(real.read_bytes())
    img = pio.read_image(fake)
    assert img.spec.format == "png" and img.spec.colorspace == "srgb"
    np.testing.assert_allclose(img.pixels, srgb_eotf(src / 255.0), rtol=1e-5, atol=1e-8)


def test_alpha_none_is_an_ordinary_channel(tmp_path):
    src = np.array([[[200, 100, 50, 128]]], dtype=np.uint8)
    path = tmp_path / "a.png"
    write_raw(path, src, "uint8", alpha=3, oiio__UnassociatedAlpha=1)
    img = pio.read_image(path, alpha="none")
    assert img.spec.alpha_mode == "none" and not img.premultiplied
    np.testing.assert_allclose(img.pixels[0, 0, :3], srgb_eotf(src[0, 0, :3] / 255), rtol=1e-6)
    assert img.pixels[0, 0, 3] == pytest.approx(128 / 255)  # alpha never decoded
    pio.write_image(tmp_path / "b.png", img)
    back, _ = read_raw(tmp_path / "b.png")
    np.testing.assert_array_equal(back, src)


def test_keep_half_converts_where_decoding_applies(tmp_path):
    """sRGB-tagged half or straight alpha: decoded in float32, exactly as without keep_half."""
    src = RNG.uniform(0.0, 1.0, (5, 7, 4)).astype(np.float16)
    srgb = tmp_path / "srgb.exr"
    write_raw(srgb, src, "half", names=["R", "G", "B", "A"], alpha=3, oiio__ColorSpace="sRGB")
    kept, plain = pio.read_image(srgb, keep_half=True), pio.read_image(srgb)
    assert kept.pixels.dtype == np.float32
    np.testing.assert_array_equal(kept.pixels, plain.pixels)
    assert not pio.stores_half_unchanged(tmp_path / "o.exr", kept.spec)
    straight = pio.read_image(srgb, keep_half=True, alpha="straight", colorspace="linear")
    assert straight.pixels.dtype == np.float32
    np.testing.assert_array_equal(straight.pixels[..., :3], (src[..., :3].astype(np.float32) * src[..., 3:]))


def test_read_shape_reads_the_header_only(tmp_path):
    path = tmp_path / "in.exr"
    write_raw(path, np.zeros((9, 13, 5), np.float16), "half")
    assert pio.read_shape(path) == (9, 13, 5)
    assert pio.read_shape(tmp_path / "missing.exr") is None
    (tmp_path / "bad.png").write_bytes(b"not a png")
    assert pio.read_shape(tmp_path / "bad.png") is None


# ---------------------------------------------------------------------------
# Input errors


def assert_input_error(path: Path, **kwargs) -> str:
    with pytest.raises(InputError) as err:
        pio.read_image(path, **kwargs)
    message = str(err.value)
    assert str(path) in message
    assert "\n" not in message
    assert err.value.exit_code == 3
    return message


def test_missing_file(tmp_path):
    assert "no such file" in assert_input_error(tmp_path / "nope.png")


def test_directory(tmp_path):
    assert "directory" in assert_input_error(tmp_path)


def test_empty_file(tmp_path):
    (tmp_path / "empty.png").write_bytes(b"")
    assert "empty" in assert_input_error(tmp_path / "empty.png")


def test_text_file_named_png(tmp_path):
    (tmp_path / "notes.png").write_text("this is not an image\n")
    assert_input_error(tmp_path / "notes.png")


def test_fifo_is_not_read(tmp_path):
    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    assert "regular" in assert_input_error(fifo)


def test_unknown_format(tmp_path):
    (tmp_path / "data.xyz").write_bytes(b"\x00\x01\x02\x03" * 64)
    assert_input_error(tmp_path / "data.xyz")


@pytest.mark.parametrize("name,ptype", [("t.png", "uint8"), ("t16.png", "uint16"),
                                        ("t.exr", "half"), ("tf.exr", "float")])
def test_truncated_file(tmp_path, name, ptype):
    src = RNG.random((64, 64, 4)).astype(np.float32)
    if ptype == "uint8":
        src = (src * 255).astype(np.uint8)
    elif ptype == "uint16":
        src = (src * 65535).astype(np.uint16)
    path = tmp_path / name
    write_raw(path, src, ptype)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    assert_input_error(path)


def test_zero_size_png(tmp_path):
    good = tmp_path / "ok.png"
    good.write_bytes(make_png_bytes(3, 2))  # the hand-made PNG itself is valid
    assert pio.read_image(good).pixels.shape == (2, 3, 1)
    bad = tmp_path / "zero.png"
    bad.write_bytes(make_png_bytes(0, 2))
    assert_input_error(bad)


@pytest.mark.skipif(os.geteuid() == 0, reason="root can read anything")
def test_unreadable_file(tmp_path):
    path = tmp_path / "secret.png"
    path.write_bytes(make_png_bytes(2, 2))
    path.chmod(0)
    try:
        assert_input_error(path)
    finally:
        path.chmod(0o644)


# ---------------------------------------------------------------------------
# NaN / Inf


@pytest.fixture
def nan_exr(tmp_path):
    src = np.ones((4, 6, 3), dtype=np.float32)
    src[2, 5, 1] = np.nan
    src[3, 0, 2] = np.inf
    path = tmp_path / "nan.exr"
    write_raw(path, src, "float")
    return path


def test_nan_keep(nan_exr):
    img = pio.read_image(nan_exr)
    assert pio.count_nonfinite(img.pixels) == img.nonfinite == 2  # counted as read, once
    assert np.isnan(img.pixels[2, 5, 1]) and np.isinf(img.pixels[3, 0, 2])


def test_nan_zero(nan_exr):
    img = pio.read_image(nan_exr, nan="zero")
    assert pio.count_nonfinite(img.pixels) == img.nonfinite == 0
    assert img.pixels[2, 5, 1] == 0.0 and img.pixels[3, 0, 2] == 0.0
    assert img.pixels[0, 0, 0] == 1.0


def test_nan_fail(nan_exr):
    with pytest.raises(DataError) as err:
        pio.read_image(nan_exr, nan="fail")
    message = str(err.value)
    assert str(nan_exr) in message and "\n" not in message
    assert "2 non-finite" in message
    assert "x=5, y=2, channel 1 (G)" in message
    assert err.value.exit_code == 5


def test_nan_fail_passes_clean_file(tmp_path):
    write_raw(tmp_path / "ok.exr", np.zeros((2, 2, 3), np.float32), "half")
    assert pio.count_nonfinite(pio.read_image(tmp_path / "ok.exr", nan="fail").pixels) == 0

