"""Files in, files out for the pyramid methods (pyramid_cli.run.methods_files): pyramid fill and blend on image
files, mask files, and mipmap --fill's texture fill; what they do to arrays: tests/workflows/test_methods.py."""

from __future__ import annotations

import json

import numpy as np
import pytest

import pyramid_cli as pyr
from helpers.cli import invoke
from helpers.images import write_method_files


# ------------------------------------------------------------------ the command line
@pytest.fixture(scope="module")
def files(tmp_path_factory):
    return write_method_files(tmp_path_factory.mktemp("methods"))


def test_cli_fill_alpha_equals_the_api_and_is_opaque(files, tmp_path):
    out = tmp_path / "filled.exr"
    r = invoke("fill", files / "holes.exr", out, "--json", "--backend", "cpu")
    assert r.exit_code == 0, r.output
    info = json.loads(r.output)
    assert info["empty"] == 20 * 40 and info["partial"] == 1 and info["levels"] == 6
    src = pyr.read_image(files / "holes.exr").pixels
    got = pyr.read_image(out).pixels
    np.testing.assert_allclose(got, pyr.fill(src, backend="reference"), rtol=0, atol=1e-5)
    assert np.all(got[..., 3] == 1)
    known = src[..., 3] == 1
    np.testing.assert_array_equal(got[known], src[known])


def test_cli_fill_mask_and_nan(files, tmp_path):
    r = invoke("fill", "--mask", files / "m.exr", files / "a.exr", tmp_path / "m.exr", "-q")
    assert r.exit_code == 0 and r.output == ""
    a = pyr.read_image(files / "a.exr").pixels
    m = pyr.read_image(files / "m.exr").pixels[..., 0]
    np.testing.assert_allclose(pyr.read_image(tmp_path / "m.exr").pixels, pyr.fill(a, mask=m, backend="reference"),
                               rtol=0, atol=1e-5)
    r = invoke("fill", "--holes", "nan", files / "nan.exr", tmp_path / "n.exr")
    assert r.exit_code == 0, r.output
    assert np.all(np.isfinite(pyr.read_image(tmp_path / "n.exr").pixels))


@pytest.mark.parametrize("args, code, message", [
    (["fill", "{d}/empty.exr", "{o}"], 5, "no known pixel"),
    (["fill", "{d}/a.exr", "{o}"], 2, "no alpha channel"),
    (["fill", "--holes", "nan", "--nan", "zero", "{d}/nan.exr", "{o}"], 2, "--nan zero"),
    (["fill", "{d}/missing.exr", "{o}"], 3, "missing.exr"),
    (["blend", "{d}/a.exr", "{d}/holes.exr", "{d}/m.exr", "{o}"], 3, "channel"),
])
def test_cli_errors_are_one_line_with_their_exit_code(files, tmp_path, args, code, message):
    r = invoke(*[a.format(d=files, o=tmp_path / "x.exr") for a in args])
    assert r.exit_code == code, r.output
    assert message in r.output and "Traceback" not in r.output
    assert not (tmp_path / "x.exr").exists()


def test_cli_blend_equals_the_api(files, tmp_path):
    r = invoke("blend", files / "a.exr", files / "b.exr", files / "m.exr", tmp_path / "o.exr", "--levels", "3",
                "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["levels"] == 3
    a, b = pyr.read_image(files / "a.exr").pixels, pyr.read_image(files / "b.exr").pixels
    m = pyr.read_image(files / "m.exr").pixels
    np.testing.assert_allclose(pyr.read_image(tmp_path / "o.exr").pixels,
                               pyr.blend(a, b, m, levels=3, backend="reference"), rtol=0, atol=1e-5)


# ------------------------------------------------------------------ mipmap --fill and --keep-alpha
def _uv_islands(path):
    """An 8-bit sRGB RGBA texture: three islands of different colours (alpha 255) on empty texels (alpha 0)."""
    import OpenImageIO as oiio

    h, w = 96, 80
    px = np.zeros((h, w, 4), np.uint8)
    y, x = np.mgrid[0:h, 0:w]
    islands = [((y - 25) ** 2 + (x - 22) ** 2 < 300, (200, 60, 40)), ((y > 55) & (y < 90) & (x > 8) & (x < 40),
               (40, 170, 90)), ((y - 40) ** 2 / 4 + (x - 62) ** 2 < 150, (230, 200, 60))]
    for where, rgb in islands:
        px[where] = (*rgb, 255)
    px[..., :3] += (np.arange(w) % 7).astype(np.uint8)[None, :, None] * (px[..., 3:] > 0)  # some texture
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), oiio.ImageSpec(w, h, 4, "uint8"))
    out.write_image(px)
    out.close()
    return px


