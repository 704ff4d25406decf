"""The quality half of bench/tiles.py: tile pyramids' levels against an ideal band-limited reduction (issue 27).

Deterministic (nothing is timed). Three pictures, each made here in 8-bit sRGB (stored as a PNG):

* a **zone plate** ``N × N`` (N a power of two): ``L = ½ + ½ cos(π r² / (2 r_max))`` in *linear light*, r from
  the centre, r_max the half-diagonal: its local frequency r / (2 r_max) cycles per pixel runs from 0 at the
  centre to Nyquist in the corners, so every level has content on both sides of its own cut-off;
* a **1-pixel black/white checkerboard** (codes 0 and 255): its linear-light mean is ½, code 188; a 2×2 mean of
  the stored codes gives 128 (or 127);
* a **red disc on transparent** (RGBA, straight alpha as PNG stores it, anti-aliased edge; transparent pixels
  are black (0, 0, 0, 0), as most tools write them): averaging straight colour with the transparent black darkens
  the edge; premultiplied averaging does not. (libvips 8.18's ``dzsave`` and ``tiffsave --pyramid`` premultiply
  when they shrink; the naive ``coarsen`` contender below does not.)

The **ideal reduction** of level k (scale 2^k) is computed from the stored level 0 decoded to linear light:
the orthonormal DCT-II of the picture, truncated to its first M = N / 2^k coefficients per axis, evaluated at
the level's pixel centres 2^k (m + ½) (an inverse DCT-II of size M, times √(M/N) per axis). That is an ideal
brick-wall low-pass at the level's Nyquist frequency (|fx|, |fy| < 1 / 2^(k+1) cycles per input pixel: the
Nyquist cell of the level's square lattice) on the picture's even-symmetric extension (no wrap-around edge,
unlike a plain FFT), followed by exact point sampling at the centres the tile layouts assume (pixel m of
level k covers input pixels [2^k m, 2^k (m + 1))): Shannon's ideal, with no second filter in the passband.
As a second, blurrier reference the same brick-wall is followed by area sampling (the 2^k × 2^k mean of the
band-limited picture); both are reported, the first is the headline. The ideal is clipped to [0, 1] (what
8-bit can store) before it is compared: its Gibbs ripples past 0 and 1 are not counted against anyone.

The contenders' levels are their stored 8-bit values: ``vips dzsave --suffix .png`` (lossless tiles, read back
and stitched, overlap removed) and ours, either ``pyramid tiles --format png`` stitched the same way (when this
checkout has the command) or ``pyr.pyramid`` with the default MIP analysis on the pixels as
:func:`~pyramid_cli.imageio.read.read_image` decodes them (linear, premultiplied), encoded for a PNG by
:func:`~pyramid_cli.imageio.encode.encoded_rows`: exactly the rows ``pyramid tiles`` hands its writers before
they cut tiles. For scale, ``coarsen`` is the 2×2 mean of the stored codes truncated to 8 bits
(:func:`coarsen_levels`: ``dask.array.coarsen`` as OME-Zarr writers use it) and, for the zone plate,
``box-linear`` is ``pyr.pyramid`` with the 2×2 box (``analysis="box"``): dzsave's filter in linear light, which
tells how much of the difference is linear light and how much the filter. RMS errors are taken over every
pixel of a level, in linear light (stored values decoded with the exact sRGB curve) and in codes (against the
clipped ideal encoded to sRGB, unrounded); half a code (0.0028 in linear light near code 188) is the floor
of any 8-bit level.
"""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SCRIPTS = HERE / "scripts"
ROOT = HERE.parent
if str(ROOT) not in sys.path:  # run from a checkout even without the editable install
    sys.path.insert(0, str(ROOT))

from pyramid_cli.imageio.colour import linear_to_srgb, srgb_to_linear  # noqa: E402

LINEAR_HALF_CODE = int(np.rint(255 * linear_to_srgb(np.array(0.5))))  # 188
# The bar: ours / dzsave RMS at reduction 1 within this, and below 1 from reduction 2 down.
FIRST_LEVEL_LIMIT = 1.2


