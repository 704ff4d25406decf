"""Make the shipped sample images (the project generates them; no third-party licence involved).

    python samples/generate.py            # rewrites samples/zoneplate.png and samples/highlights.exr
"""

from __future__ import annotations

import os

import numpy as np
import OpenImageIO as oiio

HERE = os.path.dirname(os.path.abspath(__file__))


def zone_plate(n: int = 512) -> np.ndarray:
    """cos(k·r²): spatial frequency grows linearly from the centre to Nyquist at the edge."""
    y, x = np.mgrid[0:n, 0:n].astype(np.float64)
    r2 = (x - n / 2 + 0.5) ** 2 + (y - n / 2 + 0.5) ** 2
    v = 0.5 + 0.5 * np.cos(np.pi * r2 / n)
    return np.repeat(v[..., None], 3, axis=2)


def highlights(w: int = 640, h: int = 400) -> np.ndarray:
    """A dim linear-light gradient with small very bright lights (values up to ~200), as a renderer makes."""
    rng = np.random.default_rng(2007)
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    img = np.stack([0.05 + 0.10 * x / w, 0.04 + 0.06 * y / h, 0.08 + 0.02 * (x + y) / (w + h)], axis=2)
    for _ in range(40):
        cx, cy = rng.uniform(0, w), rng.uniform(0, h)
        rad = rng.uniform(0.6, 3.0)
        power = rng.uniform(5, 200)
        colour = rng.uniform(0.3, 1.0, 3)
        img += power * colour * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * rad ** 2))[..., None]
    # a thin bright window frame: hard edges that expose box-filter blockiness
    img[100:104, 60:300] += 20.0
    img[100:300, 60:63] += 20.0
    return img


def write(path: str, pixels: np.ndarray, pixel_type: str, **attrs) -> None:
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], pixel_type)
    for k, v in attrs.items():
        spec.attribute(k, v)
    out = oiio.ImageOutput.create(path)
    if out is None or not out.open(path, spec):
        raise SystemExit(f"cannot write {path}: {oiio.geterror()}")
    out.write_image(pixels.astype(np.float32) if pixel_type != "uint8" else pixels)
    out.close()


def main() -> None:
    zp = zone_plate()
    srgb = np.where(zp <= 0.0031308, 12.92 * zp, 1.055 * zp ** (1 / 2.4) - 0.055)
    write(os.path.join(HERE, "zoneplate.png"), np.round(srgb * 255).astype(np.uint8), "uint8")
    write(os.path.join(HERE, "highlights.exr"), highlights(), "half", compression="zip")


if __name__ == "__main__":
    main()
