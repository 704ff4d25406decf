"""MIP-map bookkeeping shared by ``pyramid mipmap`` and :func:`pyramid_cli.imageio.write_levels`.

Pure computations (numpy and hashlib only): maketx's wrap-mode names and how
they map onto the Plan's border, and the metadata maketx writes (average and
constant colour, the SHA-1 of the source pixels), computed the way OpenImageIO's
``maketexture.cpp`` computes them. Writing the metadata is :mod:`pyramid_cli.imageio`'s.
"""

from __future__ import annotations

import hashlib

import numpy as np

from pyramid_cli.core.errors import UsageError
from pyramid_cli.core.version import __version__

# maketx's wrap modes and the Plan's border that reads past the edges the same way.
WRAP_TO_BORDER: dict[str, str] = {"black": "zero", "clamp": "clamp", "periodic": "wrap", "mirror": "mirror"}
BORDER_TO_WRAP: dict[str, str] = {b: w for w, b in WRAP_TO_BORDER.items()}
WRAP_NAMES = tuple(WRAP_TO_BORDER)

# computePixelHashSHA1's block height in maketx (scanlines per block digest).
SHA1_BLOCK = 256


def channel_plan(nchannels: int, names: list[str], alpha: int, wanted: int | None,
                 monochrome_detect: bool, monochrome: bool) -> tuple[int, list[str], int] | None:
    """maketx's channel changes before the levels: ``--monochrome-detect`` (3 channels, no alpha, R = G = B at
    every pixel → one channel named Y) unless ``--nchannels`` is given, then ``--nchannels`` (keep the first
    ``wanted``; more appends channels of zeros named as OpenImageIO names them: R G B A channel4 …, an added
    A is not treated as alpha here, it stays an ordinary channel of zeros).

    Returns (channels kept from the source, new names, new alpha index) or None when nothing changes.
    ``monochrome`` says whether the pixels are monochrome (checked by the caller only when it matters).
    """
    if wanted is None and monochrome_detect and nchannels == 3 and alpha < 0 and monochrome:
        return 1, ["Y"], -1
    if wanted is None or wanted == nchannels:
        return None
    default = ["R", "G", "B", "A"]
    new = [names[c] if c < nchannels else (default[c] if c < 4 else f"channel{c}") for c in range(wanted)]
    return min(wanted, nchannels), new, alpha if alpha < wanted else -1


def is_monochrome(pixels: np.ndarray) -> bool:
    """Every pixel's three channels equal (ImageBufAlgo::isMonochrome with threshold 0)."""
    return pixels.shape[-1] == 3 and bool(np.all(pixels[..., 0] == pixels[..., 1])
                                          and np.all(pixels[..., 0] == pixels[..., 2]))


def apply_channels(pixels: np.ndarray, kept: int, total: int) -> np.ndarray:
    """The first ``kept`` channels, padded with zeros to ``total`` channels."""
    if kept == total == pixels.shape[-1]:
        return pixels
    out = np.zeros(pixels.shape[:2] + (total,), dtype=pixels.dtype)
    out[..., :kept] = pixels[..., :kept]
    return out


def shrink_constant(pixels: np.ndarray, tile: int) -> np.ndarray | None:
    """maketx's ``--constant-color-detect``: a constant image as ``min(tile, h) × min(tile, w)`` of its colour.

    None when the pixels are not all the same (compared exactly, as maketx compares min and max).
    """
    flat = pixels.reshape(-1, pixels.shape[-1])
    if not np.all(flat[:pixels.shape[1]] == flat[0]) or not np.all(flat == flat[0]):  # the first row, then all
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
    """Per-channel mean of the stored values (computePixelStats' ``avg``: integers as 0..1, encoding as stored).

    Summed down the rows first (one vectorised pass over the image as an (H, W·C) array: integers exactly in
    integer accumulators, floats in float64), then across the row's columns.
    """
    h, w, c = data.shape
    rows = data.reshape(h, w * c)
    if np.issubdtype(data.dtype, np.integer):
        acc = np.uint32 if data.dtype.itemsize == 1 and h < (1 << 24) else np.uint64
        sums = rows.sum(axis=0, dtype=acc).reshape(w, c).sum(axis=0, dtype=np.uint64).astype(np.float64)
        sums /= np.iinfo(data.dtype).max
    else:
        sums = rows.sum(axis=0, dtype=np.float64).reshape(w, c).sum(axis=0)
    return [float(v) for v in sums / max(1, h * w)]


