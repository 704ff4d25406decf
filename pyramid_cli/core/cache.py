"""The one cache folder: what a process may reuse from an earlier one (kernels, plans, the renderer).

Everything here is a speed-up only: an entry that is missing, unreadable or corrupt is
recomputed, and a folder that cannot be written is passed over silently. Entries are
written atomically (a temporary file renamed onto the name), so processes racing on a
farm's shared home folder never read a half-written entry.

The root is ``$PYRAMID_CACHE_HOME`` if set, else ``$XDG_CACHE_HOME/bilinear-pyramid``, else
``~/.cache/bilinear-pyramid`` (the XDG base directory convention). Each user of the cache
keeps a sub-folder of its own (:func:`folder`): ``cpu`` (the compiled kernels), and so on.
"""

from __future__ import annotations

import hashlib
import os
import threading
from pathlib import Path

HOME_ENV = "PYRAMID_CACHE_HOME"


def root() -> Path:
    """The cache's root folder (see the module); not created here."""
    env = os.environ.get(HOME_ENV)
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "bilinear-pyramid"


def folder(name: str) -> Path:
    """The sub-folder ``name`` of :func:`root` (not created here)."""
    return root() / name


def key(*parts: object) -> str:
    """A file-name-safe digest of ``parts`` (their ``repr``), for an entry's name."""
    return hashlib.sha256(repr(parts).encode("utf-8")).hexdigest()[:32]


def read(name: str, entry: str) -> bytes | None:
    """The bytes of ``entry`` in :func:`folder` ``name``, or None when there is none (or it cannot be read)."""
    try:
        return (folder(name) / entry).read_bytes()
    except OSError:
        return None


def write(name: str, entry: str, data: bytes) -> bool:
    """Store ``data`` as ``entry`` in :func:`folder` ``name`` atomically; False (and nothing left behind)
    when the folder cannot be written."""
    where = folder(name)
    tmp = where / f".{entry}.{os.getpid()}.{threading.get_ident()}.tmp"
    try:
        where.mkdir(parents=True, exist_ok=True)
        tmp.write_bytes(data)
        os.replace(tmp, where / entry)
        return True
    except OSError:
        try:
            tmp.unlink()
        except OSError:
            pass
        return False


__all__ = ["HOME_ENV", "root", "folder", "key", "read", "write"]
