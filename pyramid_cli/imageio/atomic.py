"""Atomic file replacement: a failed or interrupted write never leaves a half file.

Rules (the README's "Outputs" paragraph):

- a missing output folder is created (:func:`ensure_output_dir`), whatever the command and
  however many inputs it has;
- every output is written to a hidden temporary file beside it (``.NAME.tmp-XXXX.EXT``; an
  ASCII name when NAME is not valid UTF-8), flushed to disk and renamed over the output only
  when complete; on any failure or interruption (KeyboardInterrupt, and SIGTERM/SIGHUP once
  :func:`pyramid_cli.core.signals.install` ran) the temporary is removed and the previous output
  is untouched;
- several outputs of one command (:func:`atomic_paths`) are all written first and renamed
  together at the end: either all are replaced or none is.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator, Sequence

from pyramid_cli.core.errors import OutputError, PyramidError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def error_reason(exc: OSError) -> str:
    """What an OS error says, for a one-line message (``"No space left on device"``)."""
    return exc.strerror or str(exc)


def ensure_output_dir(path: str | os.PathLike[str]) -> None:
    """Create the folder that will hold ``path`` (and its parents) if missing.

    Raises
    ------
    OutputError
        The folder cannot be created, or a file stands where it should be.
    """
    folder = os.path.dirname(os.path.abspath(os.fspath(path)))
    if os.path.isdir(folder):
        return
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot write {os.fspath(path)}: cannot create folder {folder}: "
                          f"{error_reason(exc)}") from None


def is_utf8(name: str) -> bool:
    """Can ``name`` be encoded as UTF-8 (what OpenImageIO needs of a file name)?"""
    try:
        name.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def make_temp(path: str) -> str:
    """A new empty hidden file beside ``path`` with the same extension (an ASCII name if need be)."""
    ensure_output_dir(path)
    folder = os.path.dirname(os.path.abspath(path))
    base = os.path.basename(path)
    ext = os.path.splitext(base)[1]
    if not is_utf8(base):
        # Image libraries take UTF-8 names; the temporary gets one, the rename gives the real name.
        base, ext = "pyramid-output", ext if is_utf8(ext) else ""
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{base}.tmp-", suffix=ext, dir=folder)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {error_reason(exc)}") from None
    os.close(fd)
    return tmp


def _fsync(path: str, flags: int = os.O_RDONLY) -> None:
    fd = os.open(path, flags)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def remove_quietly(tmp: str) -> None:
    """Remove the temporary file ``tmp`` if it is still there (a failure to do so is not an error)."""
    with contextlib.suppress(OSError):
        os.unlink(tmp)


def _sync_folders(paths: Sequence[str]) -> None:
    for folder in {os.path.dirname(os.path.abspath(p)) for p in paths}:
        with contextlib.suppress(OSError):
            _fsync(folder)


@contextlib.contextmanager
def atomic_path(path: str) -> Iterator[str]:
    """Yield a hidden temporary path beside ``path`` (same extension); on success it is
    fsynced, given the usual permissions and renamed onto ``path``.

    The temporary file lives in the same folder (created if missing), so the final
    ``os.replace`` is atomic on POSIX; on any exception (KeyboardInterrupt included) it is
    removed and whatever was at ``path`` before is untouched. OS errors become
    :class:`OutputError` naming ``path``, never the temporary.
    """
    with atomic_paths([path]) as (tmp,):
        yield tmp


@contextlib.contextmanager
def atomic_paths(paths: Sequence[str]) -> Iterator[list[str]]:
    """All-or-nothing writing of several files: yield one temporary path per path.

    Every temporary is written by the body, then all are fsynced and only then renamed onto
    their paths, one after the other: a failure or interruption before the renames leaves
    every previous output untouched and no temporary behind. (The renames themselves cannot
    be made one atomic step; they are the last, fastest part, after everything could fail.)
    """
    paths = [os.fspath(p) for p in paths]
    if len({os.path.abspath(p) for p in paths}) < len(paths):
        raise OutputError(f"cannot write {paths[0]}: the same output path is given twice")
    tmps: list[str] = []  # emptied as each is renamed
    made: list[str] = []
    try:
        for p in paths:
            made.append(make_temp(p))
            tmps.append(made[-1])
        yield list(tmps)
        mode = 0o666 & ~_umask()
        for p, tmp in zip(paths, tmps, strict=True):
            try:
                _fsync(tmp)
                os.chmod(tmp, mode)
            except OSError as exc:
                raise OutputError(f"cannot write {p}: {error_reason(exc)}") from None
        for k, (p, tmp) in enumerate(zip(paths, tmps, strict=True)):
            try:
                os.replace(tmp, p)
            except OSError as exc:
                raise OutputError(f"cannot write {p}: {error_reason(exc)}") from None
            tmps[k] = ""
    except BaseException as exc:
        for tmp in tmps:
            if tmp:
                remove_quietly(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, PyramidError):  # InputError is an OSError too
            raise OutputError(f"cannot write {paths[0] if len(paths) == 1 else ', '.join(paths)}: "
                              f"{error_reason(exc)}") from None
        if isinstance(exc, OutputError) and any(t in exc.message for t in made):
            message = exc.message
            for p, tmp in zip(paths, made, strict=False):
                message = message.replace(tmp, p)
            raise OutputError(message) from None
        raise
    _sync_folders(paths)
