"""The colour layer over the OpenColorIO config: names, sources, the sRGB fast path against OCIO, conversions."""

from __future__ import annotations

import numpy as np
import pytest

from helpers.colour import ocio as oiio_convert
from helpers.colour import studio_config
from pyramid_cli.core.errors import UsageError
from pyramid_cli.imageio import colour, ocio


@pytest.fixture(scope="module")
def studio(tmp_path_factory):
    return str(studio_config(tmp_path_factory.mktemp("ocio")))


def test_names_aliases_and_roles_resolve_to_the_configs_spaces():
    assert ocio.canonical("acescg") == ocio.canonical("scene_linear") == "ACEScg"
    assert ocio.canonical("g22_rec709_scene") == "Gamma 2.2 Encoded Rec.709"
    assert ocio.short_name("srgb_rec709_scene") == ocio.short_name("sRGB") == "srgb"
    assert ocio.short_name("lin_rec709_scene") == "linear" and ocio.short_name("ACEScct") == "ACEScct"
    assert ocio.kind("data") == "data" and ocio.kind("ACEScg") == "linear-other" and ocio.kind("ACEScct") == "encoded"
    assert ocio.working_space("ACEScct") == "ACEScg" and ocio.working_space("srgb") == "linear"
    assert ocio.working_space("Raw") == "Raw" and ocio.working_space("lin_ap0") == "ACES2065-1"


def test_the_builtin_names_known_without_loading_are_the_configs():
    import OpenImageIO as oiio

    config = oiio.ColorConfig(ocio.BUILTIN)
    for name, short in ocio.BUILTIN_REC709.items():
        assert config.resolve(ocio.LABELS[short]) == name and config.resolve(short) == name
    ocio._canonical.cache_clear()
    ocio._kind.cache_clear()
    assert ocio._canonical(ocio.BUILTIN, "srgb") == "sRGB Encoded Rec.709 (sRGB)"  # the table
    assert ocio._kind(ocio.BUILTIN, "Linear Rec.709 (sRGB)") == "linear"


def test_an_unknown_space_names_the_nearest_and_a_bad_config_gives_ocios_message(tmp_path, studio):
    with pytest.raises(UsageError, match=r"unknown colour space 'acescgg'.*nearest: ACEScg") as e:
        ocio.canonical("acescgg")
    assert e.value.exit_code == 2
    with pytest.raises(UsageError, match=r"'plate_lgo' in the colour config .*studio.ocio; nearest: plate_log"):
        ocio.canonical("plate_lgo", studio)
    bad = tmp_path / "broken.ocio"
    bad.write_text("ocio_profile_version: 2\ncolorspaces: [\n")
    with pytest.raises(UsageError, match=r"cannot load colour config .*broken.ocio: .*yaml-cpp") as e:
        ocio.load(str(bad))
    assert e.value.exit_code == 2
    with pytest.raises(UsageError, match="non-existent OCIO config"):
        ocio.check_names("srgb", colorconfig=str(tmp_path / "missing.ocio"))


def test_the_input_space_comes_from_option_metadata_file_rule_then_type(studio, monkeypatch):
    assert ocio.input_space("ACEScct", "a.exr", False, "auto") == ("ACEScct", "metadata")
    assert ocio.input_space("nonsense", "a.exr", False, "auto") == ("linear", "default")
    assert ocio.input_space(None, "a.png", True, "auto") == ("srgb", "default")
    assert ocio.input_space("ACEScct", "a.exr", False, "g22_rec709") == ("Gamma 2.2 Encoded Rec.709", "option")
    assert ocio.input_space(None, "shot_log.exr", False, "auto", studio) == ("plate_log", "file rule")
    assert ocio.input_space(None, "shot.exr", False, "auto", studio) == ("plate_lin", "default")
    monkeypatch.setenv("OCIO", studio)  # $OCIO is the default config
    assert ocio.input_space("studio_texture", "x.png", True, "auto") == ("tex_srgb", "metadata")
    assert ocio.short_name("srgb") == "tex_srgb" and ocio.short_name("linear") == "plate_lin"  # their roles


def test_the_exact_srgb_tables_agree_with_ocio():
    codes = np.arange(256, dtype=np.float32) / 255
    px = np.repeat(codes[None, :, None], 3, axis=2)
    decoded = oiio_convert(px, "srgb_rec709_scene", "lin_rec709_scene")[0, :, 0]
    table = colour.srgb_to_linear(codes.astype(np.float64))
    assert np.abs(decoded - table).max() < 3e-5  # OCIO's float32 power function; the tables are exact float64
    ramp = np.linspace(0, 1, 1 << 16, dtype=np.float32)
    encoded = oiio_convert(np.repeat(ramp[None, :, None], 3, axis=2), "lin_rec709_scene", "srgb_rec709_scene")
    theirs = np.floor(encoded[0, :, 0].astype(np.float64) * 255 + 0.5)
    ours = colour.srgb8(ramp).astype(np.float64)
    assert np.abs(ours - theirs).max() <= 1 and np.mean(ours == theirs) > 0.999


def test_conversions_are_ocios_per_pixel_with_grey_for_one_channel():
    rng = np.random.default_rng(1)
    px = rng.random((4, 5, 4)).astype(np.float32)
    got = ocio.convert(px, "ACEScg", "srgb")
    assert np.array_equal(got[..., :3], oiio_convert(px[..., :3], "ACEScg", "srgb_rec709_scene"))
    assert np.array_equal(got[..., 3], px[..., 3])
    grey = ocio.convert(px[..., :1], "srgb", "ACEScct")
    want = oiio_convert(np.repeat(px[..., :1], 3, axis=2), "srgb_rec709_scene", "ACEScct").mean(axis=2)
    assert np.allclose(grey[..., 0], want, atol=1e-6)
    band = ocio.convert(px[1:3], "ACEScg", "srgb")  # pixel by pixel: a band converts as the whole does
    assert np.array_equal(band, got[1:3])


def test_filtering_in_the_inputs_primaries_equals_filtering_in_scene_linear():
    from pyramid_cli.reference.pyramids import blur_reference as blur

    rng = np.random.default_rng(2)
    px = rng.random((16, 16, 3)).astype(np.float32)
    in_709 = blur(px.astype(np.float64), 3)
    in_ap1 = blur(ocio.convert(px, "linear", "ACEScg").astype(np.float64), 3)
    assert np.abs(ocio.convert(in_709.astype(np.float32), "linear", "ACEScg") - in_ap1).max() < 1e-5


def test_which_formats_hold_which_spaces():
    assert ocio.holds("png", "png", "uint8", "srgb") and ocio.holds("png", "png", "uint8", "g22_rec709")
    assert not ocio.holds("png", "png", "uint8", "ACEScct") and not ocio.holds("png", "png", "uint8", "adobergb")
    assert ocio.holds("openexr", "exr", "half", "ACEScct")
    assert ocio.output_space("ACEScg", "ACEScg", False, "png", "png", "uint8") == "srgb"
    assert ocio.output_space("ACEScct", "ACEScg", False, "openexr", "exr", "half") == "ACEScct"
    assert ocio.output_space("srgb", "linear", True, "openexr", "exr", "half") == "linear"
    assert ocio.output_space("Raw", "Raw", True, "openexr", "exr", "half") == "Raw"
