#!/usr/bin/env python3
"""Benchmark suite of ``pyramid``: ratios against peers measured in the same run.

    python bench/run.py [--quick] [--json OUT.json] [--only SCENARIO[,SCENARIO]] [--reps N] [--no-profile]
                        [--torch-device DEVICE]

Scenarios (see bench/README.md): ``filter`` (warm filtering, in process), ``e2e``
(``pyramid blur`` in a fresh process vs bare OpenImageIO and an OpenCV script),
``batch`` (many small images: one process vs one call each), ``startup``
(``pyramid --help``, ``pyramid explain``), ``gpu`` (the blur on a GPU through EGL vs a
PyTorch conv2d peer and a device-to-device copy; in the default list only when torch sees
a CUDA device).

Every comparison is interleaved: repetition k runs A, B, C…, rotated by k, and
each contender's median is reported, so the ratios survive a noisy machine.
Targets are reported as met / missed, never asserted. A missing peer library
(OpenCV, scikit-image) is reported and skipped, not a crash.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as _dt
import gc
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCRIPTS = Path(__file__).resolve().parent / "scripts"  # helper programs run in fresh interpreters
if str(ROOT) not in sys.path:  # run from a checkout even without the editable install
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

SCENARIOS = ["filter", "e2e", "batch", "startup", "gpu", "cpu", "cluster"]  # cluster: bench/cluster.py, on demand
CPU_SCENARIOS = ["filter", "e2e", "batch", "startup", "cpu"]  # the default list, plus "gpu" where CUDA is present
SIGMA7 = math.sqrt(6) / 2  # binomial 7-tap [1 6 15 20 15 6 1]/64 has variance 6/4
perf = time.perf_counter


# ====================================================================== helpers
def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def wait_for_kernel_builds(timeout: float = 600.0) -> float:
    """Wait while ``pyramid``'s ahead-of-time kernel builders run (their live locks in the cache folder), so that none
    competes with a timed run after a warm-up that loaded new kernels through numba; the seconds waited."""
    from pyramid_cli.exec.cpu import aot
    from pyramid_cli.exec.cpu.compile import cache_dir

    where, t0 = aot.folder(cache_dir()), time.perf_counter()
    time.sleep(0.2)  # a builder just spawned takes its locks before the warm-up's process exits
    while where is not None and aot.building(where) and time.perf_counter() - t0 < timeout:
        time.sleep(0.5)
    return time.perf_counter() - t0


def peers() -> tuple[dict, list[str]]:
    """Importable peer libraries, and a line for each one that is missing."""
    found, missing = {}, []
    os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
    try:
        import cv2

        found["cv2"] = cv2
    except ImportError as e:
        missing.append(f"OpenCV is not installed ({e}); its comparisons are skipped "
                       "(pip install opencv-python-headless, or pip install -e '.[bench]')")
    try:
        import skimage.filters
        import skimage.transform

        found["skimage"] = skimage
    except ImportError as e:
        missing.append(f"scikit-image is not installed ({e}); its comparisons are skipped "
                       "(pip install scikit-image, or pip install -e '.[bench]')")
    return found, missing


def interleaved(fns: dict, reps: int, warmup: int = 1) -> dict:
    """Run every callable ``reps`` times, alternating between them; per name: median seconds and runs.

    A callable may return a dict of named sub-timings (seconds); their medians are kept too.
    """
    names = list(fns)
    for _ in range(warmup):
        for n in names:
            fns[n]()
    runs: dict[str, list[float]] = {n: [] for n in names}
    parts: dict[str, dict[str, list[float]]] = {n: {} for n in names}
    for k in range(reps):
        order = names[k % len(names):] + names[:k % len(names)]
        for n in order:
            gc.collect()
            t0 = perf()
            extra = fns[n]()
            runs[n].append(perf() - t0)
            if isinstance(extra, dict):
                for key, v in extra.items():
                    parts[n].setdefault(key, []).append(v)
    out = {}
    for n in names:
        out[n] = {"median_s": statistics.median(runs[n]), "min_s": min(runs[n]), "runs_s": runs[n]}
        if parts[n]:
            out[n]["parts_median_s"] = {k: _median_parts(v) for k, v in parts[n].items()}
    return out


def _median_parts(values):
    if values and isinstance(values[0], list):  # per-pass lists: median per position
        return [statistics.median(col) for col in zip(*values, strict=False)]
    return statistics.median(values)


def cmd_time(argv: list[str], env=None) -> float:
    """Wall time of one subprocess; raises with its stderr when it fails."""
    t0 = perf()
    p = subprocess.run(argv, capture_output=True, text=True, env=env)
    dt = perf() - t0
    if p.returncode != 0:
        shown = " ".join(a if len(a) < 80 else "<script>" for a in argv[:4])
        raise RuntimeError(f"{shown} … exited {p.returncode}: {p.stderr.strip()[-600:]}")
    return dt


def cmd_time_cpu_peak_rss(argv: list[str], env=None) -> tuple[float, float, float]:
    """Wall time (s), peak resident memory (MiB) and CPU time (s, user and system) of one command, measured by
    ``bench/scripts/peak_rss.py``.

    A child forked from this (large) process would inherit its high-water mark across exec, so
    a small launcher forks the command from its own fresh address space and reports its rusage;
    the time runs from that fork to the command's exit (the launcher's own start is not in it).
    """
    p = subprocess.run([sys.executable, "-S", str(SCRIPTS / "peak_rss.py"), *argv], capture_output=True, text=True,
                       env=env)
    if p.returncode:
        raise RuntimeError(f"{' '.join(argv[:4])} … exited {p.returncode}: {p.stderr.strip()[-600:]}")
    cpu, seconds, mib = p.stdout.split()[-3:]
    return float(seconds), float(mib), float(cpu)


def cmd_time_peak_rss(argv: list[str], env=None) -> tuple[float, float]:
    """Wall time (s) and peak resident memory (MiB) of one command (:func:`cmd_time_cpu_peak_rss`)."""
    return cmd_time_cpu_peak_rss(argv, env)[:2]


def cmd_peak_rss(argv: list[str]) -> float:
    """Peak resident memory (MiB) of one command (:func:`cmd_time_peak_rss`)."""
    return cmd_time_peak_rss(argv)[1]


def pyramid_cmd() -> list[str]:
    exe = Path(sys.executable).parent / "pyramid"
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "pyramid_cli.cli"]


def fmt_s(s: float | None) -> str:
    if s is None:
        return "—"
    return f"{s * 1e3:8.1f} ms" if s < 10 else f"{s:8.2f} s "


def fmt_x(r: float | None) -> str:
    return "—" if r is None else f"{r:.2f}×"


# ====================================================================== machine
def machine_info() -> dict:
    info = {"cpu": "unknown", "cores_logical": os.cpu_count(), "python": platform.python_version(),
            "platform": platform.platform()}
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                info["cpu"] = line.split(":", 1)[1].strip()
                break
    with contextlib.suppress(AttributeError):
        info["cores_usable"] = len(os.sched_getaffinity(0))
    with contextlib.suppress(OSError, ValueError, IndexError):
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                info["memory_gib"] = round(int(line.split()[1]) / 2**20, 1)
    versions = {"numpy": np.__version__}
    for mod, attr in [("moderngl", "__version__"), ("OpenImageIO", "__version__"), ("cv2", "__version__"),
                      ("skimage", "__version__"), ("pyramid_cli", "__version__")]:
        try:
            versions[mod] = getattr(__import__(mod), attr)
        except Exception:  # noqa: BLE001 - missing peers are reported elsewhere
            versions[mod] = None
    info["versions"] = versions
    try:
        from pyramid_cli.exec.gl import GLExecutor

        with GLExecutor() as ex:
            gl_info = ex.info()
        info["gl_renderer"] = gl_info.get("renderer")
        info["gl_version"] = gl_info.get("version")
    except Exception as e:  # noqa: BLE001 - say why, do not crash
        info["gl_renderer"] = None
        info["gl_error"] = " ".join(str(e).split())[:300]
    with contextlib.suppress(Exception):
        import cv2

        info["opencv_threads"] = cv2.getNumThreads()
    info["LP_NUM_THREADS"] = os.environ.get("LP_NUM_THREADS")
    with contextlib.suppress(Exception):
        info["git_commit"] = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                                            capture_output=True, text=True).stdout.strip()
    return info


def machine_line(m: dict) -> str:
    return (f"{m.get('cpu')}, {m.get('cores_usable', m.get('cores_logical'))} cores, "
            f"{m.get('memory_gib', '?')} GiB; GL: {m.get('gl_renderer') or 'unavailable'}")


# ====================================================================== scenario 1: filtering
def gradient_noise(rows: int, cols: int, channels: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y = np.linspace(0, 1, rows, dtype=np.float32)[:, None, None]
    x = np.linspace(0, 1, cols, dtype=np.float32)[None, :, None]
    c = np.arange(channels, dtype=np.float32)[None, None, :]
    img = 0.5 * x + 0.3 * y + 0.05 * c + 0.1 * rng.standard_normal((rows, cols, channels), dtype=np.float32)
    if channels == 4:
        img[..., 3] = 1.0
    return np.ascontiguousarray(img if channels > 1 else img[..., 0])


def plan_bytes(plan) -> int:
    """Bytes the plan must move: per pass, its target's stored extent written plus each source read, RGBA32F."""
    total = 0
    for ps in plan.passes:
        h, w = plan.images[ps.target].stored
        total += h * w * 16
        for s in ps.sources():
            h, w = plan.images[s].stored
            total += h * w * 16
    return total