def _levels_of(path):
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    levels, m = [], 0
    while inp.seek_subimage(0, m):  # a "Plain Texture" TIFF's subimages read as MIP levels
        levels.append(inp.read_image(0, m, 0, 4, "uint8"))
        m += 1
    inp.close()
    return levels


def test_mipmap_fill_keeps_known_texels_and_levels_off_the_hole_colour(tmp_path):
    src = tmp_path / "bake.png"
    px = _uv_islands(src)
    for name, extra in [("plain.tx", []), ("filled.tx", ["--fill"])]:
        r = invoke("mipmap", *extra, src, tmp_path / name, "--tile", "16", "-q", "--backend", "cpu")
        assert r.exit_code == 0, r.output
    plain, filled = _levels_of(tmp_path / "plain.tx"), _levels_of(tmp_path / "filled.tx")
    assert len(plain) == len(filled) > 5
    known = px[..., 3] == 255
    np.testing.assert_array_equal(filled[0][known], px[known])  # level 0's known texels, byte for byte
    assert np.all(filled[0][..., 3] == 255)
    lo = px[known][:, :3].min(axis=0).astype(float)
    hi = px[known][:, :3].max(axis=0).astype(float)
    for k in range(1, len(filled)):
        mean_filled = filled[k][..., :3].reshape(-1, 3).mean(axis=0)
        mean_plain = plain[k][..., :3].reshape(-1, 3).mean(axis=0)
        assert np.all(mean_filled >= lo - 1) and np.all(mean_filled <= hi + 1), (k, mean_filled)
        island_mean = px[known][:, :3].mean(axis=0)
        # the chain without --fill darkens toward the empty texels' black; --fill stays near the islands' colours
        assert np.abs(mean_filled - island_mean).max() < 0.5 * np.abs(mean_plain - island_mean).max(), k


def test_cli_keep_alpha_png_keeps_the_cut_out_with_colour_under_it(tmp_path):
    import OpenImageIO as oiio

    src = tmp_path / "decal.png"
    px = _uv_islands(src)
    for name, extra in [("opaque.png", []), ("kept.png", ["--keep-alpha"])]:
        r = invoke("fill", *extra, src, tmp_path / name, "-q", "--backend", "cpu")
        assert r.exit_code == 0, r.output

    def codes(path):  # the stored codes, as they are (OpenImageIO would associate alpha on read)
        config = oiio.ImageSpec()
        config.attribute("oiio:UnassociatedAlpha", 1)
        inp = oiio.ImageInput.open(str(path), config)
        out = np.asarray(inp.read_image(0, 0, 0, 4, "uint8"))
        inp.close()
        return out

    opaque, kept = codes(tmp_path / "opaque.png"), codes(tmp_path / "kept.png")
    np.testing.assert_array_equal(kept[..., 3], px[..., 3])          # the cut-out as it was
    np.testing.assert_array_equal(kept[..., :3], opaque[..., :3])    # the fill's colours under it, everywhere
    known = px[..., 3] == 255
    np.testing.assert_array_equal(kept[known], px[known])
    assert np.all(opaque[..., 3] == 255) and kept[~known][:, :3].any()


# ------------------------------------------------------------------ mask files
def _mask_file(path, pixels, channel_names=None):
    pyr.write_image(path, np.asarray(pixels, np.float32), pixel_type="float", channel_names=channel_names)
    return path


