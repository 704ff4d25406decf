#!/usr/bin/env python3
"""``pyramid fill`` against ``oiiotool --fillholes`` on a 4K RGBA half EXR: time, smoothness, closeness.

    python bench/fill.py [--width 3840 --height 2160] [--reps 3] [--backend cpu|gl|auto] [--json OUT.json]

A true image (smooth shading, edges and fine texture, linear light) is cut two ways:
``holes50`` (blobs covering half the pixels) and ``sparse1`` (1 % of the pixels kept at
random); the cut pixels get alpha 0 and colour 0 (premultiplied), as a renderer or a baker
leaves them. Both tools run as fresh processes on the same half EXR, interleaved repetition
by repetition (A, B, then B, A, …), and each one's median wall time is reported (start-up,
read, fill and write included; ``pyramid`` first warms its kernel cache). Then, inside the
holes only: the RMS error to the true image (closeness) and the mean absolute 4-neighbour
Laplacian of the result (smoothness; the true image's own is printed beside it). The fills
alone are also timed warm in this process (``ImageBufAlgo.fillholes_pushpull``, what oiiotool
calls, against ``pyramid_cli.fill`` on the same float32 pixels, interleaved). Timings and
quality are printed and written as JSON, never asserted.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

BIN = Path(sys.executable).parent


def truth(h: int, w: int) -> np.ndarray:
    """RGB float32: a lit sphere on a gradient, soft waves, a few hard edges and fine texture."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    y, x = y / h, x / w
    r = np.hypot(x - 0.55, (y - 0.5) * h / w) / 0.22
    light = np.clip(1 - r ** 2, 0, 1) ** 0.5
    base = np.stack([0.2 + 0.5 * x, 0.3 + 0.3 * y, 0.5 - 0.3 * x * y], -1)
    waves = 0.1 * np.sin(9 * x + 5 * y)[..., None] * np.array([1, 0.5, 0.2], np.float32)
    sphere = (light[..., None] * np.array([0.9, 0.45, 0.2], np.float32)) * (r < 1)[..., None]
    edges = ((x > 0.1) & (x < 0.25) & (y > 0.6) & (y < 0.85))[..., None] * np.float32(0.3)
    grain = 0.02 * np.sin(400 * x * (1 + y))[..., None]
    return (base + waves + sphere + edges + grain).astype(np.float32)


