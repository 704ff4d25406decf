"""What a write stores (pyramid_cli.imageio.encode): pixel types, colour encoding, alpha, rounding and dither,
compression, windows and metadata, checked by round trips through files.

Fixture files are written, and outputs read back, with OpenImageIO directly (helpers.images, helpers.stored);
expected values are computed here from the formulas, never by the code under test.
"""

from __future__ import annotations

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.images import write as write_raw
from helpers.stored import png_row_filters, read_raw, srgb_eotf, srgb_oetf
from pyramid_cli import imageio as pio
from pyramid_cli.core.errors import UsageError

RNG = np.random.default_rng(12345)


# ---------------------------------------------------------------------------
# Round trips


@pytest.mark.parametrize("ptype", ["half", "float"])
@pytest.mark.parametrize("compression", ["zip", "piz"])
def test_exr_multichannel_round_trip(tmp_path, ptype, compression):
    names = ["diffuse.R", "diffuse.G", "diffuse.B", "A", "depth.Z"]
    src = RNG.uniform(-2.0, 8.0, (9, 13, 5))
    src = src.astype(np.float16 if ptype == "half" else np.float32).astype(np.float32)
    path = tmp_path / "in.exr"
    write_raw(path, src, ptype, names=names, alpha=3, compression=compression,
              studio__shot="sh010_take2")

    img = pio.read_image(path)
    info = img.spec
    # EXR keeps channels sorted by layer, so compare by name, not position.
    assert sorted(info.channel_names) == sorted(names)
    order = [names.index(n) for n in info.channel_names]
    src = src[..., order]
    assert img.pixels.dtype == np.float32 and img.pixels.shape == (9, 13, 5)
    np.testing.assert_array_equal(img.pixels, src)  # EXR: linear, premultiplied as stored
    assert (info.format, info.pixel_type) == ("openexr", ptype)
    assert info.channel_names[info.alpha_channel] == "A"
    assert (info.colorspace, info.alpha_mode) == ("linear", "premultiplied")
    assert info.attributes["studio:shot"] == "sh010_take2"

    out = tmp_path / "out.exr"
    pio.write_image(out, img, inputs=[path])
    back, spec = read_raw(out, "float")
    np.testing.assert_array_equal(back, src)
    assert str(spec.format) == ptype
    assert list(spec.channelnames) == info.channel_names
    assert spec.channelnames[spec.alpha_channel] == "A"
    assert spec.get_string_attribute("compression") == compression
    assert spec.get_string_attribute("studio:shot") == "sh010_take2"


def test_exr_compression_override_and_window(tmp_path):
    src = RNG.random((6, 8, 3)).astype(np.float32)
    path = tmp_path / "in.exr"
    h, w, c = src.shape
    spec = oiio.ImageSpec(w, h, c, "half")
    spec.x, spec.y = 5, 7
    spec.full_x, spec.full_y, spec.full_width, spec.full_height = 0, 0, 32, 24
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), spec)
    out.write_image(src)
    out.close()

    img = pio.read_image(path)
    dst = tmp_path / "out.exr"
    pio.write_image(dst, img, compression="piz")
    _, spec2 = read_raw(dst)
    assert spec2.get_string_attribute("compression") == "piz"
    assert (spec2.x, spec2.y, spec2.width, spec2.height) == (5, 7, 8, 6)
    assert (spec2.full_width, spec2.full_height) == (32, 24)

    # A resized image no longer matches the windows: written at the origin.
    small = pio.Image(img.pixels[::2, ::2].copy(), img.spec)
    pio.write_image(tmp_path / "small.exr", small)
    _, spec3 = read_raw(tmp_path / "small.exr")
    assert (spec3.x, spec3.y, spec3.width, spec3.height) == (0, 0, 4, 3)


