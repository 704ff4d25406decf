"""Golden images for samples/Makefile, made by the numpy reference of the paper's formulas
(never by the GL path they check).

    python samples/make_goldens.py
"""

from __future__ import annotations

import os

import numpy as np
import OpenImageIO as oiio

from pyramid_cli import imageio as io
from pyramid_cli.reference.pyramids import blur_reference

HERE = os.path.dirname(os.path.abspath(__file__))
LEVELS = 4  # keep in step with samples/Makefile


def main() -> None:
    for name in ("highlights.exr", "zoneplate.png"):
        image = io.read_image(os.path.join(HERE, name))
        out = blur_reference(image.pixels.astype(np.float64), LEVELS, "box4", "doosabin").astype(np.float32)
        path = os.path.join(HERE, "golden", f"{os.path.splitext(name)[0]}_blur.exr")
        spec = oiio.ImageSpec(out.shape[1], out.shape[0], out.shape[2], "float")
        spec.attribute("compression", "zip")
        spec.attribute("Software", "pyramid reference executor (samples/make_goldens.py)")
        o = oiio.ImageOutput.create(path)
        o.open(path, spec)
        o.write_image(out)
        o.close()
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
