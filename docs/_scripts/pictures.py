"""Draw the documentation's pictures with the package itself, on the CPU executor (``make docs-pictures``).

    python docs/_scripts/pictures.py docs/_static

Writes ``demo_figure3.png`` (the demo's Figure 3 sheet, downscaled), ``figure2_<filter>.png`` (the powers of
the analysis filters, the paper's Figure 2: needs the ``plot`` extra), ``mip_levels.png`` (a MIP chain side by
side), and the demo's ``fill_holes.png`` and ``blend_apple_orange.png`` (before and after).
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile

import numpy as np
import OpenImageIO as oiio

import pyramid_cli as pyr
from pyramid_cli import demo
from pyramid_cli.core.parse import parse
from pyramid_cli.run.explain import plot_powers
from pyramid_cli.run.sheet import contact_sheet


def _downscale(src: str, dst: str, width: int) -> None:
    buf = oiio.ImageBuf(src)
    spec = buf.spec()
    height = max(1, round(spec.height * width / spec.width))
    out = oiio.ImageBufAlgo.resize(buf, roi=oiio.ROI(0, width, 0, height, 0, 1, 0, spec.nchannels))
    out.write(dst)


def main(outdir: str) -> None:
    os.makedirs(outdir, exist_ok=True)
    with tempfile.TemporaryDirectory() as scratch:
        demo.main(scratch, backend="cpu")
        _downscale(os.path.join(scratch, "highlights_figure3.png"), os.path.join(outdir, "demo_figure3.png"), 968)
        for name in ("fill_holes.png", "blend_apple_orange.png"):
            shutil.copy(os.path.join(scratch, name), os.path.join(outdir, name))
    for name in ("box", "box4", "quadratic", "cubic"):
        plot_powers(parse(f"{name} *v g"), os.path.join(outdir, f"figure2_{name}.png"))
    zone = pyr.read_image(os.path.join(demo.SAMPLES, "zoneplate.png")).pixels
    with pyr.Session(backend="cpu") as session:
        levels = list(pyr.mipmap(zone, session=session))
    h = levels[0].shape[0]
    panels = [np.repeat(np.repeat(lv, h // lv.shape[0], 0), h // lv.shape[0], 1) for lv in levels[:6]]
    sheet = contact_sheet(panels)
    pyr.write_image(os.path.join(outdir, "mip_levels_full.png"), sheet[..., :3])
    _downscale(os.path.join(outdir, "mip_levels_full.png"), os.path.join(outdir, "mip_levels.png"), 968)
    os.remove(os.path.join(outdir, "mip_levels_full.png"))
    for name in sorted(os.listdir(outdir)):
        print(f"  {os.path.join(outdir, name)}: {os.path.getsize(os.path.join(outdir, name)) // 1024} KiB")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "_static"))