# ====================================================================== pictures
def zone_plate(n: int) -> np.ndarray:
    """The zone plate (see the module), ``n × n × 3`` 8-bit sRGB codes (grey)."""
    c = (n - 1) / 2
    y, x = np.mgrid[0:n, 0:n].astype(np.float64)
    r2 = (x - c) ** 2 + (y - c) ** 2
    r_max = math.sqrt(2) * n / 2
    lin = 0.5 + 0.5 * np.cos(np.pi * r2 / (2 * r_max))
    code = np.rint(255 * linear_to_srgb(lin)).astype(np.uint8)
    return np.repeat(code[..., None], 3, axis=2)


def checkerboard(n: int) -> np.ndarray:
    """A 1-pixel black/white checkerboard, ``n × n × 3`` codes 0 and 255."""
    y, x = np.mgrid[0:n, 0:n]
    code = (((x + y) % 2) * 255).astype(np.uint8)
    return np.repeat(code[..., None], 3, axis=2)


def red_disc(n: int, radius: float | None = None, supersample: int = 4) -> np.ndarray:
    """A red disc on transparent black, ``n × n × 4`` straight-alpha codes; the edge's alpha is its coverage."""
    radius = 0.35 * n if radius is None else radius
    s = supersample
    off = (np.arange(s) + 0.5) / s
    y = (np.arange(n)[:, None] + off[None, :]).reshape(-1) - n / 2
    inside = (y[:, None] ** 2 + y[None, :] ** 2) <= radius ** 2
    cover = inside.reshape(n, s, n, s).mean(axis=(1, 3))
    alpha = np.rint(cover * 255).astype(np.uint8)
    out = np.zeros((n, n, 4), np.uint8)
    out[..., 0] = np.where(alpha > 0, 255, 0)
    out[..., 3] = alpha
    return out


def write_png(path: Path, codes: np.ndarray) -> Path:
    """``codes`` (H, W, C uint8) as a PNG, through OpenImageIO (straight alpha, as PNG stores it)."""
    import OpenImageIO as oiio

    h, w, c = codes.shape
    spec = oiio.ImageSpec(w, h, c, "uint8")
    if c == 4:
        spec.channelnames, spec.alpha_channel = ("R", "G", "B", "A"), 3
        spec.attribute("oiio:UnassociatedAlpha", 1)
    out = oiio.ImageOutput.create(str(path))
    if out is None or not out.open(str(path), spec) or not out.write_image(codes) or not out.close():
        raise RuntimeError(f"cannot write {path}: {oiio.geterror()}")
    return path


def read_codes(path: Path) -> np.ndarray:
    """A PNG's stored 8-bit values (straight alpha as stored: OpenImageIO must not premultiply them)."""
    import OpenImageIO as oiio

    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    buf = oiio.ImageBuf(str(path), 0, 0, config)
    px = buf.get_pixels(oiio.UINT8)
    if buf.has_error or px is None:
        raise RuntimeError(f"cannot read {path}: {buf.geterror()}")
    return px.reshape(px.shape[0], px.shape[1], -1)


# ====================================================================== the ideal
def dct_rows(n: int, m: int) -> np.ndarray:
    """The first ``m`` rows of the orthonormal DCT-II matrix of size ``n`` (m × n)."""
    j = np.arange(m)[:, None]
    i = np.arange(n)[None, :]
    c = np.cos(np.pi * j * (i + 0.5) / n) * math.sqrt(2 / n)
    c[0] /= math.sqrt(2)
    return c


def ideal_operators(n: int, k: int) -> dict[str, np.ndarray]:
    """Per axis, the (n / 2^k) × n matrices of the two ideal reductions by 2^k (see the module):
    ``point`` (brick-wall, then the value at each level pixel's centre) and ``area`` (brick-wall, then the
    mean over each level pixel's footprint)."""
    m = n >> k
    if m << k != n:
        raise ValueError(f"the ideal reduction needs a power-of-two size, not {n}")
    low = dct_rows(n, m)
    point = math.sqrt(m / n) * dct_rows(m, m).T @ low
    box = np.kron(np.eye(m), np.full((1, 1 << k), 1.0 / (1 << k)))
    area = box @ (low.T @ low)
    return {"point": point, "area": area}


