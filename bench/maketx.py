#!/usr/bin/env python3
"""``pyramid mipmap`` against the real ``maketx`` on the same texture: wall time and what each wrote.

    python bench/maketx.py [--size N] [--reps N] [--backend cpu|gl|auto] [--json OUT.json]

Both run as fresh processes on one synthetic 8-bit sRGB PNG (a tileable texture
plus noise) with ``--wrap periodic``, interleaved repetition by repetition (A, B,
then B, A, ...), and each one's median is reported. Timings are printed, never
asserted. Then both outputs are described: levels, pixel type, the metadata keys
the other lacks, and how far their 1×1 levels are from the source's average
(maketx filters the stored sRGB values, pyramid linear light, so the two 1×1
levels differ by design on anything but flat colour).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

BIN = Path(sys.executable).parent


def texture(size: int) -> np.ndarray:
    """A tileable 8-bit texture: integer-period sinusoids plus a little noise."""
    y, x = np.mgrid[0:size, 0:size] * (2 * np.pi / size)
    base = np.stack([0.5 + 0.3 * np.sin(4 * x), 0.5 + 0.3 * np.cos(3 * y + x), 0.5 + 0.2 * np.sin(x + 2 * y)], -1)
    noise = np.random.default_rng(0).normal(0, 0.05, base.shape)
    return (np.clip(base + noise, 0, 1) * 255 + 0.5).astype(np.uint8)


def write_png(path: Path, pixels: np.ndarray) -> None:
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], "uint8"))
    out.write_image(pixels)
    out.close()


def run(argv: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(argv, check=True, capture_output=True)
    return time.perf_counter() - start


def describe(path: Path) -> dict:
    inp = oiio.ImageInput.open(str(path))
    spec = inp.spec()
    levels = []
    while inp.seek_subimage(0, len(levels)):
        levels.append(f"{inp.spec().width}x{inp.spec().height}")
    last = np.asarray(inp.read_image(0, len(levels) - 1, 0, spec.nchannels, "float")).reshape(-1)
    inp.close()
    return {"type": str(spec.format), "levels": levels, "last": [float(v) for v in last],
            "keys": sorted(a.name for a in spec.extra_attribs),
            "average": spec.get_string_attribute("oiio:AverageColor")}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=2048)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--json", dest="json_out")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "albedo.png"
        write_png(src, texture(args.size))
        ours, theirs = Path(tmp) / "ours.tx", Path(tmp) / "theirs.tx"
        contenders = {
            "pyramid mipmap": [str(BIN / "pyramid"), "mipmap", "-q", "--backend", args.backend, "--wrap", "periodic",
                               str(src), str(ours)],
            "maketx": [str(BIN / "maketx"), str(src), "-o", str(theirs), "--wrap", "periodic"],
        }
        times: dict[str, list[float]] = {name: [] for name in contenders}
        names = list(contenders)
        for k in range(args.reps + 1):  # the first round warms caches and is dropped
            for name in names[k % 2:] + names[:k % 2]:
                t = run(contenders[name])
                if k:
                    times[name].append(t)
        report = {"size": args.size, "reps": args.reps, "backend": args.backend,
                  "median_s": {n: statistics.median(v) for n, v in times.items()},
                  "pyramid": describe(ours), "maketx": describe(theirs)}
    a, b = report["pyramid"], report["maketx"]
    report["keys_only_in_maketx"] = sorted(set(b["keys"]) - set(a["keys"]))
    report["keys_only_in_pyramid"] = sorted(set(a["keys"]) - set(b["keys"]))
    for name, median in report["median_s"].items():
        print(f"{name:16s} {median:8.3f} s  (median of {args.reps}, {args.size}²)")
    for name in ("pyramid", "maketx"):
        d = report[name]
        print(f"{name:16s} {d['type']}, levels {' '.join(d['levels'])}, 1×1 {d['last']}, average {d['average']}")
    print(f"keys only in maketx: {report['keys_only_in_maketx']}; only in pyramid: {report['keys_only_in_pyramid']}")
    if args.json_out:
        Path(args.json_out).write_text(json.dumps(report, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
