"""The read+write floor: OpenImageIO reads and writes each pair, nothing else (a fresh interpreter per run).

    python bench/scripts/io_floor.py IN OUT [IN OUT …]    # prints the seconds the loop took
"""

import sys
import time

import OpenImageIO as oiio

from pyramid_cli.imageio.formats import PNG_FILTERS  # the PNG row filters pyramid writes with

t0 = time.perf_counter()
a = sys.argv[1:]
for src, dst in zip(a[0::2], a[1::2], strict=True):
    inp = oiio.ImageInput.open(src)
    spec = inp.spec()
    spec.attribute("png:filter", PNG_FILTERS)
    px = inp.read_image(0, 0, 0, spec.nchannels, spec.format)
    inp.close()
    out = oiio.ImageOutput.create(dst)
    out.open(dst, spec)
    out.write_image(px)
    out.close()
print(time.perf_counter() - t0)
