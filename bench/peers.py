#!/usr/bin/env python3
"""``pyramid`` against the tools a user would pick instead (issue 24's table), fresh processes, interleaved.

    python bench/peers.py                         # every job, 4K, 5 repeats: bench/results/peers-DATE.json + .png
    python bench/peers.py --quick                 # tiny pictures, 1 repeat, no warm-up (a smoke run, seconds)
    python bench/peers.py --only png-blur,exr-blur --repeat 9
    python bench/peers.py --pyramid-tree /work/main   # also time another checkout's code, interleaved with this one
    python bench/peers.py --profile png-blur      # pyramid for that job under cProfile: the top entries

Jobs (see ``JOBS``; outputs in the same format and compression as the peer's):

* ``png-blur``: ``pyramid blur --sigma 8 --compression 6`` of a 4K 8-bit RGB PNG against libvips
  ``gaussblur`` 8 (``bench/scripts/vips_blur.py``: a fresh interpreter importing pyvips, as a user's
  script; ``pngsave compression=6``, both zlib level 6); ``png-blur-unfiltered``: the same with
  ``--compression 6:none``, PNG rows unfiltered as libvips writes them (``pyramid``'s default filters them);
* ``tiff-blur``: the same on a 4K float RGB TIFF (deflate) against libvips (``tiffsave compression=deflate``);
  both blurs have the bare OpenImageIO read+write of their input (``bench/scripts/io_floor.py``) beside them;
* ``exr-blur``: ``pyramid blur --levels 5`` of a 4K RGBA half EXR (zip) against ``oiiotool IN -o OUT``;
* ``png-mipmap`` / ``exr-mipmap``: ``pyramid mipmap --tile 64 --compression zip`` of the 4K PNG (to ``.tx``)
  and of the 4K half EXR (to a tiled EXR) against ``maketx --tile 64 64 --compression zip`` (each tool's
  default filter: pyramid's quadratic ⊗↓, maketx's 2×2 box);
* ``cpu-opencv``: in one warm process, the CPU executor's 4K RGBA float32 ``blur --levels 5`` against
  OpenCV's pyrDown⁵/pyrUp⁵ (``bench/scripts/cpu_blur.py``, 15 interleaved runs each), in one such process per
  checkout and repetition, the checkouts interleaved; the medians pool every process's runs;
* ``backend-1080p`` / ``backend-4k`` / ``backend-batch``: ``pyramid blur --levels 5`` with ``--backend auto``,
  ``cpu`` and ``gl`` on one half EXR at 1080p and 4K, and on 50 half EXRs of 512² in one call.

Each repetition runs every contender of a job once, in an order rotated by the repetition (A B, B A, …), each in a
fresh process launched by ``bench/scripts/peak_rss.py`` (its time from fork to exit, its peak RSS and CPU seconds
from ``os.wait4``); the first round is a dropped warm-up (numba's kernel cache, the page cache). Medians are
reported with the ratio pyramid/peer and PASS/MISS against the issue's targets (``TARGETS``), never asserted; the
CPU seconds' ratio has no target. A peer that is not installed is a ``skipped`` entry, not a failure. Inputs are
made once, deterministically (smooth content plus noise, so compression does real work), under ``--data``.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import shlex
import shutil
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from run import ROOT, SCRIPTS, cmd_time_cpu_peak_rss, interleaved, log, machine_info, wait_for_kernel_builds  # noqa: E402

BIN = Path(sys.executable).parent
SIZES = {"4k": (2160, 3840), "1080p": (1080, 1920), "tile": (512, 512)}
QUICK_SIZES = {"4k": (90, 160), "1080p": (45, 80), "tile": (32, 32)}
BATCH, QUICK_BATCH = 50, 3
# The targets: pyramid / peer, medians of fresh processes (the backend jobs: auto / the faster of cpu, gl).
TARGETS = {
    "png-blur": {"time": 1.25, "memory": 4.0},
    "png-blur-unfiltered": {"time": 1.25, "memory": 4.0},
    "tiff-blur": {"time": 1.6, "memory": 3.0},
    "exr-blur": {"time": 1.15, "memory": 1.5},
    "png-mipmap": {"time": 0.8, "memory": 1.0},
    "exr-mipmap": {"time": 0.8, "memory": 1.0},
    "cpu-opencv": {"time": 0.7},
    "backend-1080p": {"time": 1.1},
    "backend-4k": {"time": 1.1},
    "backend-batch": {"time": 1.1},
}
BACKEND_JOBS = ("backend-1080p", "backend-4k", "backend-batch")
DEFAULT_PYRAMID = f"{shlex.quote(sys.executable)} -m pyramid_cli.cli"


# ====================================================================== inputs
def content(rows: int, cols: int, channels: int, seed: int, band: tuple[int, int] | None = None) -> np.ndarray:
    """Smooth colour (a few low-frequency waves) plus a little Gaussian noise, float32 in about [0, 1].

    ``band`` (y0, y1): only those rows of the ``rows``-high picture (its noise seeded by ``seed`` and y0), so
    that bench/tiles.py can write pictures too big to hold whole."""
    y = np.linspace(0, 1, rows, dtype=np.float32)[slice(*band) if band else slice(None), None]
    x = np.linspace(0, 1, cols, dtype=np.float32)[None, :]
    waves = [0.5 + 0.3 * np.sin(2 * np.pi * (3 * x + y)), 0.5 + 0.3 * np.cos(2 * np.pi * (2 * y - x)),
             0.2 + 0.6 * x * y, np.ones_like(x * y)]
    img = np.stack(waves[:channels], -1)
    rng = np.random.default_rng([seed, band[0]] if band else seed)
    noise = rng.normal(0, 0.02, (y.shape[0], cols, min(channels, 3))).astype(np.float32)
    img[..., :3] += noise
    return np.clip(img, 0, 1)


def make_file(path: Path, rows: int, cols: int, kind: str, seed: int = 1) -> Path:
    """Write one input once (atomically): ``png`` 8-bit RGB, ``tiff`` float RGB deflate, ``exr`` RGBA half zip."""
    import OpenImageIO as oiio

    if path.exists():
        return path
    channels, fmt = {"png": (3, "uint8"), "tiff": (3, "float"), "exr": (4, "half")}[kind]
    px = content(rows, cols, channels, seed)
    data = {"uint8": lambda: np.rint(px * 255).astype(np.uint8), "float": lambda: px,
            "half": lambda: px.astype(np.float16)}[fmt]()
    spec = oiio.ImageSpec(cols, rows, channels, fmt)
    if kind != "png":
        spec.attribute("compression", "zip")
    if kind == "exr":
        spec.channelnames, spec.alpha_channel = ("R", "G", "B", "A"), 3
    tmp = path.with_name(f".{path.stem}.{os.getpid()}{path.suffix}")
    out = oiio.ImageOutput.create(str(tmp))
    if out is None or not out.open(str(tmp), spec) or not out.write_image(data) or not out.close():
        raise RuntimeError(f"cannot write {tmp}: {oiio.geterror()}")
    os.replace(tmp, path)
    return path


def make_inputs(data: Path, quick: bool) -> dict[str, Path]:
    """The inputs the jobs read, made once under ``data`` (file names carry the size)."""
    sizes = QUICK_SIZES if quick else SIZES
    data.mkdir(parents=True, exist_ok=True)
    files = {}
    for key, (size, kind) in {"png": ("4k", "png"), "tiff": ("4k", "tiff"), "exr": ("4k", "exr"),
                              "exr1080": ("1080p", "exr")}.items():
        rows, cols = sizes[size]
        files[key] = make_file(data / f"v1_{kind}_{cols}x{rows}.{'tif' if kind == 'tiff' else kind}", rows, cols, kind)
    rows, cols = sizes["tile"]
    n = QUICK_BATCH if quick else BATCH
    batch = data / f"v1_batch_{n}x{cols}x{rows}"
    batch.mkdir(exist_ok=True)
    for i in range(n):
        make_file(batch / f"tile_{i:03d}.exr", rows, cols, "exr", seed=100 + i)
    files["batch"] = batch
    return files


# ====================================================================== contenders
@dataclass
class Pyramid:
    """One ``pyramid`` to time: a command prefix and the environment it runs in."""
    label: str
    argv: list[str]
    env: dict | None = None
    tree: str | None = None


def pyramids(args) -> list[Pyramid]:
    """This checkout's ``pyramid`` (or ``--pyramid CMD``) and one more per ``--pyramid-tree``."""
    # PYTHONSAFEPATH: `python -m` would put the working folder first on sys.path, ahead of PYTHONPATH, and
    # time the checkout the bench was started from under every label (Python 3.11+; 3.10 has no -m from elsewhere)
    # PYTHONDONTWRITEBYTECODE dropped: a package pip installed has its modules compiled, and a tree timed without
    # bytecode compiles every module in every run (an 8K Deep Zoom took 0.3–0.5 s longer, 2026-11-28); the dropped
    # warm-up round writes it
    base = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    here = dict(base, PYTHONSAFEPATH="1",
                PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    out = [Pyramid("pyramid", shlex.split(args.pyramid), here if args.pyramid == DEFAULT_PYRAMID else None,
                   str(ROOT) if args.pyramid == DEFAULT_PYRAMID else None)]
    for tree in args.pyramid_tree or []:
        t = Path(tree).resolve()
        if not (t / "pyramid_cli").is_dir():
            raise SystemExit(f"peers: --pyramid-tree {tree}: no pyramid_cli/ there")
        env = dict(base, PYTHONSAFEPATH="1", PYTHONPATH=str(t))
        out.append(Pyramid(f"pyramid@{t.name}", shlex.split(DEFAULT_PYRAMID), env, str(t)))
    return out


def tool(name: str) -> str | None:
    """An OpenImageIO command-line tool: the one beside this interpreter (the wheel's), else on PATH."""
    exe = BIN / name
    return str(exe) if exe.exists() else shutil.which(name)


def have_module(name: str) -> str | None:
    """None when ``name`` imports here, else why not (with how to install it)."""
    try:
        __import__(name)
    except Exception as e:  # noqa: BLE001 - pyvips raises OSError/ImportError without libvips
        return f"{name} is not installed ({' '.join(str(e).split())[:160]}); pip install -e '.[bench]'"
    return None


@dataclass
class Job:
    """One row of the table: our command(s) after the ``pyramid`` prefix, and the peer's whole command."""
    id: str
    what: str
    peer: str
    ours: dict[str, list[str]]
    peer_argv: list[str] | None = None
    skipped: str | None = None  # why the peer is not run
    extras: dict[str, list[str]] = field(default_factory=dict)  # for scale, no target (e.g. the I/O floor)


def jobs(files: dict[str, Path], out: Path) -> list[Job]:
    """The fresh-process jobs, their outputs under ``out``; ``{o}`` in a command is its contender's output."""
    png, tif, exr, exr1080, batch = (str(files[k]) for k in ("png", "tiff", "exr", "exr1080", "batch"))
    vips = [sys.executable, str(SCRIPTS / "vips_blur.py"), "8"]
    no_vips = have_module("pyvips")
    maketx, oiiotool = tool("maketx"), tool("oiiotool")
    mk = ["--tile", "64", "64", "--compression", "zip"]
    pyr_mip = ["mipmap", "-q", "--tile", "64", "--compression", "zip"]
    blur5 = ["blur", "-q", "--levels", "5"]
    found = {"maketx": maketx, "oiiotool": oiiotool}
    missing = {k: None if v else f"{k} not found (it ships in the OpenImageIO wheel)" for k, v in found.items()}
    backends = {"auto": [], "cpu": ["--backend", "cpu"], "gl": ["--backend", "gl"]}
    return [
        Job("png-blur", "blur sigma 8, 4K 8-bit RGB PNG (zlib level 6)", "libvips gaussblur 8 (pyvips)",
            {"": ["blur", "-q", "--sigma", "8", "--compression", "6", png, "{o}.png"]},
            [*vips, png, "{o}.png"], no_vips,
            {"OIIO read+write (floor)": [sys.executable, str(SCRIPTS / "io_floor.py"), png, "{o}.png"]}),
        Job("png-blur-unfiltered", "the same, PNG rows unfiltered as libvips writes them",
            "libvips gaussblur 8 (pyvips)",
            {"": ["blur", "-q", "--sigma", "8", "--compression", "6:none", png, "{o}.png"]},
            [*vips, png, "{o}.png"], no_vips),
        Job("tiff-blur", "blur sigma 8, 4K float RGB TIFF (deflate)", "libvips gaussblur 8 (pyvips, deflate)",
            {"": ["blur", "-q", "--sigma", "8", "--compression", "zip", tif, "{o}.tif"]},
            [*vips, tif, "{o}.tif"], no_vips,
            {"OIIO read+write (floor)": [sys.executable, str(SCRIPTS / "io_floor.py"), tif, "{o}.tif"]}),
        Job("exr-blur", "blur --levels 5, 4K RGBA half EXR (zip)", "oiiotool IN -o OUT (a plain copy)",
            {"": [*blur5, exr, "{o}.exr"]}, [oiiotool or "oiiotool", exr, "-o", "{o}.exr"], missing["oiiotool"]),
        Job("png-mipmap", "mipmap, 4K 8-bit PNG to .tx (tile 64, zip)", "maketx --tile 64 64 --compression zip",
            {"": [*pyr_mip, png, "{o}.tx"]}, [maketx or "maketx", png, "-o", "{o}.tx", *mk], missing["maketx"]),
        Job("exr-mipmap", "mipmap, 4K RGBA half EXR (tile 64, zip)", "maketx --tile 64 64 --compression zip",
            {"": [*pyr_mip, exr, "{o}.exr"]}, [maketx or "maketx", exr, "-o", "{o}.exr", *mk], missing["maketx"]),
        Job("backend-1080p", "blur --levels 5, 1080p RGBA half EXR", "the faster of --backend cpu and gl",
            {k: [*blur5, *v, exr1080, "{o}.exr"] for k, v in backends.items()}),
        Job("backend-4k", "blur --levels 5, 4K RGBA half EXR", "the faster of --backend cpu and gl",
            {k: [*blur5, *v, exr, "{o}.exr"] for k, v in backends.items()}),
        Job("backend-batch", f"blur --levels 5, {len(list(Path(batch).glob('*.exr')))} half EXRs in one call",
            "the faster of --backend cpu and gl",
            {k: [*blur5, *v, f"{batch}/*.exr", "-o", "{o}/{stem}.exr"] for k, v in backends.items()}),
    ]


# ====================================================================== measuring
class Runs:
    """One contender's fresh-process runs (seconds, MiB, CPU seconds), or why it could not run."""

    def __init__(self, argv: list[str], out: Path, env: dict | None = None):
        self.argv, self.out, self.env, self.runs, self.error = argv, out, env, [], None

    def __call__(self, keep: bool = True) -> None:
        if self.error:
            return
        try:
            run = cmd_time_cpu_peak_rss(self.argv, self.env)
        except RuntimeError as e:
            self.error = " ".join(str(e).split())[:400]
            return
        if keep:
            self.runs.append(run)

    def summary(self) -> dict:
        if self.error or not self.runs:
            return {"error": self.error or "no run"}
        written = [f for f in self.out.parent.iterdir() if f.name == self.out.name or
                   f.name.startswith(self.out.name + ".")]
        written += [f for d in written if d.is_dir() for f in d.iterdir()]
        return {"median_s": statistics.median(t for t, _, _ in self.runs),
                "peak_rss_mib": statistics.median(m for _, m, _ in self.runs),
                "median_cpu_s": statistics.median(c for _, _, c in self.runs), "runs": self.runs,
                "output_bytes": sum(f.stat().st_size for f in written if f.is_file())}


def outputs(argv: list[str], out: Path) -> list[str]:
    """``argv`` with ``{o}`` naming ``out`` (a batch template's folder is created)."""
    if any("{o}/" in a for a in argv):
        out.mkdir(parents=True, exist_ok=True)
    return [a.replace("{o}", str(out)) for a in argv]


def verdict(ratio: float | None, limit: float | None) -> str:
    if ratio is None or limit is None:
        return "n/a"
    return "PASS" if ratio <= limit else "MISS"


def ratio_entry(job_id: str, metric: str, ratio: float | None, targets: dict | None = None) -> dict:
    limit = (TARGETS if targets is None else targets).get(job_id, {}).get(metric)
    return {"ratio": ratio, "target": limit, "verdict": verdict(ratio, limit)}


def measure_job(job: Job, pyrs: list[Pyramid], out: Path, args, targets: dict | None = None,
                runs: type[Runs] = Runs) -> dict:
    """Interleave every contender of ``job`` (each pyramid × our commands, the peer, the extras); medians, ratios.

    ``targets`` (default :data:`TARGETS`) and ``runs`` (a :class:`Runs` subclass) let bench/tiles.py reuse it.
    """
    folder = out / job.id
    folder.mkdir(parents=True, exist_ok=True)
    cons: dict[str, Runs] = {}
    for p in pyrs:
        for label, a in job.ours.items():
            name = f"{p.label} {label}".strip()
            o = folder / name.replace(" ", "_").replace("@", "_")
            cons[name] = runs(p.argv + outputs(a, o), o, p.env)
    if job.peer_argv and not job.skipped:
        cons["peer"] = runs(outputs(job.peer_argv, folder / "peer"), folder / "peer")
    for label, a in job.extras.items():
        o = folder / label.split()[0]
        cons[label] = runs(outputs(a, o), o)
    loads = [os.getloadavg()[0]]
    for _ in range(args.warmup):  # dropped: the kernel cache, the page cache
        for c in cons.values():
            c(keep=False)
    if args.warmup:
        wait_for_kernel_builds()  # kernels the warm-up ran through numba are built ahead of time first
    interleaved({n: (lambda c=c: c()) for n, c in cons.items()}, reps=args.repeat, warmup=0)
    loads.append(os.getloadavg()[0])
    res = {"id": job.id, "what": job.what, "peer": job.peer, "load_avg": loads,
           "contenders": {n: c.summary() | {"argv": c.argv} for n, c in cons.items()}, "rows": []}
    if job.skipped:
        res["skipped"] = job.skipped
    for p in pyrs:
        res["rows"].append(job_row(job, p.label, res["contenders"], targets))
    return res


def job_row(job: Job, label: str, cons: dict, targets: dict | None = None) -> dict:
    """One pyramid's line of a job: its time and memory, the peer's, the ratios and verdicts."""
    def med(name, key):
        return cons.get(name, {}).get(key)

    if job.id in BACKEND_JOBS:
        mine = {k: med(f"{label} {k}", "median_s") for k in job.ours}
        best = min((v for k, v in mine.items() if k != "auto" and v), default=None)
        ratio = mine["auto"] / best if mine["auto"] and best else None
        return {"pyramid": label, "times_s": mine, "memory_mib": {k: med(f"{label} {k}", "peak_rss_mib")
                                                                  for k in job.ours},
                "time": ratio_entry(job.id, "time", ratio, targets)}
    t, m, c = med(label, "median_s"), med(label, "peak_rss_mib"), med(label, "median_cpu_s")
    pt, pm, pc = med("peer", "median_s"), med("peer", "peak_rss_mib"), med("peer", "median_cpu_s")
    return {"pyramid": label, "pyramid_s": t, "pyramid_mib": m, "pyramid_cpu_s": c, "peer_s": pt, "peer_mib": pm,
            "peer_cpu_s": pc, "time": ratio_entry(job.id, "time", t / pt if t and pt else None, targets),
            "memory": ratio_entry(job.id, "memory", m / pm if m and pm else None, targets),
            "cpu": ratio_entry(job.id, "cpu", c / pc if c and pc else None, targets)}


def measure_cpu_opencv(pyrs: list[Pyramid], args) -> dict:
    """The in-process job: ``bench/scripts/cpu_blur.py`` once per checkout (this one for ``--pyramid CMD``)."""
    rows, cols = (QUICK_SIZES if args.quick else SIZES)["4k"]
    res = {"id": "cpu-opencv", "what": f"warm in-process blur --levels 5, {cols}×{rows} RGBA float32, CPU executor",
           "peer": "OpenCV pyrDown⁵/pyrUp⁵", "rows": [], "runs": {}}
    why = have_module("cv2")
    if why:
        res["skipped"] = why
        return res
    # one process per checkout and round, the checkouts interleaved (A B, B A, …): a process's ratio moves with the
    # machine's state (other tenants, the kernel's page zeroing), so the medians pool every round's runs
    rounds = 1 if args.quick else max(args.repeat, 1)
    pooled: dict[str, dict[str, list[float]]] = {p.label: {"pyramid": [], "opencv": []} for p in pyrs}
    for k in range(rounds):
        for p in (pyrs if k % 2 == 0 else pyrs[::-1]):
            if p.label in res["runs"] and "error" in res["runs"][p.label]:
                continue
            proc = subprocess.run([sys.executable, str(SCRIPTS / "cpu_blur.py"), str(rows), str(cols), "15"],
                                  capture_output=True, text=True, env=p.env)
            if proc.returncode:
                res["runs"][p.label] = {"error": proc.stderr.strip()[-400:]}
                continue
            doc = json.loads(proc.stdout.strip().splitlines()[-1])
            res["runs"].setdefault(p.label, {"processes": []})["processes"].append(doc)
            for name in ("pyramid", "opencv"):
                pooled[p.label][name] += doc["results"][name]["runs_s"]
    for p in pyrs:
        if "error" in res["runs"].get(p.label, {}):
            res["rows"].append({"pyramid": p.label, "error": res["runs"][p.label]["error"]})
            continue
        t, pt = (statistics.median(pooled[p.label][n]) for n in ("pyramid", "opencv"))
        res["rows"].append({"pyramid": p.label, "pyramid_s": t, "pyramid_mib": None, "peer_s": pt, "peer_mib": None,
                            "time": ratio_entry("cpu-opencv", "time", t / pt)})
    return res


# ====================================================================== report
def versions(tools: tuple[str, ...] = ("maketx", "oiiotool"), numba: bool = True) -> dict:
    """The peers' and pyramid's libraries (machine_info has numpy, OpenImageIO, OpenCV, moderngl): libvips, and
    ``numba`` and the OpenImageIO ``tools`` unless told otherwise (bench/tiles.py needs only libvips)."""
    v = {}
    try:
        import pyvips

        v["pyvips"] = pyvips.__version__
        v["libvips"] = ".".join(str(pyvips.version(i)) for i in range(3))
    except Exception as e:  # noqa: BLE001 - reported, not fatal
        v["pyvips"] = v["libvips"] = None
        v["pyvips_error"] = " ".join(str(e).split())[:160]
    try:
        v["numba"] = __import__("numba").__version__ if numba else None
    except ImportError:
        v["numba"] = None
    for name in tools:
        exe = tool(name)
        v[name] = exe and subprocess.run([exe, "--version"], capture_output=True, text=True).stdout.strip()
    return v


def fmt(v: float | None, unit: str) -> str:
    if v is None:
        return "—"
    return f"{v:.3f} s" if unit == "s" else f"{v:.0f} MiB" if unit == "MiB" else f"{v:.2f}×"


def table_lines(report: dict) -> list[str]:
    """The table printed at the end (and kept in the JSON): one line per job and pyramid."""
    lines = [f"{'job':15s} {'pyramid':18s} {'time':>9s} {'mem':>8s} {'peer time':>10s} {'peer mem':>9s} "
             f"{'t ratio':>8s} {'target':>7s}      {'m ratio':>8s} {'target':>7s}      {'cpu ratio':>9s}"]
    for j in report["jobs"]:
        if not j["rows"]:
            lines.append(f"{j['id']:15s} skipped: {j.get('skipped')}")
        for name, c in j.get("contenders", {}).items():
            if not name.startswith(("pyramid", "peer")) and "median_s" in c:  # a floor, for scale
                lines.append(f"{j['id']:15s} {name[:18]:18s} {fmt(c['median_s'], 's'):>9s} "
                             f"{fmt(c['peak_rss_mib'], 'MiB'):>8s}")
        for r in j["rows"]:
            if "error" in r:
                lines.append(f"{j['id']:15s} {r['pyramid']:18s} failed: {r['error'][:80]}")
                continue
            t, m = r["time"], r.get("memory", {})
            if "times_s" in r:
                ts = r["times_s"]
                mine, peer = fmt(ts.get("auto"), "s"), f"cpu {fmt(ts.get('cpu'), 's')} gl {fmt(ts.get('gl'), 's')}"
                lines.append(f"{j['id']:15s} {r['pyramid']:18s} {mine:>9s} {'':>8s} {peer:>20s}"
                             f"{fmt(t['ratio'], 'x'):>8s} {'≤' + str(t['target']):>7s} {t['verdict']:4s}")
                continue
            lines.append(f"{j['id']:15s} {r['pyramid']:18s} {fmt(r['pyramid_s'], 's'):>9s} "
                         f"{fmt(r['pyramid_mib'], 'MiB'):>8s} {fmt(r['peer_s'], 's'):>10s} "
                         f"{fmt(r['peer_mib'], 'MiB'):>9s} {fmt(t['ratio'], 'x'):>8s} "
                         f"{'≤' + str(t['target']):>7s} {t['verdict']:4s} {fmt(m.get('ratio'), 'x'):>8s} "
                         f"{('≤' + str(m['target'])) if m.get('target') else '':>7s} {m.get('verdict', ''):4s} "
                         f"{fmt(r.get('cpu', {}).get('ratio'), 'x'):>9s}")
    return lines


def plot(report: dict, path: Path) -> str | None:
    """Time and memory ratios per job, each against its target (matplotlib, from the bench extra)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return "matplotlib is not installed (pip install -e '.[bench]'): no plot"
    bars = [(f"{j['id']} ({r['pyramid']})", metric, r[metric]) for j in report["jobs"] for r in j["rows"]
            for metric in ("time", "memory") if r.get(metric, {}).get("ratio")]
    if not bars:
        return "nothing measured: no plot"
    fig, ax = plt.subplots(figsize=(9, 0.45 * len(bars) + 1.5))
    ys = np.arange(len(bars))[::-1]
    for y, (_, metric, e) in zip(ys, bars, strict=True):
        ax.barh(y, e["ratio"], color={"PASS": "tab:green", "MISS": "tab:red"}.get(e["verdict"], "tab:gray"),
                hatch="//" if metric == "memory" else None, edgecolor="black", linewidth=0.5)
        if e["target"]:
            ax.plot([e["target"]] * 2, [y - 0.45, y + 0.45], color="black", linewidth=2)
        ax.text(e["ratio"], y, f" {e['ratio']:.2f}×", va="center", fontsize=8)
    ax.set_yticks(ys, [f"{name}: {metric}" for name, metric, _ in bars], fontsize=8)
    ax.axvline(1, color="gray", linestyle=":", linewidth=1)
    ax.set_xscale("log")
    ax.set_xlabel("pyramid / peer (median of fresh processes; black tick: the issue's target)")
    ax.set_title(f"pyramid against its peers, {report['created'][:10]}, load {report['load_avg']['start']:.1f}"
                 f"–{report['load_avg']['end']:.1f} on {report['machine'].get('cores_usable', '?')} cores")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return None


# ====================================================================== profile
def profile(job_id: str, job: Job | None, pyr: Pyramid, data: Path, out_txt: Path, lines: int = 30) -> dict:
    """Our command of ``job_id`` (``auto`` for the backend jobs) once under cProfile in a fresh process."""
    import pstats

    if job is None or pyr.argv[-2:] != ["-m", "pyramid_cli.cli"]:
        raise SystemExit(f"peers: --profile {job_id}: profiles a fresh-process job of `python -m pyramid_cli.cli`")
    a = outputs(job.ours.get("auto", job.ours.get("")), data / "out" / job_id / "profile")
    out_txt.parent.mkdir(parents=True, exist_ok=True)
    stats_file = out_txt.with_suffix(".prof")
    argv = [*pyr.argv[:-2], str(SCRIPTS / "profile_threads.py"), str(stats_file), "pyramid_cli.cli", *a]
    for _ in range(2):  # the first is a warm-up (kernel cache, page cache); the second is kept
        t0 = time.perf_counter()
        p = subprocess.run(argv, env=pyr.env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if p.returncode:
            raise SystemExit(f"peers: --profile {job_id}: {shlex.join(argv)} exited {p.returncode}: "
                             f"{p.stderr.strip()[-600:]}")
    with out_txt.open("w") as f:
        st = pstats.Stats(str(stats_file), stream=f)
        imports = max((v[3] for k, v in st.stats.items() if k[2] == "_find_and_load"), default=0.0)
        waits = sum(v[2] for k, v in st.stats.items() if any(w in k[2] for w in ("acquire", "SimpleQueue", "sleep")))
        f.write(f"# {job_id}: {shlex.join(argv)}\n# wall {wall:.3f} s under the profiler; every Python thread's "
                f"stats merged: imports {imports:.3f} s (cumulative), waits {waits:.3f} s (locks, idle pool threads)\n")
        for key in ("cumulative", "tottime"):
            st.sort_stats(key).print_stats(lines)
        f.write("# the package's own functions and numba's cache loads, by cumulative time: the phases\n")
        st.sort_stats("cumulative").print_stats(r"pyramid_cli|numba/core/caching|\(_find_and_load\)", 2 * lines)
    stats_file.unlink()
    return {"job": job_id, "argv": argv, "wall_s": wall, "imports_s": imports, "waits_s": waits, "text": str(out_txt)}


# ====================================================================== main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ids = [*TARGETS]
    ap.add_argument("--quick", action="store_true", help="tiny pictures, 1 repeat, no warm-up: a smoke run")
    ap.add_argument("--repeat", type=int, help="interleaved rounds per job (default 5; --quick 1)")
    ap.add_argument("--only", help=f"comma-separated jobs among {', '.join(ids)}")
    ap.add_argument("--pyramid", default=DEFAULT_PYRAMID, help="the pyramid command (default: this checkout's)")
    ap.add_argument("--pyramid-tree", action="append", metavar="DIR",
                    help="also time DIR's pyramid_cli (PYTHONPATH=DIR), interleaved; repeatable")
    ap.add_argument("--data", default="/tmp/pyramid-bench-peers", help="where inputs are made once and outputs go")
    ap.add_argument("--json", help="default bench/results/peers-DATE.json (--quick: DATA/peers-quick.json)")
    ap.add_argument("--plot", help="default: the JSON's path with .png")
    ap.add_argument("--profile", metavar="JOB[,JOB]", help="profile pyramid on these jobs (cProfile), nothing else")
    args = ap.parse_args(argv)
    only = (args.only or args.profile or ",".join(ids)).split(",")
    if bad := [j for j in only if j not in ids]:
        ap.error(f"unknown job(s) {bad}; choose from {ids}")
    args.repeat = args.repeat or (1 if args.quick else 5)
    args.warmup = 0 if args.quick else 1
    day = _dt.date.today().isoformat()
    default = Path(args.data) / "peers-quick.json" if args.quick else HERE / "results" / f"peers-{day}.json"
    out_json = Path(args.json or default)  # a smoke run never overwrites the committed results
    pyrs = pyramids(args)
    data = Path(args.data)
    log("peers: making the inputs …")
    files = make_inputs(data, args.quick)
    fresh = {j.id: j for j in jobs(files, data / "out")}
    if args.profile:
        for job_id in only:
            txt = out_json.with_name(f"peers-profile-{job_id}-{day}.txt")
            p = profile(job_id, fresh.get(job_id), pyrs[0], data, txt)
            print(f"{job_id}: {p['wall_s']:.2f} s under cProfile, imports {p['imports_s']:.2f} s: {txt}")
        return 0
    report = {"schema": 1, "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
              "command": shlex.join([Path(sys.argv[0]).name, *(argv if argv is not None else sys.argv[1:])]),
              "quick": args.quick, "repeat": args.repeat, "warmup_rounds_dropped": args.warmup,
              "load_avg": {"start": os.getloadavg()[0]}, "machine": machine_info() | {"versions_peers": versions()},
              "pyramids": [{"label": p.label, "argv": p.argv, "tree": p.tree, "commit": p.tree and subprocess.run(
                  ["git", "-C", p.tree, "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()}
                  for p in pyrs],
              "inputs": {k: {"path": str(v), "bytes": v.stat().st_size if v.is_file() else None}
                         for k, v in files.items()},
              "targets": TARGETS, "jobs": [], "skipped": []}
    for job_id in only:
        log(f"peers: {job_id} …")
        res = measure_cpu_opencv(pyrs, args) if job_id == "cpu-opencv" else measure_job(fresh[job_id], pyrs,
                                                                                        data / "out", args)
        if res.get("skipped"):
            report["skipped"].append(f"{job_id}: {res['skipped']}")
        report["jobs"].append(res)
    report["failed"] = [f"{j['id']}: {r['pyramid']}: {r['error']}" for j in report["jobs"] for r in j["rows"]
                        if "error" in r]
    return finish(report, table_lines, out_json, args.plot)


def finish(report: dict, lines, out_json: Path, plot_path: str | None) -> int:
    """End a bench run (this one's, bench/tiles.py's): the load average at the end, every contender's error added
    to ``report["failed"]``, the table (``lines(report)``) printed and kept, the JSON written, and the plot drawn
    when anything was timed. 1 when anything failed."""
    report["load_avg"]["end"] = os.getloadavg()[0]
    report["failed"] = [f"{j['id']}: {name}: {c['error']}" for j in report["jobs"]
                        for name, c in j.get("contenders", {}).items() if "error" in c] + report.get("failed", [])
    report["table"] = lines(report)
    print("\n".join(report["table"] + [f"failed: {f}" for f in report["failed"]]))
    print(f"load average {report['load_avg']['start']:.1f} at the start, {report['load_avg']['end']:.1f} at the end")
    out_json.parent.mkdir(parents=True, exist_ok=True)
    out_json.write_text(json.dumps(report, indent=1, ensure_ascii=False, default=str) + "\n")
    print(f"wrote {out_json}")
    if report["jobs"]:
        why = plot(report, Path(plot_path or out_json.with_suffix(".png")))
        print(why or f"plot: {plot_path or out_json.with_suffix('.png')}")
    return 1 if report["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