@pytest.mark.parametrize("bits", [8, 16])
@pytest.mark.parametrize("channels", [3, 4])
def test_png_round_trip_bit_exact(tmp_path, bits, channels):
    top = 255 if bits == 8 else 65535
    dtype = np.uint8 if bits == 8 else np.uint16
    src = RNG.integers(0, top + 1, (17, 23, channels)).astype(dtype)
    if channels == 4:
        # Alpha 0 holds no colour once premultiplied, so keep alpha > 0 here
        # (the transparent case is tested on its own below).
        src[..., 3] = RNG.integers(1, top + 1, (17, 23))
        src[0, 0, 3] = top
        src[0, 1, 3] = 1
    path = tmp_path / "in.png"
    write_raw(path, src, "uint8" if bits == 8 else "uint16",
              alpha=3 if channels == 4 else None, oiio__UnassociatedAlpha=1)

    img = pio.read_image(path)
    info = img.spec
    assert info.pixel_type == ("uint8" if bits == 8 else "uint16")
    assert info.colorspace == "srgb"
    expected = srgb_eotf(src[..., :3] / top)
    if channels == 4:
        a = src[..., 3:] / top
        assert info.alpha_mode == "straight" and info.alpha_channel == 3
        expected = expected * a
        np.testing.assert_allclose(img.pixels[..., 3:], a, rtol=1e-6)
    np.testing.assert_allclose(img.pixels[..., :3], expected, rtol=1e-5, atol=1e-7)

    out = tmp_path / "out.png"
    pio.write_image(out, img)
    back, spec = read_raw(out)
    assert back.dtype == dtype
    np.testing.assert_array_equal(back, src)


def test_png_16bit_every_code_round_trips(tmp_path):
    src = np.arange(65536, dtype=np.uint16).reshape(256, 256, 1)
    path = tmp_path / "ramp16.png"
    write_raw(path, src, "uint16")
    img = pio.read_image(path)
    pio.write_image(tmp_path / "out.png", img)
    back, _ = read_raw(tmp_path / "out.png")
    np.testing.assert_array_equal(back, src)


@pytest.mark.parametrize("ptype", ["uint8", "uint16", "float"])
def test_tiff_round_trip(tmp_path, ptype):
    if ptype == "float":
        src = RNG.uniform(-1.0, 4.0, (11, 7, 3)).astype(np.float32)
    else:
        top = 255 if ptype == "uint8" else 65535
        src = RNG.integers(0, top + 1, (11, 7, 3)).astype(
            np.uint8 if ptype == "uint8" else np.uint16)
    path = tmp_path / "in.tif"
    write_raw(path, src, ptype, compression="lzw")
    img = pio.read_image(path)
    assert img.spec.pixel_type == ptype
    assert img.spec.colorspace == ("linear" if ptype == "float" else "srgb")
    if ptype == "float":
        np.testing.assert_array_equal(img.pixels, src)
    pio.write_image(tmp_path / "out.tif", img)
    back, spec = read_raw(tmp_path / "out.tif")
    assert str(spec.format) == ptype
    assert spec.get_string_attribute("compression") == "lzw"
    np.testing.assert_array_equal(back, src)


def test_tiff_associated_alpha_round_trip(tmp_path):
    # OpenImageIO writes TIFF alpha as associated (ExtraSamples=1).
    src = RNG.integers(0, 256, (5, 6, 4)).astype(np.uint8)
    src[..., 3] = 255
    src[0, :, 3] = 128
    src[0, :, :3] = np.minimum(src[0, :, :3], 128)  # valid premultiplied data
    path = tmp_path / "in.tif"
    write_raw(path, src, "uint8", alpha=3)
    img = pio.read_image(path)
    assert img.spec.alpha_mode == "premultiplied"
    pio.write_image(tmp_path / "out.tif", img)
    back, _ = read_raw(tmp_path / "out.tif")
    np.testing.assert_array_equal(back, src)


def test_jpeg_round_trip_with_tolerance(tmp_path):
    y, x = np.mgrid[0:32, 0:48]
    src = np.stack([x * 5, y * 7, (x + y) * 3], axis=-1).clip(0, 255).astype(np.uint8)
    path = tmp_path / "in.jpg"
    write_raw(path, src, "uint8", Compression="jpeg:100")
    img = pio.read_image(path)
    assert (img.spec.format, img.spec.pixel_type, img.spec.colorspace) == ("jpeg", "uint8", "srgb")
    pio.write_image(tmp_path / "out.jpg", img, compression="jpeg:100")
    back, spec = read_raw(tmp_path / "out.jpg")
    assert str(spec.format) == "uint8"
    assert np.abs(back.astype(int) - src.astype(int)).max() <= 8
    assert np.abs(back.astype(int) - src.astype(int)).mean() < 1.5