class GLSplit:
    """One executor run split into upload / passes / read-back, through ``GLExecutor.profile``.

    With ``per_pass`` every pass is followed by ``ctx.finish()`` and timed alone; without, the
    passes run back to back as the executor issues them, between two finishes (on a GPU a finish
    after every pass costs about as much as a pass at 4K), and ``passes`` is then one span per
    channel group.
    """

    def __init__(self, executor, per_pass: bool = True):
        self.ex = executor
        self.per_pass = per_pass
        self.available = hasattr(executor, "profile")
        self.why = "" if self.available else "this executor has no profile() hook; no split"

    def __call__(self, plan, img) -> dict:
        t = self.ex.profile(plan, [img], img.dtype if img.dtype in (np.float16, np.float32) else np.float32,
                            per_pass=self.per_pass)
        return {"upload": t["upload"], "device": t["device"], "readback_host": t["total"] - t["upload"] - t["device"],
                "passes": t["passes"] if self.per_pass else []}


def _ski_kw(x) -> dict:
    return {"channel_axis": -1 if x.ndim == 3 else None}


def peer_blurs(cv2, sizes5):
    """The peers' 5-level blur and pyramid: OpenCV pyrDown⁵/pyrUp⁵ (with ``dstsize``, so odd sizes match),
    pyrDown to 1×1, and scikit-image pyramid_reduce⁵/pyramid_expand⁵ cropped to each level's size."""

    def cv_blur(x):
        for _ in range(5):
            x = cv2.pyrDown(x)
        for k in range(5, 0, -1):
            h, w = sizes5[k - 1]
            x = cv2.pyrUp(x, dstsize=(w, h))
        return x

    def cv_pyramid(x):
        out = [x]
        while out[-1].shape[0] > 1 or out[-1].shape[1] > 1:
            out.append(cv2.pyrDown(out[-1]))
        return out

    def ski_blur(x):
        from skimage.transform import pyramid_expand, pyramid_reduce

        for _ in range(5):
            x = pyramid_reduce(x, 2, **_ski_kw(x))
        for k in range(5, 0, -1):
            x = pyramid_expand(x, 2, **_ski_kw(x))[:sizes5[k - 1][0], :sizes5[k - 1][1]]
        return x

    return cv_blur, cv_pyramid, ski_blur


def _filter_contenders(session, split, plan, img, peer_fns, copy_in, copy_plan) -> dict:
    fns = {"GL upload+run+readback": lambda: session.run_plan(plan, [img])}
    if split.available:
        fns["GL split"] = lambda: split(plan, img)
    for pname, fn in peer_fns.items():
        if fn:
            fns[pname] = lambda fn=fn: fn(img)
    fns["memcpy input"] = lambda: np.copyto(copy_in[1], copy_in[0])
    fns["memcpy plan bytes"] = lambda: np.copyto(copy_plan[1], copy_plan[0])
    return fns


