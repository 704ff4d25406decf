"""The checked writer: every file goes to a hidden temporary, every OpenImageIO call is checked, and the
file must read back before it is renamed onto the output (see :mod:`pyramid_cli.imageio`, "Writing")."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable, Sequence

import numpy as np
import OpenImageIO as oiio

from pyramid_cli.core.errors import OutputError, PyramidError
from pyramid_cli.imageio.atomic import atomic_path, atomic_paths
from pyramid_cli.imageio.encode import check_output_path, check_write_options, encode
from pyramid_cli.imageio.formats import ENCODE_IN_MEMORY, format_from_path, format_title, one_line
from pyramid_cli.imageio.image import Image

# Messages OpenImageIO's writers leave in their error state on every successful write
# (OpenImageIO 3.2's TIFF writer, for an image without Exif data); the read-back checks the file.
_BENIGN_ERRORS = frozenset({"failed TIFFWriteCustomDirectory() of the Exif data"})


class WriteFailed(Exception):
    """An OpenImageIO call on the output failed; the message is OpenImageIO's."""


def checked(out, ok, what: str) -> None:
    """Raise WriteFailed unless ``ok`` and the writer holds no error (PNG and TGA writers report a
    failed write only through their error state, returning success)."""
    if ok and not out.has_error:
        return
    lines = [ln.strip() for ln in (out.geterror() or oiio.geterror()).splitlines()
             if ln.strip() and ln.strip() not in _BENIGN_ERRORS]
    if ok and not lines:
        return
    raise WriteFailed(lines[0] if lines else f"{what} failed")


def _write_pixels(out, spec: oiio.ImageSpec, data: np.ndarray) -> None:
    """Write one (sub)image: scanlines whole, tiled images one row of tiles at a time.

    OpenImageIO's write_image of a tiled OpenEXR hangs for ever when a write fails (its parallel
    tile writer deadlocks on ENOSPC/EFBIG); a row of tiles per call fails cleanly.
    """
    if spec.tile_width > 0 and spec.tile_height > 0:
        th = spec.tile_height
        for y0 in range(0, spec.height, th):
            y1 = min(y0 + th, spec.height)
            ok = out.write_tiles(spec.x, spec.x + spec.width, spec.y + y0, spec.y + y1, spec.z, spec.z + 1,
                                 np.ascontiguousarray(data[y0:y1]))
            checked(out, ok, "write")
    else:
        checked(out, out.write_image(data), "write")


def _oiio_write_parts(target: str, fmt: str, parts: list[tuple[oiio.ImageSpec, np.ndarray]], mode: str) -> None:
    """Write ``parts`` to ``target`` with OpenImageIO, checking every call; raise WriteFailed.

    ``mode``: "single" (one image), "mipmap" (MIP levels of one tiled image), "multipart" (subimages).
    """
    out = oiio.ImageOutput.create(fmt) if fmt else oiio.ImageOutput.create(target)
    if out is None:
        raise WriteFailed(one_line(oiio.geterror(), "no writer for this format"))
    failure: WriteFailed | None = None
    try:
        if mode == "multipart":
            ok = out.open(target, tuple(spec for spec, _ in parts))
        else:
            ok = out.open(target, parts[0][0], "Create")
        checked(out, ok, "open")
        for k, (spec, data) in enumerate(parts):
            if k:
                # A format without MIP levels of its own (TIFF) holds them as subimages, which its reader
                # presents as MIP levels when the file says "textureformat" (maketx does the same).
                append = "AppendMIPLevel" if mode == "mipmap" and out.supports("mipmap") else "AppendSubimage"
                checked(out, out.open(target, spec, append), "open")
            _write_pixels(out, spec, data)
    except WriteFailed as exc:
        failure = exc
    except (RuntimeError, TypeError, ValueError) as exc:  # binding errors
        failure = WriteFailed(one_line(str(exc), "write failed"))
    finally:
        closed = out.close()
    if failure is not None:
        raise failure
    checked(out, closed, "close")


def _size_limit() -> int | None:
    """The process's file size limit (ulimit -f) in bytes, None when unlimited."""
    try:
        import resource
    except ImportError:  # not on Windows: no file size limit to respect
        return None
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return None if soft == resource.RLIM_INFINITY else int(soft)


