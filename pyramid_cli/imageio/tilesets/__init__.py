"""Tile sets for viewers (issue 27): Deep Zoom and IIIF folders, OME-Zarr multiscales, pyramidal TIFF.

Each layout is a :class:`~pyramid_cli.imageio.tilesets.base.TileSetWriter` in a module of its own,
loaded only when asked for (:func:`writer_class`); :func:`layout_of` picks the layout from the
output's name unless ``--layout`` names it.
"""

from __future__ import annotations

import importlib

from pyramid_cli.core.errors import UsageError
from pyramid_cli.imageio.tilesets.base import TileOptions, TileSetWriter, ceil_levels

# layout name → "module:class" under this package (imported on demand: zarr and tifffile are extras)
LAYOUTS = {
    "dz": "deepzoom:DeepZoomWriter",
    "iiif3": "deepzoom:IIIF3Writer",
    "iiif": "deepzoom:IIIF2Writer",
    "ome-zarr": "omezarr:OmeZarrWriter",
    "tiff": "tiff:PyramidTiffWriter",
    "ome-tiff": "tiff:OmeTiffWriter",
}


def layout_of(path: str, layout: str | None = None) -> str:
    """The layout ``path`` is written in: ``layout`` when given, else from the name (``.dzi`` Deep Zoom,
    ``.zarr``/``.ome.zarr`` OME-Zarr, ``.ome.tif(f)`` OME-TIFF, ``.tif(f)``/``.tx`` pyramidal TIFF)."""
    if layout is not None:
        if layout not in LAYOUTS:
            raise UsageError(f"--layout {layout}: not one of {', '.join(LAYOUTS)}")
        return layout
    name = path.rstrip("/").lower()
    for ends, found in ((".dzi", "dz"), (".zarr", "ome-zarr"), (".ome.tif", "ome-tiff"), (".ome.tiff", "ome-tiff"),
                        (".tif", "tiff"), (".tiff", "tiff")):
        if name.endswith(ends):
            return found
    raise UsageError(f"cannot tell the layout of {path}: name it .dzi, .zarr, .ome.zarr, .tif or .ome.tif, "
                     "or give --layout (iiif3 and iiif write a folder)")


def writer_class(layout: str) -> type[TileSetWriter]:
    """The writer of ``layout`` (its module imported now)."""
    module, name = LAYOUTS[layout].split(":")
    return getattr(importlib.import_module(f"{__name__}.{module}"), name)


__all__ = ["LAYOUTS", "TileOptions", "TileSetWriter", "ceil_levels", "layout_of", "writer_class"]
