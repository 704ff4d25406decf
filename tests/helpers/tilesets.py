"""What a tile set's tests compare: every file's bytes."""

from __future__ import annotations

from pathlib import Path


def tree(top) -> dict[str, bytes]:
    """Every file under ``top`` (a file or a folder), by its path relative to ``top``'s folder, with its bytes."""
    top = Path(top)
    if top.is_file():
        return {top.name: top.read_bytes()}
    return {str(p.relative_to(top.parent)): p.read_bytes() for p in sorted(top.rglob("*")) if p.is_file()}


def outputs(out) -> dict[str, bytes]:
    """The whole tile set at ``out`` (Deep Zoom: the .dzi and its _files folder)."""
    out = Path(out)
    found = tree(out)
    if out.suffix == ".dzi":
        found.update(tree(out.with_name(out.stem + "_files")))
    return found

