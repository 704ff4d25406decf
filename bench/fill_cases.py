"""The fill's test set against ``oiiotool --fillholes``: three kinds of image × three kinds of hole.

Images (RGB, linear, in [0, 1]): ``ramp`` (a linear ramp per channel), ``waves`` (periodic sinusoids of 3 to
4 periods across the image) and ``texture`` (1/f noise, random phases). Holes: ``random40+big`` (40 % of the
pixels at random and a disc of radius 0.2·n), ``big`` (one disc of radius 0.3·n) and ``sparse10`` (10 % of the
pixels kept at random). Each case has :data:`INSTANCES` hole patterns (seeded); its error is the mean absolute
error inside the holes summed over them, and a case's ratio is ours over oiiotool's. Used by
``tests/system/test_fill_oiiotool.py`` (64×64) and ``bench/fill.py`` (any size); deterministic for a size.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

IMAGES = ("ramp", "waves", "texture")
HOLES = ("random40+big", "big", "sparse10")
CASES = tuple((image, holes) for image in IMAGES for holes in HOLES)
INSTANCES = 3
OIIOTOOL = str(Path(sys.executable).parent / "oiiotool")


def images(n: int) -> dict[str, np.ndarray]:
    """The three n×n RGB float64 images."""
    y, x = (np.mgrid[0:n, 0:n] + 0.5) / n
    ramp = np.stack([0.1 + 0.8 * x, 0.2 + 0.5 * y + 0.2 * x, 0.9 - 0.4 * x - 0.3 * y], -1)
    waves = np.stack([0.5 + 0.3 * np.sin(2 * np.pi * 3 * x) * np.cos(2 * np.pi * 2 * y),
                      0.5 + 0.35 * np.sin(2 * np.pi * (2 * x + 3 * y)),
                      0.5 + 0.3 * np.cos(2 * np.pi * 4 * y)], -1)
    rng = np.random.default_rng(1)
    fy, fx = np.fft.fftfreq(n)[:, None], np.fft.fftfreq(n)[None, :]
    f = np.hypot(fy, fx)
    f[0, 0] = 1
    channels = []
    for _ in range(3):
        spectrum = (rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n))) / f
        spectrum[0, 0] = 0
        t = np.real(np.fft.ifft2(spectrum))
        channels.append((t - t.mean()) / (4 * t.std()) + 0.5)
    return {"ramp": ramp, "waves": waves, "texture": np.stack(channels, -1)}


def known_masks(n: int, seed: int) -> dict[str, np.ndarray]:
    """The three kinds of hole for instance ``seed``: boolean n×n, True where a pixel is known."""
    rng = np.random.default_rng(100 + seed)
    y, x = np.mgrid[0:n, 0:n] + 0.5
    cy, cx = rng.uniform(0.35, 0.65, 2) * n
    disc = np.hypot(y - cy, x - cx) < 0.2 * n
    rand = (rng.random((n, n)) >= 0.4) & ~disc
    cy, cx = rng.uniform(0.4, 0.6, 2) * n
    big = ~(np.hypot(y - cy, x - cx) < 0.3 * n)
    sparse = rng.random((n, n)) < 0.1
    return {"random40+big": rand, "big": big, "sparse10": sparse}


def rgba(image: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Premultiplied RGBA float32: the known pixels with alpha 1, the holes 0 (colour and alpha)."""
    return np.concatenate([image * known[..., None], known[..., None]], -1).astype(np.float32)


def hole_error(filled: np.ndarray, image: np.ndarray, known: np.ndarray) -> float:
    """Mean absolute error over the hole pixels and the RGB channels."""
    return float(np.abs(filled[..., :3][~known] - image[~known]).mean())


def inputs(n: int) -> list[tuple[str, str, int, np.ndarray, np.ndarray]]:
    """(image, holes, instance, truth, known) for every case and instance."""
    ims = images(n)
    out = []
    for seed in range(INSTANCES):
        masks = known_masks(n, seed)
        out += [(image, holes, seed, ims[image], masks[holes]) for image, holes in CASES]
    return out


def oiiotool_fill(sources: list[Path], targets: list[Path]) -> None:
    """``oiiotool SRC --fillholes -o DST`` for every pair, in one process."""
    argv = [OIIOTOOL]
    for src, dst in zip(sources, targets, strict=True):
        argv += [str(src), "--fillholes", "-d", "float", "-o", str(dst)]
    subprocess.run(argv, check=True, capture_output=True)


def ratios(ours: dict, theirs: dict) -> dict[tuple[str, str], float]:
    """Each case's error ratio (ours / oiiotool's), the errors summed over the instances."""
    return {case: sum(ours[case + (s,)] for s in range(INSTANCES)) / sum(theirs[case + (s,)] for s in range(INSTANCES))
            for case in CASES}


def geometric_mean(values) -> float:
    v = np.asarray(list(values), dtype=np.float64)
    return float(np.exp(np.log(v).mean()))
