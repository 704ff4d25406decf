"""MIP-map bookkeeping shared by ``pyramid mipmap`` and :func:`pyramid_cli.io.write_levels`.

Pure computations (numpy and hashlib only): maketx's wrap-mode names and how
they map onto the Plan's border, and the metadata maketx writes (average and
constant colour, the SHA-1 of the source pixels), computed the way OpenImageIO's
``maketexture.cpp`` computes them. Writing the metadata is :mod:`pyramid_cli.io`'s.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from .errors import UsageError
from .work import Levels

# maketx's wrap modes and the Plan's border that reads past the edges the same way.
WRAP_TO_BORDER: dict[str, str] = {"black": "zero", "clamp": "clamp", "periodic": "wrap", "mirror": "mirror"}
BORDER_TO_WRAP: dict[str, str] = {b: w for w, b in WRAP_TO_BORDER.items()}
WRAP_NAMES = tuple(WRAP_TO_BORDER)

# computePixelHashSHA1's block height in maketx (scanlines per block digest).
SHA1_BLOCK = 256


@dataclass(frozen=True, kw_only=True)
class TextureLevels(Levels):
    """A MIP chain down to 1×1 (:class:`pyramid_cli.work.Levels`) with maketx's ``--constant-color-detect``.

    ``constant_detect``: an image whose pixels are all the same becomes one tile of that colour before
    the levels are made (:func:`shrink_constant`).
    """

    constant_detect: bool = False
    round_down: bool = False  # maketx's level sizes ⌊n/2⌋, by area resampling (:func:`area_levels`)
    fill: bool = False        # pull-push texels of alpha < 1 first (pyramid_cli.methods_files.fill_texture)

    @property
    def filter_name(self) -> str:
        """The filter that makes the levels: ``"area"`` when rounding down, else ``analysis``."""
        return "area" if self.round_down else self.analysis


def area_weights(n: int, m: int) -> np.ndarray:
    """The (m, n) matrix resampling n samples to m by area: output j averages input over [j·n/m, (j+1)·n/m)."""
    scale = n / m
    lo = np.arange(m)[:, None] * scale
    i = np.arange(n)[None, :]
    overlap = np.clip(np.minimum(lo + scale, i + 1) - np.maximum(lo, i), 0, None)
    return overlap / scale


def area_levels(pixels: np.ndarray) -> list[np.ndarray]:
    """MIP levels 1.. down to 1×1 with maketx's sizes ``max(1, ⌊n/2⌋)``, each the area average of the one above.

    Every output texel covers its exact share of the level above (no sample of the domain is dropped
    or counted twice for odd sizes), so every level keeps the image's mean. Computed in float64.
    """
    levels, x = [], pixels.astype(np.float64)
    while x.shape[0] > 1 or x.shape[1] > 1:
        h, w = x.shape[:2]
        x = np.einsum("ji,ikc->jkc", area_weights(h, max(1, h // 2)), x)
        x = np.einsum("lk,jkc->jlc", area_weights(w, max(1, w // 2)), x)
        levels.append(x.astype(np.float32))
    return levels


def shrink_constant(pixels: np.ndarray, tile: int) -> np.ndarray | None:
    """maketx's ``--constant-color-detect``: a constant image as ``min(tile, h) × min(tile, w)`` of its colour.

    None when the pixels are not all the same (compared exactly, as maketx compares min and max).
    """
    flat = pixels.reshape(-1, pixels.shape[-1])
    if not np.all(flat == flat[0]):
        return None
    h, w = min(tile, pixels.shape[0]), min(tile, pixels.shape[1])
    return np.ascontiguousarray(np.broadcast_to(flat[0], (h, w, pixels.shape[-1])))


def parse_wrap(wrap: str | None, swrap: str | None = None, twrap: str | None = None) -> tuple[str, str] | None:
    """The (s, t) wrap modes of ``--wrap MODE[,MODE]``, ``--swrap`` and ``--twrap`` (maketx's flags).

    Returns None when none is given. Raises UsageError (exit 2) for an unknown mode.
    """
    if wrap is None and swrap is None and twrap is None:
        return None
    s = t = "black"
    if wrap is not None:
        parts = [p.strip().lower() for p in wrap.split(",")]
        if len(parts) > 2 or not all(parts):
            raise UsageError(f"--wrap {wrap!r}: expected MODE or SMODE,TMODE (modes: {', '.join(WRAP_NAMES)})")
        s, t = parts[0], parts[-1]
    s = swrap.lower() if swrap is not None else s
    t = twrap.lower() if twrap is not None else t
    for mode in (s, t):
        if mode not in WRAP_TO_BORDER:
            raise UsageError(f"unknown wrap mode {mode!r} (modes: {', '.join(WRAP_NAMES)})")
    return s, t


def border_for_wrap(s: str, t: str) -> str:
    """The Plan's one border for wrap modes (s, t); UsageError when they differ (one border for both axes)."""
    if s != t:
        raise UsageError(f"wrap modes {s},{t} differ per axis; the filters read both axes through one border, "
                         "so give one mode for both (e.g. --wrap periodic)")
    return WRAP_TO_BORDER[s]


def wrapmodes(border: str) -> str:
    """maketx's ``wrapmodes`` attribute for a Plan border, e.g. ``"periodic,periodic"`` for ``wrap``."""
    mode = BORDER_TO_WRAP[border]
    return f"{mode},{mode}"


def _normalised(data: np.ndarray) -> np.ndarray:
    """Stored values as float64 the way OpenImageIO's pixel statistics see them (integers scaled to 0..1)."""
    if np.issubdtype(data.dtype, np.integer):
        return data.astype(np.float64) / np.iinfo(data.dtype).max
    return data.astype(np.float64)


def average_color(data: np.ndarray) -> list[float]:
    """Per-channel mean of the stored values (computePixelStats' ``avg``: integers as 0..1, encoding as stored)."""
    px = _normalised(data).reshape(-1, data.shape[-1])
    return [float(v) for v in px.mean(axis=0)]


def constant_color(data: np.ndarray) -> list[float] | None:
    """The stored colour when every pixel has it (computePixelStats' ``min == max``), else None."""
    px = data.reshape(-1, data.shape[-1])
    if not np.all(px == px[0]):
        return None
    return [float(v) for v in _normalised(px[:1])[0]]


def format_floats(values: list[float]) -> str:
    """Values joined the way maketx writes them (``Strutil::join``: ``%g``-like, comma separated)."""
    return ",".join(f"{v:g}" for v in values)


def pixel_sha1(data: np.ndarray, extra: str = "", block: int = SHA1_BLOCK) -> str:
    """OpenImageIO's ``computePixelHashSHA1(buf, extra, ROI::All(), block)`` of stored pixels ``data``.

    ``data`` is (H, W, C) as maketx holds the source: float32 of the stored values (integers as
    0..1, no colour conversion), bytes in native order. Up to
    ``block`` rows: the SHA-1 of the bytes then ``extra``. More: the SHA-1 of the concatenated
    upper-case hex digests of each ``block`` rows, then ``extra``.
    """
    data = np.ascontiguousarray(data)
    extra_bytes = extra.encode()
    if block <= 0 or block >= data.shape[0]:
        return hashlib.sha1(data.tobytes() + extra_bytes).hexdigest().upper()
    sha = hashlib.sha1()
    for y in range(0, data.shape[0], block):
        sha.update(hashlib.sha1(data[y:y + block].tobytes()).hexdigest().upper().encode())
    sha.update(extra_bytes)
    return sha.hexdigest().upper()


def hash_extra(border: str, analysis: str) -> str:
    """What ``pyramid mipmap`` appends to the pixels it hashes, as maketx appends its filter name.

    It names this tool, the filter and the wrap mode (which changes every level below 0 here), so a
    file never shares a hash with a maketx file of the same source whose lower levels differ
    (OpenImageIO's ImageCache treats files with the same ``oiio:SHA-1`` as one).
    """
    return f"pyramid:{analysis}:{BORDER_TO_WRAP[border]} "


def texture_metadata(border: str, analysis: str, sha1: str | None = None, oiio_version: str = "") -> dict[str, str]:
    """The attributes ``pyramid mipmap`` adds to level 0 besides the colours: wrap modes, hash, provenance.

    ``Software`` says the file was written with OpenImageIO (``oiio_version``) by this tool: OpenImageIO's
    readers drop ``oiio:SHA-1`` from a texture whose ``Software`` starts neither with "OpenImageIO" nor
    "maketx" (``check_texture_metadata_sanity``). ``Exif:ImageHistory`` gets a line saying how the
    levels were made (maketx appends its command line).
    """
    from . import __version__

    tool = f"pyramid mipmap (bilinear-pyramid {__version__})"
    meta = {"wrapmodes": wrapmodes(border),
            "Software": f"OpenImageIO {oiio_version} : {tool}" if oiio_version else tool,
            "Exif:ImageHistory": f"pyramid mipmap {'--round down' if analysis == 'area' else '--analysis ' + analysis}"
                                 f" --wrap {BORDER_TO_WRAP[border]}"}
    if sha1:
        meta["oiio:SHA-1"] = sha1
    return meta
