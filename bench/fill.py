#!/usr/bin/env python3
"""``pyramid fill`` against ``oiiotool --fillholes``: the error on the test set, and time on a 4K RGBA half EXR.

    python bench/fill.py [--cases-size 64 256] [--width 3840 --height 2160] [--reps 3] [--backend cpu|gl|auto]
                         [--no-timing] [--json OUT.json]

**Cases** (``bench/fill_cases.py``, the set the test suite holds the defaults to at 64×64): ramps, waves and
1/f textures × random 40 % holes with a big one, one big hole, 10 % samples, three hole patterns each, at
every ``--cases-size``. Each case's mean absolute error in the holes (summed over its patterns) for
``pyramid fill``'s defaults and for the classic pull-push (``--analysis box4 --weight-scale 4 --sweeps 0``,
the former defaults), each over oiiotool's, and their geometric means. oiiotool runs once on every file.

**Timing**:
a true image (smooth shading, edges and fine texture, linear light) is cut two ways:
``holes50`` (blobs covering half the pixels) and ``sparse1`` (1 % of the pixels kept at
random); the cut pixels get alpha 0 and colour 0 (premultiplied), as a renderer or a baker
leaves them. The tools (``pyramid`` with its defaults, ``classic`` = ``pyramid fill`` with the former
defaults, ``oiiotool``) run as fresh processes on the same half EXR, interleaved repetition by repetition
(the order rotated each time), and each one's median wall time is reported (start-up, read, fill and write
included; ``pyramid`` first warms its kernel cache). Then, inside the
holes only: the RMS error to the true image (closeness) and the mean absolute 4-neighbour
Laplacian of the result (smoothness; the true image's own is printed beside it). The fills
alone are also timed warm in this process (``ImageBufAlgo.fillholes_pushpull``, what oiiotool
calls, against ``pyramid_cli.fill`` with both option sets on the same float32 pixels, interleaved).
Timings and quality are printed and written as JSON, never asserted.
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

sys.path.insert(0, str(Path(__file__).parent))
import fill_cases  # noqa: E402  (beside this script)

BIN = Path(sys.executable).parent
CLASSIC = {"analysis": "box4", "weight_scale": 4, "sweeps": 0}  # the former defaults: Gortler's pull-push
CLASSIC_ARGS = ["--analysis", "box4", "--weight-scale", "4", "--sweeps", "0"]


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
    times: dict[str, list[float]] = {"pyramid": [], "classic": [], "oiiotool": []}
    with Session(backend) as session:
        pyr.fill(px, session=session)  # warm: kernels loaded, memory touched
        pyr.fill(px, session=session, **CLASSIC)
        for k in range(reps):
            order = list(times)
            for who in order[k % 3:] + order[:k % 3]:
                start = time.perf_counter()
                if who == "pyramid":
                    pyr.fill(px, session=session)
                elif who == "classic":
                    pyr.fill(px, session=session, **CLASSIC)
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


def cases_report(n: int, backend: str) -> dict:
    """The test set at n×n: each case's hole error for oiiotool, the defaults and the classic options, the ratios
    (ours over oiiotool's) and their geometric means."""
    import pyramid_cli as pyr

    runs = fill_cases.inputs(n)
    errors: dict[str, dict] = {"oiiotool": {}, "default": {}, "classic": {}}
    with tempfile.TemporaryDirectory() as tmp:
        sources = [Path(tmp) / f"in{i}.exr" for i in range(len(runs))]
        targets = [Path(tmp) / f"oiio{i}.exr" for i in range(len(runs))]
        for src, (_, _, _, image, known) in zip(sources, runs, strict=True):
            spec = oiio.ImageSpec(n, n, 4, "float")
            spec.channelnames = ("R", "G", "B", "A")
            spec.alpha_channel = 3
            out = oiio.ImageOutput.create(str(src))
            assert out.open(str(src), spec), oiio.geterror()
            out.write_image(fill_cases.rgba(image, known))
            out.close()
        fill_cases.oiiotool_fill(sources, targets)
        for dst, (image, holes, seed, truth_px, known) in zip(targets, runs, strict=True):
            key = (image, holes, seed)
            errors["oiiotool"][key] = fill_cases.hole_error(read(dst), truth_px, known)
            src = fill_cases.rgba(truth_px, known)
            errors["default"][key] = fill_cases.hole_error(pyr.fill(src, backend=backend), truth_px, known)
            errors["classic"][key] = fill_cases.hole_error(pyr.fill(src, backend=backend, **CLASSIC), truth_px, known)
    report: dict = {"size": n, "instances": fill_cases.INSTANCES, "cases": {}}
    ratios = {name: fill_cases.ratios(errors[name], errors["oiiotool"]) for name in ("default", "classic")}
    print(f"cases at {n}×{n} (mean |error| in the holes, {fill_cases.INSTANCES} patterns each; "
          "ratio = over oiiotool's)")
    print(f"  {'image':8s} {'holes':13s} {'oiiotool':>9s} {'default':>9s} {'ratio':>6s} {'classic':>9s} {'ratio':>6s}")
    for case in fill_cases.CASES:
        e = {name: sum(errors[name][case + (s,)] for s in range(fill_cases.INSTANCES)) / fill_cases.INSTANCES
             for name in errors}
        report["cases"]["/".join(case)] = {**e, "ratio_default": ratios["default"][case],
                                           "ratio_classic": ratios["classic"][case]}
        print(f"  {case[0]:8s} {case[1]:13s} {e['oiiotool']:9.5f} {e['default']:9.5f} "
              f"{ratios['default'][case]:6.3f} {e['classic']:9.5f} {ratios['classic'][case]:6.3f}")
    for name in ("default", "classic"):
        report[f"geomean_{name}"] = fill_cases.geometric_mean(ratios[name].values())
        report[f"worst_{name}"] = max(ratios[name].values())
    print(f"  geometric mean of the ratios: default {report['geomean_default']:.3f} (worst "
          f"{report['worst_default']:.3f}), classic {report['geomean_classic']:.3f} "
          f"(worst {report['worst_classic']:.3f})")
    return report


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases-size", type=int, nargs="*", default=[64, 256])
    ap.add_argument("--width", type=int, default=3840)
    ap.add_argument("--height", type=int, default=2160)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--backend", default="cpu")
    ap.add_argument("--no-timing", action="store_true", help="only the cases")
    ap.add_argument("--json", default=str(Path(__file__).parent / "results" / "fill-latest.json"))
    args = ap.parse_args(argv)
    h, w = args.height, args.width
    report = {"machine": platform.processor() or platform.machine(), "size": [w, h], "reps": args.reps,
              "backend": args.backend, "oiio": oiio.__version__, "test_set": [], "cases": {}}
    for n in args.cases_size:
        report["test_set"].append(cases_report(n, args.backend))
    if not args.no_timing:
        timing(report, true=truth(h, w), args=args)
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(report, indent=1))
    print(f"wrote {args.json}")
    return report