def ideal_levels(linear: np.ndarray, reductions: list[int]) -> dict[str, dict[int, np.ndarray]]:
    """The ideal reductions of a square grey linear picture, clipped to [0, 1]: {"point"|"area": {k: level}}."""
    n = linear.shape[0]
    out: dict[str, dict[int, np.ndarray]] = {"point": {}, "area": {}}
    for k in reductions:
        for name, a in ideal_operators(n, k).items():
            out[name][k] = np.clip(a @ linear @ a.T, 0.0, 1.0)
    return out


# ====================================================================== reading the contenders' levels
def read_dz(dzi: Path) -> dict[int, np.ndarray]:
    """Every level of a Deep Zoom tree as stored codes, by reduction (0 = full size): its tiles stitched, the
    overlap dropped (overlapping pixels are written twice, the same values)."""
    root = ET.parse(dzi).getroot()
    tile, overlap, suffix = int(root.get("TileSize")), int(root.get("Overlap")), root.get("Format")
    size = root.find("{*}Size")
    width, height = int(size.get("Width")), int(size.get("Height"))
    files = dzi.with_name(dzi.name[:-len(".dzi")] + "_files")
    top = max(int(p.name) for p in files.iterdir() if p.name.isdigit())
    levels = {}
    for k in range(top + 1):
        h, w = -(-height // (1 << k)), -(-width // (1 << k))
        canvas = None
        for f in (files / str(top - k)).glob(f"*.{suffix}"):
            col, row = (int(v) for v in f.stem.split("_"))
            px = read_codes(f)
            if canvas is None:
                canvas = np.zeros((h, w, px.shape[2]), np.uint8)
            x0, y0 = col * tile - (overlap if col else 0), row * tile - (overlap if row else 0)
            canvas[y0:y0 + px.shape[0], x0:x0 + px.shape[1]] = px
        levels[k] = canvas
    return levels


def fresh_dzi(out: Path) -> Path:
    """``out``.dzi with no earlier tree there (a rerun must not read an earlier run's tiles, nor be refused)."""
    dzi = out.with_suffix(".dzi")
    dzi.unlink(missing_ok=True)
    shutil.rmtree(dzi.with_name(dzi.stem + "_files"), ignore_errors=True)
    return dzi


def dzsave_levels(png: Path, out: Path) -> dict[int, np.ndarray]:
    """``vips dzsave --suffix .png`` of ``png`` in a fresh interpreter (bench/scripts/vips_tiles.py), read back."""
    dzi = fresh_dzi(out)
    p = subprocess.run([sys.executable, str(SCRIPTS / "vips_tiles.py"), "dzsave", str(png), str(dzi), ".png"],
                       capture_output=True, text=True)
    if p.returncode:
        raise RuntimeError(f"dzsave {png}: {p.stderr.strip()[-400:]}")
    return read_dz(dzi)


def tiles_levels(png: Path, out: Path, pyramid: list[str], env: dict | None) -> dict[int, np.ndarray]:
    """``pyramid tiles PNG OUT.dzi --format png`` (this checkout's CLI), read back."""
    dzi = fresh_dzi(out)
    p = subprocess.run([*pyramid, "tiles", str(png), str(dzi), "--format", "png"], capture_output=True, text=True,
                       env=env)
    if p.returncode:
        raise RuntimeError(f"pyramid tiles {png}: {p.stderr.strip()[-400:]}")
    return read_dz(dzi)


def coarsen_levels(codes: np.ndarray) -> dict[int, np.ndarray]:
    """The naive reduction many OME-Zarr writers use: the 2×2 mean of the stored codes (straight alpha as
    stored), truncated back to the type, as ``dask.array.coarsen(np.mean, a, {0: 2, 1: 2}).astype(a.dtype)``
    does; down to 1×1 (power-of-two sizes)."""
    levels = {0: codes}
    while levels[len(levels) - 1].shape[0] > 1:
        a = levels[len(levels) - 1].astype(np.float64)
        h, w, c = a.shape
        levels[len(levels)] = a.reshape(h // 2, 2, w // 2, 2, c).mean(axis=(1, 3)).astype(np.uint8)
    return levels


def api_levels(png: Path, count: int, backend: str, analysis: str | None = None) -> dict[int, np.ndarray]:
    """``pyr.pyramid`` (default: the default MIP analysis) of ``png`` as read_image decodes it, each level encoded
    as a PNG stores it: the rows ``pyramid tiles`` writes, before they are cut into tiles."""
    import pyramid_cli as pyr
    from pyramid_cli.core.catalogue import MIP_ANALYSIS_DEFAULT
    from pyramid_cli.imageio.encode import encoded_rows
    from pyramid_cli.imageio.image import Image
    from pyramid_cli.imageio.read import read_image

    img = read_image(png)
    levels = pyr.pyramid(img.pixels, analysis=analysis or MIP_ANALYSIS_DEFAULT, levels=count, backend=backend)
    return {k: np.asarray(encoded_rows("x.png", Image(np.ascontiguousarray(lv, np.float32), img.spec)))
            for k, lv in enumerate(levels)}


# ====================================================================== measures
def rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((np.asarray(a, np.float64) - b) ** 2)))


