#!/usr/bin/env python3
"""``pyramid mipmap`` against the real ``maketx`` on the same texture: wall time and what each wrote.

    python bench/maketx.py [--size N] [--source png|exr] [--reps N] [--backend cpu|gl|auto] [--json OUT.json]

Both run as fresh processes on one synthetic texture (a tileable pattern plus
noise): an 8-bit sRGB PNG made into a ``.tx``, or a half EXR (zip) made into a
tiled ``.exr``, with ``--wrap periodic`` and zip compression for both,
interleaved repetition by repetition (A, B, then B, A, ...), and each one's median
is reported. Timings are printed, never
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


def write_source(path: Path, pixels: np.ndarray) -> None:
    """The texture as an 8-bit PNG, or as a zip-compressed half EXR (its codes read as linear values)."""
    exr = path.suffix == ".exr"
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], "half" if exr else "uint8")
    if exr:
        spec.attribute("compression", "zip")
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), spec)
    out.write_image((pixels / 255.0).astype(np.float16) if exr else pixels)
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
    ap.add_argument("--source", choices=["png", "exr"], default="png")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--json", dest="json_out")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / f"albedo.{args.source}"
        write_source(src, texture(args.size))
        ext = "tx" if args.source == "png" else "exr"
        ours, theirs = Path(tmp) / f"ours.{ext}", Path(tmp) / f"theirs.{ext}"
        contenders = {
            "pyramid mipmap": [str(BIN / "pyramid"), "mipmap", "-q", "--backend", args.backend, "--wrap", "periodic",
                               "--compression", "zip", str(src), str(ours)],
            "maketx": [str(BIN / "maketx"), str(src), "-o", str(theirs), "--wrap", "periodic", "--compression", "zip"],
        }
        times: dict[str, list[float]] = {name: [] for name in contenders}
        names = list(contenders)
        for k in range(args.reps + 1):  # the first round warms caches and is dropped
            for name in names[k % 2:] + names[:k % 2]:
                t = run(contenders[name])
                if k:
                    times[name].append(t)
        report = {"size": args.size, "source": args.source, "reps": args.reps, "backend": args.backend,
                  "median_s": {n: statistics.median(v) for n, v in times.items()},
                  "pyramid": describe(ours), "maketx": describe(theirs)}
    a, b = report["pyramid"], report["maketx"]
    report["keys_only_in_maketx"] = sorted(set(b["keys"]) - set(a["keys"]))
    report["keys_only_in_pyramid"] = sorted(set(a["keys"]) - set(b["keys"]))
    for name, median in report["median_s"].items():
        print(f"{name:16s} {median:8.3f} s  (median of {args.reps}, {args.size}² {args.source})")
    for name in ("pyramid", "maketx"):
        d = report[name]
        print(f"{name:16s} {d['type']}, levels {' '.join(d['levels'])}, 1×1 {d['last']}, average {d['average']}")
    print(f"keys only in maketx: {report['keys_only_in_maketx']}; only in pyramid: {report['keys_only_in_pyramid']}")
    if args.json_out:
        Path(args.json_out).write_text(json.dumps(report, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