def scenario_filter(args, libs: dict, report: dict) -> None:
    from pyramid_cli.core.geometry import level_sizes
    from pyramid_cli.core.parse import parse
    from pyramid_cli.exec.session import Session
    from pyramid_cli.plan import plan as make_plan
    from pyramid_cli.workflows.pyramids import blur_plan

    rows, cols = (270, 480) if args.quick else (2160, 3840)
    reps = args.reps or (2 if args.quick else 5)
    cv2, ski = libs.get("cv2"), libs.get("skimage")
    sc = report["scenarios"]["filter"] = {"size": [rows, cols], "reps": reps, "cases": [], "notes": []}
    notes = sc["notes"]
    try:
        session = Session("gl")
    except Exception as e:  # noqa: BLE001
        notes.append(f"GL backend unavailable ({e}); scenario skipped")
        report["skipped"].append("filter: no GL context")
        return
    ex = session.executor
    split = GLSplit(ex)
    if not split.available:
        notes.append(split.why)
    notes.append("GL device-only = the passes, each followed by ctx.finish() (upload and read-back timed apart "
                 "in the same run through GLExecutor.profile)")
    notes.append("memcpy floors: np.copyto of the input's bytes, and of the plan's bytes "
                 "(Σ passes: target stored extent + each source's stored extent, ×16 B RGBA32F)")
    levels_full = max(math.ceil(math.log2(rows)), math.ceil(math.log2(cols)))
    sizes5 = level_sizes((rows, cols), 5)

    cv_blur, cv_pyramid, ski_blur = peer_blurs(cv2, sizes5)

    ski_kw = _ski_kw

    half = ((rows + 1) // 2, (cols + 1) // 2)
    cases = [
        # name, plan, {peer: fn(x)}
        ("reduce box (2×2)", make_plan(parse("box *v g"), (rows, cols)), {
            "opencv resize INTER_AREA": cv2 and (lambda x: cv2.resize(x, half[::-1], interpolation=cv2.INTER_AREA)),
            "skimage downscale_local_mean": ski and (lambda x: ski.transform.downscale_local_mean(
                x, (2, 2, 1) if x.ndim == 3 else (2, 2))),
        }),
        ("reduce box4 (4×4)", make_plan(parse("box4 *v g"), (rows, cols)), {
            "opencv pyrDown": cv2 and (lambda x: cv2.pyrDown(x)),
            "skimage pyramid_reduce": ski and (lambda x: ski.transform.pyramid_reduce(x, 2, **ski_kw(x))),
        }),
        ("reduce quadratic", make_plan(parse("quadratic *v g"), (rows, cols)), {
            "opencv pyrDown": cv2 and (lambda x: cv2.pyrDown(x)),
            "skimage pyramid_reduce": ski and (lambda x: ski.transform.pyramid_reduce(x, 2, **ski_kw(x))),
        }),
        (f"pyramid to 1×1 ((box4)^{levels_full})",
         make_plan(parse(f"(box4)^{levels_full} *v g"), (rows, cols)), {
             "opencv pyrDown to 1×1": cv2 and cv_pyramid,
             "skimage pyramid_gaussian": ski and (lambda x: list(ski.transform.pyramid_gaussian(x, **ski_kw(x)))),
         }),
        ("blur 5 levels box4/doosabin", blur_plan((rows, cols), 5, "box4", "doosabin"), {
            "opencv pyrDown⁵/pyrUp⁵": cv2 and cv_blur,
            "skimage reduce⁵/expand⁵": ski and ski_blur,
        }),
        ("blur 5 levels box4/doosabin, border mirror",
         blur_plan((rows, cols), 5, "box4", "doosabin", border="mirror"), {
             "opencv pyrDown⁵/pyrUp⁵": cv2 and cv_blur,
         }),
        ("gauss7 (binomial 7×7)", make_plan(parse("gauss7 * g"), (rows, cols)), {
            "opencv GaussianBlur 7×7 σ=√6/2": cv2 and (lambda x: cv2.GaussianBlur(
                x, (7, 7), SIGMA7, borderType=cv2.BORDER_REPLICATE)),
            "skimage gaussian σ=√6/2": ski and (lambda x: ski.filters.gaussian(
                x, sigma=SIGMA7, truncate=3 / SIGMA7, mode="nearest", preserve_range=True, **ski_kw(x))),
        }),
    ]
    notes.append(f"pyramid to 1×1: GL runs (box4)^{levels_full} ⊗↓ g as one plan and reads back only the 1×1 "
                 "level; OpenCV/scikit-image keep every level in host memory")
    notes.append("OpenCV/scikit-image filters are their own (5-tap Gaussian pyrDown/pyrUp, Gaussian-smoothed "
                 "resize): the same job, not the same numbers")
    if args.case:
        cases = [c for c in cases if any(s in c[0] for s in args.case)]
    for channels in (4, 1):
        img = gradient_noise(rows, cols, channels)
        cbytes = img.nbytes
        src_in, dst_in = img.copy(), np.empty_like(img)
        for name, plan, peer_fns in cases:
            pb = plan_bytes(plan)
            pb_src = np.ones(pb // 4, np.float32)
            pb_dst = np.empty_like(pb_src)
            fns = _filter_contenders(session, split, plan, img, peer_fns, (src_in, dst_in), (pb_src, pb_dst))
            log(f"filter: {name}, {cols}×{rows}×{channels} …")
            res = interleaved(fns, reps)
            skipped = [p for p, fn in peer_fns.items() if not fn]
            case = {"case": name, "channels": channels, "shape": list(img.shape), "input_bytes": cbytes,
                    "plan_bytes": pb, "passes": len(plan.passes), "fetches": plan.fetches,
                    "fetches_per_output_pixel": plan.fetches_per_output_pixel,
                    "results": {k: {kk: vv for kk, vv in v.items() if kk != "runs_s"} | {"runs_s": v["runs_s"]}
                                for k, v in res.items()},
                    "skipped_peers": skipped}
            gl_t = res["GL upload+run+readback"]["median_s"]
            dev = res.get("GL split", {}).get("parts_median_s", {})
            case["gl_s"] = gl_t
            case["gl_device_s"] = dev.get("device")
            case["gl_upload_s"] = dev.get("upload")
            case["gl_readback_host_s"] = dev.get("readback_host")
            case["gl_pass_s"] = dev.get("passes")
            case["ratios"] = {}
            for k, v in res.items():
                if k.startswith("GL"):
                    continue
                case["ratios"][f"GL / {k}"] = gl_t / v["median_s"]
                if case["gl_device_s"]:
                    case["ratios"][f"GL device / {k}"] = case["gl_device_s"] / v["median_s"]
            sc["cases"].append(case)
            del pb_src, pb_dst
        del src_in, dst_in, img
    session.close()


# ====================================================================== inputs for process scenarios
def make_image_files(folder: Path, rows: int, cols: int) -> dict[str, Path]:
    """A 4K-class half EXR (zip, piz) and an 8-bit PNG: smooth gradient plus noise."""
    import OpenImageIO as oiio

    rgba = gradient_noise(rows, cols, 4, seed=7)
    files = {}
    for comp in ("zip", "piz"):
        p = folder / f"in_{comp}.exr"
        spec = oiio.ImageSpec(cols, rows, 4, "half")
        spec.channelnames = ("R", "G", "B", "A")
        spec.alpha_channel = 3
        spec.attribute("compression", comp)
        _write(oiio, p, spec, rgba.astype(np.float16))
        files[f"exr half {comp}"] = p
    p = folder / "in.png"
    rgb8 = np.clip(np.rint(rgba[..., :3] * 255), 0, 255).astype(np.uint8)
    _write(oiio, p, oiio.ImageSpec(cols, rows, 3, "uint8"), rgb8)
    files["png 8-bit RGB"] = p
    return files


def _write(oiio, path: Path, spec, data) -> None:
    out = oiio.ImageOutput.create(str(path))
    if out is None or not out.open(str(path), spec) or not out.write_image(data):
        raise RuntimeError(f"cannot write {path}: {oiio.geterror()}")
    out.close()


def opencv_has_exr(cv2) -> bool:
    """Whether this OpenCV build reads and writes OpenEXR (the 5.0 headless wheels do not)."""
    os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
    with tempfile.TemporaryDirectory() as d:  # haveImageReader() opens the file, so write a tiny one
        p = os.path.join(d, "t.exr")
        try:
            return bool(cv2.imwrite(p, np.zeros((2, 2, 3), np.float32))) and cv2.imread(p, -1) is not None
        except Exception:  # noqa: BLE001 - "could not find a writer" is a cv2.error
            return False


def in_process_profile(path: Path, out: Path) -> dict:
    """``pyramid blur --levels 5`` in this process, split as the CLI runs it: read (half kept half) /
    context / plan / compile / texture allocation (the CLI overlaps these with the read) / upload /
    passes / read-back / write."""
    from pyramid_cli import imageio as io
    from pyramid_cli.exec.gl import GLExecutor
    from pyramid_cli.workflows.pyramids import blur_plan

    t = {}
    t["fresh interpreter + imports (subprocess)"] = cmd_time([sys.executable, "-c", (
        "import numpy, OpenImageIO, moderngl, click, pyramid_cli.cli, pyramid_cli.imageio, pyramid_cli.exec.session, "
        "pyramid_cli.exec.gl, pyramid_cli.workflows.pyramids")])
    t0 = perf()
    image = io.read_image(str(path), keep_half=True)
    t["read (io.read_image)"] = perf() - t0
    t0 = perf()
    ex = GLExecutor()
    ex.open()
    t["GL context"] = perf() - t0
    t0 = perf()
    plan = blur_plan(image.pixels.shape[:2], 5)
    t["plan"] = perf() - t0
    t0 = perf()
    with ex.current():
        ex.programs(plan)
    t["compile programs (this process's shader cache state)"] = perf() - t0
    t0 = perf()
    ex.prepare(plan)
    t["allocate textures (first touch)"] = perf() - t0
    dtype_read = str(image.pixels.dtype)
    half = image.pixels.dtype == np.float16 and io.stores_half_unchanged(str(out), image.spec)
    split = GLSplit(ex)
    if split.available:
        s = split(plan, image.pixels)
        t["GL upload"], t["GL passes"], t["GL read-back + host"] = s["upload"], s["device"], s["readback_host"]
    image.pixels = ex.run_outputs(plan, [image.pixels], np.float16 if half else np.float32)[-1]
    ex.close()
    t0 = perf()
    io.write_image(str(out), image, inputs=(str(path),), force=True)
    t["write (io.write_image)"] = perf() - t0
    return {"pixels_dtype_after_read": dtype_read, "read_back_dtype": str(image.pixels.dtype), "split_s": t}


def cprofile_top(argv: list[str], lines: int = 22) -> list[str]:
    """``python -m cProfile -s cumtime`` of a command; its top lines."""
    p = subprocess.run([sys.executable, "-m", "cProfile", "-s", "cumtime", *argv], capture_output=True, text=True)
    out = p.stdout.splitlines()
    start = next((i for i, ln in enumerate(out) if "ncalls" in ln), 0)
    return [ln.rstrip() for ln in out[max(0, start - 2):start + lines]]


# ====================================================================== scenario 2: end to end
def scenario_e2e(args, libs: dict, report: dict, tmp: Path) -> None:
    rows, cols = (270, 480) if args.quick else (2160, 3840)
    reps = args.reps or (2 if args.quick else 3)
    sc = report["scenarios"]["e2e"] = {"size": [rows, cols], "reps": reps, "cases": [], "notes": [
        "wall time of fresh processes (interpreter start, imports, GL context, shader compile, read, filter, write)",
        "I/O floor: a python script reading the file with OpenImageIO in its stored pixel type and writing it "
        "with the same spec (same compression, PNG at OIIO's default zlib level)",
        "OpenCV script: imread(IMREAD_UNCHANGED) → float32 → pyrDown⁵/pyrUp⁵ → imwrite (EXR half with the "
        "input's compression, PNG at zlib level 6); no sRGB decode, unlike pyramid",
    ]}
    folder = tmp / "e2e"
    folder.mkdir()
    log(f"e2e: making {cols}×{rows} inputs …")
    files = make_image_files(folder, rows, cols)
    pyr = pyramid_cmd()
    cv_mode = "cv2"
    if "cv2" in libs and not opencv_has_exr(libs["cv2"]):
        cv_mode = "oiio-exr"
        sc["notes"].append(f"this OpenCV build ({libs['cv2'].__version__}) has no OpenEXR codec: the OpenCV script "
                           "reads and writes EXR through OpenImageIO (as float, written half) and filters with "
                           "OpenCV; PNG goes through cv2.imread/imwrite")
    sc["opencv_exr_io"] = cv_mode
    for label, path in files.items():
        ext = path.suffix
        commands = {
            "pyramid blur --levels 5": [*pyr, "blur", "--levels", "5", "--backend", "gl", "-q", "--force", str(path),
                                        str(folder / f"o_pyr{ext}")],
            "pyramid blur --levels 5 --backend cpu": [*pyr, "blur", "--levels", "5", "--backend", "cpu", "-q",
                                                      "--force", str(path), str(folder / f"o_cpu{ext}")],
            "OIIO read+write (python)": [sys.executable, str(SCRIPTS / "io_floor.py"), str(path),
                                         str(folder / f"o_io{ext}")],
        }
        fns = {name: lambda argv=argv: cmd_time(argv) for name, argv in commands.items()}
        if "cv2" in libs:
            fns["OpenCV script"] = lambda p=path, e=ext: cmd_time(
                [sys.executable, str(SCRIPTS / "opencv_blur.py"), cv_mode, str(p), str(folder / f"o_cv{e}")])
        log(f"e2e: {label} …")
        res = interleaved(fns, reps)
        case = {"case": label, "file_bytes": path.stat().st_size,
                "results": res, "ratios": {},
                "peak_rss_mb": {name: cmd_peak_rss(argv) for name, argv in commands.items()}}
        base = res["pyramid blur --levels 5"]["median_s"]
        for k, v in res.items():
            if k != "pyramid blur --levels 5":
                case["ratios"][f"pyramid / {k}"] = base / v["median_s"]
        cpu_t = res["pyramid blur --levels 5 --backend cpu"]["median_s"]
        for k, v in res.items():
            if not k.startswith("pyramid"):
                case["ratios"][f"pyramid cpu / {k}"] = cpu_t / v["median_s"]
        rss = case["peak_rss_mb"]
        case["ratios"]["peak RSS pyramid cpu / OIIO read+write"] = (
            rss["pyramid blur --levels 5 --backend cpu"] / rss["OIIO read+write (python)"])
        sc["cases"].append(case)
    sc["files"] = {k: str(v) for k, v in files.items()}


# ====================================================================== scenario 3: batch
def scenario_batch(args, libs: dict, report: dict, tmp: Path) -> None:
    import OpenImageIO as oiio

    side = 128 if args.quick else 256
    counts = [10] if args.quick else [50, 500]
    reps = args.reps or (1 if args.quick else 2)
    sample_calls = 10 if args.quick else 50
    folder = tmp / "batch"
    (folder / "out").mkdir(parents=True)
    sc = report["scenarios"]["batch"] = {"image": f"{side}×{side} 8-bit RGB PNG", "reps": reps, "cases": [],
                                         "notes": []}
    help_text = subprocess.run([*pyramid_cmd(), "blur", "--help"], capture_output=True, text=True).stdout
    many = "INPUT..." in help_text and "TEMPLATE" in help_text
    sc["cli_accepts_many_inputs"] = many
    sc["notes"].append("one-process loop: a python script that imports pyramid_cli and loops io.read_image → "
                       "Session.run(Blur(levels=5)) → io.write_image with one Session (one GL context, programs "
                       "compiled once)")
    sc["notes"].append("`pyramid blur IN… -o TEMPLATE` (the CLI's own batch mode) is timed too and carries the "
                       "targets: per-image cost = its wall time / N vs the OIIO loop's wall time / N"
                       if many else "`pyramid blur` takes one INPUT: the one-process loop script carries the targets")
    sc["notes"].append("per-image cost = the loop's own time / N (interpreter start and imports excluded, "
                       "GL context and shader compile included for pyramid); the read+write floor is the "
                       "same loop with OpenImageIO only")
    n_max = max(counts)
    rgb = (gradient_noise(side, side, 3, seed=3) * 255).clip(0, 255).astype(np.uint8)
    ins = []
    for i in range(n_max):
        p = folder / f"im{i:03d}.png"
        _write(oiio, p, oiio.ImageSpec(side, side, 3, "uint8"), np.roll(rgb, i, axis=1))
        ins.append(p)
    pyr = pyramid_cmd()

    def pairs(n, tag):
        return [str(x) for i in range(n) for x in (ins[i], folder / "out" / f"{tag}{i:03d}.png")]

    def loop(script, n, tag):
        def fn():
            t0 = perf()
            p = subprocess.run([sys.executable, str(script), *pairs(n, tag)], capture_output=True, text=True)
            wall = perf() - t0
            if p.returncode:
                raise RuntimeError(p.stderr[-600:])
            return {"loop_s": float(p.stdout.split()[0]), "wall_s": wall}
        return fn

    def calls(n, tag):
        def fn():
            t0 = perf()
            for i in range(n):
                cmd_time([*pyr, "blur", "--levels", "5", "--backend", "gl", "-q", "--force",
                          str(ins[i]), str(folder / "out" / f"{tag}{i:03d}.png")])
            return {"wall_s": perf() - t0}
        return fn

    def cli_batch(n):
        def fn():
            t0 = perf()
            cmd_time([*pyr, "blur", "--levels", "5", "--backend", "gl", "-q", "--force", *map(str, ins[:n]),
                      "-o", str(folder / "out" / "d{stem}.png")])
            return {"wall_s": perf() - t0}
        return fn

    for n in counts:
        n_calls = min(n, sample_calls)
        fns = {"pyramid, one process": loop(SCRIPTS / "pyramid_batch.py", n, "a"),
               **({"pyramid blur IN… -o TEMPLATE": cli_batch(n)} if many else {}),
               "OIIO read+write, one process": loop(SCRIPTS / "io_floor.py", n, "b"),
               f"pyramid blur, one call each ({n_calls} timed)": calls(n_calls, "c")}
        log(f"batch: {n} images …")
        res = interleaved(fns, reps, warmup=0)
        one = res["pyramid, one process"]["parts_median_s"]
        floor = res["OIIO read+write, one process"]["parts_median_s"]
        each = res[f"pyramid blur, one call each ({n_calls} timed)"]["parts_median_s"]["wall_s"] * n / n_calls
        case = {"images": n, "results": res,
                "one_process_wall_s": one["wall_s"], "one_process_per_image_s": one["loop_s"] / n,
                "read_write_per_image_s": floor["loop_s"] / n,
                "calls_wall_s": each, "calls_extrapolated_from": n_calls if n_calls < n else None,
                "per_image_ratio_vs_read_write": (one["loop_s"] / n) / (floor["loop_s"] / n),
                "speedup_one_process_vs_calls": each / one["wall_s"]}
        if many:
            cli = res["pyramid blur IN… -o TEMPLATE"]["parts_median_s"]["wall_s"]
            case |= {"cli_batch_wall_s": cli, "cli_batch_per_image_s": cli / n,
                     "read_write_wall_per_image_s": floor["wall_s"] / n,
                     "loop_per_image_ratio_vs_read_write": case["per_image_ratio_vs_read_write"],
                     "per_image_ratio_vs_read_write": cli / floor["wall_s"],
                     "speedup_one_process_vs_calls": each / cli, "measured_by": "pyramid blur IN… -o TEMPLATE"}
        else:
            case["measured_by"] = "one-process loop script (emulation)"
        sc["cases"].append(case)
        if n_calls < n:
            sc["notes"].append(f"{n} calls: the first {n_calls} were timed and scaled by {n / n_calls:g}")


# ====================================================================== scenario 4: start-up
def scenario_startup(args, libs: dict, report: dict) -> None:
    reps = args.reps or (3 if args.quick else 7)
    pyr = pyramid_cmd()
    fns = {
        "python -c pass": lambda: cmd_time([sys.executable, "-c", "pass"]),
        "python -c 'import numpy'": lambda: cmd_time([sys.executable, "-c", "import numpy"]),
        "pyramid --help": lambda: cmd_time([*pyr, "--help"]),
        "pyramid explain 'quadratic *v g'": lambda: cmd_time([*pyr, "explain", "quadratic *v g"]),
    }
    log("startup …")
    res = interleaved(fns, reps)
    report["scenarios"]["startup"] = {"reps": reps, "results": res, "command": pyr,
                                      "notes": ["wall time of a fresh process, median of interleaved runs"]}


# ====================================================================== scenario 6: the compiled CPU executor
CPU_COMPILE_SCRIPT = r"""
import json, sys, time
t0 = time.perf_counter()
from pyramid_cli.exec import cpu
from pyramid_cli.workflows import pyramids
t1 = time.perf_counter()
rows, cols = int(sys.argv[1]), int(sys.argv[2])
plan = pyramids.blur_plan((rows, cols), 5, strategy="fused")
ex = cpu.CPUExecutor()
t2 = time.perf_counter()
ex.prepare(plan)
t3 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "prepare_s": t3 - t2, "compiles": ex.compiles,
                  "cache_loads": ex.cache_loads, "kernels": len(ex._kernels)}))
"""


def cpu_plan_bytes(plan, channels: int) -> int:
    """Bytes a plan moves on the CPU: per pass, its target's stored extent written plus each source read,
    float32 × channels (no power-of-two or RGBA padding)."""
    total = 0
    for ps in plan.passes:
        h, w = plan.images[ps.target].stored
        total += h * w * 4 * channels
        for s in ps.sources():
            h, w = plan.images[s].stored
            total += h * w * 4 * channels
    return total


def _binomial(n: int) -> np.ndarray:
    row = np.array([math.comb(n - 1, k) for k in range(n)], dtype=np.float32)
    return row / row.sum()


def _cpu_compile_times(tmp: Path, rows: int, cols: int) -> dict:
    """Cold compile (empty cache folder, fresh process) and cached load (a second fresh process) of the blur plan."""
    from pyramid_cli.exec import cpu

    folder = tmp / "cpu-cache-cold"
    env = dict(os.environ, **{cpu.CACHE_ENV: str(folder)})
    out = {"cache_dir": "a fresh temporary folder (PYRAMID_CACHE_DIR)"}
    for name in ("cold", "cached"):
        t0 = perf()
        p = subprocess.run([sys.executable, "-c", CPU_COMPILE_SCRIPT, str(rows), str(cols)], capture_output=True,
                           text=True, env=env, timeout=600)
        wall = perf() - t0
        if p.returncode != 0:
            raise RuntimeError(f"compile child failed: {p.stderr.strip()[-600:]}")
        out[name] = json.loads(p.stdout.strip().splitlines()[-1]) | {"process_wall_s": wall}
    return out


def scenario_cpu(args, libs: dict, report: dict, tmp: Path) -> None:
    """The compiled CPU executor (numba) side by side with OpenCV, scikit-image, GL on llvmpipe, memcpy."""
    from pyramid_cli.core.parse import parse
    from pyramid_cli.exec import cpu
    from pyramid_cli.plan import plan as make_plan
    from pyramid_cli.workflows.pyramids import blur_plan, level_sizes

    sc = report["scenarios"]["cpu"] = {"cases": [], "notes": []}
    ok, why = cpu.available()
    if not ok:
        report["skipped"].append(f"cpu: {why}")
        return
    rows, cols = (270, 480) if args.quick else (2160, 3840)
    reps = args.reps or (2 if args.quick else 7)
    cv2, ski = libs.get("cv2"), libs.get("skimage")
    sc.update({"size": [rows, cols], "reps": reps})
    ex = cpu.CPUExecutor()
    sc["executor"] = ex.info()
    sc["notes"] += [
        f"CPU executor: {ex.info()['renderer']}; kernels compiled before timing (one warm-up run per contender)",
        "memcpy floor: np.copyto of the bytes the plan moves on the CPU (Σ passes: target stored extent + each "
        "source's stored extent, float32 × channels), into a preallocated (warm) buffer",
        "OpenCV: its own filters (5-tap Gaussian pyrDown/pyrUp, area resize); sepFilter2D/filter2D carry the "
        "same binomial/quasi weights with BORDER_REPLICATE (the clamp border)",
        "'CPU executor, runs back to back': the same plan run reps times with nothing between (OpenCV's worker "
        "threads spin after its calls and compete with the executor's two threads in the interleaved runs)",
        "CPU executor: the planner's 'fused' strategy (one pass per written step); GL: plan.plan / "
        "pyramids.blur_plan (its cost model's recipes); where they differ the GL plan also runs on the CPU",
    ]
    log("cpu: compile times (fresh processes) …")
    try:
        sc["compile"] = _cpu_compile_times(tmp, rows, cols)
    except Exception as e:  # noqa: BLE001 - report, do not lose the timings
        sc["compile"] = {"error": " ".join(str(e).split())[:400]}
    runner = None
    try:
        from pyramid_cli.exec.session import Session

        runner = Session("gl")
        sc["gl_renderer"] = runner.name
    except Exception as e:  # noqa: BLE001
        sc["notes"].append(f"GL unavailable ({' '.join(str(e).split())[:200]}): no GL contender")
    sizes5 = level_sizes((rows, cols), 5)
    half = ((rows + 1) // 2, (cols + 1) // 2)
    replicate = cv2.BORDER_REPLICATE if cv2 else None

    cv_blur, cv_pyramid, ski_blur = peer_blurs(cv2, sizes5)

    def cv_sep(n):
        k = _binomial(n)
        return lambda x: cv2.sepFilter2D(x, -1, k, k, borderType=replicate)


    quasi = np.array([[-1, -2, -1], [-2, 36, -2], [-1, -2, -1]], np.float32) / 24
    levels_full = max(math.ceil(math.log2(rows)), math.ceil(math.log2(cols)))
    def both(text):  # the GL executor's plan (its cost model's recipes) and the CPU's (one pass per step)
        return make_plan(parse(text), (rows, cols)), make_plan(parse(text), (rows, cols), "fused")

    cases = [  # name, (GL plan, CPU plan), {peer: fn}, GL too
        ("blur 5 levels box4/doosabin", (blur_plan((rows, cols), 5), blur_plan((rows, cols), 5, strategy="fused")), {
            "opencv pyrDown⁵/pyrUp⁵": cv2 and cv_blur, "skimage reduce⁵/expand⁵": ski and ski_blur}, True),
        ("reduce box ⊗↓", both("box *v g"), {
            "opencv resize INTER_AREA": cv2 and (lambda x: cv2.resize(x, half[::-1], interpolation=cv2.INTER_AREA))},
         True),
        ("reduce box4 ⊗↓", both("box4 *v g"), {
            "opencv pyrDown": cv2 and cv2.pyrDown}, True),
        ("reduce quadratic ⊗↓", both("quadratic *v g"), {
            "opencv pyrDown": cv2 and cv2.pyrDown}, False),
        ("reduce cubic ⊗↓", both("cubic *v g"), {"opencv pyrDown": cv2 and cv2.pyrDown},
         False),
        (f"pyramid to 1×1 ((box4)^{levels_full})", both(f"(box4)^{levels_full} *v g"), {
            "opencv pyrDown to 1×1": cv2 and cv_pyramid}, False),
        ("box ⊗ (2×2)", both("box * g"), {
            "opencv boxFilter 2×2": cv2 and (lambda x: cv2.boxFilter(x, -1, (2, 2), borderType=replicate))}, False),
        ("bartlett ⊗ (3×3)", both("bartlett * g"), {
            "opencv sepFilter2D [1 2 1]/4": cv2 and cv_sep(3)}, False),
        ("gauss5 ⊗ (5×5)", both("gauss5 * g"), {
            "opencv sepFilter2D binomial 5": cv2 and cv_sep(5)}, False),
        ("gauss7 ⊗ (7×7)", both("gauss7 * g"), {
            "opencv sepFilter2D binomial 7": cv2 and cv_sep(7),
            "opencv GaussianBlur 7×7 σ=√6/2": cv2 and (lambda x: cv2.GaussianBlur(
                x, (7, 7), SIGMA7, borderType=replicate))}, False),
        ("quasi ⊗ (3×3)", both("quasi * g"), {
            "opencv filter2D quasi": cv2 and (lambda x: cv2.filter2D(x, -1, quasi, borderType=replicate))}, False),
    ]
    if args.case:
        cases = [c for c in cases if any(s in c[0] for s in args.case)]
    for channels in (4, 1):
        img = gradient_noise(rows, cols, channels)
        for name, (gl_plan, plan), peer_fns, with_gl in cases:
            pb = cpu_plan_bytes(plan, channels)
            pb_src = np.ones(pb // 4, np.float32)
            pb_dst = np.empty_like(pb_src)
            pb_dst.fill(0)  # warm: the floor is the copy, not page faults
            fns = _cpu_contenders(ex, runner if with_gl else None, plan, gl_plan, img, peer_fns, (pb_src, pb_dst))
            if len(gl_plan.passes) != len(plan.passes):  # the GL planner's recipe, run on the CPU, for scale
                fns["CPU executor, GL cost-model plan"] = lambda gl_plan=gl_plan, img=img: ex.run(gl_plan, img)
            log(f"cpu: {name}, {cols}×{rows}×{channels} …")
            ex.prepare(plan)
            ex.prepare(gl_plan)
            res = interleaved(fns, reps)
            mine = res["CPU executor"]["median_s"]
            case = {"case": name, "channels": channels, "passes": len(plan.passes), "plan_bytes": pb,
                    "gl_plan_passes": len(gl_plan.passes),
                    "results": res, "cpu_s": mine,
                    "ratios": {f"CPU / {k}": mine / v["median_s"] for k, v in res.items() if k != "CPU executor"},
                    "skipped_peers": [p for p, fn in peer_fns.items() if not fn]}
            # the same runs back to back, nothing between them: OpenCV's worker threads keep spinning
            # for a while after each of its calls, and the executor's thread pool competes with them
            alone = []
            for _ in range(reps):
                t0 = perf()
                ex.run(plan, img)
                alone.append(perf() - t0)
            case["cpu_alone_s"] = statistics.median(alone)
            if not args.no_profile:
                case["per_pass_s"] = _cpu_per_pass(ex, plan, img)
                case["pass_labels"] = [f"{ps.label} → {plan.images[ps.target].stored[1]}×"
                                       f"{plan.images[ps.target].stored[0]}" for ps in plan.passes]
            sc["cases"].append(case)
            del pb_src, pb_dst
        del img
    sc["compiles"], sc["cache_loads"] = ex.compiles, ex.cache_loads
    ex.close()
    if runner is not None:
        runner.close()


def _cpu_contenders(ex, runner, plan, gl_plan, img, peer_fns, copy) -> dict:
    fns = {"CPU executor": lambda: ex.run(plan, img)}
    for pname, fn in peer_fns.items():
        if fn:
            fns[pname] = lambda fn=fn: fn(img)
    if runner is not None:
        fns["GL llvmpipe upload+run+readback"] = lambda: runner.run_plan(gl_plan, [img])
    fns["memcpy plan bytes"] = lambda: np.copyto(copy[1], copy[0])
    return fns


def _cpu_per_pass(ex, plan, img, reps: int = 3) -> list[float]:
    """Seconds of each pass of one CPU run (kernel and border windows; the best of ``reps`` runs)."""
    real = ex._run_pass
    times: list[float] = []

    def timed(*a, **k):
        t0 = perf()
        real(*a, **k)
        times.append(perf() - t0)

    best: list[float] | None = None
    ex._run_pass = timed
    try:
        for _ in range(reps):
            times.clear()
            ex.run(plan, img)
            best = list(times) if best is None else [min(a, b) for a, b in zip(best, times, strict=True)]
    finally:
        del ex._run_pass  # back to the class's method
    return best or []


def cpu_targets(report: dict, add, args) -> None:
    """The compiled CPU executor's targets (issue 13), with the per-pass profile of each miss."""
    c = report["scenarios"].get("cpu")
    if not c or "cases" not in c:
        return
    prof = report["profiles"]
    size = "4K" if c["size"] == [2160, 3840] else f"{c['size'][1]}×{c['size'][0]}"
    for case in c["cases"]:
        if case["channels"] != 4:
            continue
        peers = [k for k in case["ratios"] if "opencv" in k]
        key = f"cpu {case['case']}"
        missed = False
        if case["case"].startswith("blur"):
            missed |= add(f"cpu blur 5 levels, {size} RGBA float32: ≤ 0.7× OpenCV pyrDown⁵/pyrUp⁵",
                          case["ratios"].get("CPU / opencv pyrDown⁵/pyrUp⁵"), 0.7, "<=", "×", key) is False
            missed |= add(f"cpu blur 5 levels, {size} RGBA float32: within 2× memcpy of the plan's bytes",
                          case["ratios"].get("CPU / memcpy plan bytes"), 2.0, "<=", "×", key) is False
        elif peers:
            best = min(peers, key=lambda k: case["ratios"][k])
            missed |= add(f"cpu {case['case']}, {size} RGBA float32: no slower than {best[6:]}",
                          case["ratios"][best], 1.0, "<=", "×", key) is False
        if missed and not args.no_profile:
            prof[key] = {"cpu_s": case["cpu_s"], "per_pass_s": case.get("per_pass_s"),
                         "pass_labels": case.get("pass_labels"), "plan_bytes": case["plan_bytes"],
                         "peers_s": {k: v["median_s"] for k, v in case["results"].items()}}
    comp = c.get("compile", {})
    if "cold" in comp:
        add("cpu compile of the blur plan, cold cache, fresh process ≤ 3 s", comp["cold"]["prepare_s"], 3.0, "<=",
            "s", None)
        add("cpu kernels of the blur plan from the disk cache, fresh process ≤ 0.2 s", comp["cached"]["prepare_s"],
            0.2, "<=", "s", None)


def print_cpu(report: dict) -> None:
    c = report["scenarios"].get("cpu")
    if not c or "cases" not in c:
        return
    p = print
    p(f"\n== cpu (compiled CPU executor, warm, in process), {c['size'][1]}×{c['size'][0]}, {c['reps']} reps")
    for n in c["notes"]:
        p(f"   note: {n}")
    comp = c.get("compile", {})
    if "cold" in comp:
        for k in ("cold", "cached"):
            v = comp[k]
            p(f"   {k:6s} blur plan: prepare {fmt_s(v['prepare_s']).strip()} ({v['compiles']} compiled, "
              f"{v['cache_loads']} loaded), import {fmt_s(v['import_s']).strip()}, "
              f"process {fmt_s(v['process_wall_s']).strip()}")
    elif comp:
        p(f"   compile: {comp.get('error')}")
    for case in c["cases"]:
        p(f"-- {case['case']}, {case['channels']} ch: {case['passes']} passes (GL plan {case['gl_plan_passes']}), "
          f"plan bytes {case['plan_bytes'] / 1e6:.0f} MB")
        for k, v in case["results"].items():
            r = case["ratios"].get(f"CPU / {k}")
            p(f"   {k:36s} {fmt_s(v['median_s'])}" + (f"   CPU/it {fmt_x(r):>7s}" if r else ""))
        if case.get("cpu_alone_s"):
            p(f"   {'CPU executor, runs back to back':36s} {fmt_s(case['cpu_alone_s'])}   (not interleaved)")
        if case.get("per_pass_s") and case["case"].startswith("blur"):
            p("   CPU per pass (ms): " + " ".join(f"{x * 1e3:.1f}" for x in case["per_pass_s"]))


# ====================================================================== scenario 5: GPU
TORCH_HINT = "pip install -e '.[bench,bench-gpu]'"
EGL_NVIDIA = "__EGL_VENDOR_LIBRARY_FILENAMES=/usr/share/glvnd/egl_vendor.d/10_nvidia.json"


def cuda_present() -> bool:
    """Whether torch is installed and sees a CUDA device (imports torch only when it is installed)."""
    import importlib.util

    if importlib.util.find_spec("torch") is None:
        return False
    try:
        import torch

        return bool(torch.cuda.is_available())
    except Exception:  # noqa: BLE001 - a broken torch install is "no CUDA" here; the scenario says why
        return False


def default_scenarios() -> list[str]:
    return CPU_SCENARIOS + (["gpu"] if cuda_present() else [])


def _software_gl(renderer: str | None) -> bool:
    return renderer is None or any(k in renderer.lower() for k in ("llvmpipe", "softpipe", "swrast", "lavapipe"))


def scenario_gpu(args, libs: dict, report: dict) -> None:
    """The 5-level blur, 4K RGBA16F and RGBA32F: GL (device-only and total) vs the torch conv2d peer and a copy."""
    def skip(line: str, **extra) -> None:
        report["scenarios"]["gpu"] = {"skipped": line, **extra}
        report["skipped"].append(f"gpu: {line}")
        log(f"gpu: {line}")

    try:
        import torch
    except ImportError as e:
        return skip(f"torch is not installed ({e}; {TORCH_HINT}): skipped")
    device = torch.device(args.torch_device)
    if device.type == "cuda" and not torch.cuda.is_available():
        return skip("no CUDA device: skipped", torch=torch.__version__)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import torch_peer as tp

    from pyramid_cli.exec.gl import GLExecutor
    from pyramid_cli.workflows.pyramids import blur_plan

    cuda = device.type == "cuda"
    rows, cols = (270, 480) if args.quick else (2160, 3840)
    reps = args.reps or (2 if args.quick else 9)
    if cuda:
        torch.backends.cudnn.benchmark = True  # the peer's best conv algorithm per shape (picked in the warm-up)
        name = torch.cuda.get_device_name(device)
        sync = torch.cuda.synchronize
    else:
        name = f"CPU ({report['machine'].get('cpu')}, {torch.get_num_threads()} torch threads)"

        def sync():
            return None

    sc = report["scenarios"]["gpu"] = {
        "size": [rows, cols], "reps": reps, "levels": 5, "cases": [], "notes": [],
        "torch": {"version": torch.__version__, "device": str(device), "device_name": name, "cuda": torch.version.cuda,
                  "cudnn": torch.backends.cudnn.version() if cuda else None}}
    notes = sc["notes"]
    if not cuda:
        notes.append("torch on the CPU: a smoke check of the scenario, not the GPU measurement the targets are for")
    plan = blur_plan((rows, cols), 5, "box4", "doosabin")
    notes.append("the same job everywhere: 5 × box4 ⊗↓ then 5 × Doo-Sabin ⊗↑ back to the input size; the torch peer "
                 "(bench/torch_peer.py) takes its weights from the project's masks and equals the numpy reference "
                 "(tests/system/test_torch_peer.py); each torch contender ends with a device synchronize")
    notes.append("GL device = the passes back to back (ctx.finish() before the first and after the last); "
                 "'finish after each pass' is the filter scenario's per-pass split, sync cost included")
    img32 = gradient_noise(rows, cols, 4)
    for label, precision, np_dtype, t_dtype in [("RGBA16F", "half", np.float16, torch.float16),
                                                ("RGBA32F", "float", np.float32, torch.float32)]:
        img = img32.astype(np_dtype)
        case = {"case": f"blur 5 levels box4/doosabin, {label}", "format": label, "gl_precision": precision,
                "image_bytes": img.nbytes, "passes": len(plan.passes), "notes": []}
        fns: dict = {}
        ex = GLExecutor(precision=precision)
        try:
            ex.open()
            renderer = ex.info().get("renderer")
        except Exception as e:  # noqa: BLE001 - no GL: time the peer alone, say why
            renderer = None
            case["notes"].append(f"GL unavailable ({' '.join(str(e).split())[:300]}); GL contenders skipped")
            ex = None
        case["gl_renderer"] = renderer
        if cuda and _software_gl(renderer):
            case["notes"].append(f"GL renders on {renderer or 'nothing'}, not the GPU: EGL did not find the NVIDIA "
                                 f"driver (run with {EGL_NVIDIA})")
        if ex is not None:
            per_pass, span = GLSplit(ex), GLSplit(ex, per_pass=False)
            fns["GL upload+run+readback"] = lambda ex=ex, img=img: ex.run_outputs(plan, [img], dtype=img.dtype)
            if span.available:
                fns["GL device (passes back to back)"] = lambda span=span, img=img: span(plan, img)
                fns["GL split (finish after each pass)"] = lambda per_pass=per_pass, img=img: per_pass(plan, img)
            else:
                case["notes"].append(span.why)
        x = tp.to_nchw(img, device, t_dtype)
        dst = torch.empty_like(x)

        def synced(fn):
            def run():
                fn()
                sync()
            return run

        fns["torch conv2d blur"] = synced(lambda x=x: tp.blur(x, 5))
        fns["torch host→device + blur + device→host"] = synced(
            lambda img=img, t_dtype=t_dtype: tp.from_nchw(tp.blur(tp.to_nchw(img, device, t_dtype), 5)))
        fns["torch copy_ (device to device)"] = synced(lambda x=x, dst=dst: tp.copy_floor(x, dst))
        log(f"gpu: {case['case']}, {cols}×{rows}, torch on {device} ({name}) …")
        try:
            res = interleaved(fns, reps)
        finally:
            if ex is not None:
                ex.close()
        case["results"] = res
        med = {k: v["median_s"] for k, v in res.items()}
        dev_gl = res.get("GL device (passes back to back)", {}).get("parts_median_s", {}).get("device")
        per = res.get("GL split (finish after each pass)", {}).get("parts_median_s", {})
        case["pass_labels"] = [ps.label for ps in plan.passes]
        case |= {"gl_s": med.get("GL upload+run+readback"), "gl_device_s": dev_gl,
                 "gl_device_per_pass_sum_s": per.get("device"), "gl_pass_s": per.get("passes"),
                 "torch_blur_s": med["torch conv2d blur"],
                 "torch_round_trip_s": med["torch host→device + blur + device→host"],
                 "copy_s": med["torch copy_ (device to device)"]}
        r = case["ratios"] = {}
        if dev_gl:
            r["GL device / torch copy"] = dev_gl / case["copy_s"]
            r["torch blur / GL device"] = case["torch_blur_s"] / dev_gl
        if case["gl_s"]:
            r["GL upload+run+readback / torch host→device+blur+device→host"] = case["gl_s"] / case["torch_round_trip_s"]
        r["torch blur / torch copy"] = case["torch_blur_s"] / case["copy_s"]
        sc["cases"].append(case)
        del x, dst
        if cuda:
            torch.cuda.empty_cache()


def importtime_top(argv: list[str], n: int = 12) -> list[str]:
    """``python -X importtime`` of a command: the n slowest imports by cumulative time."""
    p = subprocess.run([sys.executable, "-X", "importtime", *argv], capture_output=True, text=True)
    rows = []
    for ln in p.stderr.splitlines():
        if ln.startswith("import time:") and "|" in ln and "cumulative" not in ln:
            _, cum, name = ln[len("import time:"):].split("|")
            rows.append((int(cum), name.rstrip()))
    rows.sort(reverse=True)
    return [f"{c / 1e3:8.1f} ms  {nm}" for c, nm in rows[:n]]


# ====================================================================== targets, table
def targets(report: dict, args, tmp: Path) -> None:
    out = report["targets"]
    prof = report["profiles"]
    scs = report["scenarios"]

    def add(name, value, limit, op, unit, profile_key=None):
        met = None if value is None else (value <= limit if op == "<=" else value >= limit)
        out.append({"target": name, "value": value, "limit": limit, "op": op, "unit": unit, "met": met,
                    "profile": profile_key})
        return met

    f = scs.get("filter")
    if f:
        blur = next((c for c in f["cases"] if c["case"].startswith("blur") and c["channels"] == 4), None)
        if blur:
            r_cv = blur["ratios"].get("GL / opencv pyrDown⁵/pyrUp⁵")
            m1 = add("blur 5 levels, RGBA float32: GL ≤ 1.0× OpenCV pyrDown⁵/pyrUp⁵", r_cv, 1.0, "<=", "×",
                     "filter_blur")
            m2 = add("blur 5 levels, RGBA float32: GL within 2× memcpy of the plan's bytes",
                     blur["ratios"].get("GL / memcpy plan bytes"), 2.0, "<=", "×", "filter_blur")
            if (m1 is False or m2 is False) and not args.no_profile:
                prof["filter_blur"] = {
                    "split_median_s": {"upload": blur["gl_upload_s"], "passes (device)": blur["gl_device_s"],
                                       "read-back + host": blur["gl_readback_host_s"]},
                    "per_pass_s": blur["gl_pass_s"],
                    "plan": {"passes": blur["passes"], "fetches": blur["fetches"],
                             "fetches_per_output_pixel": blur["fetches_per_output_pixel"],
                             "plan_bytes": blur["plan_bytes"], "input_bytes": blur["input_bytes"]},
                    "per_level_note": "passes 1–10: box4 ⊗↓ as 2 passes per level (box↖ ⊗↓, box↘ ⊗); "
                                      "passes 11–15: doosabin ⊗↑ 5,4,3,2,1 back to full size",
                }
    e = scs.get("e2e")
    if e:
        for c in e["cases"]:
            m1 = add(f"e2e {c['case']}: pyramid blur ≤ 1.15× OIIO read+write",
                     c["ratios"].get("pyramid / OIIO read+write (python)"), 1.15, "<=", "×", "e2e")
            m2 = add(f"e2e {c['case']}: pyramid blur ahead of the OpenCV script (< 1.0×)",
                     c["ratios"].get("pyramid / OpenCV script"), 1.0, "<=", "×", "e2e")
            add(f"e2e {c['case']}: pyramid blur --backend cpu ≤ 1.15× OIIO read+write",
                c["ratios"].get("pyramid cpu / OIIO read+write (python)"), 1.15, "<=", "×", "e2e")
            add(f"e2e {c['case']}: pyramid blur --backend cpu peak memory ≤ 1.5× OIIO read+write's",
                c["ratios"].get("peak RSS pyramid cpu / OIIO read+write"), 1.5, "<=", "×", "e2e")
            if (m1 is False or m2 is False) and not args.no_profile:
                pe = prof.setdefault("e2e", {})
                if c["case"] not in pe:
                    path = Path(e["files"][c["case"]])
                    log(f"profile: e2e {c['case']} …")
                    pe[c["case"]] = in_process_profile(path, path.with_name("o_prof" + path.suffix))
                    pe[c["case"]]["cprofile_pyramid_blur"] = cprofile_top(
                        ["-m", "pyramid_cli.cli", "blur", "--levels", "5", "--backend", "gl", "-q", "--force",
                         str(path), str(path.with_name("o_cprof" + path.suffix))])
    b = scs.get("batch")
    if b:
        for c in b["cases"]:
            m1 = add(f"batch {c['images']} ({c['measured_by']}): per-image cost ≤ 1.1× OIIO read+write",
                     c["per_image_ratio_vs_read_write"], 1.1, "<=", "×", "batch")
            add(f"batch {c['images']} ({c['measured_by']}): one process ≥ 5× faster than one call each",
                c["speedup_one_process_vs_calls"], 5.0, ">=", "×", "batch")
            if m1 is False and not args.no_profile and "batch" not in prof:
                folder = tmp / "batch"
                ins = sorted(folder.glob("im*.png"))[:c["images"]]
                argv = [str(x) for p in ins for x in (p, folder / "out" / f"p_{p.name}")]
                log("profile: batch …")
                prof["batch"] = {"cprofile_one_process_loop": cprofile_top([str(SCRIPTS / "pyramid_batch.py"), *argv],
                                                                           lines=28)}
                if b.get("cli_accepts_many_inputs"):
                    prof["batch"]["cprofile_cli_batch"] = cprofile_top(
                        ["-m", "pyramid_cli.cli", "blur", "--levels", "5", "--backend", "gl", "-q", "--force",
                         *[str(p) for p in ins], "-o", str(folder / "out" / "q{stem}.png")], lines=28)
    g = scs.get("gpu")
    half = next((c for c in (g or {}).get("cases", []) if c["format"] == "RGBA16F"), None)
    if half:
        cuda = g["torch"]["device"].startswith("cuda")
        size = "4K" if g["size"] == [2160, 3840] else f"{g['size'][1]}×{g['size'][0]}"
        where = f"torch on {g['torch']['device_name']}, GL on {half['gl_renderer']}"
        m1 = add(f"gpu blur 5 levels, {size} RGBA16F: GL device within 2× a device-to-device copy ({where})",
                 half["ratios"].get("GL device / torch copy"), 2.0, "<=", "×", "gpu")
        m2 = add(f"gpu blur 5 levels, {size} RGBA16F: GL device ≥ 3× faster than the PyTorch conv2d peer ({where})",
                 half["ratios"].get("torch blur / GL device"), 3.0, ">=", "×", "gpu")
        if not cuda:  # the targets are the GPU's: a CPU smoke run measures them but does not judge them
            for t in out[-2:]:
                t["met"] = None
                t["note"] = "torch on the CPU (--torch-device cpu): smoke check, not judged"
        elif (m1 is False or m2 is False) and not args.no_profile:
            prof["gpu"] = {"gl_device_s": half["gl_device_s"],
                           "gl_device_per_pass_sum_s": half["gl_device_per_pass_sum_s"],
                           "per_pass_s": half["gl_pass_s"], "pass_labels": half["pass_labels"],
                           "torch_blur_s": half["torch_blur_s"], "copy_s": half["copy_s"],
                           "gl_renderer": half["gl_renderer"], "notes": half["notes"]}
    cpu_targets(report, add, args)
    s = scs.get("startup")
    if s:
        m = add("pyramid --help < 0.2 s", s["results"]["pyramid --help"]["median_s"], 0.2, "<=", "s", "startup")
        if m is False and not args.no_profile:
            prof["startup"] = {"importtime_help": importtime_top(["-m", "pyramid_cli.cli", "--help"]),
                               "importtime_explain": importtime_top(["-m", "pyramid_cli.cli", "explain",
                                                                     "quadratic *v g"])}


def print_table(report: dict) -> None:
    p = print
    p(f"\nMachine: {machine_line(report['machine'])}")
    p(f"Mode: {'quick' if report['quick'] else 'full'}; times are medians of interleaved repetitions\n")
    scs = report["scenarios"]
    if "filter" in scs:
        f = scs["filter"]
        p(f"== filter (warm, in process), {f['size'][1]}×{f['size'][0]}, {f['reps']} reps")
        for n in f["notes"]:
            p(f"   note: {n}")
        for c in f["cases"]:
            p(f"-- {c['case']}, {c['channels']} ch: {c['passes']} passes, fetches {c['fetches']:g}, "
              f"per output pixel {c['fetches_per_output_pixel']:.2f}, plan bytes {c['plan_bytes'] / 1e6:.0f} MB")
            p(f"   GL upload+run+readback {fmt_s(c['gl_s'])}   split: upload {fmt_s(c['gl_upload_s'])}, "
              f"device {fmt_s(c['gl_device_s'])}, readback+host {fmt_s(c['gl_readback_host_s'])}")
            for k, v in c["results"].items():
                if k.startswith("GL"):
                    continue
                p(f"   {k:34s} {fmt_s(v['median_s'])}   GL/it {fmt_x(c['ratios'].get('GL / ' + k)):>7s}"
                  f"   GL device/it {fmt_x(c['ratios'].get('GL device / ' + k)):>7s}")
            for s in c["skipped_peers"]:
                p(f"   {s:34s} skipped (library missing)")
    if "e2e" in scs:
        e = scs["e2e"]
        p(f"\n== end to end (fresh process), {e['size'][1]}×{e['size'][0]}, {e['reps']} reps")
        for c in e["cases"]:
            p(f"-- {c['case']} ({c['file_bytes'] / 1e6:.1f} MB)")
            for k, v in c["results"].items():
                r = c["ratios"].get(f"pyramid / {k}")
                mb = c.get("peak_rss_mb", {}).get(k)
                p(f"   {k:38s} {fmt_s(v['median_s'])}" + (f"  peak {mb:.0f} MB" if mb else "")
                  + (f"   pyramid/it {fmt_x(r)}" if r else ""))
    if "batch" in scs:
        b = scs["batch"]
        p(f"\n== batch, {b['image']}, {b['reps']} reps")
        for c in b["cases"]:
            ext = f" (extrapolated from {c['calls_extrapolated_from']})" if c["calls_extrapolated_from"] else ""
            if "cli_batch_wall_s" in c:
                p(f"-- {c['images']} images: CLI batch `pyramid blur IN… -o T` {fmt_s(c['cli_batch_wall_s'])} wall, "
                  f"{fmt_s(c['cli_batch_per_image_s'])}/image vs OIIO loop {fmt_s(c['read_write_wall_per_image_s'])}"
                  f"/image (both wall/N) → {fmt_x(c['per_image_ratio_vs_read_write'])}; "
                  f"{fmt_x(c['speedup_one_process_vs_calls'])} faster than one call each")
            p(f"-- {c['images']} images: loop script {fmt_s(c['one_process_wall_s'])} wall, "
              f"{fmt_s(c['one_process_per_image_s'])}/image; OIIO read+write {fmt_s(c['read_write_per_image_s'])}"
              f"/image ({fmt_x(c.get('loop_per_image_ratio_vs_read_write', c['per_image_ratio_vs_read_write']))}); "
              f"one call each {fmt_s(c['calls_wall_s'])}"
              f"{ext} → {fmt_x(c['calls_wall_s'] / c['one_process_wall_s'])} faster in one process")
    if "startup" in scs:
        s = scs["startup"]
        p(f"\n== start-up, {s['reps']} reps")
        for k, v in s["results"].items():
            p(f"   {k:34s} {fmt_s(v['median_s'])}")
    g = scs.get("gpu")
    if g and "cases" in g:
        tg = g["torch"]
        p(f"\n== gpu (warm, in process), {g['size'][1]}×{g['size'][0]} RGBA, {g['reps']} reps; torch {tg['version']} "
          f"on {tg['device']} ({tg['device_name']})")
        for n in g["notes"]:
            p(f"   note: {n}")
        for c in g["cases"]:
            p(f"-- {c['case']}: {c['passes']} passes, GL {c['gl_precision']} on {c['gl_renderer'] or 'unavailable'}")
            for n in c["notes"]:
                p(f"   note: {n}")
            for k, v in c["results"].items():
                shown = v["median_s"]
                if k.startswith("GL device") or k.startswith("GL split"):
                    shown = v.get("parts_median_s", {}).get("device", shown)
                    k += " [device]"
                p(f"   {k:50s} {fmt_s(shown)}")
            p("   " + "; ".join(f"{k} {fmt_x(v)}" for k, v in c["ratios"].items()))
    print_cpu(report)
    p("\n== targets")
    for t in report["targets"]:
        mark = {True: "MET   ", False: "MISSED", None: "n/a   "}[t["met"]]
        val = "—" if t["value"] is None else f"{t['value']:.3g}{t['unit']}"
        p(f"   {mark} {t['target']}: {val} (target {t['op']} {t['limit']}{t['unit']})"
          + (f" [{t['note']}]" if t.get("note") else ""))
    for s in report["skipped"]:
        p(f"   skipped: {s}")
    if report["profiles"]:
        p("\n== profiles of misses (full text in the JSON under 'profiles')")
        fb = report["profiles"].get("filter_blur")
        if fb:
            sp = fb["split_median_s"]
            p("   blur: " + ", ".join(f"{k} {fmt_s(v).strip()}" for k, v in sp.items()))
            if fb["per_pass_s"]:
                p("   blur per pass (ms): " + " ".join(f"{x * 1e3:.0f}" for x in fb["per_pass_s"]))
        for name, pr in report["profiles"].get("e2e", {}).items():
            p(f"   e2e {name}: " + ", ".join(f"{k} {v * 1e3:.0f} ms" for k, v in pr["split_s"].items()))
        gp = report["profiles"].get("gpu")
        if gp:
            p(f"   gpu RGBA16F blur: GL device {fmt_s(gp['gl_device_s']).strip()} (per-pass sum "
              f"{fmt_s(gp['gl_device_per_pass_sum_s']).strip()}), torch {fmt_s(gp['torch_blur_s']).strip()}, "
              f"copy {fmt_s(gp['copy_s']).strip()}")
            if gp["per_pass_s"]:
                p("   gpu per pass (ms): " + " ".join(f"{x * 1e3:.2f}" for x in gp["per_pass_s"]))
        if "startup" in report["profiles"]:
            p("   --help slowest imports (cumulative):")
            for ln in report["profiles"]["startup"]["importtime_help"][:6]:
                p(f"     {ln}")


# ====================================================================== main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small sizes and few repetitions (seconds, for CI)")
    ap.add_argument("--json", default=str(ROOT / "bench" / "results" / "latest.json"), help="where to write JSON")
    ap.add_argument("--only", default=None,
                    help=f"comma-separated scenarios among {', '.join(SCENARIOS)} "
                         "(default: all but gpu, which joins when torch sees a CUDA device)")
    ap.add_argument("--case", action="append", help="filter scenario: only cases whose name contains this")
    ap.add_argument("--reps", type=int, help="repetitions per contender (default: by mode)")
    ap.add_argument("--no-profile", action="store_true", help="do not profile missed targets")
    ap.add_argument("--torch-device", default="cuda",
                    help="gpu scenario: torch device of the peer and the copy (default cuda; 'cpu' for a smoke check "
                         "where there is no GPU: the targets are then measured, not judged)")
    args = ap.parse_args(argv)
    only = [s.strip() for s in (args.only or ",".join(default_scenarios())).split(",") if s.strip()]
    bad = [s for s in only if s not in SCENARIOS]
    if bad:
        ap.error(f"unknown scenario(s) {bad}; choose from {SCENARIOS}")
    libs, missing = peers()
    for m in missing:
        log(f"bench: warning: {m}")
    report = {"schema": 1, "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
              "command": " ".join([Path(sys.argv[0]).name, *(argv if argv is not None else sys.argv[1:])]),
              "quick": args.quick, "only": only, "machine": machine_info(), "scenarios": {}, "targets": [],
              "skipped": list(missing), "profiles": {}}
    t_start = perf()
    with tempfile.TemporaryDirectory(prefix="pyramid-bench-") as td:
        tmp = Path(td)
        for name in only:
            try:
                if name == "filter":
                    scenario_filter(args, libs, report)
                elif name == "e2e":
                    scenario_e2e(args, libs, report, tmp)
                elif name == "batch":
                    scenario_batch(args, libs, report, tmp)
                elif name == "startup":
                    scenario_startup(args, libs, report)
                elif name == "gpu":
                    scenario_gpu(args, libs, report)
                elif name == "cluster":
                    __import__("cluster").scenario_cluster(args, report, tmp)
                elif name == "cpu":
                    scenario_cpu(args, libs, report, tmp)
            except Exception as e:  # noqa: BLE001 - one broken scenario must not lose the others
                report["skipped"].append(f"{name}: failed: {type(e).__name__}: {' '.join(str(e).split())[:500]}")
                log(f"bench: {name} failed: {e}")
        targets(report, args, tmp)
    report["elapsed_s"] = perf() - t_start
    print_table(report)
    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp_json = out.with_name(out.name + ".tmp")
    tmp_json.write_text(json.dumps(report, indent=1, ensure_ascii=False, default=str) + "\n")
    os.replace(tmp_json, out)
    print(f"\nwrote {out} ({report['elapsed_s']:.0f} s)")
    failed = [s for s in report["skipped"] if ": failed:" in s]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