def zone_errors(level: np.ndarray, ideal: np.ndarray) -> dict:
    """RMS of a stored grey level (all three channels) against the clipped linear ideal: linear and codes."""
    codes = level[..., :3].astype(np.float64)
    return {"rms_linear": rms(srgb_to_linear(codes / 255), ideal[..., None]),
            "rms_codes": rms(codes, 255 * linear_to_srgb(ideal)[..., None])}


def pattern_stats(level: np.ndarray) -> dict:
    """Where a reduced checkerboard lands: its mean and median code, and the share within ±1 of code 188."""
    c = level[..., :3].astype(np.float64)
    return {"mean_code": float(c.mean()), "median_code": float(np.median(c)),
            "share_within_1_of_188": float(np.mean(np.abs(c - LINEAR_HALF_CODE) <= 1))}


def fringe_stats(level: np.ndarray) -> dict:
    """How dark a reduced red disc's colour gets where it is partly transparent. ``weighted_darkness``:
    Σ α (1 − R) / Σ α in linear light over every pixel with α > 0 (what compositing shows); ``max_darkness``:
    the largest 1 − R/255 in codes where α ≥ 16 (below that 8-bit straight colour is coarse anyway)."""
    red = srgb_to_linear(level[..., 0] / 255)
    alpha = level[..., 3] / 255
    seen = alpha > 0
    strong = level[..., 3] >= 16
    partial = seen & (level[..., 3] < 255)
    return {"weighted_darkness": float(np.sum(alpha[seen] * (1 - red[seen])) / max(np.sum(alpha[seen]), 1e-12)),
            "max_darkness": float(np.max(1 - level[..., 0][strong] / 255)) if strong.any() else 0.0,
            "partial_pixels": int(partial.sum()),
            "mean_partial_red_code": float(level[..., 0][partial].mean()) if partial.any() else None}


# ====================================================================== the whole quality run
def measure(folder: Path, *, zone: int = 2048, pattern: int = 256, disc: int = 512, ours: str = "api",
            backend: str = "cpu", pyramid: list[str] | None = None, env: dict | None = None,
            log=print) -> dict:
    """Make the three pictures under ``folder``, reduce them with dzsave and ours, and measure (see the module).

    ``ours``: "api" (``pyr.pyramid`` + the PNG encoding) or "cli" (``pyramid tiles``, command ``pyramid``)."""
    folder.mkdir(parents=True, exist_ok=True)
    pictures = {"zone": zone_plate(zone), "pattern": checkerboard(pattern), "disc": red_disc(disc)}
    res: dict = {"ours": ours, "sizes": {"zone": zone, "pattern": pattern, "disc": disc}}
    levels: dict[str, dict[str, dict[int, np.ndarray]]] = {}
    for name, codes in pictures.items():  # the zone plate also with the 2×2 box in linear light
        png = write_png(folder / f"{name}.png", codes)
        log(f"tiles quality: {name} {codes.shape[1]}×{codes.shape[0]}: dzsave, ours ({ours}) …")
        count = int(math.log2(codes.shape[0]))
        mine = (tiles_levels(png, folder / f"{name}-ours", pyramid or [], env) if ours == "cli"
                else api_levels(png, count, backend))
        levels[name] = {"dzsave": dzsave_levels(png, folder / f"{name}-dzsave"), "ours": mine,
                        "coarsen": coarsen_levels(codes)}
        if name == "zone":
            levels[name]["box-linear"] = api_levels(png, count, backend, "box")
        for who, lv in levels[name].items():
            if not np.array_equal(lv[0], codes):
                raise RuntimeError(f"{who}'s level 0 of {name} is not the input")
    res["zone_plate"] = zone_table(pictures["zone"], levels["zone"], log)
    res["pattern"] = {who: {k: pattern_stats(lv[k]) for k in sorted(lv) if k} for who, lv in levels["pattern"].items()}
    res["pattern"]["linear_light_code"] = LINEAR_HALF_CODE
    res["alpha_fringe"] = {who: {k: fringe_stats(lv[k]) for k in sorted(lv) if k} for who, lv in levels["disc"].items()}
    return res


