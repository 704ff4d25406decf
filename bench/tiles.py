#!/usr/bin/env python3
"""``pyramid tiles`` against libvips (issue 27's "What must show"): quality, speed and peak memory.

    python bench/tiles.py                              # everything: bench/results/tiles-DATE.json + .png
    python bench/tiles.py --only quality               # the deterministic part: bench/results/tiles-quality-DATE.json
    python bench/tiles.py --only speed --sizes 8k --repeat 5
    python bench/tiles.py --quick                      # tiny pictures, 1 round, no warm-up (a smoke run, seconds)
    python bench/tiles.py --pyramid-tree /work/main    # also time another checkout's pyramid, interleaved

Parts (``--only``):

* ``quality`` (bench/tiles_quality.py, nothing timed): a zone plate's levels against an ideal band-limited
  reduction, ``vips dzsave``'s against ours, RMS per level in linear light and in codes; a 1-pixel
  checkerboard's mean code (linear light: 188; the 2×2 mean of codes: 128); a red disc on transparent, the
  darkness of its partly transparent edge. Ours is ``pyramid tiles --format png`` when this checkout has the
  command, else ``pyr.pyramid`` with the default MIP analysis encoded as the tiles store it (``--ours``).
* ``speed``: on 8K and 16K 8-bit RGB JPEGs (``--sizes``; square, 8192² and 16384²), ``vips dzsave`` (defaults:
  JPEG Q 75 tiles of 254 with overlap 1) against ``pyramid tiles IN OUT.dzi``, and ``vips tiffsave --tile
  --pyramid`` against ``pyramid tiles IN OUT.tif``, both with ``--tiff-compression`` (JPEG) and
  ``--tiff-tile`` (256). The peers run as a user's pyvips script in a fresh interpreter
  (bench/scripts/vips_tiles.py; pyvips-binary has no ``vips`` executable). JPEG input: the pictures Deep Zoom
  and pyramidal TIFF viewers are fed (stitched panoramas, scans, photographs) mostly arrive as JPEG, and
  PNG's single-threaded zlib decode would dominate both sides at 16K.
* ``flat``: ours alone at ``--flat`` sizes (default 32K) after the speed sizes: peak memory must stay flat.

Timing is bench/peers.py's: each round runs every contender once in a fresh process (order rotated by the round),
through bench/scripts/peak_rss.py (time from fork to exit, peak RSS and CPU seconds from ``os.wait4``), after one
dropped warm-up round; medians, ratios ours / peer against the issue's targets (time ≤ 1.5×, memory ≤ 4×), reported,
never asserted. The ratio of CPU seconds is reported beside them, without a target: on a shared machine it moves
less with the hour than the time does. Every run starts on an empty output folder (the previous run's set aside,
deleted at the end: :func:`set_aside`). Without ``pyramid tiles`` in a checkout, its rows say "not available" and
the peers are still measured.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import peers  # noqa: E402
import tiles_quality  # noqa: E402
from run import SCRIPTS, cmd_time_peak_rss, log, machine_info  # noqa: E402

PARTS = ("quality", "speed", "flat")
SIZES = {"8k": (8192, 8192), "16k": (16384, 16384), "32k": (32768, 32768)}
QUICK_SIZES = {"8k": (150, 200), "16k": (301, 257), "32k": (420, 390)}  # odd sizes: the ⌈n/2⌉ edges
QUALITY = {"zone": 2048, "pattern": 256, "disc": 512}
QUICK_QUALITY = {"zone": 64, "pattern": 32, "disc": 512}  # the disc: dzsave tiles to stitch
TARGET = {"time": 1.5, "memory": 4.0}  # ours / libvips, medians of fresh processes
BAND = 512  # rows per write when making an input
JPEG_QUALITY = 90
NOT_AVAILABLE = "not available: `pyramid tiles` is not a command of this checkout"


# ====================================================================== inputs
def make_input(path: Path, rows: int, cols: int) -> Path:
    """An 8-bit RGB JPEG (quality 90) of peers.content, written once, band by band (a 32K picture is 3 GiB)."""
    import OpenImageIO as oiio

    if path.exists():
        return path
    spec = oiio.ImageSpec(cols, rows, 3, "uint8")
    spec.attribute("Compression", f"jpeg:{JPEG_QUALITY}")
    tmp = path.with_name(f".{path.stem}.{os.getpid()}{path.suffix}")
    out = oiio.ImageOutput.create(str(tmp))
    if out is None or not out.open(str(tmp), spec):
        raise RuntimeError(f"cannot write {tmp}: {oiio.geterror()}")
    for y0 in range(0, rows, BAND):
        y1 = min(rows, y0 + BAND)
        px = peers.content(rows, cols, 3, seed=1, band=(y0, y1))
        if not out.write_scanlines(y0, y1, 0, (px * 255 + 0.5).astype("uint8")):
            raise RuntimeError(f"cannot write {tmp}: {out.geterror()}")
    if not out.close():
        raise RuntimeError(f"cannot write {tmp}: {out.geterror()}")
    os.replace(tmp, path)
    return path


# ====================================================================== contenders
def set_aside(folder: Path) -> None:
    """Move ``folder`` (a run's tile tree) out of the way, into ``.set-aside`` beside it, deleted by
    :func:`clear_aside` when the timing is over. Not deleted now: on ext4 without a journal (these machines'
    disks), a file made within minutes of thousands being deleted first passes over the deleted inodes
    (``recently_deleted`` in the kernel's inode allocator), and the next contender's run paid for the previous
    one's tiles: 0.3-1 s of kernel time in an 8K Deep Zoom, whichever tool wrote it."""
    if folder.exists():
        aside = folder.parent / ".set-aside"
        aside.mkdir(exist_ok=True)
        folder.rename(aside / f"{folder.name}.{len(list(aside.iterdir()))}")


def clear_aside(root: Path) -> None:
    """Delete every ``.set-aside`` folder under ``root`` (:func:`set_aside`)."""
    for aside in root.rglob(".set-aside"):
        shutil.rmtree(aside, ignore_errors=True)


class TileRuns(peers.Runs):
    """peers.Runs on an empty output folder each time (a tile tree is a folder, set aside, not deleted, before the
    next run: :func:`set_aside`), its size counted recursively."""

    def __call__(self, keep: bool = True) -> None:
        set_aside(self.out)
        self.out.mkdir(parents=True)
        super().__call__(keep)

    def summary(self) -> dict:
        s = super().summary()
        if "error" not in s:
            files = [f for f in self.out.rglob("*") if f.is_file()]
            s |= {"output_bytes": sum(f.stat().st_size for f in files), "output_files": len(files)}
        return s


def has_tiles(p: peers.Pyramid) -> bool:
    """Whether ``p`` has the ``tiles`` command (``pyramid tiles --help`` exits 0)."""
    r = subprocess.run([*p.argv, "tiles", "--help"], capture_output=True, text=True, env=p.env)
    return r.returncode == 0


def ours_dz(src: str) -> list[str]:
    """Our Deep Zoom command after the ``pyramid`` prefix: every option at its default (libvips's)."""
    return ["tiles", src, "{o}/out.dzi"]


def ours_tif(src: str, compression: str, tile: int) -> list[str]:
    """Our pyramidal TIFF command: the tile size and compression given to the peer."""
    return ["tiles", src, "{o}/out.tif", "--tile-size", str(tile), "--compression", compression]


def jobs(files: dict[str, Path], args, with_ours: bool) -> list[peers.Job]:
    """The speed jobs, two per size: Deep Zoom against dzsave, pyramidal TIFF against tiffsave."""
    vips = [sys.executable, str(SCRIPTS / "vips_tiles.py")]
    no_vips = peers.have_module("pyvips")
    out = []
    for size, path in files.items():
        src, (h, w) = str(path), (QUICK_SIZES if args.quick else SIZES)[size]
        what = f"{w}×{h} 8-bit RGB JPEG (q {JPEG_QUALITY})"
        comp, tile = args.tiff_compression, args.tiff_tile
        out.append(peers.Job(f"dz-{size}", f"Deep Zoom: JPEG Q 75 tiles 254, overlap 1, of a {what}",
                             "vips dzsave (defaults)", {"": ours_dz(src)} if with_ours else {},
                             [*vips, "dzsave", src, "{o}/out.dzi"], no_vips))
        out.append(peers.Job(f"tif-{size}", f"pyramidal TIFF: {comp} tiles {tile}², of a {what}",
                             f"vips tiffsave --tile --pyramid --compression {comp}",
                             {"": ours_tif(src, comp, tile)} if with_ours else {},
                             [*vips, "tiffsave", src, "{o}/out.tif", comp, str(tile)], no_vips))
    return out


# ====================================================================== parts
def speed(args, pyrs: list[peers.Pyramid], ours: list[peers.Pyramid], data: Path) -> list[dict]:
    """The interleaved fresh-process jobs (peers.measure_job): ours (where available) and the peer."""
    sizes = QUICK_SIZES if args.quick else SIZES
    files = {}
    for s in args.sizes:
        log(f"tiles: making the {s} input …")
        files[s] = make_input(data / f"v1_tiles_{sizes[s][1]}x{sizes[s][0]}.jpg", *sizes[s])
    targets = {f"{kind}-{s}": TARGET for kind in ("dz", "tif") for s in args.sizes}
    res = []
    for job in jobs(files, args, bool(ours)):
        log(f"tiles: {job.id} …")
        if job.skipped:
            res.append({"id": job.id, "what": job.what, "peer": job.peer, "skipped": job.skipped, "rows": []})
            continue
        r = peers.measure_job(job, ours or pyrs[:1], data / "out", args, targets, TileRuns)
        for p in pyrs:
            if p not in ours:
                # its runs failed or never ran: job_row gives the peer's figures, ours and every ratio None
                r["rows"] = [x for x in r["rows"] if x["pyramid"] != p.label] + [
                    peers.job_row(job, p.label, r["contenders"], targets) | {"not_available": NOT_AVAILABLE}]
        res.append(r)
    return res


def flat(args, ours: list[peers.Pyramid], speed_jobs: list[dict], data: Path) -> dict:
    """Ours' peak memory at the speed sizes (their medians) and, one run each, at the ``--flat`` sizes."""
    if not ours:
        return {"skipped": NOT_AVAILABLE}
    sizes = QUICK_SIZES if args.quick else SIZES
    p, res = ours[0], {"pyramid": ours[0].label, "peak_rss_mib": {}, "seconds": {}}
    for j in speed_jobs:
        c = j.get("contenders", {}).get(p.label, {})
        if j["id"].startswith("dz-") and "peak_rss_mib" in c:
            res["peak_rss_mib"][j["id"][3:]], res["seconds"][j["id"][3:]] = c["peak_rss_mib"], c["median_s"]
    for s in args.flat:
        log(f"tiles: ours alone at {s} (one run) …")
        src = make_input(data / f"v1_tiles_{sizes[s][1]}x{sizes[s][0]}.jpg", *sizes[s])
        o = data / "out" / f"flat-{s}"
        set_aside(o)
        o.mkdir(parents=True)
        try:
            t, mib = cmd_time_peak_rss(p.argv + [a.replace("{o}", str(o)) for a in ours_dz(str(src))], p.env)
        except RuntimeError as e:
            res.setdefault("errors", {})[s] = " ".join(str(e).split())[:400]
            continue
        res["peak_rss_mib"][s], res["seconds"][s] = mib, t
    mem = list(res["peak_rss_mib"].values())
    res["largest_over_smallest"] = max(mem) / min(mem) if mem else None
    return res


def size_lines(jobs: list[dict]) -> list[str]:
    """Each job's output size, every contender's (the last run's: tiles and files, as a viewer's server holds them)."""
    lines = []
    for j in jobs:
        sizes = [f"{'libvips' if name == 'peer' else name} {c['output_bytes'] / 1e6:.2f} MB in {c['output_files']} "
                 f"file(s)" for name, c in j.get("contenders", {}).items() if "output_bytes" in c]
        if sizes:
            lines.append(f"{j['id']} output: " + ", ".join(sizes))
    return lines


def summary_lines(report: dict) -> list[str]:
    """What is printed at the end (and kept in the JSON)."""
    lines = []
    if "quality" in report:
        lines += tiles_quality.table_lines(report["quality"])
    if report["jobs"]:
        lines += peers.table_lines(report) + [f"{j['id']}: {r['pyramid']}: {r['not_available']}" for j in
                                              report["jobs"] for r in j["rows"] if "not_available" in r][:1]
        lines += size_lines(report["jobs"])
    if "flat" in report:
        f = report["flat"]
        lines.append("ours' peak memory by size: " + (f.get("skipped") or ", ".join(
            f"{s} {m:.0f} MiB" for s, m in f["peak_rss_mib"].items())))
    return lines


# ====================================================================== main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="tiny pictures, 1 round, no warm-up: a smoke run")
    ap.add_argument("--only", default=",".join(PARTS), help=f"comma-separated parts among {', '.join(PARTS)}")
    ap.add_argument("--sizes", default="8k,16k", help=f"speed inputs among {', '.join(SIZES)} (default 8k,16k)")
    ap.add_argument("--flat", default="32k", help="sizes ours alone runs at for flat memory ('' for none)")
    ap.add_argument("--repeat", type=int, help="interleaved rounds per job (default 3; --quick 1)")
    ap.add_argument("--tiff-compression", default="jpeg", help="both TIFF writers' compression (default jpeg)")
    ap.add_argument("--tiff-tile", type=int, default=256, help="both TIFF writers' tile edge (default 256)")
    ap.add_argument("--ours", choices=("auto", "cli", "api"), default="auto",
                    help="quality: ours from `pyramid tiles` (cli), pyr.pyramid (api), or cli where it exists")
    ap.add_argument("--backend", default="cpu", help="quality with --ours api: pyr.pyramid's backend")
    ap.add_argument("--pyramid", default=peers.DEFAULT_PYRAMID, help="the pyramid command (default: this checkout's)")
    ap.add_argument("--pyramid-tree", action="append", metavar="DIR",
                    help="also time DIR's pyramid_cli (PYTHONPATH=DIR), interleaved; repeatable")
    ap.add_argument("--data", default="/tmp/pyramid-bench-tiles", help="where inputs are made once and outputs go")
    ap.add_argument("--json", help="default bench/results/tiles[-quality]-DATE.json (--quick: DATA/tiles-quick.json)")
    ap.add_argument("--plot", help="default: the JSON's path with .png (when anything was timed)")
    args = ap.parse_args(argv)
    parts = args.only.split(",")
    if bad := [p for p in parts if p not in PARTS]:
        ap.error(f"unknown part(s) {bad}; choose from {list(PARTS)}")
    args.sizes, args.flat = ([s for s in v.split(",") if s] for v in (args.sizes, args.flat))
    if bad := [s for s in args.sizes + args.flat if s not in SIZES]:
        ap.error(f"unknown size(s) {bad}; choose from {list(SIZES)}")
    args.repeat = args.repeat or (1 if args.quick else 3)
    args.warmup = 0 if args.quick else 1
    day = _dt.date.today().isoformat()
    name = "tiles-quality" if parts == ["quality"] else "tiles"
    out_json = Path(args.json or (Path(args.data) / "tiles-quick.json" if args.quick
                                  else HERE / "results" / f"{name}-{day}.json"))
    data = Path(args.data)
    data.mkdir(parents=True, exist_ok=True)
    pyrs = peers.pyramids(args)
    ours = [p for p in pyrs if has_tiles(p)]
    report = {"schema": 1, "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
              "command": shlex.join([Path(sys.argv[0]).name, *(argv if argv is not None else sys.argv[1:])]),
              "quick": args.quick, "repeat": args.repeat, "warmup_rounds_dropped": args.warmup, "parts": parts,
              "load_avg": {"start": os.getloadavg()[0]},
              "machine": machine_info() | {"versions_peers": peers.versions((), numba=False)},
              "pyramids": [{"label": p.label, "tree": p.tree, "tiles": p in ours, "commit": p.tree and subprocess.run(
                  ["git", "-C", p.tree, "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()}
                  for p in pyrs],
              "targets": {"time": TARGET["time"], "memory": TARGET["memory"],
                          "quality": "ours/dzsave RMS ≤ 1.2 at reduction 1, < 1 from reduction 2 down"},
              "jobs": [], "skipped": [], "failed": []}
    if "quality" in parts:
        if why := peers.have_module("pyvips"):
            report["skipped"].append(f"quality: {why}")
        else:
            mode = args.ours if args.ours != "auto" else ("cli" if pyrs[0] in ours else "api")
            q = QUICK_QUALITY if args.quick else QUALITY
            report["quality"] = tiles_quality.measure(data / "quality", **q, ours=mode, backend=args.backend,
                                                      pyramid=pyrs[0].argv, env=pyrs[0].env, log=log)
    if "speed" in parts:
        report["jobs"] = speed(args, pyrs, ours, data)
        report["skipped"] += [f"{j['id']}: {j['skipped']}" for j in report["jobs"] if j.get("skipped")]
    if "flat" in parts:
        report["flat"] = flat(args, ours, report["jobs"], data)
    clear_aside(data / "out")
    report["failed"] = [f"flat {s}: {e}" for s, e in report.get("flat", {}).get("errors", {}).items()]
    return peers.finish(report, summary_lines, out_json, args.plot)


if __name__ == "__main__":
    sys.exit(main())
