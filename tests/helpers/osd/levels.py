"""A tile set's levels read back the way a viewer finds them, and what one of them looks like on screen.

The readers here follow the formats' own rules (the Deep Zoom descriptor's tile size and overlap, the IIIF Image
API's canonical region and size names), not the writers' code: a tile missing, of the wrong size or at the wrong
place fails here as it would in a viewer.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

#: The viewer page's background (viewer.html), what the screen shows where no tile is drawn.
BACKGROUND = np.array([255, 0, 255], np.int16)


def read_rgb(path: Path) -> np.ndarray:
    """The picture at ``path``: its first three channels' codes (h, w, 3), int16."""
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, f"{path}: {oiio.geterror()}"
    try:
        px = np.asarray(inp.read_image(0, 0, 0, 3, "uint8"))
    finally:
        inp.close()
    return px.astype(np.int16)


def halved(size: tuple[int, int], k: int) -> tuple[int, int]:
    """``size`` (w, h) after ``k`` halvings rounding up (Deep Zoom's and IIIF's level sizes)."""
    w, h = size
    for _ in range(k):
        w, h = -(-w // 2), -(-h // 2)
    return w, h


class DeepZoom:
    """A Deep Zoom tile set: ``name.dzi`` and ``name_files/LEVEL/COL_ROW.FORMAT``."""

    def __init__(self, dzi: Path):
        root = ET.parse(dzi).getroot()
        ns = root.tag.split("}")[0] + "}" if root.tag.startswith("{") else ""
        size = root.find(f"{ns}Size")
        assert size is not None, f"{dzi}: no Size element"
        self.folder = dzi.with_name(dzi.stem + "_files")
        self.size = int(size.get("Width", 0)), int(size.get("Height", 0))
        self.tile, self.overlap = int(root.get("TileSize", 0)), int(root.get("Overlap", 0))
        self.format = root.get("Format", "")
        #: Deep Zoom's top level: level 0 is 1 × 1, this one the picture itself.
        self.top = math.ceil(math.log2(max(self.size)))

    def level(self, k: int) -> np.ndarray:
        """The picture halved ``k`` times (Deep Zoom level ``top - k``), its tiles stitched; every tile's size
        is checked against the grid, the tile size and the overlap the descriptor names."""
        w, h = halved(self.size, k)
        ts, ov = self.tile, self.overlap
        out, filled = np.zeros((h, w, 3), np.int16), np.zeros((h, w), bool)
        for c in range(-(-w // ts)):
            for r in range(-(-h // ts)):
                x0, y0 = max(c * ts - ov, 0), max(r * ts - ov, 0)
                x1, y1 = min((c + 1) * ts + ov, w), min((r + 1) * ts + ov, h)
                path = self.folder / str(self.top - k) / f"{c}_{r}.{self.format}"
                px = read_rgb(path)
                assert px.shape[:2] == (y1 - y0, x1 - x0), f"{path}: {px.shape[:2]}, not {(y1 - y0, x1 - x0)}"
                out[y0:y1, x0:x1], filled[y0:y1, x0:x1] = px, True
        assert filled.all(), f"{self.folder}: the tiles of level {self.top - k} leave holes"
        return out


class IIIF:
    """A static (level 0) IIIF Image API tree, version 2 or 3: ``info.json`` and
    ``REGION/SIZE/0/default.FORMAT`` beside it, the names in their canonical form."""

    def __init__(self, info: Path):
        self.info = json.loads(info.read_text())
        self.folder = info.parent
        self.version = 3 if "/3/" in str(self.info.get("@context", "")) else 2
        self.size = int(self.info["width"]), int(self.info["height"])
        tiles = self.info["tiles"][0]
        self.tile = int(tiles["width"]), int(tiles.get("height", tiles["width"]))
        self.scale_factors = sorted(int(s) for s in tiles["scaleFactors"])
        self.format = (self.info.get("preferredFormats") or ["jpg"])[0]

    def level(self, k: int) -> np.ndarray:
        """The picture at scale factor 2^k, its tiles stitched and their sizes checked."""
        s = 2 ** k
        assert s in self.scale_factors, f"scale factor {s} is not in info.json's {self.scale_factors}"
        (W, H), (tw, th) = self.size, self.tile
        lw, lh = -(-W // s), -(-H // s)
        out, filled = np.zeros((lh, lw, 3), np.int16), np.zeros((lh, lw), bool)
        for x in range(0, W, tw * s):
            for y in range(0, H, th * s):
                rw, rh = min(tw * s, W - x), min(th * s, H - y)
                sw, sh = -(-rw // s), -(-rh // s)
                region = "full" if (x, y, rw, rh) == (0, 0, W, H) else f"{x},{y},{rw},{rh}"
                if self.version == 3:
                    size = "max" if (sw, sh) == (W, H) else f"{sw},{sh}"
                else:
                    size = "full" if sw == W else f"{sw},"
                path = self.folder / region / size / "0" / f"default.{self.format}"
                px = read_rgb(path)
                assert px.shape[:2] == (sh, sw), f"{path}: {px.shape[:2]}, not {(sh, sw)}"
                out[y // s:y // s + sh, x // s:x // s + sw] = px
                filled[y // s:y // s + sh, x // s:x // s + sw] = True
        assert filled.all(), f"{self.folder}: the tiles of scale factor {s} leave holes"
        return out


def on_screen(level: np.ndarray, x0: int, y0: int, width: int, height: int, scale: float = 1.0,
              reach: int = 0, extent: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """What a width × height screen shows of ``level`` drawn ``scale`` screen pixels per level pixel, nearest
    neighbour, the screen's pixel (0, 0) at (x0, y0) screen pixels from the level's corner, the background outside
    the picture; and where the picture's edge cuts a pixel (which may show either).

    ``extent``: the picture's (w, h) in screen pixels, by default the level's. A viewer draws a level of an odd
    size at the picture's true extent (1501 pixels at 1/4 are 375.25 on screen, though the level stores 376).
    ``reach``: pixels more on each side (the neighbourhood :func:`error` searches)."""
    ew, eh = extent if extent is not None else (level.shape[1] * scale, level.shape[0] * scale)
    ys, xs = np.arange(-reach, height + reach) + y0, np.arange(-reach, width + reach) + x0
    out = level[np.clip(np.floor((ys + 0.5) / scale).astype(int), 0, level.shape[0] - 1)][
        :, np.clip(np.floor((xs + 0.5) / scale).astype(int), 0, level.shape[1] - 1)]
    cut_y, cut_x = (ys < eh) & (ys + 1 > eh), (xs < ew) & (xs + 1 > ew)
    outside = ((ys < 0) | (ys >= eh))[:, None] | ((xs < 0) | (xs >= ew))[None, :]
    out[outside] = BACKGROUND
    return out, ~outside & (cut_y[:, None] | cut_x[None, :])


def error(shot: np.ndarray, screen: tuple[np.ndarray, np.ndarray], reach: int = 0) -> np.ndarray:
    """Per screen pixel, the largest channel difference in codes between ``shot`` and the nearest match in
    ``screen`` (:func:`on_screen`'s answer with the same ``reach``) within ``reach`` pixels, a pixel the edge cuts
    matching the picture or the background."""
    px, cut = screen
    h, w = shot.shape[:2]
    planes = [np.ascontiguousarray(shot[..., c], np.int16) for c in range(3)]
    screen_planes = [np.ascontiguousarray(px[..., c], np.int16) for c in range(3)]

    def far(a: list[np.ndarray], b: list[np.ndarray] | np.ndarray) -> np.ndarray:
        return np.maximum(np.maximum(np.abs(a[0] - b[0]), np.abs(a[1] - b[1])), np.abs(a[2] - b[2]))

    off_background = far(planes, BACKGROUND)
    best = np.full((h, w), np.iinfo(np.int16).max, np.int16)
    for dy in range(2 * reach + 1):
        for dx in range(2 * reach + 1):
            d = far(planes, [p[dy:dy + h, dx:dx + w] for p in screen_planes])
            np.minimum(best, np.where(cut[dy:dy + h, dx:dx + w], np.minimum(d, off_background), d), out=best)
    return best
