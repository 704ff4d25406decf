"""The libvips peers of ``pyramid tiles``: what ``vips dzsave`` / ``vips tiffsave`` do, in a fresh interpreter.

    python bench/scripts/vips_tiles.py dzsave IN OUT.dzi [SUFFIX]
    python bench/scripts/vips_tiles.py tiffsave IN OUT.tif COMPRESSION TILE [Q]

``dzsave`` with libvips's defaults (tile 254, overlap 1, JPEG Q 75, the 2×2 mean in the stored values); SUFFIX
(e.g. ``.png``) changes only the tiles' format, for the quality bench, which reads the tiles back. ``tiffsave``
writes a tiled pyramidal TIFF (``--tile --pyramid``) with the given compression and square tile edge. The input
is opened with sequential access, as the ``vips`` command line opens it. The ``vips`` executable is not needed:
pyvips-binary ships libvips without it.
"""

import sys

import pyvips

mode, src, dst = sys.argv[1:4]
image = pyvips.Image.new_from_file(src, access="sequential")
if mode == "dzsave":
    base = dst[:-4] if dst.endswith(".dzi") else dst
    image.dzsave(base, **({"suffix": sys.argv[4]} if len(sys.argv) > 4 else {}))
elif mode == "tiffsave":
    compression, tile = sys.argv[4], int(sys.argv[5])
    options = {"Q": int(sys.argv[6])} if len(sys.argv) > 6 else {}
    image.tiffsave(dst, tile=True, pyramid=True, compression=compression, tile_width=tile, tile_height=tile,
                   **options)
else:
    sys.exit(f"vips_tiles.py: unknown mode {mode!r} (dzsave or tiffsave)")
