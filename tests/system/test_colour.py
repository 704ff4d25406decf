"""Colour as VFX pipelines manage it (issue 25), against OpenImageIO's own OpenColorIO: every result equals
"convert with OCIO, filter with the reference, convert back" (1e-4 in float, one code in 8 bits), every label
names the space the pixels are in, and a studio config works through ``$OCIO`` and ``--colorconfig``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.cli import invoke
from helpers.colour import ocio, studio_config
from helpers.images import write
from pyramid_cli.imageio import ocio as layer
from pyramid_cli.reference.pyramids import blur_reference

BIN = Path(sys.executable).parent
MAKETX, OIIOTOOL = str(BIN / "maketx"), str(BIN / "oiiotool")
CPU = ["--backend", "cpu"]
N = 24  # small pictures: the whole module runs in a few seconds


def read(path, nch: int | None = None) -> tuple[np.ndarray, str]:
    """The stored values as float (no colour rules) and the label."""
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, oiio.geterror()
    spec = inp.spec()
    px = np.asarray(inp.read_image(0, 0, 0, nch or spec.nchannels, "float"), dtype=np.float64)
    label = spec.get_string_attribute("oiio:ColorSpace")
    inp.close()
    return px.reshape(spec.height, spec.width, -1), label


def codes(values) -> np.ndarray:
    return np.floor(np.clip(np.asarray(values, dtype=np.float64), 0, 1) * 255 + 0.5)


def blur(px, levels: int = 2) -> np.ndarray:
    return blur_reference(np.asarray(px, dtype=np.float64), levels)


def rgb(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).random((N, N, 3)).astype(np.float32)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("colour")


def run(*args) -> str:
    r = invoke(*CPU[:0], *args)
    assert r.exit_code == 0, r.output
    return r.output


def test_acescg_exr_to_srgb_png_matches_oiiotools_conversion(folder):
    """ACEScg filtered in linear light and written as an 8-bit PNG: sRGB-encoded Rec.709, primaries
    converted, labelled sRGB (it was AP1 values sRGB-encoded, up to 137 codes off)."""
    src = write(folder / "plate_cg.exr", rgb(1), "float", oiio__ColorSpace="ACEScg")
    run("blur", *CPU, "--levels", "2", src, folder / "cg.png")
    ref = folder / "cg_ref.exr"
    write(ref, blur(rgb(1)), "float", oiio__ColorSpace="ACEScg")
    subprocess.run([OIIOTOOL, str(ref), "--colorconvert", "ACEScg", "srgb_rec709_scene", "-d", "uint8", "-o",
                    str(folder / "cg_ref.png")], check=True)
    got, label = read(folder / "cg.png")
    want, _ = read(folder / "cg_ref.png")
    assert np.abs(codes(got) - codes(want)).max() <= 1
    assert layer.equivalent(label, "srgb_rec709_scene")


@pytest.mark.parametrize("space, pixel_type, scale", [("ACEScct", "half", 1.0), ("pq_rec2020_display", "half", 0.6)])
def test_encoded_float_exrs_in_and_out(folder, space, pixel_type, scale):
    """A log (ACEScct) and a PQ half EXR are decoded by OCIO, filtered in scene_linear, written back in their
    own space and labelled so (the ACEScct one was filtered in log: off by up to 0.13)."""
    stored = ocio(rgb(2), "ACEScg", space) * scale
    src = write(folder / f"{space}.exr", stored, pixel_type, oiio__ColorSpace=space)
    stored = read(src)[0]
    run("blur", *CPU, "--levels", "2", "--type", "float", src, folder / f"{space}_out.exr")
    got, label = read(folder / f"{space}_out.exr")
    want = ocio(blur(ocio(stored, space, "ACEScg")), "ACEScg", space)
    assert np.abs(got - want).max() < 1e-4
    assert np.abs(blur(stored) - want).max() > 1e-3  # filtering the stored values is visibly wrong
    assert layer.equivalent(label, space)


@pytest.mark.parametrize("space, option, out_label", [
    ("g22_rec709_scene", [], "g22_rec709_scene"),          # PNG holds gamma 2.2 (gAMA): stays
    ("adobergb", ["--colorspace", "adobergb"], "srgb_rec709_scene"),  # PNG cannot say AdobeRGB: sRGB
])
def test_gamma_and_adobergb_pngs(folder, space, option, out_label):
    stored = codes(rgb(3)).astype(np.uint8)
    src = write(folder / f"{space}.png", stored, "uint8",
                **({"oiio__ColorSpace": space} if not option else {}))
    out = folder / f"{space}_out.png"
    run("apply", *CPU, *option, "h_Bartlett ⊗ g", src, out)
    got, label = read(out)
    linear = ocio(stored / 255.0, space, "ACEScg")
    from pyramid_cli.api import apply

    filtered = apply("h_Bartlett ⊗ g", linear.astype(np.float32), backend="reference")
    want = ocio(filtered, "ACEScg", out_label)
    assert np.abs(codes(got) - codes(want)).max() <= 1
    assert layer.equivalent(label, out_label)


def test_a_data_matte_is_filtered_as_stored(folder):
    matte = np.random.default_rng(4).random((N, N, 1)).astype(np.float32) * 4 - 1
    src = write(folder / "matte.exr", matte, "float", oiio__ColorSpace="Raw")
    out = run("blur", *CPU, "-v", "--levels", "2", src, folder / "matte_out.exr")
    got, label = read(folder / "matte_out.exr")
    assert np.abs(got - blur(matte)).max() < 1e-6 and layer.kind(label) == "data"
    assert "Raw (metadata): linear light, no decoding" in out


@pytest.mark.parametrize("name, pixel_type, label", [("id_cct.exr", "float", "ACEScct"),
                                                      ("id_g22.png", "uint8", "g22_rec709_scene")])
def test_the_identity_keeps_pixels_and_label(folder, name, pixel_type, label):
    stored = rgb(5) if pixel_type == "float" else codes(rgb(5)).astype(np.uint8)
    src = write(folder / name, stored, pixel_type, oiio__ColorSpace=label)
    out = folder / f"out_{name}"
    run("apply", *CPU, "[1] * g", src, out)
    got, got_label = read(out)
    if pixel_type == "uint8":
        assert np.array_equal(codes(got), codes(read(src)[0]))
    else:
        assert np.abs(got - stored).max() < 1e-5
    assert got_label == read(src)[1]


def test_whole_and_streamed_give_the_same_bytes(folder):
    tall = np.random.default_rng(6).random((128, 16, 3)).astype(np.float32)  # bands cost less than the whole
    src = write(folder / "stream_cct.exr", ocio(tall, "ACEScg", "ACEScct"), "half", oiio__ColorSpace="ACEScct")
    run("blur", *CPU, "--levels", "2", src, folder / "whole.exr")
    out = run("blur", *CPU, "-v", "--levels", "2", "--memory", "40K", src, folder / "bands.exr")
    assert "streams in bands of 8" in out and "ACEScct (metadata): converted to ACEScg" in out
    a, b = read(folder / "whole.exr"), read(folder / "bands.exr")
    assert np.array_equal(a[0], b[0]) and a[1] == b[1]


def test_mipmap_colorconvert_matches_maketx_and_the_texture_system(folder):
    stored = codes(rgb(7)[:16, :16]).astype(np.uint8)
    src = write(folder / "albedo.png", stored, "uint8")
    ours, theirs = folder / "ours.tx.exr", folder / "theirs.tx.exr"
    run("mipmap", *CPU, "--analysis", "box", "--type", "float", "--colorconvert", "sRGB", "ACEScg", src, ours)
    subprocess.run([MAKETX, "--colorconvert", "sRGB", "ACEScg", "-d", "float", str(src), "-o", str(theirs)],
                   check=True, capture_output=True)
    for level in range(5):
        a, b = (np.asarray(oiio.ImageBuf(str(p), 0, level).get_pixels(oiio.FLOAT)) for p in (ours, theirs))
        assert np.abs(a - b).max() < 1e-4, level
    spec = oiio.ImageInput.open(str(ours)).spec()
    assert "--colorconvert sRGB ACEScg" in spec.get_string_attribute("Exif:ImageHistory")
    assert layer.equivalent(spec.get_string_attribute("oiio:ColorSpace"), "ACEScg")
    run("mipmap", *CPU, "--analysis", "box", "--type", "float", src, folder / "plain.tx.exr")
    plain = oiio.ImageInput.open(str(folder / "plain.tx.exr")).spec()
    assert plain.get_string_attribute("oiio:SHA-1") != spec.get_string_attribute("oiio:SHA-1")
    ts = oiio.TextureSystem(shared=False)
    opt = oiio.TextureOpt()
    opt.interpmode = oiio.InterpMode.Closest
    looked = np.array([[ts.texture(str(ours), opt, (x + 0.5) / 16, (y + 0.5) / 16, 0, 0, 0, 0, 3)
                        for x in range(16)] for y in range(16)])
    assert np.abs(looked - ocio(stored / 255.0, "srgb_rec709_scene", "ACEScg")).max() < 1e-4


def test_a_studio_config_through_ocio_and_colorconfig(folder, monkeypatch):
    config = studio_config(folder)
    plate = ocio(rgb(8), "plate_lin", "plate_log", str(config))
    src = write(folder / "shot_log.exr", plate, "float")  # no label: the config's file rule names it
    out = run("apply", *CPU, "-v", "--colorconfig", config, "[1] * g", src, folder / "shot_out.exr")
    assert "plate_log (file rule)" in out and "output " in out
    got, label = read(folder / "shot_out.exr")
    assert label == "plate_log" and np.abs(got - plate).max() < 1e-4
    r = invoke("apply", *CPU, "--colorconfig", config, "--tocolorspace", "plate_lgo", "[1] * g", src,
               folder / "x.exr")
    assert r.exit_code == 2 and "nearest: plate_log" in r.output and "studio.ocio" in r.output
    monkeypatch.setenv("OCIO", str(config))
    run("apply", *CPU, "--tocolorspace", "studio_texture", "h_Bartlett ⊗ g", src, folder / "tex.png")
    got, label = read(folder / "tex.png")
    from pyramid_cli.api import apply

    lin = ocio(plate, "plate_log", "plate_lin", str(config))
    want = ocio(apply("h_Bartlett ⊗ g", lin, backend="reference").astype(np.float32), "plate_lin", "tex_srgb",
                str(config))
    assert np.abs(codes(got) - codes(want)).max() <= 1


def test_errors_name_the_nearest_spaces_and_the_configs_message(folder):
    src = write(folder / "e.exr", rgb(9), "float")
    r = invoke("apply", *CPU, "--colorspace", "acescgg", "[1] * g", src, folder / "e_out.exr")
    assert r.exit_code == 2 and "nearest: ACEScg" in r.output
    bad = folder / "bad.ocio"
    bad.write_text("ocio_profile_version: 2\ncolorspaces: [\n")
    r = invoke("apply", *CPU, "--colorconfig", bad, "[1] * g", src, folder / "e_out.exr")
    assert r.exit_code == 2 and "cannot load colour config" in r.output and "yaml-cpp" in r.output
    r = invoke("apply", *CPU, "--tocolorspace", "ACEScct", "[1] * g", src, folder / "e_out.png")
    assert r.exit_code == 2 and "cannot be stored in PNG" in r.output
    assert not (folder / "e_out.exr").exists() and not (folder / "e_out.png").exists()


def test_diff_compares_in_a_named_space(folder):
    """``pyramid diff --tocolorspace`` decodes both files and converts them to one space: an ACEScg EXR and the
    sRGB PNG made of it agree within a code there, and differ grossly as stored."""
    inside = ocio(rgb(10) * 0.9 + 0.05, "lin_rec709_scene", "ACEScg")  # within the sRGB gamut
    src = write(folder / "diff_cg.exr", inside, "float", oiio__ColorSpace="ACEScg")
    run("apply", *CPU, "[1] * g", src, folder / "cg_id.png")
    r = invoke("diff", "--tocolorspace", "srgb", "--fail", "0.0045", src, folder / "cg_id.png")
    assert r.exit_code == 0, r.output
    assert invoke("diff", "--fail", "0.0045", src, folder / "cg_id.png").exit_code == 2  # idiff: failure
    r = invoke("diff", "--tocolorspace", "srgbb", src, folder / "cg_id.png")
    assert r.exit_code == 2 and "nearest:" in r.output


def test_blend_mixes_two_spaces_in_one(folder):
    """An ACEScct plate blended with an sRGB PNG: B is brought into A's linear space first (a constant mask of 0
    gives B, converted to A's space)."""
    a = write(folder / "blend_a.exr", ocio(rgb(11), "ACEScg", "ACEScct"), "float", oiio__ColorSpace="ACEScct")
    stored = codes(rgb(12)).astype(np.uint8)
    b = write(folder / "blend_b.png", stored, "uint8")
    m = write(folder / "blend_m.exr", np.zeros((N, N, 1), np.float32), "float")
    run("blend", "--backend", "reference", a, b, m, folder / "blend_out.exr")
    got, label = read(folder / "blend_out.exr")
    assert np.abs(got - ocio(stored / 255.0, "srgb_rec709_scene", "ACEScct")).max() < 1e-4
    assert layer.equivalent(label, "ACEScct")


def test_laplacian_bands_stay_in_linear_light(folder):
    """Band-pass levels of an ACEScct plate are signed linear detail: written in ACEScg, labelled so, and they
    collapse back to the plate (in its own space again)."""
    src = write(folder / "cct_for_laplacian.exr", ocio(rgb(13), "ACEScg", "ACEScct"), "float",
                oiio__ColorSpace="ACEScct")
    run("levels", "--backend", "reference", "--laplacian", "--levels", "2", src, folder / "lap_{level}.exr")
    labels = [read(folder / f"lap_{k}.exr")[1] for k in range(3)]
    assert all(layer.equivalent(label, "ACEScg") for label in labels)
    run("collapse", "--backend", "reference", "--tocolorspace", "ACEScct", folder / "lap_*.exr",
        folder / "lap_back.exr")
    assert np.abs(read(folder / "lap_back.exr")[0] - read(src)[0]).max() < 1e-4
