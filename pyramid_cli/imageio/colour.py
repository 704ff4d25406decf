"""Colour maths on pixel arrays: the sRGB transfer functions, premultiplication, and 8/16-bit coding.

Pure numpy (no file formats): :mod:`pyramid_cli.imageio` reads and writes files with OpenImageIO and calls
these to turn stored codes into linear premultiplied float32 and back. Decoding and 8-bit encoding go
through per-code tables that are bit-identical to the float64 formulas they replace (tested at every
code boundary).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from functools import cache

import numpy as np

from pyramid_cli.core import cache as disk_cache
from pyramid_cli.core.fingerprint import sources

# 8x8 Bayer matrix for ordered dither.
_BAYER8 = np.array(
    [[0, 32, 8, 40, 2, 34, 10, 42],
     [48, 16, 56, 24, 50, 18, 58, 26],
     [12, 44, 4, 36, 14, 46, 6, 38],
     [60, 28, 52, 20, 62, 30, 54, 22],
     [3, 35, 11, 43, 1, 33, 9, 41],
     [51, 19, 59, 27, 49, 17, 57, 25],
     [15, 47, 7, 39, 13, 45, 5, 37],
     [63, 31, 55, 23, 61, 29, 53, 21]],
    dtype=np.float64,
)


def srgb_to_linear(encoded: np.ndarray) -> np.ndarray:
    """Decode sRGB values with the exact piecewise sRGB EOTF.

    Parameters
    ----------
    encoded : numpy.ndarray
        sRGB-encoded values; negative values are mirrored.

    Returns
    -------
    numpy.ndarray
        Linear values, float64.
    """
    v = np.asarray(encoded, dtype=np.float64)
    a = np.abs(v)
    out = np.where(a <= 0.04045, a / 12.92, ((a + 0.055) / 1.055) ** 2.4)
    return np.copysign(out, v)


def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """Encode linear values with the inverse of the sRGB EOTF.

    Parameters
    ----------
    linear : numpy.ndarray
        Linear values; negative values are mirrored.

    Returns
    -------
    numpy.ndarray
        sRGB-encoded values, float64.
    """
    v = np.asarray(linear, dtype=np.float64)
    a = np.abs(v)
    with np.errstate(invalid="ignore"):
        out = np.where(a <= 0.0031308, a * 12.92, 1.055 * a ** (1.0 / 2.4) - 0.055)
    return np.copysign(out, v)


# Values scanned at a time for NaN and Inf (a quarter of a million: 512 KiB of half bits, 256 KiB of flags)
NONFINITE_BLOCK = 1 << 18


def count_nonfinite(pixels: np.ndarray) -> int:
    """Count NaN and infinite values.

    Parameters
    ----------
    pixels : numpy.ndarray
        Any array.

    Returns
    -------
    int
        Number of elements that are NaN, +Inf or -Inf.
    """
    if (not isinstance(pixels, np.ndarray) or not pixels.flags.c_contiguous or pixels.dtype.kind != "f"
            or not pixels.size):
        return int(np.size(pixels) - np.count_nonzero(np.isfinite(pixels)))
    flat = pixels.reshape(-1)
    half = pixels.dtype == np.float16
    if half:
        # exponent bits all ones: ±inf and NaN. numpy's isfinite on half takes 7x as long (a 4K RGBA band of 272
        # rows: 5.9 ms against 0.8), and a streamed half EXR is scanned band by band as it is read
        flat = flat.view(np.uint16)
    # in blocks, through two small buffers that stay in cache: a whole 4K RGBA half picture took 15 ms warm and
    # 19 ms in a fresh process (its 100 MB of temporaries' pages), in blocks 6 ms
    block = min(flat.size, NONFINITE_BLOCK)
    flags = np.empty(block, dtype=bool)
    exponent = np.empty(block, dtype=np.uint16) if half else None
    bad = 0
    for i in range(0, flat.size, block):
        part = flat[i:i + block]
        found = flags[:len(part)]
        if exponent is not None:
            bits = exponent[:len(part)]
            np.bitwise_and(part, 0x7C00, out=bits)
            np.equal(bits, 0x7C00, out=found)
            bad += int(np.count_nonzero(found))
        else:
            np.isfinite(part, out=found)
            bad += len(part) - int(np.count_nonzero(found))
    return bad


def colour_mask(nchannels: int, alpha_channel: int, names: list[str]) -> np.ndarray:
    """Channels that carry colour: everything but alpha and depth."""
    mask = np.ones(nchannels, dtype=bool)
    if 0 <= alpha_channel < nchannels:
        mask[alpha_channel] = False
    for i, name in enumerate(names[:nchannels]):
        if name.split(".")[-1].lower() in ("z", "zback", "depth"):
            mask[i] = False
    return mask


def premultiply(px: np.ndarray, alpha_channel: int, colour: np.ndarray) -> None:
    """Multiply the ``colour`` channels of ``px`` by its alpha channel, in place."""
    alpha = px[..., alpha_channel:alpha_channel + 1]
    px[..., colour] *= alpha


def unpremultiply(px: np.ndarray, alpha_channel: int, colour: np.ndarray) -> None:
    """Divide the ``colour`` channels of ``px`` by its alpha channel, in place (0 where alpha is not positive)."""
    alpha = px[..., alpha_channel:alpha_channel + 1]
    # Where alpha is 0 (or negative after filtering) there is no colour to
    # recover: store 0 rather than dividing by zero.
    safe = np.where(alpha > 0, alpha, 1.0)
    px[..., colour] = np.where(alpha > 0, px[..., colour] / safe, 0.0)


@cache
def _integer_levels(dtype: str, srgb: bool) -> np.ndarray:
    """float64 value of every code of an 8/16-bit type: ``code / max``, sRGB-decoded if asked."""
    levels = np.arange(256 if dtype == "uint8" else 65536) / (255.0 if dtype == "uint8" else 65535.0)
    return srgb_to_linear(levels) if srgb else levels


@cache
def integer_table(dtype: str, srgb: bool) -> np.ndarray:
    """float32 value of every code of ``dtype`` ("uint8" or "uint16") in a colour channel without alpha to
    premultiply: what :func:`decode_integer` gives each code (sRGB-decoded if asked), rounded once."""
    return _integer_levels(dtype, srgb).astype(np.float32)


@cache
def _pair_table(srgb: bool) -> np.ndarray:
    """float32 values of every two consecutive 8-bit codes, by the uint16 they read as in memory: (65536, 2)."""
    codes = np.arange(65536, dtype=np.uint16).view(np.uint8).reshape(-1, 2)  # the machine's byte order
    return integer_table("uint8", srgb)[codes]


PAIR_BAND = 1 << 15  # code pairs gathered per step: their index conversion stays in cache


def _decode_pairs(data: np.ndarray, srgb: bool) -> np.ndarray:
    """:func:`decode_integer` of contiguous 8-bit codes without alpha to premultiply: two codes per gather from
    :func:`_pair_table` (half the gathers and index conversions of one code at a time, 1.5× faster), the same
    float32 values."""
    pairs, out = _pair_table(srgb), np.empty(data.shape, dtype=np.float32)
    flat, res = data.reshape(-1), out.reshape(-1)
    even = flat.size // 2 * 2
    index = flat[:even].view(np.uint16)
    for i in range(0, index.size, PAIR_BAND):
        j = min(index.size, i + PAIR_BAND)
        np.take(pairs, index[i:j], axis=0, out=res[2 * i:2 * j].reshape(-1, 2))
    if even < flat.size:
        res[even:] = integer_table("uint8", srgb)[flat[even:]]
    return out


def decode_integer(data: np.ndarray, srgb: bool, colour: np.ndarray, alpha: int, straight: bool) -> np.ndarray:
    """Linear premultiplied float32 pixels of 8/16-bit codes, a channel at a time through per-code tables.

    Every value is what decoding ``code / max`` in float64 with the exact sRGB EOTF, then
    premultiplying in float64, gives (rounded once to float32), without float64 copies of
    the whole image. ``alpha`` is the channel to premultiply by (-1: none).
    """
    linear = _integer_levels(data.dtype.name, False)
    decoded = _integer_levels(data.dtype.name, True) if srgb else linear
    if alpha >= 0 and srgb and not straight:
        # Associated sRGB (rare): divide the encoded values out, decode, multiply back.
        px = linear[data]
        unpremultiply(px, alpha, colour)
        px[..., colour] = srgb_to_linear(px[..., colour])
        premultiply(px, alpha, colour)
        return px.astype(np.float32)
    a = linear[data[..., alpha]] if alpha >= 0 and straight else None
    if a is None and all(colour):  # gathers through a float32 table (the same single rounding), no strides,
        if data.dtype == np.uint8 and data.flags.c_contiguous:
            return _decode_pairs(data, srgb)
        table = integer_table(data.dtype.name, srgb)  # in bands of rows so the index conversion stays in cache
        out = np.empty(data.shape, dtype=np.float32)
        for y in range(0, data.shape[0], 64):
            np.take(table, data[y:y + 64], out=out[y:y + 64])
        return out
    out = np.empty(data.shape, dtype=np.float32)
    for c in range(data.shape[2]):
        codes = data[..., c]
        if colour[c]:
            out[..., c] = decoded[codes] if a is None else decoded[codes] * a
        else:
            out[..., c] = linear[codes]
    return out


@cache
def srgb8_tables() -> tuple[np.ndarray, np.ndarray]:
    """Exact 8-bit sRGB encoding of float32 values by table: (thresholds, codes by the top 16 bits).

    ``thresholds[k - 1]`` is the smallest float32 that :func:`encode_integer` turns into
    code k (sRGB in float64, ×255, round half up). A float32's top 16 bits (sign, exponent,
    7 mantissa bits) as an unsigned index pick a bucket at most 0.78 % wide; the thresholds are at least 0.9 %
    apart (checked as they are made), so the code is the bucket's code (of its first value) plus one comparison
    (:func:`srgb8_buckets`). Negative values and NaNs code 0, but for +inf's bucket, whose NaNs are told by value.

    Computing them takes about 40 ms, a fixed cost of every process that writes 8 bits; they are kept in the
    cache folder (:mod:`pyramid_cli.core.cache`, ``tables/``) under the digest of this code and numpy's
    version, with a SHA-256 of their bytes: an entry that does not match is computed again.
    """
    entry = _tables_entry()
    cached = _read_tables(entry)
    if cached is not None:
        return cached
    thresholds, codes = _compute_srgb8_tables()
    disk_cache.write("tables", entry, _SRGB8_HEAD + hashlib.sha256(thresholds.tobytes() + codes.tobytes()).digest()
                + thresholds.tobytes() + codes.tobytes())
    return thresholds, codes


_SPECIAL = 0x7F80    # the bucket (top 16 bits) of +inf and of the NaNs below 0x7F810000: a code by value
_SRGB8_HEAD = b"srgb8-tables-2\n"
_SRGB8_SIZES = (255 * 4, 1 << 16)  # bytes of the thresholds (float32) and of the codes (uint8)


def _tables_entry() -> str:
    return f"srgb8-{disk_cache.key(sources('imageio'), np.__version__)}.bin"


def _read_tables(entry: str) -> tuple[np.ndarray, np.ndarray] | None:
    data = disk_cache.read("tables", entry)
    head, t_size, c_size = len(_SRGB8_HEAD), *_SRGB8_SIZES
    if data is None or len(data) != head + 32 + t_size + c_size or not data.startswith(_SRGB8_HEAD):
        return None
    body = data[head + 32:]
    if hashlib.sha256(body).digest() != data[head:head + 32]:
        return None
    thresholds = np.frombuffer(body[:t_size], dtype=np.float32).copy()
    codes = np.frombuffer(body[t_size:], dtype=np.uint8).copy()
    return thresholds, codes


def _compute_srgb8_tables() -> tuple[np.ndarray, np.ndarray]:
    def code(bits: np.ndarray) -> np.ndarray:
        x = bits.astype(np.uint32).view(np.float32).astype(np.float64)
        return np.clip(np.floor(linear_to_srgb(x) * 255.0 + 0.5), 0, 255)

    lo = np.zeros(255, dtype=np.int64)                 # bisection on the bit patterns of x ≥ 0
    hi = np.full(255, 0x7F800000, dtype=np.int64)      # +inf encodes to 255
    want = np.arange(1, 256)
    while np.any(hi - lo > 1):
        mid = (lo + hi) // 2
        up = code(mid) >= want
        hi, lo = np.where(up, mid, hi), np.where(up, lo, mid)
    thresholds = hi.astype(np.uint32).view(np.float32)
    firsts = (np.arange(1 << 15, dtype=np.uint32) << 16).view(np.float32)  # non-negative buckets
    lasts = ((np.arange(1 << 15, dtype=np.uint32) << 16) | 0xFFFF).view(np.float32)
    with np.errstate(invalid="ignore"):
        start = np.searchsorted(thresholds, firsts, side="right")
        finite = np.isfinite(lasts)
        assert np.all(np.searchsorted(thresholds, lasts[finite], side="right") - start[finite] <= 1)
    start[_SPECIAL + 1:] = 0  # exponent all ones, mantissa's top 7 bits not all zero: NaNs only
    codes = np.concatenate([start, np.zeros(1 << 15, dtype=start.dtype)]).astype(np.uint8)  # negatives: 0
    return thresholds, codes


SRGB8_BAND = 1 << 16  # values encoded per step: the temporaries stay in cache instead of faulting in fresh pages


@cache
def srgb8_buckets() -> tuple[np.ndarray, np.ndarray]:
    """:func:`srgb8_tables`'s codes by the top 16 bits of a float32 (as an unsigned index: the sign half last, so
    that numpy's signed index of the bits shifted as int32 reaches the same bucket from the end), with the
    threshold of each bucket's next code (NaN where there is none: the comparison is then false)."""
    thresholds, codes = srgb8_tables()
    above = np.concatenate([thresholds, np.full(1, np.nan, np.float32)])  # code 255 has no next
    bucket_threshold = above[codes]
    bucket_threshold[1 << 15:] = np.nan  # negatives stay code 0
    return codes, bucket_threshold


