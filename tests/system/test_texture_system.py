"""``pyramid mipmap`` with OpenImageIO's TextureSystem as the client (the lookup renderers use).

Files are written by the CLI (CPU executor) with the default level rule (maketx's sizes, domain-true
resampling where a level is not exactly half the one above) and read back through ``TextureSystem.texture``
only: every level texel by texel (``Closest``, ``OneLevel``, derivatives of one texel of that level), bilinear
lookups inside a level, trilinear lookups of single-pixel dots at growing footprints, and whole-image lookups.

The means hold under every wrap mode: periodic and mirror build as they read, and their reads past the edges keep
every column of the resampling weights at m/n (:mod:`pyramid_cli.plan.resample`); clamp and black (whose lookups
read the edge texel or zero) build their levels inside the domain, by the mirror fold (issue 26, docs/design.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from click.testing import CliRunner

from helpers.images import write
from pyramid_cli.cli import main
from pyramid_cli.core.geometry import mip_sizes

CPU = ["--backend", "cpu"]


def make(tmp_path: Path, pixels: np.ndarray, *args: str, name: str = "tex") -> str:
    src, dst = tmp_path / f"{name}.exr", tmp_path / f"{name}.tx.exr"
    write(src, pixels.astype(np.float32))
    r = CliRunner().invoke(main, ["mipmap", *CPU, "--type", "float", *args, str(src), str(dst)])
    assert r.exit_code == 0, r.output
    return str(dst)


def options(interp=oiio.InterpMode.Closest, mip=oiio.MipMode.OneLevel) -> oiio.TextureOpt:
    opt = oiio.TextureOpt()
    opt.interpmode, opt.mipmode = interp, mip
    return opt


def selectable(sizes, k: int) -> bool:
    """Can a lookup's footprint single out level k? Not where an axis kept its size (a 1-pixel axis): the
    TextureSystem picks the first level its footprint fits, so of 7×1 → 3×1 → 1×1 it never picks 3×1."""
    return k == 0 or k == len(sizes) - 1 or all(a < b for a, b in zip(sizes[k], sizes[k - 1], strict=True))


def ts_level(ts, path: str, h: int, w: int, nch: int, last: bool = False) -> np.ndarray:
    """Level h×w texel by texel through the TextureSystem: lookups at texel centres with a one-texel footprint
    (the 1×1 level: a footprint of the whole texture and more)."""
    opt = options()
    ds, dt = (4, 4) if last else (1 / w, 1 / h)
    out = np.empty((h, w, nch))
    for y in range(h):
        t = (y + 0.5) / h
        for x in range(w):
            out[y, x] = ts.texture(path, opt, (x + 0.5) / w, t, ds, 0, 0, dt, nch)
    assert not ts.has_error(), ts.geterror()
    return out


def read_levels(path: str, nch: int) -> list[np.ndarray]:
    inp = oiio.ImageInput.open(path)
    levels = []
    while inp.seek_subimage(0, len(levels)):
        levels.append(np.asarray(inp.read_image(0, len(levels), 0, nch, "float"), dtype=np.float64))
    inp.close()
    return levels


def positive(shape, seed=0) -> np.ndarray:
    """Non-negative test image: noise plus a centred disk (whose mean a whole-image lookup must give)."""
    h, w, c = shape
    y, x = np.mgrid[0:h, 0:w]
    disk = ((y + 0.5 - h / 2) ** 2 + (x + 0.5 - w / 2) ** 2 < (0.3 * min(h, w)) ** 2).astype(float)
    noise = np.random.default_rng(seed).random(shape)
    return (0.5 * noise + 2 * disk[:, :, None]).astype(np.float32)


def check_means(tmp_path, shape, wrap):
    g = positive(shape)
    path = make(tmp_path, g, "--wrap", wrap)
    ts = oiio.TextureSystem(shared=False)
    mean = g.astype(np.float64).mean(axis=(0, 1))
    sizes = mip_sizes(shape[:2])
    files = read_levels(path, shape[2])
    assert [lv.shape[:2] for lv in files] == sizes
    for k, (h, w) in enumerate(sizes):
        level = ts_level(ts, path, h, w, shape[2], k == len(sizes) - 1) if selectable(sizes, k) else files[k]
        np.testing.assert_allclose(level.mean(axis=(0, 1)), mean, rtol=1e-4, err_msg=f"level {k} {w}×{h}")
    # the 1×1 level is the image's mean, and a lookup whose footprint covers the whole image returns it
    whole = ts.texture(path, options(oiio.InterpMode.Bilinear, oiio.MipMode.Trilinear), 0.5, 0.5, 4, 0, 0, 4,
                       shape[2])
    np.testing.assert_allclose(whole, mean, rtol=1e-4)
    assert sizes[-1] == (1, 1)


@pytest.mark.parametrize("shape", [(3, 5, 3), (1, 7, 2), (7, 1, 1), (37, 50, 4), (256, 256, 3), (64, 16, 3)])
@pytest.mark.parametrize("wrap", ["periodic", "mirror"])
def test_every_level_keeps_the_mean_through_the_texture_system(tmp_path, shape, wrap):
    check_means(tmp_path, shape, wrap)


@pytest.mark.parametrize("shape", [(3, 5, 3), (1, 7, 2), (7, 1, 1), (37, 51, 2)])
@pytest.mark.parametrize("wrap", ["clamp", "black"])
def test_clamp_and_black_levels_keep_the_mean_and_name_the_lookup_mode(tmp_path, shape, wrap):
    """Built inside the domain, read by the lookup's mode: the file's wrapmodes is still what was asked."""
    check_means(tmp_path, shape, wrap)
    inp = oiio.ImageInput.open(str(tmp_path / "tex.tx.exr"))
    assert inp.spec().get_string_attribute("wrapmodes") == f"{wrap},{wrap}"
    inp.close()


@pytest.mark.slow
@pytest.mark.parametrize("shape", [(777, 1001, 3), (1080, 1920, 4)])
def test_every_level_keeps_the_mean_on_large_odd_images(tmp_path, shape):
    check_means(tmp_path, shape, "periodic")


DOTS = [(200, 250), (390, 500), (600, 760), (150, 820), (650, 180)]


def centroid_errors(path: str, h: int, w: int, footprint: int) -> np.ndarray:
    """(x, y) of each dot's trilinear response centroid minus the dot's centre, in level-0 pixels."""
    ts = oiio.TextureSystem(shared=False)
    opt = options(oiio.InterpMode.Bilinear, oiio.MipMode.Trilinear)
    errors = []
    for y0, x0 in DOTS:
        reach, step = int(2.5 * footprint) + 4, max(1, footprint // 4)
        ys = np.arange(y0 - reach, y0 + reach + 1, step) + 0.5
        xs = np.arange(x0 - reach, x0 + reach + 1, step) + 0.5
        v = np.array([[ts.texture(path, opt, x / w, y / h, footprint / w, 0, 0, footprint / h, 1)[0] for x in xs]
                      for y in ys])
        errors.append(((v.sum(0) * xs).sum() / v.sum() - (x0 + 0.5), (v.sum(1) * ys).sum() / v.sum() - (y0 + 0.5)))
    return np.array(errors)


def test_single_pixel_dots_keep_their_centroid_at_every_footprint(tmp_path):
    """With the default (quadratic) filter. Box cannot: it hands a dot to one coarse texel, so the centroid
    snaps to that texel's centre (up to half a coarse texel off: ±4 px at an 8-px footprint), at any level size."""
    h, w = 777, 1001
    g = np.zeros((h, w, 1), np.float32)
    for y, x in DOTS:
        g[y, x] = 1
    path = make(tmp_path, g)  # the default wrap, clamp: levels built inside the domain
    for footprint in (2, 8, 32):
        err = centroid_errors(path, h, w, footprint)
        assert np.abs(err).max() < 0.1, f"footprint {footprint}: centroid off by {err}"