def timing(report: dict, true: np.ndarray, args) -> None:
    """The 4K fresh-process and warm timings and the quality on the 4K image, into ``report["cases"]``."""
    h, w = true.shape[:2]
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
            cmd_classic = cmd_ours[:3] + [str(tmp / f"{name}_classic.exr")] + cmd_ours[4:] + CLASSIC_ARGS
            timed(cmd_ours)  # warm the kernel cache (a machine's first run compiles once)
            timed(cmd_classic)
            times = {"pyramid": [], "classic": [], "oiiotool": []}
            order = [("pyramid", cmd_ours), ("classic", cmd_classic), ("oiiotool", cmd_theirs)]
            for k in range(args.reps):
                for who, cmd in order[k % 3:] + order[:k % 3]:
                    times[who].append(timed(cmd))
            holes = ~known
            warm = in_process(src, args.reps, args.backend)
            case = {"known_fraction": float(known.mean()),
                    "in_process_seconds": {k: statistics.median(v) for k, v in warm.items()}, "in_process_runs": warm,
                    "seconds": {k: statistics.median(v) for k, v in times.items()}, "runs": times,
                    "pyramid": quality(read(ours), true_half, holes),
                    "classic": quality(read(tmp / f"{name}_classic.exr"), true_half, holes),
                    "oiiotool": quality(read(theirs), true_half, holes),
                    "truth_mean_abs_laplacian_in_holes": float(laplacian(true_half)[holes].mean())}
            case["ratio"] = case["seconds"]["pyramid"] / case["seconds"]["oiiotool"]
            case["in_process_ratio"] = case["in_process_seconds"]["pyramid"] / case["in_process_seconds"]["oiiotool"]
            report["cases"][name] = case
            q_o, q_c, q_t = case["pyramid"], case["classic"], case["oiiotool"]
            sec, warm_s = case["seconds"], case["in_process_seconds"]
            print(f"{name}: known {case['known_fraction']:.1%}; fresh process pyramid {sec['pyramid']:.2f} s, "
                  f"classic {sec['classic']:.2f} s, oiiotool {sec['oiiotool']:.2f} s; warm in process "
                  f"{warm_s['pyramid']:.3f} s, "
                  f"{warm_s['classic']:.3f} s, {warm_s['oiiotool']:.3f} s; RMS in holes {q_o['rms_in_holes']:.4f}, "
                  f"{q_c['rms_in_holes']:.4f}, {q_t['rms_in_holes']:.4f}; |Laplacian| in holes "
                  f"{q_o['mean_abs_laplacian_in_holes']:.5f}, {q_c['mean_abs_laplacian_in_holes']:.5f}, "
                  f"{q_t['mean_abs_laplacian_in_holes']:.5f} (truth {case['truth_mean_abs_laplacian_in_holes']:.5f})")


if __name__ == "__main__":
    main()