def constant_color(data: np.ndarray) -> list[float] | None:
    """The stored colour when every pixel has it (computePixelStats' ``min == max``), else None."""
    px = data.reshape(-1, data.shape[-1])
    if not np.all(px[:data.shape[1]] == px[0]) or not np.all(px == px[0]):  # the first row settles most images
        return None
    return [float(v) for v in _normalised(px[:1])[0]]


def format_floats(values: list[float]) -> str:
    """Values joined the way maketx writes them (``Strutil::join``: ``%g``-like, comma separated)."""
    return ",".join(f"{v:g}" for v in values)


def stored_floats(data: np.ndarray) -> np.ndarray:
    """Stored values as OpenImageIO converts them to float32: integers times ``float32(1/max)``
    (``convert_type``, bit for bit), half widened, float as is."""
    if np.issubdtype(data.dtype, np.integer):
        out = data.astype(np.float32)
        out *= np.float32(1 / np.iinfo(data.dtype).max)  # in place: one float copy of the rows held, not two
        return out
    return data.astype(np.float32, copy=False)


def sha1_state(data: np.ndarray, block: int = SHA1_BLOCK, threads: int = 2):
    """The unfinished SHA-1 of ``computePixelHashSHA1(buf, extra, ROI::All(), block)`` over stored pixels.

    ``data`` is (H, W, C) as the file stores it (uint8, uint16, float16 or float32); each ``block`` rows
    are converted to float32 as OpenImageIO converts them (:func:`stored_floats`: what maketx hashes,
    since it works in float) and hashed in ``threads`` threads. Up to ``block`` rows: the SHA-1 of the
    bytes; more: the SHA-1 of the concatenated upper-case hex digests of each block. :func:`finish_sha1`
    appends ``extra`` and gives the digest, so the state can be computed from the pixels as they are read.
    """
    if block <= 0 or block >= data.shape[0]:
        return hashlib.sha1(np.ascontiguousarray(stored_floats(data)).tobytes())

    def digest(y: int) -> bytes:
        return block_digest(data[y:y + block])

    starts = range(0, data.shape[0], block)
    if threads > 1 and len(starts) > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=threads) as pool:  # hashlib and numpy release the GIL
            digests = list(pool.map(digest, starts))
    else:
        digests = [digest(y) for y in starts]
    return sha1_of_blocks(digests)


def block_digest(rows: np.ndarray) -> bytes:
    """The upper-case hex SHA-1 of one block of rows as stored (:func:`sha1_state` of a picture of more than one
    block hashes these, in order: :func:`sha1_of_blocks`)."""
    return hashlib.sha1(np.ascontiguousarray(stored_floats(rows)).data).hexdigest().upper().encode()


def sha1_of_blocks(digests) -> hashlib._Hash:
    """:func:`sha1_state` of a picture of more than one block, from its blocks' :func:`block_digest` in order."""
    return hashlib.sha1(b"".join(digests))


def finish_sha1(state, extra: str = "") -> str:
    """The upper-case hex SHA-1 of a :func:`sha1_state` with ``extra`` appended (the state is not changed)."""
    sha = state.copy()
    sha.update(extra.encode())
    return sha.hexdigest().upper()


def pixel_sha1(data: np.ndarray, extra: str = "", block: int = SHA1_BLOCK) -> str:
    """OpenImageIO's ``computePixelHashSHA1(buf, extra, ROI::All(), block)`` of stored pixels ``data``.

    ``data`` is (H, W, C) as maketx holds the source: float32 of the stored values (integers as
    0..1, no colour conversion), bytes in native order; other stored types are converted as
    OpenImageIO converts them (:func:`sha1_state`).
    """
    return finish_sha1(sha1_state(data, block), extra)


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
    tool = f"pyramid mipmap (bilinear-pyramid {__version__})"
    name, *flags = analysis.split("/")  # TextureLevels.filter_name: "quadratic", "quadratic/up/resize", …
    options = "".join(f" --{f.replace('=', ' ')}" for f in flags if f != "up")
    meta = {"wrapmodes": wrapmodes(border),
            "Software": f"OpenImageIO {oiio_version} : {tool}" if oiio_version else tool,
            "Exif:ImageHistory": f"pyramid mipmap --analysis {name} --round {'up' if 'up' in flags else 'down'}"
                                 f"{options} --wrap {BORDER_TO_WRAP[border]}"}
    if sha1:
        meta["oiio:SHA-1"] = sha1
    return meta