# ---------------------------------------------------------------------------
# Colour


def test_linear_average_of_black_and_white_is_188(tmp_path):
    src = np.array([[[0, 0, 0], [255, 255, 255]]], dtype=np.uint8)
    path = tmp_path / "bw.png"
    write_raw(path, src, "uint8")
    img = pio.read_image(path)
    avg = img.pixels.mean(axis=1, keepdims=True)
    pio.write_image(tmp_path / "avg.png", pio.Image(avg, img.spec))
    back, _ = read_raw(tmp_path / "avg.png")
    assert back.tolist() == [[[188, 188, 188]]]
    assert round(float(srgb_oetf(0.5)) * 255) == 188  # the golden, from the formula


def test_linear_metadata_and_override(tmp_path):
    src = np.array([[[64, 128, 255]]], dtype=np.uint8)
    tagged = tmp_path / "lin.png"
    write_raw(tagged, src, "uint8", oiio__ColorSpace="lin_rec709_scene")
    img = pio.read_image(tagged)
    assert img.spec.colorspace == "linear"
    np.testing.assert_allclose(img.pixels[0, 0], src[0, 0] / 255.0, rtol=1e-6)
    pio.write_image(tmp_path / "lin_out.png", img)
    back, spec = read_raw(tmp_path / "lin_out.png")
    np.testing.assert_array_equal(back, src)
    assert "lin" in spec.get_string_attribute("oiio:ColorSpace").lower()

    plain = tmp_path / "plain.png"
    write_raw(plain, src, "uint8")
    forced = pio.read_image(plain, colorspace="linear")
    np.testing.assert_allclose(forced.pixels[0, 0], src[0, 0] / 255.0, rtol=1e-6)
    # Write the same linear pixels explicitly as sRGB.
    pio.write_image(tmp_path / "as_srgb.png", forced, colorspace="srgb")
    back, _ = read_raw(tmp_path / "as_srgb.png")
    expected = np.floor(srgb_oetf(src[0, 0] / 255.0) * 255 + 0.5)
    np.testing.assert_array_equal(back[0, 0], expected)


def test_exr_to_png_and_jpeg_conversions(tmp_path):
    lin = np.array([[[0.0, 0.5, 1.0, 1.0], [0.25, 0.25, 0.25, 0.5]]], dtype=np.float32)
    # 16x16 blocks so JPEG chroma subsampling does not mix the two colours.
    lin = np.repeat(np.repeat(lin, 16, axis=0), 16, axis=1)
    path = tmp_path / "in.exr"
    write_raw(path, lin, "half", names=list("RGBA"), alpha=3, compression="piz",
              studio__note="keep me")
    img = pio.read_image(path)

    # half cannot go into PNG: uint16, sRGB-encoded, straight alpha.
    pio.write_image(tmp_path / "out.png", img)
    back, spec = read_raw(tmp_path / "out.png")
    assert str(spec.format) == "uint16"
    straight = lin[..., :3] / lin[..., 3:]
    expected = np.floor(srgb_oetf(straight) * 65535 + 0.5)
    np.testing.assert_array_equal(back[..., :3], expected)
    np.testing.assert_array_equal(back[..., 3], np.floor(lin[..., 3] * 65535 + 0.5))
    assert spec.get_string_attribute("studio:note") == "keep me"

    # JPEG: uint8, no alpha (composited over black); a float asked for is refused, not ignored.
    with pytest.raises(UsageError, match="JPEG"):
        pio.write_image(tmp_path / "out.jpg", img, pixel_type="float", compression="jpeg:100")
    pio.write_image(tmp_path / "out.jpg", img, compression="jpeg:100")
    back, spec = read_raw(tmp_path / "out.jpg")
    assert str(spec.format) == "uint8" and spec.nchannels == 3
    expected = np.floor(srgb_oetf(lin[..., :3]) * 255 + 0.5)
    for x in (8, 24):  # block centres, away from JPEG edge ringing
        assert np.abs(back[8, x].astype(int) - expected[8, x]).max() <= 3

    # And back to EXR from a PNG: integer input, float output -> linear.
    png = pio.read_image(tmp_path / "out.png")
    pio.write_image(tmp_path / "again.exr", png)
    again, spec = read_raw(tmp_path / "again.exr", "float")
    assert str(spec.format) == "half"
    np.testing.assert_allclose(again, lin, atol=2e-3)


