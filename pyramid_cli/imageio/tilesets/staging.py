"""A tile set built beside its output and moved into place at the end, descriptor last.

A tile set is several paths (Deep Zoom: ``name_files/`` and ``name.dzi``; IIIF and OME-Zarr: one
folder; a TIFF: one file). :class:`Staging` gives each a path inside a hidden folder beside the
first one (``.NAME.tmp-XXXX``, on the same file system, so every move is a rename); :meth:`Staging.commit`
moves them onto their paths in the order given (the descriptor last: a viewer that opens the
descriptor finds its tiles), each previous output moved aside first and removed only after every new
path is in place; :meth:`Staging.discard` (any failure or interruption) removes the hidden folder and
leaves the previous output as it was.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Sequence

from pyramid_cli.core.errors import OutputError
from pyramid_cli.imageio.atomic import ensure_output_dir, error_reason


class Staging:
    """Hidden staging paths for ``paths`` (the user's outputs, the descriptor last); see the module."""

    def __init__(self, paths: Sequence[str]):
        self.paths = [os.fspath(p) for p in paths]
        first = self.paths[0].rstrip(os.sep) or self.paths[0]
        ensure_output_dir(first)
        folder = os.path.dirname(os.path.abspath(first))
        try:
            self.root = tempfile.mkdtemp(prefix=f".{os.path.basename(first)}.tmp-", dir=folder)
        except OSError as exc:
            raise OutputError(f"cannot write {self.paths[0]}: {error_reason(exc)}") from None
        self.staged = [os.path.join(self.root, os.path.basename(p.rstrip(os.sep))) for p in self.paths]

    @classmethod
    def existing(cls, paths: Sequence[str], root: str) -> Staging:
        """The staging that another process made at ``root`` for ``paths`` (a part of a tile set written on a
        cluster worker into its client's staging folder); only its client commits or discards it."""
        self = cls.__new__(cls)
        self.paths = [os.fspath(p) for p in paths]
        self.root = os.fspath(root)
        self.staged = [os.path.join(self.root, os.path.basename(p.rstrip(os.sep))) for p in self.paths]
        return self

    def commit(self) -> None:
        """Move every staged path onto its output, in order; the previous outputs are removed last."""
        old = os.path.join(self.root, ".previous")
        done: list[tuple[str, str, str]] = []  # (target, staged, previous or "") moved so far
        try:
            os.mkdir(old)
            for k, (path, staged) in enumerate(zip(self.paths, self.staged, strict=True)):
                target = path.rstrip(os.sep) or path
                aside = ""
                if os.path.lexists(target):
                    aside = os.path.join(old, str(k))
                    os.replace(target, aside)
                done.append((target, staged, aside))
                os.replace(staged, target)
        except OSError as exc:
            self._restore(done)
            raise OutputError(f"cannot write {self.paths[0]}: {error_reason(exc)}") from None
        self.discard()

    @staticmethod
    def _restore(done: list[tuple[str, str, str]]) -> None:
        """Undo a commit that failed part way: every previous output back on its path (the new ones back into
        the staging folder, which :meth:`discard` then removes)."""
        for target, staged, aside in reversed(done):
            with contextlib.suppress(OSError):
                if not os.path.lexists(staged) and os.path.lexists(target):
                    os.replace(target, staged)
                if aside:
                    os.replace(aside, target)

    def discard(self) -> None:
        """Remove the hidden folder and everything in it (what a failed run wrote, or the previous outputs). It is
        renamed first: a part still being written by a cluster worker (:meth:`existing`) then finds no folder to
        write into, instead of filling the folder while it is removed."""
        gone = f"{self.root}.discarded"
        try:
            os.rename(self.root, gone)
        except OSError:
            gone = self.root
        shutil.rmtree(gone, ignore_errors=True)


__all__ = ["Staging"]
