"""Independent references for the imageio tests: the sRGB formulas, stored values read back with OpenImageIO
directly, and hand-made PNG bytes."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import OpenImageIO as oiio


def srgb_eotf(v: np.ndarray) -> np.ndarray:
    """sRGB decode, straight from IEC 61966-2-1."""
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def srgb_oetf(v: np.ndarray) -> np.ndarray:
    """sRGB encode, straight from IEC 61966-2-1."""
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.0031308, v * 12.92, 1.055 * v ** (1 / 2.4) - 0.055)


def read_raw(path: Path, fmt: str | None = None):
    """Read the stored values of ``path`` and its spec, alpha untouched."""
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    inp = oiio.ImageInput.open(str(path), config)
    assert inp is not None, oiio.geterror()
    spec = inp.spec()
    data = inp.read_image(fmt or str(spec.format))
    inp.close()
    assert data is not None
    return np.asarray(data), spec


def make_png_bytes(width: int, height: int) -> bytes:
    """A minimal 8-bit grey PNG with the given IHDR size (may be invalid)."""
    def chunk(tag: bytes, body: bytes) -> bytes:
        return (struct.pack(">I", len(body)) + tag + body
                + struct.pack(">I", zlib.crc32(tag + body) & 0xFFFFFFFF))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    raw = b"".join(b"\0" + b"\x80" * width for _ in range(height))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def png_row_filters(path: Path) -> set[int]:
    """The filter type byte of every row of a non-interlaced PNG (its IDAT stream inflated), read by hand."""
    data = Path(path).read_bytes()
    at, idat, header = 8, b"", None
    while at < len(data):
        (size,), kind = struct.unpack(">I", data[at:at + 4]), data[at + 4:at + 8]
        body = data[at + 8:at + 8 + size]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        at += 12 + size
    assert header is not None, f"{path}: no IHDR"
    width, height, depth, colour, _, _, interlace = header
    assert interlace == 0, f"{path}: interlaced"
    stride = 1 + width * {0: 1, 2: 3, 4: 2, 6: 4}[colour] * depth // 8
    raw = zlib.decompress(idat)
    assert len(raw) == stride * height
    return {raw[y * stride] for y in range(height)}