def zone_table(codes: np.ndarray, levels: dict[str, dict[int, np.ndarray]], log=print) -> dict:
    """The zone plate's errors per reduction against both ideals, ours ÷ dzsave, and the issue's verdict."""
    linear = srgb_to_linear(codes[..., 0] / 255)
    ks = [k for k in sorted(levels["ours"]) if k]
    log(f"tiles quality: the ideal reductions of the {codes.shape[0]}² zone plate …")
    ideal = ideal_levels(linear, ks)
    rows = []
    for k in ks:
        row: dict = {"reduction": k, "size": list(levels["ours"][k].shape[1::-1])}
        for ref in ("point", "area"):
            e = {who: zone_errors(lv[k], ideal[ref][k]) for who, lv in levels.items()}
            ratio = e["ours"]["rms_linear"] / e["dzsave"]["rms_linear"] if e["dzsave"]["rms_linear"] else None
            limit = FIRST_LEVEL_LIMIT if k == 1 else 1.0
            ok = ratio is not None and (ratio <= limit if k == 1 else ratio < limit)
            row[ref] = e | {"ratio_linear": ratio, "limit": limit, "verdict": "PASS" if ok else "MISS"}
        rows.append(row)
    return {"reference_headline": "point", "levels": rows,
            "verdict": "PASS" if all(r["point"]["verdict"] == "PASS" for r in rows) else "MISS"}


def table_lines(q: dict) -> list[str]:
    """The quality results as printed lines."""
    lines = [f"zone plate {q['sizes']['zone']}² against the ideal (brick-wall at each level's Nyquist, point "
             f"sampled; [area sampled]); ours = {q['ours']}",
             f"{'k':>3s} {'size':>11s} {'ours lin':>9s} {'dz lin':>9s} {'ratio':>6s} {'ours code':>9s} "
             f"{'dz code':>8s} {'box-lin':>8s} {'[area ratio]':>12s} verdict"]
    for r in q["zone_plate"]["levels"]:
        p, a = r["point"], r["area"]
        lines.append(f"{r['reduction']:>3d} {'×'.join(map(str, r['size'])):>11s} {p['ours']['rms_linear']:9.4f} "
                     f"{p['dzsave']['rms_linear']:9.4f} {p['ratio_linear']:6.2f} {p['ours']['rms_codes']:9.2f} "
                     f"{p['dzsave']['rms_codes']:8.2f} {p['box-linear']['rms_linear']:8.4f} "
                     f"{a['ratio_linear']:12.2f} {p['verdict']} "
                     f"(≤{p['limit']})")
    pat, fr = q["pattern"], q["alpha_fringe"]
    who = ("ours", "dzsave", "coarsen")
    lines.append(f"1-pixel checkerboard {q['sizes']['pattern']}², mean code per reduction (linear light: "
                 f"{pat['linear_light_code']}):")
    lines += [f"  {w:8s} " + " ".join(f"{v['mean_code']:.1f}" for v in pat[w].values()) for w in who]
    lines.append(f"red disc on transparent {q['sizes']['disc']}², alpha-weighted darkness Σα(1−R)/Σα per reduction "
                 "(0: no fringe):")
    lines += [f"  {w:8s} " + " ".join(f"{v['weighted_darkness']:.3f}" for v in fr[w].values()) for w in who]
    return lines