def _copy_to(src_fd: int, dst: str) -> None:
    """Copy the whole of ``src_fd`` into the file ``dst`` with os.write (OSError on ENOSPC/EFBIG/EDQUOT)."""
    fd = os.open(dst, os.O_WRONLY | os.O_TRUNC)
    try:
        offset, size = 0, os.fstat(src_fd).st_size
        while offset < size:
            chunk = os.pread(src_fd, min(1 << 23, size - offset), offset)
            view = memoryview(chunk)
            while view:
                n = os.write(fd, view)
                view = view[n:]
            offset += len(chunk)
    finally:
        os.close(fd)


_PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"


def verify(tmp: str, fmt: str, parts: Sequence[tuple[oiio.ImageSpec, np.ndarray | None]], mode: str) -> None:
    """Check what was written: not empty, the format's end marker where it has one (PNG, JPEG),
    and a header that reads back with the size and channels written (each part's spec: its pixels are
    not read, and may be None)."""
    size = os.path.getsize(tmp)
    if size == 0:
        raise WriteFailed("nothing was written (the file is empty)")
    if fmt in ("png", "jpeg"):
        with open(tmp, "rb") as f:
            f.seek(max(0, size - 12))
            tail = f.read()
        if not tail.endswith(_PNG_END if fmt == "png" else b"\xff\xd9"):
            raise WriteFailed(f"the file is incomplete ({size} bytes, no end marker)")
    inp = oiio.ImageInput.open(tmp)
    if inp is None:
        raise WriteFailed(f"the file does not read back ({one_line(oiio.geterror(), 'unreadable')})")
    try:
        spec, want = inp.spec(), parts[0][0]
        if (spec.width, spec.height) != (want.width, want.height):
            raise WriteFailed(f"the file reads back as {spec.width}x{spec.height}, not {want.width}x{want.height}")
        if mode == "multipart" and not inp.seek_subimage(len(parts) - 1, 0):
            raise WriteFailed(f"the file reads back with fewer than {len(parts)} parts")
        if mode == "mipmap" and not inp.seek_subimage(0, len(parts) - 1):
            raise WriteFailed(f"the file reads back with fewer than {len(parts)} MIP levels")
    finally:
        inp.close()
        oiio.geterror()  # leave no stale error behind


def write_file(tmp: str, user_path: str, fmt: str, parts: list[tuple[oiio.ImageSpec, np.ndarray]],
                mode: str = "single") -> None:
    """Write ``parts`` into the temporary ``tmp`` and check the result; OutputError names ``user_path``."""
    try:
        if fmt in ENCODE_IN_MEMORY and hasattr(os, "memfd_create") and os.path.isdir("/proc/self/fd"):
            limit = _size_limit()
            bound = 2 * sum(data.nbytes for _, data in parts) + (1 << 20)
            if limit is not None and bound > limit:
                # The encoder would exit the process if the limit stopped it: refuse first.
                raise WriteFailed(f"a {format_title(fmt)} file of this size may need up to {bound} "
                                   f"bytes, over the file size limit (ulimit -f) of {limit} bytes")
            mem = os.memfd_create("pyramid-encode", getattr(os, "MFD_CLOEXEC", 0))
            try:
                _oiio_write_parts(f"/proc/self/fd/{mem}", fmt, parts, mode)
                _copy_to(mem, tmp)
            finally:
                os.close(mem)
        else:
            _oiio_write_parts(tmp, "", parts, mode)
        verify(tmp, fmt, parts, mode)
    except WriteFailed as exc:
        message = str(exc).replace(tmp, user_path)
        raise OutputError(f"cannot write {user_path}: {message}{diagnosis(tmp)}") from None
    except PyramidError:  # an InputError or OutputError is an OSError too: it says its own line
        raise
    except OSError as exc:
        raise OutputError(f"cannot write {user_path}: {exc.strerror or exc}") from None


def diagnosis(tmp: str) -> str:
    """Why a write may have failed, when the system says (OpenImageIO's messages do not)."""
    limit = _size_limit()
    with contextlib.suppress(OSError):
        if limit is not None and os.path.getsize(tmp) >= limit:
            return f" (the file size limit, ulimit -f, is {limit} bytes)"
    with contextlib.suppress(OSError):
        st = os.statvfs(os.path.dirname(os.path.abspath(tmp)))
        if st.f_bavail * st.f_frsize < (1 << 20):
            return " (the disk is full)"
    return ""


