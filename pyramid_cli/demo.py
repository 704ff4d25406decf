"""The main job of ``make demo``: the paper's Figure 3 comparison and an analysis-filter
comparison on a zone plate, run on the shipped samples (installed with the package).

    python -m pyramid_cli.demo [OUTDIR] [--backend auto|gl|cpu|reference]

``auto`` (the default) runs where the command line's ``auto`` would: on the executor estimated to finish the
demo's jobs first (GL or the compiled CPU executor; the CPU executor without EGL). The first line printed names
the executor and why it was chosen.
"""

from __future__ import annotations

import os
import sys
import time
from importlib.resources import files

import numpy as np

from pyramid_cli import imageio as io
from pyramid_cli.core.parse import parse
from pyramid_cli.exec.session import Session
from pyramid_cli.jobs.work import Blur, Filter
from pyramid_cli.run.sheet import contact_sheet

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


def apple_orange(size: int = 256) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Burt & Adelson's classic test, made procedurally: a streaked red apple and a dimpled orange of one
    size and place (linear light, float32 H×W×3), and the mask taking the left half from the apple."""
    y, x = np.mgrid[0:size, 0:size].astype(np.float64) / size
    dx, dy = x - 0.5, y - 0.52
    r = np.hypot(dx, dy) / 0.38
    inside = r < 1
    nz = np.sqrt(np.clip(1 - r ** 2, 0, 1))
    light = np.clip((-0.45 * dx / 0.38 - 0.55 * dy / 0.38 + 0.7 * nz) / np.sqrt(0.45 ** 2 + 0.55 ** 2 + 0.49), 0, 1)
    background = (0.55 + 0.25 * y)[..., None] * np.array([0.75, 0.8, 0.9])
    angle = np.arctan2(dy, dx)
    streaks = 1 + 0.18 * np.sin(23 * angle + 4 * r) * nz
    apple = (0.15 + 0.85 * light)[..., None] * streaks[..., None] * np.array([0.55, 0.04, 0.03])
    dimples = 1 + 0.12 * np.sin(97 * x + 3 * np.sin(41 * y)) * np.sin(89 * y + 3 * np.sin(37 * x))
    orange = (0.15 + 0.85 * light)[..., None] * dimples[..., None] * np.array([0.85, 0.3, 0.02])
    highlight = (np.clip(light, 0, 1) ** 40)[..., None] * 0.6
    a = np.where(inside[..., None], apple + highlight, background)
    b = np.where(inside[..., None], orange + 0.5 * highlight, background)
    mask = (x < 0.5).astype(np.float32)
    return a.astype(np.float32), b.astype(np.float32), mask


def _methods(session: Session, outdir: str, like: io.ImageInfo) -> list[str]:
    """The pyramid methods: the apple, the orange, the hard cut and the multiresolution blend; then the blend
    with rectangular holes and filled, and with 2 % of its pixels kept and filled."""
    from pyramid_cli.jobs.work import Blend, Fill
    from pyramid_cli.workflows.methods import fill_inputs, fill_output, mask_channels

    written = []
    a, b, mask = apple_orange(256)
    (blended,) = session.run(Blend(), [a, b, mask_channels(mask, a)])
    cut = mask[..., None] * a + (1 - mask[..., None]) * b
    path = os.path.join(outdir, "blend_apple_orange.png")
    _png(path, contact_sheet([a, b, cut, blended]), like)
    written.append(path)
    px = blended  # the orapple, with holes cut into it
    h, w = px.shape[:2]
    rng = np.random.default_rng(17)
    known = np.ones((h, w), dtype=np.float32)
    for _ in range(12):  # rectangular holes of several sizes
        hh, ww = rng.integers(4, h // 4), rng.integers(4, w // 4)
        r0, c0 = rng.integers(0, h - hh), rng.integers(0, w - ww)
        known[r0:r0 + hh, c0:c0 + ww] = 0
    sparse = (rng.random((h, w)) < 0.02).astype(np.float32)
    panels = []
    for weights in (known, sparse):
        colour, weight, pm = fill_inputs(px, "mask", weights)
        (filled,) = session.run(Fill(premultiplied=pm), [colour, weight])
        panels += [px * weights[..., None], fill_output(filled, px, "mask")]
    path = os.path.join(outdir, "fill_holes.png")
    _png(path, contact_sheet(panels), like)
    written.append(path)
    return written


DEMO_JOBS = 16  # about as many plans as the demo runs (auto estimates them as one batch)


def main(outdir: str, backend: str = "auto") -> None:
    """Write the demo's pictures into ``outdir`` on the executor ``backend`` chooses, saying which it was."""
    os.makedirs(outdir, exist_ok=True)
    start = time.perf_counter()
    notes: list[str] = []
    session = Session(backend, warn=notes.append)  # no GL is no problem here: said below, not warned about
    first = io.read_shape(os.path.join(SAMPLES, "highlights.exr"))
    session.decide(Blur(levels=4), [first] if first else [], count=DEMO_JOBS)
    print(f"demo: running on {session.name} ({session.why})", flush=True)
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
        written += _methods(session, outdir, zp.spec)
    print(f"demo: {len(written)} images in {outdir}/ ({session.name}, {time.perf_counter() - start:.1f} s):")
    for p in written:
        print(f"  {p}")
    print(f"what to look for: {os.path.join(SAMPLES, 'README.md')}")


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(prog="python -m pyramid_cli.demo", description=__doc__.splitlines()[0])
    parser.add_argument("outdir", nargs="?", default=os.path.join("samples", "out"))
    parser.add_argument("--backend", default="auto", choices=["auto", "gl", "cpu", "reference"])
    args = parser.parse_args(sys.argv[1:])
    main(args.outdir, args.backend)