# ---------------------------------------------------------------------------
# Alpha


def box3(px: np.ndarray) -> np.ndarray:
    padded = np.pad(px, ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = px.shape[:2]
    return sum(padded[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)) / 9.0


@pytest.mark.parametrize("bits", [8, 16])
def test_transparent_hole_has_no_fringe(tmp_path, bits):
    top = 255 if bits == 8 else 65535
    src = np.zeros((12, 12, 4), dtype=np.uint16)
    src[..., 0] = top
    src[..., 3] = top
    # The hole: fully transparent, with garbage colour that must not leak.
    src[4:8, 4:8] = [top // 3, top, top // 2, 0]
    src = src.astype(np.uint8 if bits == 8 else np.uint16)
    path = tmp_path / "hole.png"
    write_raw(path, src, "uint8" if bits == 8 else "uint16", alpha=3,
              oiio__UnassociatedAlpha=1)

    img = pio.read_image(path)
    assert img.spec.alpha_mode == "straight"
    np.testing.assert_array_equal(img.pixels[4:8, 4:8], 0.0)  # premultiplied: nothing there
    filtered = box3(img.pixels.astype(np.float64)).astype(np.float32)
    pio.write_image(tmp_path / "out.png", pio.Image(filtered, img.spec))

    back, _ = read_raw(tmp_path / "out.png")
    back = back.astype(np.int64)
    alpha = back[..., 3]
    visible = alpha > 0
    # Every partly or fully visible pixel is still pure red, full intensity.
    assert np.all(back[..., 1][visible] <= 1) and np.all(back[..., 2][visible] <= 1)
    assert np.all(back[..., 0][visible] >= top - 1)
    # Edge pixels really are partly transparent.
    assert 0 < alpha[3, 5] < top
    # Alpha 0 pixels carry colour 0 (no NaN turned into garbage).
    assert np.all(back[~visible][:, :3] == 0)
    assert (~visible).any()


def test_alpha_zero_writes_without_nan(tmp_path):
    info = pio.ImageInfo(path="mem", format="png", pixel_type="uint8",
                         channel_names=list("RGBA"), alpha_channel=3,
                         colorspace="srgb", alpha_mode="straight", attributes={})
    px = np.array([[[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0],
                    [-0.1, 0.2, 0.0, -0.01], [0.25, 0.25, 0.25, 0.5]]], dtype=np.float32)
    with np.errstate(all="raise"):
        pio.write_image(tmp_path / "a0.png", pio.Image(px, info))
    back, _ = read_raw(tmp_path / "a0.png")
    assert back[0, :3].tolist() == [[0, 0, 0, 0]] * 3
    expected = np.floor(srgb_oetf(0.5) * 255 + 0.5)
    assert back[0, 3].tolist() == [expected] * 3 + [128]


def test_png_rgba_to_exr_is_premultiplied(tmp_path):
    src = np.array([[[255, 128, 0, 128]]], dtype=np.uint8)
    path = tmp_path / "a.png"
    write_raw(path, src, "uint8", alpha=3, oiio__UnassociatedAlpha=1)
    img = pio.read_image(path)
    pio.write_image(tmp_path / "a.exr", img, pixel_type="float")
    back, spec = read_raw(tmp_path / "a.exr", "float")
    a = 128 / 255
    expected = np.append(srgb_eotf(src[0, 0, :3] / 255) * a, a)
    np.testing.assert_allclose(back[0, 0], expected, rtol=1e-6)
    assert str(spec.format) == "float"


# ---------------------------------------------------------------------------
# Rounding, clamping, dither


def linear_info(pixel_type="uint8", fmt="png", channels=1):
    return pio.ImageInfo(path="mem", format=fmt, pixel_type=pixel_type,
                         channel_names=["Y", "Y2", "Y3"][:channels], alpha_channel=-1,
                         colorspace="linear", alpha_mode="none", attributes={})


def test_uint8_rounds_to_nearest_and_clamps(tmp_path):
    vals = [-0.5, 0.0, 0.49 / 255, 0.51 / 255, 127.5 / 255, 200.49 / 255, 1.0, 7.0,
            float("nan"), float("inf"), float("-inf")]
    px = np.array(vals, dtype=np.float32).reshape(1, -1, 1)
    pio.write_image(tmp_path / "r.png", pio.Image(px, linear_info()))
    back, _ = read_raw(tmp_path / "r.png")
    assert back[0, :, 0].tolist() == [0, 0, 0, 1, 128, 200, 255, 255, 0, 255, 0]


def test_uint16_rounding(tmp_path):
    px = np.array([0.4 / 65535, 0.6 / 65535, 1000.4 / 65535, 1000.6 / 65535, 1.5],
                  dtype=np.float64).astype(np.float32).reshape(1, -1, 1)
    pio.write_image(tmp_path / "r16.png", pio.Image(px, linear_info("uint16")))
    back, _ = read_raw(tmp_path / "r16.png")
    assert back[0, :, 0].tolist() == [0, 1, 1000, 1001, 65535]


def test_dither_is_deterministic_and_mean_preserving(tmp_path):
    level = 100.3
    px = np.full((64, 64, 1), level / 255, dtype=np.float32)
    img = pio.Image(px, linear_info())
    pio.write_image(tmp_path / "plain.png", img)
    pio.write_image(tmp_path / "d1.png", img, dither=True)
    pio.write_image(tmp_path / "d2.png", img, dither=True)
    plain, _ = read_raw(tmp_path / "plain.png")
    d1, _ = read_raw(tmp_path / "d1.png")
    d2, _ = read_raw(tmp_path / "d2.png")
    assert np.all(plain == 100)
    np.testing.assert_array_equal(d1, d2)
    assert set(np.unique(d1).tolist()) == {100, 101}
    assert abs(d1.mean() - level) < 0.02
    # Exact codes are not disturbed by the dither.
    exact = pio.Image(np.full((16, 16, 1), 37 / 255, dtype=np.float32), linear_info())
    pio.write_image(tmp_path / "exact.png", exact, dither=True)
    assert np.all(read_raw(tmp_path / "exact.png")[0] == 37)


def test_pixel_type_override(tmp_path):
    src = RNG.integers(0, 256, (3, 4, 3)).astype(np.uint8)
    write_raw(tmp_path / "in.png", src, "uint8")
    img = pio.read_image(tmp_path / "in.png")
    pio.write_image(tmp_path / "o16.png", img, pixel_type="uint16")
    back, spec = read_raw(tmp_path / "o16.png")
    assert str(spec.format) == "uint16"
    np.testing.assert_array_equal(back, src.astype(np.uint16) * 257)
    pio.write_image(tmp_path / "o.tif", img, pixel_type="float")
    back, spec = read_raw(tmp_path / "o.tif")
    # Integer input, float output: stored linear.
    assert str(spec.format) == "float"
    np.testing.assert_allclose(back, srgb_eotf(src / 255), rtol=1e-6, atol=1e-9)


def test_bad_option_values(tmp_path):
    with pytest.raises(UsageError):
        pio.read_image(tmp_path / "x.png", nan="ignore")
    img = pio.Image(np.zeros((1, 1, 1), np.float32), linear_info())
    with pytest.raises(UsageError):
        pio.write_image(tmp_path / "x.png", img, pixel_type="int8")


# ---------------------------------------------------------------------------
# Half stored unchanged


def test_keep_half_reads_and_writes_half_unchanged(tmp_path):
    src = RNG.uniform(-2.0, 8.0, (9, 13, 4)).astype(np.float16)
    src[2, 3, 1] = np.inf
    path = tmp_path / "in.exr"
    write_raw(path, src, "half", names=["R", "G", "B", "A"], alpha=3, compression="piz")
    img = pio.read_image(path, keep_half=True)
    assert img.pixels.dtype == np.float16
    np.testing.assert_array_equal(img.pixels.view(np.uint16), src.view(np.uint16))
    assert pio.read_image(path).pixels.dtype == np.float32  # only when asked

    out = tmp_path / "out.exr"
    assert pio.stores_half_unchanged(out, img.spec)
    pio.write_image(out, img)
    back, spec = read_raw(out)
    assert str(spec.format) == "half" and spec.get_string_attribute("compression") == "piz"
    np.testing.assert_array_equal(np.asarray(back).view(np.uint16), src.view(np.uint16))

    as_float = tmp_path / "out_float.exr"
    assert not pio.stores_half_unchanged(as_float, img.spec, pixel_type="float")
    pio.write_image(as_float, img, pixel_type="float")
    back, spec = read_raw(as_float)
    assert str(spec.format) == "float"
    np.testing.assert_array_equal(back, src.astype(np.float32))


def test_stores_half_unchanged_rules(tmp_path):
    half = pio.ImageInfo(path="in.exr", format="openexr", pixel_type="half", channel_names=["R", "G", "B", "A"],
                         alpha_channel=3, colorspace="linear", alpha_mode="premultiplied")
    assert pio.stores_half_unchanged("o.exr", half)
    assert not pio.stores_half_unchanged("o.png", half)            # integers
    assert not pio.stores_half_unchanged("o.exr", half, pixel_type="float")
    assert not pio.stores_half_unchanged("o.exr", half, colorspace="srgb")
    assert not pio.stores_half_unchanged("o.exr", half, alpha="straight")
    assert not pio.stores_half_unchanged("o.hdr", half)            # float-only format without half
    assert not pio.stores_half_unchanged("o.unknown", half)
    assert not pio.stores_half_unchanged("o.tif", half)            # OpenImageIO writes float (no tiff:half)
    assert not pio.stores_half_unchanged("o.tx", half)


@pytest.mark.parametrize("name", ["o.exr", "o.tif"])
def test_a_half_result_is_rounded_before_writing_only_where_the_file_is_the_same(tmp_path, name):
    """What stores_half_unchanged promises: where it says yes, the float32 result and the result rounded to half
    write the same pixels; where they would not, it says no (a TIFF stores the float32 values)."""
    src = tmp_path / "in.exr"
    write_raw(src, np.random.default_rng(8).random((6, 7, 3)).astype(np.float16), "half", names=["R", "G", "B"])
    info = pio.read_image(src, keep_half=True).spec
    result = np.random.default_rng(9).random((6, 7, 3)).astype(np.float32)
    written = []
    for k, px in enumerate((result, result.astype(np.float16))):
        out = tmp_path / f"{k}{name}"
        pio.write_image(out, pio.Image(px, info))
        written.append(np.asarray(read_raw(out)[0], np.float32))
    same = np.array_equal(written[0], written[1])
    assert pio.stores_half_unchanged(tmp_path / name, info) == same
    assert same == (name == "o.exr")



@pytest.mark.parametrize("out, channels, alpha, options", [
    ("x.jpg", 3, -1, {}),                      # the 8-bit sRGB table
    ("x.png", 4, 3, {}),                       # straight alpha in an 8-bit file
    ("x.jpg", 4, 3, {}),                       # alpha dropped: colour over black
    ("x.png", 3, -1, {"dither": True}),        # the 8-row dither pattern
    ("x.tif", 3, -1, {"pixel_type": "uint16"}),
    ("x.exr", 4, 3, {"pixel_type": "half"}),
])
def test_an_encoder_decides_once_and_encodes_bands_as_the_whole(out, channels, alpha, options):
    """Encoder (what a streamed file and a tile set keep from band to band) gives, band by band, the values and
    the spec :func:`encode` gives for the whole picture."""
    from pyramid_cli.imageio.encode import Encoder, encode

    names = list("RGBA")[:channels]
    info = pio.ImageInfo(path="mem", format="png", pixel_type="uint8", channel_names=names, alpha_channel=alpha,
                         colorspace="srgb", alpha_mode="premultiplied" if alpha >= 0 else "none", attributes={})
    rng = np.random.default_rng(3)
    px = rng.uniform(-0.1, 1.2, (24, 13, channels)).astype(np.float32)
    if alpha >= 0:
        px[..., alpha] = rng.uniform(0, 1, (24, 13))
        px[..., :alpha] *= px[..., alpha:alpha + 1]
    spec, whole = encode(out, pio.Image(px, info), check_path=False, **options)
    enc = Encoder(out, info, channels, check_path=False, **options)
    bands = np.concatenate([enc.values(px[y:y + 8]) for y in range(0, 24, 8)])
    assert bands.dtype == whole.dtype and np.array_equal(bands, whole)
    assert enc.spec(13, 24).nchannels == spec.nchannels and enc.spec(13, 24).format == spec.format
    assert list(enc.spec(13, 24).channelnames) == list(spec.channelnames)


@pytest.mark.parametrize("ptype", ["uint8", "uint16"])
def test_png_rows_are_filtered_with_none_sub_or_up(tmp_path, ptype):
    """PNG rows are filtered with libpng's NONE, SUB or UP only (formats.PNG_FILTERS: as small files, faster
    writes than letting libpng also try AVG and PAETH); OpenImageIO's own default uses those too."""
    y, x = np.mgrid[0:64, 0:96]
    px = np.dstack([(x * y % 97) / 96.0, np.sin(x / 5.0) * 0.5 + 0.5, RNG.uniform(0, 1, (64, 96))])
    plain = tmp_path / "plain.png"  # the picture through OpenImageIO with no hint
    write_raw(plain, px.astype(np.float32), ptype)
    assert png_row_filters(plain) - {0, 1, 2}, "OpenImageIO's default uses AVG or PAETH here: this checks nothing"
    ours = tmp_path / "ours.png"
    pio.write_image(ours, pio.read_image(plain))
    assert png_row_filters(ours) <= {0, 1, 2}
    assert np.array_equal(read_raw(ours)[0], read_raw(plain)[0])


@pytest.mark.parametrize("compression, filters", [
    ("6:none", {0}),
    ("6:sub", {1}),
    ("9:all", {0, 1, 2, 3, 4}),
    ("1", {0, 1, 2}),
])
def test_png_row_filters_follow_the_compression(tmp_path, compression, filters):
    """``--compression LEVEL:FILTERS`` (formats.png_compression): the row filters libpng may choose from, by libvips's
    names (``6:none``: unfiltered, as libvips writes); the pixels are the same whatever the filters."""
    y, x = np.mgrid[0:64, 0:96]
    px = np.dstack([(x * y % 97) / 96.0, np.sin(x / 5.0) * 0.5 + 0.5, RNG.uniform(0, 1, (64, 96))])
    plain = write_raw(tmp_path / "plain.png", px.astype(np.float32), "uint8")
    out = tmp_path / "out.png"
    pio.write_image(out, pio.read_image(plain), compression=compression)
    used = png_row_filters(out)
    assert used <= filters and (len(filters) != 1 or used == filters), used
    if compression == "9:all":
        assert used - {0, 1, 2}, used  # AVG or PAETH: as OpenImageIO's default does on this picture
    assert np.array_equal(read_raw(out)[0], read_raw(plain)[0])


def test_an_unknown_png_compression_is_refused_before_anything_is_written(tmp_path):
    plain = write_raw(tmp_path / "plain.png", np.zeros((4, 4, 3), np.float32), "uint8")
    with pytest.raises(UsageError, match=r"unknown --compression 6:bogus \(PNG takes a zlib level 0-9, and "):
        pio.write_image(tmp_path / "out.png", pio.read_image(plain), compression="6:bogus")
    assert not (tmp_path / "out.png").exists()


@pytest.mark.parametrize("asked", [None, "half", "float"])
def test_a_tiff_stores_half_only_when_asked(tmp_path, asked):
    """OpenImageIO writes a TIFF's half pixels as float unless told: a half input gives a float TIFF, and
    ``--type half`` a half one (``tiff:half``), as -v says; the values are the input's either way."""
    import tifffile

    px = RNG.uniform(-2.0, 8.0, (9, 7, 3)).astype(np.float16)
    src = write_raw(tmp_path / "in.exr", px, "half")
    image = pio.read_image(src, keep_half=True)
    out = tmp_path / "o.tif"
    pio.write_image(out, image, pixel_type=asked)
    stored = "half" if asked == "half" else "float"
    assert pio.describe_output(out, image.spec, pixel_type=asked).startswith(f"output {out}: {stored},")
    inp = oiio.ImageInput.open(str(out))
    assert str(inp.spec().format) == stored
    inp.close()
    data = tifffile.imread(out)
    assert data.dtype == (np.float16 if asked == "half" else np.float32)
    assert np.array_equal(data.astype(np.float32), px.astype(np.float32))
