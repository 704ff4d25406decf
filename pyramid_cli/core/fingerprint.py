"""Which code this is: a digest of the package's sources, for results cached on disk across processes.

A cached plan or exact kernel is only valid for the code that computed it. A release names that code by its
version, but a checkout being edited keeps the version while its planner changes; :func:`sources` digests the
name, size and modification time of every file in some of the package's folders, so that any edit (or another
installation) gives new cache entries instead of stale ones. A stat per file, done once per process.
"""

from __future__ import annotations

import os
from functools import cache
from pathlib import Path

from pyramid_cli.core.cache import key
from pyramid_cli.core.version import __version__

PACKAGE = Path(__file__).resolve().parent.parent


@cache
def sources(*folders: str) -> str:
    """A digest of the version and of the ``.py`` and ``.json`` files (name, size, modification time) in the
    package's ``folders`` (``"core"``, ``"plan"`` …); folders that cannot be listed count as such."""
    files: list[tuple] = [("version", __version__)]
    for name in sorted(folders):
        try:
            with os.scandir(PACKAGE / name) as it:
                for entry in it:
                    if entry.is_file() and entry.name.endswith((".py", ".json")):
                        st = entry.stat()
                        files.append((name, entry.name, st.st_size, st.st_mtime_ns))
        except OSError:
            files.append((name, "?"))
    return key(*sorted(files, key=repr))


__all__ = ["PACKAGE", "sources"]
