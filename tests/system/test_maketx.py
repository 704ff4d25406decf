"""``pyramid mipmap`` as a renderer sees it: wrap modes, maketx's metadata, MIP-mapped .tx/.tif.

Real clients check the files: OpenImageIO's TextureSystem (the lookup renderers use),
``maketx`` (the metadata keys and values it writes for the same input) and ``oiiotool``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from click.testing import CliRunner

from helpers.images import write
from helpers.marks import slow_beyond, slow_unless
from helpers.paths import ROOT
from pyramid_cli import imageio as pio
from pyramid_cli.cli import main
from pyramid_cli.core.geometry import mip_sizes
from pyramid_cli.workflows.mip import hash_extra, parse_wrap, pixel_sha1

BIN = Path(sys.executable).parent
MAKETX, OIIOTOOL = str(BIN / "maketx"), str(BIN / "oiiotool")
CPU = ["--backend", "cpu"]


def levels_of(path: Path, pixel_type: str = "float") -> list[np.ndarray]:
    inp = oiio.ImageInput.open(str(path))
    levels = []
    while inp.seek_subimage(0, len(levels)):
        nch = inp.spec().nchannels
        levels.append(np.asarray(inp.read_image(0, len(levels), 0, nch, pixel_type)))
    inp.close()
    return levels


def attributes(path: Path) -> dict:
    inp = oiio.ImageInput.open(str(path))
    spec = inp.spec()
    inp.close()
    return {a.name: a.value for a in spec.extra_attribs}


def mipmap(*args) -> None:
    r = CliRunner().invoke(main, ["mipmap", *CPU, *map(str, args)])
    assert r.exit_code == 0, r.output


def tileable(h: int = 32, w: int = 64) -> np.ndarray:
    """A periodic texture: integer-period sinusoids, seamless when tiled."""
    y, x = np.mgrid[0:h, 0:w]
    u, v = 2 * np.pi * x / w, 2 * np.pi * y / h
    r = 0.5 + 0.25 * np.sin(3 * u) + 0.2 * np.cos(5 * v + 2 * u)
    g = 0.5 + 0.3 * np.sin(7 * u + v)
    b = 0.5 + 0.3 * np.cos(u) * np.sin(2 * v)
    return np.stack([r, g, b], axis=-1).astype(np.float32)


@pytest.fixture
def png8(tmp_path) -> Path:
    src = tmp_path / "albedo.png"
    write(src, (np.random.default_rng(3).random((64, 48, 3)) * 255).astype(np.uint8), "uint8")
    return src


# ---------------------------------------------------------------------------------------------- wrap


def seam_ratio(levels) -> float:
    """The largest jump across the wrap seam over the largest jump between neighbours inside, over levels/axes."""
    worst = 0.0
    for level in levels:
        for axis in (0, 1):
            if level.shape[axis] < 3:
                continue
            inner = np.abs(np.diff(level, axis=axis)).max()
            seam = np.abs(np.take(level, 0, axis=axis) - np.take(level, -1, axis=axis)).max()
            worst = max(worst, seam / inner)
    return float(worst)


@pytest.mark.parametrize("h, w, bound", [(32, 64, 1.01), (37, 51, 1.25)])
def test_periodic_wrap_is_seamless_at_every_level(tmp_path, h, w, bound):
    """Where levels halve exactly the seam is no larger than the largest interior step. At odd sizes (samples
    37/18 px apart) the seam pair is one more pair of neighbouring samples of the same periodic signal and may
    sit where the slope peaks (8 % over the interior's largest step here), while a seam that does not wrap
    jumps twice as far (clamp: 1.97×), which the test tells apart."""
    src, dst, clamped = tmp_path / "tile.exr", tmp_path / "tile.tx.exr", tmp_path / "clamp.tx.exr"
    write(src, tileable(h, w))
    mipmap("--wrap", "periodic", "--tile", "16", "--type", "float", src, dst)
    levels = levels_of(dst)
    assert [lv.shape[:2] for lv in levels] == mip_sizes((h, w))
    assert seam_ratio(levels) <= bound
    mipmap("--wrap", "clamp", "--tile", "16", "--type", "float", src, clamped)
    assert seam_ratio(levels_of(clamped)) > 1.5


@pytest.mark.parametrize("wrap, border, attr", [("black", "zero", "black,black"), ("clamp", "clamp", "clamp,clamp"),
                                                 ("periodic", "wrap", "periodic,periodic"),
                                                 ("mirror,mirror", "mirror", "mirror,mirror")])
def test_wrap_sets_the_border_and_the_wrapmodes(tmp_path, wrap, border, attr):
    src, a, b = tmp_path / "in.exr", tmp_path / "a.exr", tmp_path / "b.exr"
    write(src, np.random.default_rng(1).random((20, 24, 3)).astype(np.float32))
    mipmap("--wrap", wrap, src, a)
    mipmap("--border", border, src, b)
    assert attributes(a)["wrapmodes"] == attr == attributes(b)["wrapmodes"]
    for x, y in zip(levels_of(a), levels_of(b), strict=True):
        np.testing.assert_array_equal(x, y)


def test_swrap_twrap_and_the_default():
    assert parse_wrap(None) is None
    assert parse_wrap("periodic") == ("periodic", "periodic")
    assert parse_wrap(None, swrap="clamp", twrap="clamp") == ("clamp", "clamp")
    assert parse_wrap("black", twrap="mirror") == ("black", "mirror")


@pytest.mark.parametrize("args, says", [(["--swrap", "clamp", "--twrap", "periodic"], "differ per axis"),
                                        (["--wrap", "periodic,clamp"], "differ per axis"),
                                        (["--wrap", "tile"], "unknown wrap mode 'tile'"),
                                        (["--wrap", "clamp", "--border", "wrap"], "contradicts"),
                                        (["--tile", "24"], "TIFF tiles must be a multiple of 16")])
def test_bad_wrap_or_tile_exits_2(tmp_path, args, says):
    src = tmp_path / "in.exr"
    write(src, np.zeros((8, 8, 3), np.float32))
    r = CliRunner().invoke(main, ["mipmap", *CPU, *args, str(src), str(tmp_path / "o.tx")])
    assert r.exit_code == 2 and says in r.output, r.output
    assert not (tmp_path / "o.tx").exists()


# ------------------------------------------------------------------------------------------ metadata


def maketx(src: Path, dst: Path, *args: str) -> None:
    subprocess.run([MAKETX, str(src), "-o", str(dst), *args], check=True, capture_output=True)


@pytest.mark.parametrize("ext", ["tx", "exr"])
@pytest.mark.slow
def test_metadata_keys_match_maketx(tmp_path, png8, ext):
    ours, theirs = tmp_path / f"ours.{ext}", tmp_path / f"theirs.{ext}"
    mipmap("--wrap", "periodic", png8, ours)
    maketx(png8, theirs, "--wrap", "periodic")
    a, b = attributes(ours), attributes(theirs)
    # What maketx writes that a pyramid texture lacks: nothing but Exif:ImageHistory where maketx has a
    # command-line hash there and ours has a line; both exist for EXR.
    assert set(b) - set(a) <= {"Exif:ImageHistory"}, set(b) - set(a)
    for key in ("textureformat", "wrapmodes", "compression", "fovcot"):
        assert a[key] == b[key], key
    assert a["Software"].startswith("OpenImageIO ") and "pyramid mipmap" in a["Software"]


def test_average_color_and_sha1_as_maketx_computes_them(tmp_path, png8):
    ours, theirs = tmp_path / "ours.tx", tmp_path / "theirs.tx"
    mipmap(png8, ours)
    maketx(png8, theirs)
    a, b = attributes(ours), attributes(theirs)
    # Level 0 is the source's stored values in both: the same average colour.
    np.testing.assert_allclose([float(v) for v in a["oiio:AverageColor"].split(",")],
                               [float(v) for v in b["oiio:AverageColor"].split(",")], atol=2e-6)
    # maketx hashes the source as float with its filter's name; ours with hash_extra.
    inp = oiio.ImageInput.open(str(png8))
    src = np.asarray(inp.read_image("float"), dtype=np.float32)
    inp.close()
    assert pixel_sha1(src, "box ") == b["oiio:SHA-1"]
    assert a["oiio:SHA-1"] == pixel_sha1(src, hash_extra("clamp", "quadratic")) != b["oiio:SHA-1"]


def test_sha1_of_a_tall_source_hashes_in_blocks_like_maketx(tmp_path):
    src, theirs, ours = tmp_path / "tall.exr", tmp_path / "t.exr", tmp_path / "o.exr"
    write(src, np.random.default_rng(5).random((600, 8, 3)).astype(np.float32))
    maketx(src, theirs)
    mipmap(src, ours)
    assert pio.source_sha1(src, "box ") == attributes(theirs)["oiio:SHA-1"]
    assert attributes(ours)["oiio:SHA-1"] == pio.source_sha1(src, hash_extra("clamp", "quadratic"))


def test_the_1x1_level_is_the_average_color(tmp_path):
    src, dst = tmp_path / "in.exr", tmp_path / "out.exr"
    write(src, np.random.default_rng(2).random((64, 32, 4)).astype(np.float32))
    mipmap("--analysis", "box", "--type", "float", src, dst)
    average = [float(v) for v in attributes(dst)["oiio:AverageColor"].split(",")]
    np.testing.assert_allclose(levels_of(dst)[-1][0, 0], average, atol=1e-5)


@pytest.mark.parametrize("ext", ["tx", "exr"])
def test_constant_color_like_maketx(tmp_path, ext):
    src, ours, theirs = tmp_path / "c.png", tmp_path / f"ours.{ext}", tmp_path / f"theirs.{ext}"
    write(src, np.full((16, 16, 3), (10, 200, 77), np.uint8), "uint8")
    mipmap(src, ours)
    maketx(src, theirs)
    a, b = attributes(ours), attributes(theirs)
    assert "oiio:ConstantColor" in b and "oiio:ConstantColor" in a
    if ext == "tx":  # same stored values
        np.testing.assert_allclose([float(v) for v in a["oiio:ConstantColor"].split(",")],
                                   [float(v) for v in b["oiio:ConstantColor"].split(",")], atol=1e-6)
    varied = tmp_path / f"varied.{ext}"
    write(src, np.arange(16 * 16 * 3, dtype=np.uint8).reshape(16, 16, 3), "uint8")
    mipmap(src, varied)
    assert "oiio:ConstantColor" not in attributes(varied)


# --------------------------------------------------------------------------------------- .tx and .tif


@pytest.mark.parametrize("ext", ["tx", "tif"])
def test_8bit_srgb_png_gives_an_8bit_srgb_mipmapped_tiff(tmp_path, png8, ext):
    dst = tmp_path / f"albedo.{ext}"
    mipmap("--tile", "16", png8, dst)
    info = subprocess.run([OIIOTOOL, "--info", "-v", str(dst)], check=True, capture_output=True, text=True).stdout
    assert "uint8 tiff" in info and "MIP-map levels: 48x64 24x32 12x16 6x8 3x4 1x2 1x1" in info, info
    assert 'textureformat: "Plain Texture"' in info and "tile size: 16 x 16" in info
    assert "srgb" in attributes(dst)["oiio:ColorSpace"].lower()
    # Filtered in linear light and encoded back: the levels are the EXR's (linear half) levels, sRGB-encoded.
    exr = tmp_path / "albedo.exr"
    mipmap("--tile", "16", "--type", "float", png8, exr)
    for k, (tx, lin) in enumerate(zip(levels_of(dst), levels_of(exr), strict=True)):
        srgb = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * np.power(np.maximum(lin, 0), 1 / 2.4) - 0.055)
        np.testing.assert_allclose(tx, srgb, atol=0.5 / 255 + 1e-6, err_msg=f"level {k}")


def test_texture_system_reads_every_level(tmp_path, png8):
    dst = tmp_path / "albedo.tx"
    mipmap("--tile", "16", "--wrap", "periodic", png8, dst)
    levels = levels_of(dst)
    ts = oiio.TextureSystem(shared=False)
    opt = oiio.TextureOpt()
    opt.interpmode = oiio.InterpMode.Closest
    opt.mipmode = oiio.MipMode.OneLevel
    h, w = levels[0].shape[:2]
    for k, level in enumerate(levels):
        lh, lw = level.shape[:2]
        for y, x in {(0, 0), (lh - 1, lw - 1), (lh // 2, lw // 3)}:
            s, t = (x + 0.5) / lw, (y + 0.5) / lh
            got = ts.texture(str(dst), opt, s, t, 1 / lw, 0, 0, 1 / lh, 3)
            assert not ts.has_error(), ts.geterror()
            np.testing.assert_allclose(got, level[y, x], atol=1e-6, err_msg=f"level {k} texel {y},{x}")
    assert (h, w) == (64, 48)


def test_type_overrides_and_compression(tmp_path, png8):
    dst = tmp_path / "albedo.tx"
    mipmap("--type", "uint16", "--compression", "lzw", png8, dst)
    info = subprocess.run([OIIOTOOL, "--info", "-v", str(dst)], check=True, capture_output=True, text=True).stdout
    assert "uint16 tiff" in info and 'compression: "lzw"' in info, info


def test_exr_output_stays_half(tmp_path, png8):
    dst = tmp_path / "albedo.tx.exr"
    mipmap(png8, dst)
    inp = oiio.ImageInput.open(str(dst))
    assert inp.spec().format == oiio.HALF
    inp.close()


@pytest.mark.slow
def test_a_full_disk_writing_a_tx_exits_4_and_leaves_nothing(tmp_path):
    import resource

    src, dst = tmp_path / "big.png", tmp_path / "big.tx"
    write(src, (np.random.default_rng(4).random((256, 256, 3)) * 255).astype(np.uint8), "uint8")

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))

    p = subprocess.run([sys.executable, "-m", "pyramid_cli.cli", "mipmap", *CPU, str(src), str(dst)],
                       capture_output=True, text=True, preexec_fn=limit, timeout=300)
    assert p.returncode == 4, p.stderr
    assert f"cannot write {dst}" in p.stderr
    assert not dst.exists() and [f for f in os.listdir(tmp_path)] == ["big.png"]


def test_a_tx_input_gets_fresh_metadata(tmp_path, png8):
    first, second = tmp_path / "first.tx", tmp_path / "second.tx"
    maketx(png8, first, "--wrap", "periodic")
    mipmap("--analysis", "box", first, second)  # a .tx source: maketx's SHA-1 must not survive
    a = attributes(second)
    assert a["oiio:SHA-1"] == pio.source_sha1(first, hash_extra("clamp", "box")) != attributes(first)["oiio:SHA-1"]
    assert a["wrapmodes"] == "clamp,clamp"


def test_a_description_keeps_its_words_and_loses_stale_hashes(tmp_path):
    src, dst = tmp_path / "in.png", tmp_path / "out.tx"
    spec = oiio.ImageSpec(8, 8, 3, "uint8")
    spec.attribute("ImageDescription", "painted by hand oiio:SHA-1=DEADBEEF for show")
    out = oiio.ImageOutput.create(str(src))
    assert out.open(str(src), spec) and out.write_image(np.arange(192, dtype=np.uint8).reshape(8, 8, 3))
    out.close()
    mipmap(src, dst)
    a = attributes(dst)
    assert a["ImageDescription"].strip() == "painted by hand for show"  # the reader leaves a space
    assert a["oiio:SHA-1"] == pio.source_sha1(src, hash_extra("clamp", "quadratic"))


@pytest.mark.slow
def test_bench_maketx_runs_and_reports(tmp_path):
    out = tmp_path / "bench.json"
    bench = ROOT / "bench" / "maketx.py"
    p = subprocess.run([sys.executable, str(bench), "--size", "64", "--reps", "1", "--backend", "cpu",
                        "--json", str(out)], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    report = json.loads(out.read_text())
    assert set(report["median_s"]) == {"pyramid mipmap", "maketx"}
    assert report["pyramid"]["levels"] == report["maketx"]["levels"] and report["keys_only_in_maketx"] == []


@pytest.mark.parametrize("ext", ["tx", "exr"])
@pytest.mark.slow
def test_constant_color_detect_makes_one_tile_like_maketx(tmp_path, ext):
    src, ours, theirs = tmp_path / "flat.png", tmp_path / f"ours.{ext}", tmp_path / f"theirs.{ext}"
    write(src, np.full((100, 300, 4), (10, 200, 77, 255), np.uint8), "uint8")
    mipmap("--constant-color-detect", "--tile", "16", src, ours)
    maketx(src, theirs, "--constant-color-detect", "--tile", "16", "16")
    ours_levels, theirs_levels = levels_of(ours), levels_of(theirs)
    assert [x.shape for x in ours_levels] == [x.shape for x in theirs_levels]
    assert ours_levels[0].shape[:2] == (16, 16)
    for level in ours_levels:
        np.testing.assert_allclose(level, np.broadcast_to(ours_levels[0][0, 0], level.shape), atol=1e-3)
    if ext == "tx":  # the same stored colour
        np.testing.assert_allclose(ours_levels[-1], theirs_levels[-1], atol=1e-6)
    assert "oiio:ConstantColor" in attributes(ours)


def test_constant_color_detect_leaves_a_varied_image_alone(tmp_path, png8):
    dst = tmp_path / "out.tx"
    mipmap("--constant-color-detect", png8, dst)
    assert levels_of(dst)[0].shape[:2] == (64, 48)


# ------------------------------------------------------------------------------------ --round down


def maketx_sizes(path: Path) -> list[tuple[int, int]]:
    return [x.shape[:2] for x in levels_of(path)]


@pytest.mark.parametrize("shape", slow_unless([(37, 50), (64, 48), (1, 9), (5, 3)], [(5, 3)]))
@pytest.mark.parametrize("analysis", ["box", "quadratic"])
def test_default_sizes_are_maketx_and_every_level_keeps_the_mean(tmp_path, shape, analysis):
    src, ours, theirs = tmp_path / "in.exr", tmp_path / "ours.exr", tmp_path / "theirs.exr"
    g = np.random.default_rng(6).random(shape + (3,)).astype(np.float32)
    write(src, g)
    mipmap("--wrap", "periodic", "--analysis", analysis, "--type", "float", src, ours)
    maketx(src, theirs)
    assert maketx_sizes(ours) == maketx_sizes(theirs)
    mean = g.astype(np.float64).mean(axis=(0, 1))
    for level in levels_of(ours):  # every texel covers its share: no part of the domain dropped or doubled
        np.testing.assert_allclose(level.mean(axis=(0, 1)), mean, rtol=1e-5)
    average = [float(v) for v in attributes(ours)["oiio:AverageColor"].split(",")]
    np.testing.assert_allclose(levels_of(ours)[-1][0, 0], average, rtol=1e-5)


@pytest.mark.parametrize("wrap", ["clamp", "black"])
def test_clamp_and_black_keep_maketxs_sizes_and_wrapmodes_and_the_mean(tmp_path, wrap):
    """Issue 26: levels built inside the domain; the sizes and the wrapmodes maketx writes are unchanged."""
    src, ours, theirs = tmp_path / "in.exr", tmp_path / "ours.exr", tmp_path / "theirs.exr"
    g = np.random.default_rng(8).random((7, 5, 3)).astype(np.float32)
    write(src, g)
    mipmap("--wrap", wrap, "--type", "float", src, ours)
    maketx(src, theirs, "--wrap", wrap)
    assert maketx_sizes(ours) == maketx_sizes(theirs)
    assert attributes(ours)["wrapmodes"] == attributes(theirs)["wrapmodes"] == f"{wrap},{wrap}"
    for level in levels_of(ours):
        np.testing.assert_allclose(level.mean(axis=(0, 1)), g.astype(np.float64).mean(axis=(0, 1)), rtol=1e-6)


def test_round_up_keeps_the_analysis_pyramids_sizes_and_even_levels_agree(tmp_path):
    src, down, up = tmp_path / "in.exr", tmp_path / "down.exr", tmp_path / "up.exr"
    write(src, np.random.default_rng(7).random((32, 16, 4)).astype(np.float32))
    mipmap("--round", "down", "--type", "float", src, down)
    mipmap("--round", "up", "--type", "float", src, up)
    for a, b in zip(levels_of(down), levels_of(up), strict=True):  # powers of two: the same filter
        np.testing.assert_allclose(a, b, atol=1e-6)
    odd = tmp_path / "odd.exr"
    write(odd, np.random.default_rng(7).random((5, 7, 3)).astype(np.float32))
    mipmap("--round", "up", "--type", "float", odd, up)
    assert maketx_sizes(up) == [(5, 7), (3, 4), (2, 2), (1, 1)]
    assert "--round up" in attributes(up)["Exif:ImageHistory"]


def test_round_down_tx_reads_in_the_texture_system(tmp_path, png8):
    src = tmp_path / "odd.png"
    write(src, (np.random.default_rng(9).random((37, 50, 3)) * 255).astype(np.uint8), "uint8")
    dst = tmp_path / "odd.tx"
    mipmap("--tile", "16", src, dst)
    levels = levels_of(dst)
    assert [x.shape[:2] for x in levels] == [(37, 50), (18, 25), (9, 12), (4, 6), (2, 3), (1, 1)]
    ts = oiio.TextureSystem(shared=False)
    opt = oiio.TextureOpt()
    opt.interpmode, opt.mipmode = oiio.InterpMode.Closest, oiio.MipMode.OneLevel
    for level in levels:
        lh, lw = level.shape[:2]
        got = ts.texture(str(dst), opt, 0.5 / lw, 0.5 / lh, 1 / lw, 0, 0, 1 / lh, 3)
        np.testing.assert_allclose(got, level[0, 0], atol=1e-6)
    assert "--round down" in attributes(tmp_path / "odd.tx").get("Exif:ImageHistory", "--round down")


def test_round_down_refuses_an_analysis_it_cannot_resample(tmp_path):
    src = tmp_path / "in.exr"
    write(src, np.zeros((8, 8, 3), np.float32))
    r = CliRunner().invoke(main, ["mipmap", *CPU, "--analysis", "box *v^2 g", str(src), str(tmp_path / "o.exr")])
    assert r.exit_code == 2 and "need one separable ⊗↓ step" in r.output, r.output
    assert not (tmp_path / "o.exr").exists()


def test_exr_levels_that_halve_neither_way_are_refused(tmp_path):
    from pyramid_cli.core.errors import OutputError

    info = pio.read_image(_flat(tmp_path)).spec
    images = [pio.Image(np.zeros((h, w, 3), np.float32), info) for h, w in [(6, 5), (3, 3), (1, 1)]]
    with pytest.raises(OutputError, match="halve each size rounding up or down; these are 5x6 3x3 1x1"):
        pio.write_levels(tmp_path / "bad.exr", images, tile=16)
    assert not (tmp_path / "bad.exr").exists()


def _flat(tmp_path: Path) -> Path:
    src = tmp_path / "flat.exr"
    write(src, np.zeros((4, 4, 3), np.float32))
    return src


# ------------------------------------------------------------------------------------ against maketx


def write_half(path: Path, pixels: np.ndarray) -> None:
    write(path, pixels.astype(np.float16), "half")


@pytest.mark.parametrize("shape", slow_beyond([(16, 16, 3), (64, 32, 4)]))
@pytest.mark.parametrize("backend", ["cpu", "gl"])
@pytest.mark.slow
def test_box_on_even_sizes_is_bit_identical_to_maketx_box(tmp_path, shape, backend):
    """Half sources: a sum of four halves is exact in float32, so the order of the additions cannot
    matter and both tools must store the same half values at every level (float32 sources differ by
    one float32 ulp at most: each tool adds in its own order)."""
    if backend == "gl":
        from pyramid_cli.exec import gl

        ok, why = gl.available()
        if not ok and not os.environ.get("CI"):
            pytest.skip(why)
    src, ours, theirs = tmp_path / "in.exr", tmp_path / "ours.exr", tmp_path / "theirs.exr"
    write_half(src, np.random.default_rng(11).random(shape))
    r = CliRunner().invoke(main, ["mipmap", "--backend", backend, "--analysis", "box", str(src), str(ours)])
    assert r.exit_code == 0, r.output
    maketx(src, theirs, "--filter", "box")
    a, b = levels_of(ours, "half"), levels_of(theirs, "half")
    assert [x.shape for x in a] == [x.shape for x in b]
    for k, (x, y) in enumerate(zip(a, b, strict=True)):
        assert np.array_equal(x.view(np.uint16), y.view(np.uint16)), f"level {k}"


@pytest.mark.parametrize("shape", [pytest.param((777, 1001), marks=pytest.mark.slow), (3, 5), (1, 7), (7, 1), (2, 3),
                                   pytest.param((1080, 1920), marks=pytest.mark.slow)])
@pytest.mark.slow
def test_level_count_and_sizes_are_maketxs(tmp_path, shape):
    src, ours, theirs = tmp_path / "in.exr", tmp_path / "ours.tx", tmp_path / "theirs.tx"
    write_half(src, np.random.default_rng(12).random(shape + (3,)))
    mipmap(src, ours)
    maketx(src, theirs)
    assert maketx_sizes(ours) == maketx_sizes(theirs)


def test_average_color_and_the_1x1_level_equal_maketxs_for_box_on_even_sizes(tmp_path):
    src, ours, theirs = tmp_path / "in.exr", tmp_path / "ours.exr", tmp_path / "theirs.exr"
    write(src, np.random.default_rng(13).random((64, 128, 3)).astype(np.float32))
    mipmap("--analysis", "box", "--type", "float", src, ours)
    maketx(src, theirs, "--filter", "box", "-d", "float")
    a, b = attributes(ours), attributes(theirs)
    assert set(b) - set(a) <= {"Exif:ImageHistory"}
    np.testing.assert_allclose([float(v) for v in a["oiio:AverageColor"].split(",")],
                               [float(v) for v in b["oiio:AverageColor"].split(",")], rtol=1e-6)
    np.testing.assert_allclose(levels_of(ours)[-1], levels_of(theirs)[-1], rtol=1e-6)


@pytest.mark.parametrize("pixel_type, rows",
                         slow_beyond([("uint8", 40), ("uint16", 300), ("half", 520), ("float", 257)], unpack=True))
def test_sha1_is_hashed_from_the_pixels_in_memory_as_maketx_hashes_the_file(tmp_path, monkeypatch, pixel_type,
                                                                             rows):
    """The source is read once: its stored values are hashed before any conversion (integers as OpenImageIO
    converts them to float, bit for bit), in maketx's 256-row blocks, and the result is maketx's hash of the file."""
    src, dst, theirs = tmp_path / "in.tif", tmp_path / "out.tx", tmp_path / "theirs.tx"
    g = np.random.default_rng(21).random((rows, 9, 3))
    stored = {"uint8": (g * 255).astype(np.uint8), "uint16": (g * 65535).astype(np.uint16),
              "half": g.astype(np.float16), "float": g.astype(np.float32)}[pixel_type]
    write(src, stored, pixel_type)

    def reread(*args, **kwargs):
        raise AssertionError("the source was read again for its hash")

    monkeypatch.setattr(pio, "source_sha1", reread)
    mipmap("--analysis", "box", src, dst)
    monkeypatch.undo()
    assert attributes(dst)["oiio:SHA-1"] == pio.source_sha1(src, hash_extra("clamp", "box"))
    maketx(src, theirs, "--filter", "box")
    assert pio.source_sha1(src, "box ") == attributes(theirs)["oiio:SHA-1"]


# ------------------------------------------------------------------ maketx's channel and size flags


def channel_layout(path: Path) -> tuple[int, list[str], list[tuple[int, int]], list[float]]:
    inp = oiio.ImageInput.open(str(path))
    spec = inp.spec()
    sizes = []
    while inp.seek_subimage(0, len(sizes)):
        sizes.append((inp.spec().width, inp.spec().height))
    inp.close()
    return (spec.nchannels, list(spec.channelnames), sizes,
            [float(v) for v in spec.get_string_attribute("oiio:AverageColor").split(",")])


@pytest.fixture
def sources(tmp_path) -> dict[str, Path]:
    g = np.random.default_rng(14).random((20, 30, 1)).astype(np.float32)
    rgba = np.concatenate([np.random.default_rng(15).random((20, 30, 3)), np.full((20, 30, 1), 0.5)], axis=2)
    out = {}
    for name, px in [("mono", np.repeat(g, 3, axis=2)), ("rgba", rgba.astype(np.float32)),
                     ("rgb", np.random.default_rng(16).random((20, 30, 3)).astype(np.float32))]:
        out[name] = tmp_path / f"{name}.exr"
        write(out[name], px)
    return out


@pytest.mark.parametrize("source, args", [("mono", ["--monochrome-detect"]), ("rgb", ["--monochrome-detect"]),
                                          ("rgba", ["--nchannels", "3"]), ("rgba", ["--nchannels", "5"]),
                                          ("mono", ["--nchannels", "4"]), ("mono", ["--monochrome-detect",
                                                                                   "--nchannels", "2"])])
@pytest.mark.slow
def test_channel_flags_like_maketx(tmp_path, sources, source, args):
    ours, theirs = tmp_path / "ours.exr", tmp_path / "theirs.exr"
    mipmap(*args, "--type", "float", sources[source], ours)
    maketx(sources[source], theirs, *args, "-d", "float")
    a, b = channel_layout(ours), channel_layout(theirs)
    assert a[:3] == b[:3], (a, b)
    np.testing.assert_allclose(a[3], b[3], atol=1e-6)


def test_resize_makes_maketxs_power_of_two_levels(tmp_path, sources):
    ours, theirs = tmp_path / "ours.exr", tmp_path / "theirs.exr"
    mipmap("--resize", "--wrap", "periodic", "--type", "float", sources["rgb"], ours)
    maketx(sources["rgb"], theirs, "--resize")
    assert maketx_sizes(ours) == maketx_sizes(theirs) == [(32, 32), (16, 16), (8, 8), (4, 4), (2, 2), (1, 1)]
    levels = levels_of(ours)
    src = levels_of(sources["rgb"])[0].astype(np.float64)
    # level 0 is what a bilinear lookup of the source reads at the new texel centres (periodic: the mean stays)
    np.testing.assert_allclose(levels[0].mean(axis=(0, 1)), src.mean(axis=(0, 1)), rtol=2e-3)
    for level in levels[1:]:
        np.testing.assert_allclose(level.mean(axis=(0, 1)), levels[0].astype(np.float64).mean(axis=(0, 1)),
                                   rtol=1e-5)
    assert "--resize" in attributes(ours)["Exif:ImageHistory"]
    r = CliRunner().invoke(main, ["mipmap", *CPU, "--resize", "--round", "up", str(sources["rgb"]),
                                  str(tmp_path / "up.exr")])
    assert r.exit_code == 2 and "--resize" in r.output


def test_options_that_change_the_texels_change_the_sha1(tmp_path, sources):
    """The hash is of the source's pixels (as maketx's), so what changes the levels goes into its appended text:
    OpenImageIO's ImageCache treats two files with one SHA-1 as the same texture."""
    hashes = {}
    for args in ([], ["--nchannels", "1"], ["--resize"], ["--round", "up"], ["--fill"], ["--monochrome-detect"]):
        out = tmp_path / f"t{len(hashes)}.exr"
        mipmap(*args, sources["rgba"], out)
        hashes[" ".join(args)] = attributes(out)["oiio:SHA-1"]
        assert " ".join(args) in attributes(out)["Exif:ImageHistory"]
    assert len(set(hashes.values())) == len(hashes), hashes
