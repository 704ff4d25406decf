"""Big pictures in bounded memory (issue 18): peak RSS and time of a streamed blur and mipmap against a bare
read+write.

    python bench/big.py                              # 4K 8K 16K 32K square RGBA half EXRs
    python bench/big.py --sizes 4096,8192 --memory 1G --reps 3
    python bench/big.py --data /tmp/pyramid-big      # where the inputs are made once and kept

Inputs are made once, procedurally (a gradient plus noise, zip-compressed RGBA half), written band by
band through pyramid_cli.imageio's streaming writer so that making a 32K file needs no 8 GiB array; they
live under ``--data`` (default /tmp/pyramid-bench-big), never in the repository.

Contenders, each in a fresh process whose peak RSS is its own (``bench/scripts/peak_rss.py``):
  * ``pyramid blur --levels 5 --backend cpu --memory M`` (streams when the whole run would not fit M);
  * ``pyramid mipmap --backend cpu --memory M`` (the same, level 0 band by band, the coarser levels kept or
    spilled; it reads the input twice: once for level 0's header, once for the pixels; ``--no-mipmap`` skips it);
  * ``maketx`` (OpenImageIO's, from the wheel) on the same file, the peer ``pyramid mipmap`` imitates
    (with the mipmap; whole pictures in memory, its own defaults);
  * ``bench/scripts/io_floor.py``: OpenImageIO reads the whole file and writes it back, nothing else.
Repetitions interleave the contenders (rotated order); medians are reported. Targets (reported, not asserted):
peak RSS flat in the size beyond the working-set bound (32K within 2 GiB), time within 1.2× of the
read+write. Writes JSON (``--json``) and a plot of peak memory and time against pixels (``--plot``, needs
matplotlib from the bench extra).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

PEAK = [sys.executable, str(HERE / "scripts" / "peak_rss.py")]


def make_input(path: Path, n: int, band: int = 256) -> None:
    """An n×n RGBA half EXR: a gradient plus noise, band by band (deterministic)."""
    from pyramid_cli import imageio as io

    if path.exists():
        return
    info = io.info_for_array(path, 4)
    info = io.ImageInfo(**{**info.__dict__, "pixel_type": "half"})
    x = np.linspace(0, 1, n, dtype=np.float32)
    with io.stream_writers([path], [info], [(n, n, 4)], pixel_type="half", compression="zip") as (w,):
        for y0 in range(0, n, band):
            rows = min(band, n - y0)
            rng = np.random.default_rng(y0)
            y = (np.arange(y0, y0 + rows, dtype=np.float32) / n)[:, None]
            px = np.empty((rows, n, 4), dtype=np.float32)
            px[..., 0] = x[None, :] * 0.8 + 0.1
            px[..., 1] = y * 0.8 + 0.1
            px[..., 2] = 0.5 + 0.25 * np.sin(12 * x[None, :] + 7 * y)
            px[..., :3] += rng.normal(0, 0.05, (rows, n, 3)).astype(np.float32)
            px[..., 3] = 1
            w.write(y0, px.astype(np.float16))


def measure(cmd: list[str]) -> tuple[float, float]:
    """(seconds, peak RSS in MiB) of one run of ``cmd``."""
    t0 = time.perf_counter()
    r = subprocess.run(PEAK + cmd, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if r.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()}")
    return dt, float(r.stdout.split()[-1])


def load() -> float:
    return os.getloadavg()[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="4096,8192,16384,32768")
    ap.add_argument("--memory", default="512M", help="pyramid's --memory (default 512M: every size streams)")
    ap.add_argument("--reps", type=int, default=1)
    ap.add_argument("--no-mipmap", dest="mipmap", action="store_false", help="Measure blur and read+write only.")
    ap.add_argument("--data", default="/tmp/pyramid-bench-big")
    ap.add_argument("--json", default=str(HERE / "results" / "big-latest.json"))
    ap.add_argument("--plot", default=str(HERE / "results" / "big-latest.png"))
    ap.add_argument("--merge", nargs="+", metavar="JSON", help="Combine the rows of earlier runs (say, 32K run "
                    "apart) into --json and --plot, measuring nothing.")
    a = ap.parse_args()
    if a.merge:
        docs = [json.loads(Path(p).read_text()) for p in a.merge]
        doc = {**docs[0], "rows": sorted((r for d in docs for r in d["rows"]), key=lambda r: r["size"])}
        rows = doc["rows"]
        doc["targets"] = {
            "32K within 2 GiB peak RSS": (rows[-1]["pyramid blur --levels 5"]["peak_rss_mib"] <= 2048
                                          if rows[-1]["size"] >= 32768 else None),
            "time within 1.2x of read+write at every size": all(r["time_ratio"] <= 1.2 for r in rows)}
        Path(a.json).write_text(json.dumps(doc, indent=1))
        plot(rows, a.plot, doc["memory"])
        return
    data = Path(a.data)
    data.mkdir(parents=True, exist_ok=True)
    pyramid = [sys.executable, "-m", "pyramid_cli.cli"]
    rows = []
    for n in [int(s) for s in a.sizes.split(",")]:
        src = data / f"noise_{n}.exr"
        t0 = time.perf_counter()
        make_input(src, n)
        made = time.perf_counter() - t0
        out = data / f"out_{n}.exr"
        contenders = {
            "pyramid blur --levels 5": pyramid + ["blur", "--levels", "5", "--backend", "cpu", "--memory", a.memory,
                                                  "--force", str(src), str(out)],
            "OpenImageIO read+write": [sys.executable, str(HERE / "scripts" / "io_floor.py"), str(src), str(out)],
        }
        tx = data / f"out_{n}.tx.exr"
        theirs = data / f"out_{n}.maketx.exr"
        if a.mipmap:
            contenders["pyramid mipmap"] = pyramid + ["mipmap", "--backend", "cpu", "--memory", a.memory, "--force",
                                                      str(src), str(tx)]
            contenders["maketx"] = [str(Path(sys.executable).parent / "maketx"), str(src), "-o", str(theirs)]
        runs: dict[str, list[tuple[float, float]]] = {k: [] for k in contenders}
        loads = []
        for rep in range(a.reps):
            names = list(contenders)
            names = names[rep % len(names):] + names[:rep % len(names)]
            for name in names:
                loads.append(load())
                runs[name].append(measure(contenders[name]))
        row = {"size": n, "pixels": n * n, "file_bytes": src.stat().st_size, "made_s": made,
               "load_avg": max(loads)}
        for name, rs in runs.items():
            row[name] = {"seconds": statistics.median(t for t, _ in rs), "peak_rss_mib": max(m for _, m in rs),
                         "runs": rs}
        ours, floor = row["pyramid blur --levels 5"], row["OpenImageIO read+write"]
        row["time_ratio"] = ours["seconds"] / floor["seconds"]
        if "pyramid mipmap" in row:
            row["mipmap_time_ratio"] = row["pyramid mipmap"]["seconds"] / floor["seconds"]
            row["maketx_time_ratio"] = row["maketx"]["seconds"] / floor["seconds"]
            row["mipmap_vs_maketx"] = row["pyramid mipmap"]["seconds"] / row["maketx"]["seconds"]
        rows.append(row)
        print(f"{n:>6}²  blur {ours['seconds']:7.1f} s {ours['peak_rss_mib']:8.0f} MiB   read+write "
              f"{floor['seconds']:7.1f} s {floor['peak_rss_mib']:8.0f} MiB   time ×{row['time_ratio']:.2f}   "
              f"load {row['load_avg']:.1f}", flush=True)
        if "pyramid mipmap" in row:
            mm = row["pyramid mipmap"]
            mk = row["maketx"]
            print(f"{'':>7}  mipmap {mm['seconds']:5.1f} s {mm['peak_rss_mib']:8.0f} MiB   time ×"
                  f"{row['mipmap_time_ratio']:.2f}   maketx {mk['seconds']:5.1f} s {mk['peak_rss_mib']:8.0f} MiB   "
                  f"time ×{row['maketx_time_ratio']:.2f}   mipmap/maketx ×{row['mipmap_vs_maketx']:.2f}", flush=True)
        for f in (out, tx, theirs):
            f.unlink(missing_ok=True)
    largest = rows[-1]
    targets = {
        "32K within 2 GiB peak RSS": (largest["pyramid blur --levels 5"]["peak_rss_mib"] <= 2048
                                      if largest["size"] >= 32768 else None),
        "time within 1.2x of read+write at every size": all(r["time_ratio"] <= 1.2 for r in rows),
    }
    doc = {"machine": {"cpu": platform.processor() or platform.machine(), "cores": len(os.sched_getaffinity(0)),
                       "python": platform.python_version()},
           "memory": a.memory, "rows": rows, "targets": targets}
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)
    Path(a.json).write_text(json.dumps(doc, indent=1))
    print("targets:", {k: ("MET" if v else "n/a" if v is None else "MISSED") for k, v in targets.items()})
    plot(rows, a.plot, a.memory)


def plot(rows: list[dict], path: str, memory: str) -> None:
    """Peak memory and time against pixels, both contenders (matplotlib from the bench extra)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib missing (pip install -e '.[bench]'): no plot")
        return
    fig, (m, t) = plt.subplots(1, 2, figsize=(10, 4))
    px = [r["pixels"] / 1e6 for r in rows]
    for name, style in (("pyramid blur --levels 5", "o-"), ("pyramid mipmap", "^-"), ("maketx", "v:"),
                        ("OpenImageIO read+write", "s--")):
        if name not in rows[0]:
            continue
        m.plot(px, [r[name]["peak_rss_mib"] for r in rows], style, label=name)
        t.plot(px, [r[name]["seconds"] for r in rows], style, label=name)
    for ax, label in ((m, "peak RSS (MiB)"), (t, "time (s)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("megapixels (RGBA half EXR)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    m.set_title(f"peak memory (--memory {memory})")
    t.set_title("wall time")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    print("plot:", path)


if __name__ == "__main__":
    main()