def _oiio_write(path: str, spec: oiio.ImageSpec, pixels: np.ndarray) -> None:
    """Write ``pixels`` to ``path`` with OpenImageIO (checked, see :func:`write_file`); OutputError on failure."""
    write_file(path, path, format_from_path(path), [(spec, pixels)])


def write_image(path: str | os.PathLike[str], image: Image, *,
                pixel_type: str | None = None, colorspace: str | None = None,
                alpha: str | None = None, dither: bool = False,
                compression: str | None = None, force: bool = False,
                inputs: Iterable[str | os.PathLike[str]] = ()) -> None:
    """Write an image atomically, encoded like its input unless told otherwise.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; its extension picks the format.
    image : Image
        Linear pixels (premultiplied when ``image.premultiplied``) and the
        info of the input they came from.
    pixel_type : {"uint8", "uint16", "half", "float"}, optional
        Stored type; default the input's. Replaced by the nearest type the
        format can hold (see :func:`~pyramid_cli.imageio.formats.output_pixel_type`).
    colorspace : {"linear", "srgb"}, optional
        Encoding to store; default the input's when input and output are both
        integer or both float, else the output type's default (integer: sRGB,
        float: linear).
    alpha : {"straight", "premultiplied", "none"}, optional
        How to store alpha; default what the output format expects (EXR:
        premultiplied; TIFF: like a TIFF input, else straight for integers;
        other formats: straight). ``"none"`` writes alpha values as they are.
    dither : bool
        Add an ordered (Bayer 8x8, deterministic) dither of under half a step
        to colour channels before rounding to uint8.
    compression : str, optional
        OpenImageIO compression name, e.g. ``"zip"``, ``"piz"``,
        ``"dwaa:45"``; default the input's when the format is unchanged.
    force : bool
        Allow overwriting a path in ``inputs``.
    inputs : iterable of path
        Files that must not be overwritten.

    Raises
    ------
    OutputError
        Unknown extension, unwritable folder, write failure, or the output is
        one of ``inputs`` and ``force`` is false.
    UsageError
        An unknown ``pixel_type``, ``colorspace`` or ``alpha`` value.
    """
    spec, data = encode(path, image, pixel_type=pixel_type, colorspace=colorspace, alpha=alpha, dither=dither,
                         compression=compression, force=force, inputs=inputs)
    out_path = os.fspath(path)
    _atomic_write(out_path, os.path.dirname(os.path.abspath(out_path)), spec, data)


def write_images(paths: Sequence[str | os.PathLike[str]], images: list[Image], **options) -> None:
    """Write several files all-or-nothing (``pyramid levels``): every file is written and checked under
    its temporary name first, then all are renamed; a failure or interruption leaves every previous
    output untouched and no temporary behind.

    Parameters
    ----------
    paths, images
        One output path per image.
    options
        As for :func:`write_image` (pixel_type, colorspace, alpha, dither, compression, force, inputs).
    """
    out_paths = [os.fspath(p) for p in paths]
    if len(out_paths) != len(images):
        raise ValueError("write_images needs one path per image")
    for p in out_paths:  # refuse bad names and options before writing anything
        check_output_path(p, options.get("force", False), options.get("inputs", ()))
        check_write_options(p, options.get("pixel_type"), options.get("compression"), options.get("colorspace"),
                            images[0].spec.colorconfig if images else None)
    with atomic_paths(out_paths) as tmps:
        for p, tmp, image in zip(out_paths, tmps, images, strict=True):
            spec, data = encode(p, image, **options)  # one image's encoded copy at a time
            write_file(tmp, p, format_from_path(p), [(spec, data)])


def write_spec(path: str | os.PathLike[str], spec: oiio.ImageSpec, data: np.ndarray) -> None:
    """Write ``data`` exactly as ``spec`` says (no colour or alpha rules), atomically and checked like every
    other write: a failure is an OutputError naming ``path`` and leaves what was there untouched."""
    out_path = os.fspath(path)
    _atomic_write(out_path, os.path.dirname(os.path.abspath(out_path)), spec, np.ascontiguousarray(data))


def _atomic_write(out_path: str, folder: str, spec: oiio.ImageSpec, data: np.ndarray) -> None:
    with atomic_path(out_path) as tmp:
        try:
            _oiio_write(tmp, spec, data)
        except OutputError as exc:
            # Report the user's path, not the temporary one.
            raise OutputError(exc.message.replace(tmp, out_path)) from None
