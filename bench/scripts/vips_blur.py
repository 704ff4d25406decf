"""The libvips peer of ``pyramid blur --sigma S``: what a user's pyvips script does, in a fresh interpreter.

    python bench/scripts/vips_blur.py SIGMA IN OUT

``gaussblur(SIGMA)`` with libvips's defaults (integer precision on 8-bit input, min_ampl 0.2) between a
sequential read (what the ``vips`` command line uses) and a write: PNG with ``compression=6`` (zlib level 6,
``pyramid``'s default), TIFF with ``compression="deflate"`` (zip), anything else by its suffix.
"""

import sys

import pyvips

sigma, src, dst = float(sys.argv[1]), sys.argv[2], sys.argv[3]
blurred = pyvips.Image.new_from_file(src, access="sequential").gaussblur(sigma)
if dst.endswith(".png"):
    blurred.pngsave(dst, compression=6)
elif dst.endswith((".tif", ".tiff")):
    blurred.tiffsave(dst, compression="deflate")
else:
    blurred.write_to_file(dst)