@pytest.mark.parametrize("command", ["fill", "blend"])
def test_a_nan_in_a_mask_is_treated_as_in_an_image(files, tmp_path, command):
    """--nan keep (the default): kept with a warning naming the mask, as an image's NaN is; zero: read as 0;
    fail: refused (exit 5). A blend mask's NaN used to spread to thousands of pixels silently."""
    m = pyr.read_image(files / "m.exr").pixels[..., :1].copy()
    m[10, 10:14] = np.nan
    bad = _mask_file(tmp_path / "nan_mask.exr", m)
    args = (["fill", "--mask", bad, files / "a.exr"] if command == "fill"
            else ["blend", files / "a.exr", files / "b.exr", bad])
    r = invoke(*args, tmp_path / "o.exr", "--backend", "cpu")
    assert r.exit_code == 0, r.output
    assert r.stderr == (f"pyramid: warning: {bad}: 4 NaN/Inf value(s) kept in the mask; they spread through the "
                        "filter (--nan zero or --nan fail to change that)\n")
    assert np.isnan(pyr.read_image(tmp_path / "o.exr").pixels).any()
    r = invoke(*args, tmp_path / "o.exr", "--backend", "cpu", "--nan", "zero")
    assert r.exit_code == 0 and r.stderr == "", r.output
    assert np.all(np.isfinite(pyr.read_image(tmp_path / "o.exr").pixels))
    r = invoke(*args, tmp_path / "o2.exr", "--backend", "cpu", "--nan", "fail")
    assert r.exit_code == 5 and str(bad) in r.stderr and not (tmp_path / "o2.exr").exists(), r.output


@pytest.mark.parametrize("command", ["fill", "blend"])
def test_mask_values_outside_0_1_are_clipped_with_a_warning_that_counts_them(files, tmp_path, command):
    m = pyr.read_image(files / "m.exr").pixels[..., 0].copy()
    m[0, :5] = 1.25
    m[1, :3] = -0.5
    over = _mask_file(tmp_path / "over.exr", m)
    clipped = _mask_file(tmp_path / "clipped.exr", np.clip(m, 0, 1))
    outs = []
    for mask, name in [(over, "o1.exr"), (clipped, "o2.exr")]:
        args = (["fill", "--mask", mask, files / "a.exr"] if command == "fill"
                else ["blend", files / "a.exr", files / "b.exr", mask])
        r = invoke(*args, tmp_path / name, "--backend", "cpu")
        assert r.exit_code == 0, r.output
        outs.append((r.stderr, pyr.read_image(tmp_path / name).pixels))
    assert outs[0][0] == (f"pyramid: warning: {over}: 8 mask value(s) outside [0, 1] (from -0.5 to 1.25) clipped "
                          "to [0, 1]\n")
    assert outs[1][0] == ""
    np.testing.assert_array_equal(outs[0][1], outs[1][1])
    a = pyr.read_image(files / "a.exr").pixels
    with pytest.warns(UserWarning, match=r"8 mask value\(s\) outside \[0, 1\]") as caught:
        pyr.blend(a, a, m, backend="cpu") if command == "blend" else pyr.fill(a, mask=m, backend="cpu")
    assert caught[0].filename == __file__


def test_mask_channels_one_or_the_images_or_an_alpha_else_refused_naming_both(files, tmp_path):
    m = pyr.read_image(files / "m.exr").pixels[..., 0]
    noise = np.random.default_rng(4).random(m.shape)
    rg = _mask_file(tmp_path / "rg.exr", np.stack([m, noise], axis=2), ["R", "G"])
    ya = _mask_file(tmp_path / "ya.exr", np.stack([noise, m], axis=2))  # Y, A: the alpha is the mask
    for args in (["blend", files / "a.exr", files / "b.exr", rg], ["fill", "--mask", rg, files / "a.exr"]):
        r = invoke(*args, tmp_path / "o.exr", "--backend", "cpu")
        assert r.exit_code == 3, r.output
        assert r.output == (f"pyramid: error: {rg}: the mask has 2 channels (R, G) and no alpha, the image 3: give "
                            "one channel, one per channel, or an alpha channel\n")
        assert not (tmp_path / "o.exr").exists()
    r = invoke("blend", files / "a.exr", files / "b.exr", ya, tmp_path / "ya_out.exr", "--backend", "cpu")
    assert r.exit_code == 0, r.output
    assert r.stderr == f"pyramid: warning: {ya}: 2 channels for an image of 3: its alpha channel A is the mask\n"
    a, b = pyr.read_image(files / "a.exr").pixels, pyr.read_image(files / "b.exr").pixels
    np.testing.assert_allclose(pyr.read_image(tmp_path / "ya_out.exr").pixels, pyr.blend(a, b, m, backend="cpu"),
                               rtol=0, atol=1e-6)
    with pytest.raises(ValueError, match="the mask is 64x64 with 2 channel"):
        pyr.blend(a, b, np.stack([m, noise], axis=2), backend="cpu")