class PixelStats:
    """maketx's level-0 statistics gathered from bands of rows, top to bottom, each seen once: the same
    values as :func:`average_color`, :func:`constant_color` (of the encoded level 0) and :func:`sha1_state`
    (of the source's stored values) on the whole picture, for a picture that is never held whole
    (``pyramid mipmap`` streamed, :mod:`pyramid_cli.run.stream`).

    The float sums add row after row in float64, in the order :func:`average_color`'s reduction down
    the rows adds them; integer sums are exact; the SHA-1 hashes each :data:`SHA1_BLOCK` rows as they
    complete (or, for a picture of at most one block, all its bytes).
    """

    def __init__(self, height: int, block: int = SHA1_BLOCK):
        self.height, self.block = height, block
        self._single = block <= 0 or block >= height
        self._outer = hashlib.sha1()
        self._inner = hashlib.sha1()
        self._hashed = 0        # source rows hashed
        self._rows = 0          # encoded rows summed
        self._sums: np.ndarray | None = None
        self._dtype: np.dtype | None = None
        self._first: np.ndarray | None = None
        self._constant = True
        self.decoded_first: np.ndarray | None = None
        self.decoded_constant = True

    def hash_rows(self, stored: np.ndarray) -> None:
        """The next rows of the source as stored (uint8, uint16, float16 or float32), (rows, W, C)."""
        y = 0
        while y < len(stored):
            take = len(stored) if self._single else min(len(stored) - y, self.block - self._hashed % self.block)
            self._inner.update(np.ascontiguousarray(stored_floats(stored[y:y + take])).tobytes())
            y += take
            self._hashed += take
            if not self._single and (self._hashed % self.block == 0 or self._hashed == self.height):
                self._outer.update(self._inner.hexdigest().upper().encode())
                self._inner = hashlib.sha1()

    def sha1(self):
        """The unfinished SHA-1 (:func:`finish_sha1`), once every row is hashed."""
        if self._hashed != self.height:
            raise ValueError(f"{self._hashed} of {self.height} rows hashed")
        return self._inner if self._single else self._outer

    def add_encoded(self, data: np.ndarray) -> None:
        """The next rows of level 0 as the file stores them (what :func:`average_color` reads)."""
        n, w, c = data.shape
        if not n:
            return
        if self._sums is None:
            self._dtype = data.dtype
            integer = np.issubdtype(data.dtype, np.integer)
            self._sums = np.zeros(w * c, dtype=np.uint64 if integer else np.float64)
            self._first = data[0, 0].copy()
        rows = data.reshape(n, w * c)
        if np.issubdtype(self._dtype, np.integer):
            self._sums += rows.sum(axis=0, dtype=np.uint64)
        else:
            for row in rows:  # row after row, as the whole picture's reduction adds them
                np.add(self._sums, row, out=self._sums, dtype=np.float64)
        if self._constant:
            self._constant = bool(np.all(data == self._first))
        self._rows += n

    def add_decoded(self, pixels: np.ndarray) -> None:
        """The next rows of the decoded source (for ``--constant-color-detect``: :func:`shrink_constant`)."""
        if not len(pixels):
            return
        if self.decoded_first is None:
            self.decoded_first = pixels[0, 0].copy()
        if self.decoded_constant:
            self.decoded_constant = bool(np.all(pixels == self.decoded_first))

    def average(self) -> list[float]:
        totals, first, dtype = self._sums, self._first, self._dtype
        if totals is None or first is None or dtype is None:
            raise ValueError("no rows of level 0 added")
        w_c = len(totals)
        c = len(first)
        if np.issubdtype(dtype, np.integer):
            sums = totals.reshape(w_c // c, c).sum(axis=0, dtype=np.uint64).astype(np.float64)
            sums /= np.iinfo(dtype).max
        else:
            sums = totals.reshape(w_c // c, c).sum(axis=0)
        return [float(v) for v in sums / max(1, self._rows * (w_c // c))]

    def constant(self) -> list[float] | None:
        if not self._constant:
            return None
        if self._first is None:
            raise ValueError("no rows of level 0 added")
        return [float(v) for v in _normalised(self._first[None])[0]]
