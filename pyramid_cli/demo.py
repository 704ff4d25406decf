"""The main job of ``make demo``: the paper's Figure 3 comparison and an analysis-filter
comparison on a zone plate, run on the shipped samples (installed with the package).

    python -m pyramid_cli.demo OUTDIR
"""

from __future__ import annotations

import os
import sys
import time
from importlib.resources import files

import numpy as np

from . import io
from .parse import parse
from .session import Session
from .sheet import contact_sheet
from .work import Blur, Filter

SAMPLES = str(files("pyramid_cli.samples"))


def _png(path: str, pixels: np.ndarray, like: io.ImageInfo) -> None:
    info = io.ImageInfo(path=path, format="png", pixel_type="uint8", channel_names=like.channel_names[:3],
                        alpha_channel=-1, colorspace="srgb", alpha_mode="none")
    io.write_image(path, io.Image(np.ascontiguousarray(pixels[..., :3], dtype=np.float32), info),
                   pixel_type="uint8", colorspace="srgb")


def _exposure(pixels: np.ndarray) -> np.ndarray:
    """Scale HDR so that its 99th percentile maps to white (for looking at, not for pipelines)."""
    hi = float(np.percentile(pixels[..., :3], 99))
    return pixels / hi if hi > 1 else pixels


def main(outdir: str) -> None:
    os.makedirs(outdir, exist_ok=True)
    start = time.perf_counter()
    session = Session("auto")
    written = []
    with session:
        for name in ("highlights.exr", "zoneplate.png"):
            image = io.read_image(os.path.join(SAMPLES, name))
            stem = os.path.splitext(name)[0]
            px = image.pixels
            panels = [px]
            for analysis in ("box", "box4"):  # Figure 3 (a) and (b)
                (out,) = session.run(Blur(levels=4, analysis=analysis, synthesis="doosabin"), px)
                path = os.path.join(outdir, f"{stem}_blur4_{analysis}.png")
                _png(path, _exposure(out), image.spec)
                written.append(path)
                panels.append(out)
            path = os.path.join(outdir, f"{stem}_figure3.png")
            _png(path, _exposure(contact_sheet(panels)), image.spec)
            written.append(path)
        zp = io.read_image(os.path.join(SAMPLES, "zoneplate.png"))
        panels = []
        for analysis in ("box", "box4", "quadratic", "cubic"):
            (reduced,) = session.run(Filter(expr=parse(f"({analysis})^2 *v g")), zp.pixels)
            panels.append(np.repeat(np.repeat(reduced, 2, axis=0), 2, axis=1))  # nearest ×2 to look at
        path = os.path.join(outdir, "zoneplate_analysis.png")
        _png(path, contact_sheet(panels), zp.spec)
        written.append(path)
    print(f"demo: {len(written)} images in {outdir}/ ({session.name}, {time.perf_counter() - start:.1f} s):")
    for p in written:
        print(f"  {p}")
    print(f"what to look for: {os.path.join(SAMPLES, 'README.md')}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join("samples", "out"))