_LOOP: list[Callable[..., None]] = []  # the compiled loop srgb8 runs on, once one is given (use_srgb8_loop)
# values from which srgb8 runs on the loop: a few (a writer's one-pixel spec, a check of every code) stay on numpy,
# which does not wait for the loop's executor, still loading in the background while a run starts
LOOP_MIN = SRGB8_BAND


def use_srgb8_loop(loop: Callable[..., None]) -> None:
    """Have :func:`srgb8` run on ``loop`` from now on, in this process: a compiled
    ``loop(out, x, bits, codes, thresholds, i0, i1)`` that sets ``out[i] = codes[b] + (x[i] >= thresholds[b])``,
    ``b = bits[i] >> 16``, and a NaN to 0, for ``i`` in ``[i0, i1)``, given :func:`srgb8_buckets` (the CPU
    executor's ``encode8``, given by the run layer: this layer compiles nothing). The codes are the same."""
    _LOOP[:] = [loop]


def srgb8(x: np.ndarray) -> np.ndarray:
    """:func:`encode_integer` of ``linear_to_srgb(x)`` for 8 bits without dither, from float32 ``x``.

    On a compiled loop where one was given (:func:`use_srgb8_loop`) and ``x`` holds :data:`LOOP_MIN` values or
    more: one pass, 3× faster. Else by numpy, in bands of :data:`SRGB8_BAND` values into buffers reused from band
    to band (whole-image temporaries cost more in page faults than the table lookups): the bucket's index straight
    as ``intp`` (no index conversions in the gathers), its code and its threshold gathered, the comparison added
    to the code. Only a band holding +inf or a NaN of the one mixed bucket takes the slow path (``isnan``)."""
    x = np.ascontiguousarray(x, dtype=np.float32)
    out = np.empty(x.shape, dtype=np.uint8)
    flat, res = x.reshape(-1), out.reshape(-1)
    if _LOOP and flat.size >= LOOP_MIN:
        _LOOP[0](res, flat, flat.view(np.uint32), *srgb8_buckets(), 0, flat.size)
        return out
    codes, bucket_threshold = srgb8_buckets()
    bits = flat.view(np.int32)
    n = min(SRGB8_BAND, flat.size)
    index, limit, up = np.empty(n, np.intp), np.empty(n, np.float32), np.empty(n, bool)
    for i in range(0, flat.size, SRGB8_BAND):
        j = min(flat.size, i + SRGB8_BAND)
        m = j - i
        idx, t, u, k = index[:m], limit[:m], up[:m], res[i:j]
        np.right_shift(bits[i:j], 16, out=idx, casting="unsafe")
        np.take(codes, idx, out=k)
        np.take(bucket_threshold, idx, out=t)
        with np.errstate(invalid="ignore"):
            np.greater_equal(flat[i:j], t, out=u)
        np.add(k, u, out=k, casting="unsafe")
        if idx.max() >= _SPECIAL:  # +inf (255) or a NaN whose bucket it shares
            v = flat[i:j]
            k[np.isnan(v)] = 0
            k[v == np.inf] = 255
    return out


def encode_integer(values: np.ndarray, out_type: str, dither: bool,
                    colour: np.ndarray) -> np.ndarray:
    """8/16-bit codes of encoded values in [0, 1] (``out_type`` "uint8" or "uint16"): ×max, round half up,
    clamped; NaN is 0, +Inf the top code. ``dither``: an ordered 8×8 Bayer dither on ``colour`` channels (8 bits)."""
    scale = 255.0 if out_type == "uint8" else 65535.0
    v = np.nan_to_num(values, nan=0.0, posinf=1.0, neginf=0.0) * scale
    if dither and out_type == "uint8":
        h, w = v.shape[:2]
        # Ordered dither in (-0.5, 0.5) LSB: deterministic, mean preserving,
        # and alpha stays undithered so opaque stays opaque.
        offsets = (_BAYER8 + 0.5) / 64.0 - 0.5
        tile = np.tile(offsets, (math.ceil(h / 8), math.ceil(w / 8)))[:h, :w]
        v[..., colour] += tile[..., None]
    # Round half up rather than numpy's round-half-even.
    v = np.floor(v + 0.5)
    np.clip(v, 0.0, scale, out=v)
    return v.astype(np.uint8 if out_type == "uint8" else np.uint16)