def masks(h: int, w: int) -> dict[str, np.ndarray]:
    """Known-pixel masks: blobby holes over 50 % of the image, and 1 % random samples."""
    rng = np.random.default_rng(7)
    coarse = rng.random((h // 64 + 2, w // 64 + 2)).astype(np.float32)
    field = np.kron(coarse, np.ones((64, 64), np.float32))[:h, :w]
    for _ in range(3):  # smooth the blocks into blobs
        field = 0.25 * (np.roll(field, 16, 0) + np.roll(field, -16, 0) + np.roll(field, 16, 1) + np.roll(field, -16, 1))
    holes50 = field > np.median(field)
    sparse1 = rng.random((h, w)) < 0.01
    return {"holes50": ~holes50, "sparse1": sparse1}


def write_exr(path: Path, rgba: np.ndarray) -> None:
    spec = oiio.ImageSpec(rgba.shape[1], rgba.shape[0], 4, "half")
    spec.channelnames = ("R", "G", "B", "A")
    spec.alpha_channel = 3
    spec.attribute("compression", "zip")
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec), oiio.geterror()
    out.write_image(rgba.astype(np.float16))
    out.close()


def read(path: Path) -> np.ndarray:
    inp = oiio.ImageInput.open(str(path))
    px = np.asarray(inp.read_image(0, 0, 0, 4, "float"))
    inp.close()
    return px


def timed(argv: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(argv, check=True, capture_output=True)
    return time.perf_counter() - start


def laplacian(rgb: np.ndarray) -> np.ndarray:
    lap = -4 * rgb
    lap[1:] += rgb[:-1]
    lap[:-1] += rgb[1:]
    lap[:, 1:] += rgb[:, :-1]
    lap[:, :-1] += rgb[:, 1:]
    lap[0] += rgb[0]
    lap[-1] += rgb[-1]
    lap[:, 0] += rgb[:, 0]
    lap[:, -1] += rgb[:, -1]
    return np.abs(lap).mean(axis=-1)


def in_process(src: Path, reps: int, backend: str) -> dict[str, list[float]]:
    """The fills alone, warm, in this process: OpenImageIO's ImageBufAlgo.fillholes_pushpull (what oiiotool
    --fillholes calls) and pyramid_cli.fill on the same float32 pixels, interleaved."""
    import pyramid_cli as pyr
    from pyramid_cli.exec.session import Session

    buf = oiio.ImageBuf(str(src))
    buf.read(force=True, convert=oiio.FLOAT)
    px = buf.get_pixels(oiio.FLOAT)
    times: dict[str, list[float]] = {"pyramid": [], "oiiotool": []}
    with Session(backend) as session:
        pyr.fill(px, session=session)  # warm: kernels loaded, memory touched
        for k in range(reps):
            order = ["pyramid", "oiiotool"] if k % 2 == 0 else ["oiiotool", "pyramid"]
            for who in order:
                start = time.perf_counter()
                if who == "pyramid":
                    pyr.fill(px, session=session)
                else:
                    out = oiio.ImageBufAlgo.fillholes_pushpull(buf)
                    assert not out.has_error, out.geterror()
                times[who].append(time.perf_counter() - start)
    return times


def quality(out: np.ndarray, true: np.ndarray, holes: np.ndarray) -> dict:
    rgb = out[..., :3]
    err = rgb[holes] - true[holes]
    return {"rms_in_holes": float(np.sqrt(np.mean(err ** 2))), "max_abs_in_holes": float(np.abs(err).max()),
            "mean_abs_laplacian_in_holes": float(laplacian(rgb)[holes].mean()),
            "alpha_min": float(out[..., 3].min()), "finite": bool(np.all(np.isfinite(out)))}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=3840)
    ap.add_argument("--height", type=int, default=2160)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--backend", default="cpu")
    ap.add_argument("--json", default=str(Path(__file__).parent / "results" / "fill-latest.json"))
    args = ap.parse_args(argv)
    h, w = args.height, args.width
    true = truth(h, w)
    report = {"machine": platform.processor() or platform.machine(), "size": [w, h], "reps": args.reps,
              "backend": args.backend, "oiio": oiio.__version__, "cases": {}}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name, known in masks(h, w).items():
            src = tmp / f"{name}.exr"
            rgba = np.concatenate([true * known[..., None], known[..., None].astype(np.float32)], -1)
            write_exr(src, rgba)
            true_half = true.astype(np.float16).astype(np.float32)  # what the file can hold
            ours, theirs = tmp / f"{name}_pyramid.exr", tmp / f"{name}_oiio.exr"
            cmd_ours = [str(BIN / "pyramid"), "fill", str(src), str(ours), "-q", "--backend", args.backend,
                        "--compression", "zip"]
            cmd_theirs = [str(BIN / "oiiotool"), str(src), "--fillholes", "--compression", "zip", "-o", str(theirs)]
            timed(cmd_ours)  # warm the kernel cache (a machine's first run compiles once)
            times = {"pyramid": [], "oiiotool": []}
            for k in range(args.reps):
                order = [("pyramid", cmd_ours), ("oiiotool", cmd_theirs)]
                for who, cmd in order if k % 2 == 0 else order[::-1]:
                    times[who].append(timed(cmd))
            holes = ~known
            warm = in_process(src, args.reps, args.backend)
            case = {"known_fraction": float(known.mean()),
                    "in_process_seconds": {k: statistics.median(v) for k, v in warm.items()}, "in_process_runs": warm,
                    "seconds": {k: statistics.median(v) for k, v in times.items()}, "runs": times,
                    "pyramid": quality(read(ours), true_half, holes),
                    "oiiotool": quality(read(theirs), true_half, holes),
                    "truth_mean_abs_laplacian_in_holes": float(laplacian(true_half)[holes].mean())}
            case["ratio"] = case["seconds"]["pyramid"] / case["seconds"]["oiiotool"]
            case["in_process_ratio"] = case["in_process_seconds"]["pyramid"] / case["in_process_seconds"]["oiiotool"]
            report["cases"][name] = case
            q_o, q_t = case["pyramid"], case["oiiotool"]
            print(f"{name}: known {case['known_fraction']:.1%}; time pyramid {case['seconds']['pyramid']:.2f} s, "
                  f"oiiotool {case['seconds']['oiiotool']:.2f} s (ratio {case['ratio']:.2f}); warm in process "
                  f"{case['in_process_seconds']['pyramid']:.3f} s vs {case['in_process_seconds']['oiiotool']:.3f} s "
                  f"(ratio {case['in_process_ratio']:.2f}); RMS in holes "
                  f"{q_o['rms_in_holes']:.4f} vs {q_t['rms_in_holes']:.4f}; |Laplacian| in holes "
                  f"{q_o['mean_abs_laplacian_in_holes']:.5f} vs {q_t['mean_abs_laplacian_in_holes']:.5f} "
                  f"(truth {case['truth_mean_abs_laplacian_in_holes']:.5f})")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(report, indent=1))
    print(f"wrote {args.json}")
    return report


if __name__ == "__main__":
    main()