def test_round_up_drifts_as_the_issue_measured(tmp_path):
    """The other rule, for contrast: padded ⌈n/2⌉ levels pull dots toward the top left at large footprints."""
    h, w = 777, 1001
    g = np.zeros((h, w, 1), np.float32)
    for y, x in DOTS:
        g[y, x] = 1
    path = make(tmp_path, g, "--round", "up")
    assert centroid_errors(path, h, w, 32).min() < -10


def bilinear(level: np.ndarray, s: float, t: float, wrap: str) -> np.ndarray:
    """The level sampled at (s, t) with texel centres at ((x + ½)/w, (y + ½)/h), reads folded by ``wrap``."""
    h, w = level.shape[:2]

    def fold(i, n):
        if wrap == "periodic":
            return i % n
        k = i % (2 * n)  # mirror
        return k if k < n else 2 * n - 1 - k

    u, v = s * w - 0.5, t * h - 0.5
    i, j = int(np.floor(u)), int(np.floor(v))
    a, b = u - i, v - j
    row = [(1 - a) * level[fold(jj, h), fold(i, w)] + a * level[fold(jj, h), fold(i + 1, w)] for jj in (j, j + 1)]
    return (1 - b) * row[0] + b * row[1]


@pytest.mark.parametrize("shape", [(37, 50), (3, 5), (64, 64)])
@pytest.mark.parametrize("wrap", ["periodic", "mirror"])
def test_lookups_that_select_a_level_return_that_levels_values(tmp_path, shape, wrap):
    g = positive(shape + (3,), seed=4)
    path = make(tmp_path, g, "--wrap", wrap)
    levels = read_levels(path, 3)
    sizes = mip_sizes(shape)
    assert [lv.shape[:2] for lv in levels] == sizes
    ts = oiio.TextureSystem(shared=False)
    opt = options(oiio.InterpMode.Bilinear, oiio.MipMode.OneLevel)
    rng = np.random.default_rng(5)
    for k, level in enumerate(levels):
        h, w = level.shape[:2]
        assert selectable(sizes, k)
        np.testing.assert_allclose(ts_level(ts, path, h, w, 3, k == len(levels) - 1), level, atol=1e-6,
                                   err_msg=f"level {k}")
        if k == len(levels) - 1:
            continue
        for s, t in rng.random((20, 2)):
            got = ts.texture(path, opt, s, t, 1 / w, 0, 0, 1 / h, 3)
            np.testing.assert_allclose(got, bilinear(level, s, t, wrap), atol=1e-5, err_msg=f"level {k} at {s},{t}")
