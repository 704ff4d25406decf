"""Test images written with OpenImageIO directly, so that what a test reads back is what it wrote."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenImageIO as oiio


def write(path, pixels, pixel_type: str = "float", tile: int = 0, *, names=None, alpha=None, **attrs) -> Path:
    """Write ``pixels`` (H×W×C, or H×W for one channel) to ``path`` as ``pixel_type``, with no colour or alpha rules.

    Parameters
    ----------
    path : str or Path
        The file; its extension picks the format. Missing parent folders are made.
    pixels : array_like
        The values. float64 arrays are stored as float32 first when ``pixel_type`` is ``"float"`` or
        ``"half"`` (OpenImageIO would round them the same way); every other array is written as given.
    pixel_type : str
        OpenImageIO's type name of the stored channels (``"float"``, ``"half"``, ``"uint8"``, …).
    tile : int
        A square tile size, or 0 for scanlines.
    names : sequence of str, optional
        The channel names.
    alpha : int, optional
        The alpha channel's index.
    **attrs
        Extra metadata; ``__`` in a key stands for ``:`` (``oiio__ColorSpace`` is ``oiio:ColorSpace``).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    px = np.asarray(pixels)
    if px.ndim == 2:
        px = px[..., None]
    if pixel_type in ("float", "half") and px.dtype == np.float64:
        px = px.astype(np.float32)
    h, w, c = px.shape
    spec = oiio.ImageSpec(w, h, c, pixel_type)
    if tile:
        spec.tile_width = spec.tile_height = tile
    if names:
        spec.channelnames = tuple(names)
    if alpha is not None:
        spec.alpha_channel = alpha
    for key, value in attrs.items():
        spec.attribute(key.replace("__", ":"), value)
    path.parent.mkdir(parents=True, exist_ok=True)
    out = oiio.ImageOutput.create(str(path))
    assert out is not None, oiio.geterror()
    assert out.open(str(path), spec), out.geterror()
    assert out.write_image(np.ascontiguousarray(px)), out.geterror()
    assert out.close(), out.geterror()
    return path


def noise(h: int, w: int, c: int = 4, seed: int = 0) -> np.ndarray:
    """A float32 H×W×C picture of uniform noise in [0, 1), the same for the same seed."""
    return np.random.default_rng(seed).random((h, w, c)).astype(np.float32)


def write_sequence(folder: Path, first: int, last: int, name: str = "plate.{:04d}.exr", size=(8, 8)) -> None:
    """Frames ``first``…``last`` of an RGB float sequence in ``folder`` (made if missing), each frame's noise
    seeded by its number, written through the package's own writer."""
    import pyramid_cli as pyr

    folder.mkdir(parents=True, exist_ok=True)
    for f in range(first, last + 1):
        pixels = np.random.default_rng(abs(f)).random((*size, 3)).astype(np.float32)
        pyr.write_image(str(folder / name.format(f)), pixels)


def read_with_spec(path):
    """A file's pixels as float and its ImageSpec, straight from OpenImageIO (not through the package)."""
    inp = oiio.ImageInput.open(str(path))
    spec = inp.spec()
    px = inp.read_image("float")
    inp.close()
    return px, spec


def write_method_files(d: Path) -> Path:
    """The images the fill and blend command tests read: an apple/orange pair and their mask, an RGBA with a
    hole and a half-covered pixel, one with NaNs, and an all-zero RGBA."""
    import pyramid_cli as pyr
    from pyramid_cli.demo import apple_orange

    a, b, m = apple_orange(64)
    rgba = np.concatenate([a, np.ones(a.shape[:2] + (1,), np.float32)], axis=2)
    rgba[20:40, 10:50] = 0
    rgba[5, 5, 3] = 0.5
    rgba[5, 5, :3] *= 0.5
    nan = a.copy()
    nan[30:34, 30:40] = np.nan
    for name, px in [("a.exr", a), ("b.exr", b), ("m.exr", m), ("holes.exr", rgba), ("nan.exr", nan),
                     ("empty.exr", np.zeros((8, 8, 4), np.float32))]:
        pyr.write_image(d / name, px)
    return d
