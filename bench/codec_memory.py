"""What OpenEXR's codecs hold per open file, by compression, width and thread count (docs/performance.md, "What
OpenEXR's codecs hold"; ``pyramid_cli.imageio.codecs.EXR_CODEC_MEMORY`` is made from these figures).

    python bench/codec_memory.py                                   # every compression, 1920 and 3840 wide, 1 2 8 16
    python bench/codec_memory.py --compressions zip,dwab --widths 3840 --threads 1,2 --json out.json

For each compression and width it writes a half RGBA picture (the bench's 4K EXR input, resized) and runs
``pyramid blur --levels 5 --backend cpu`` on it, streamed in bands from and to that compression (the output keeps
the input's), in a fresh process with OpenImageIO told to use each thread count (``OPENIMAGEIO_THREADS``); the
peak resident memory (``ru_maxrss`` of the child) less the same run on an uncompressed file, halved (two files
are open: the input and the output), is what one file's codec holds. Peaks move by about a MiB between runs:
each figure is the least of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SOURCE = Path("/tmp/pyramid-bench-peers/v1_exr_3840x2160.exr")  # bench/peers.py makes it ("making the inputs")
COMPRESSIONS = ("none", "zip", "piz", "b44", "pxr24", "dwaa", "dwab", "rle", "zips")


def peak_mib(args: list[str], threads: int) -> float:
    """Peak resident memory of one ``pyramid ARGS`` process, in MiB (a fresh interpreter measures only it)."""
    code = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True); "
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, r.returncode)")
    env = dict(os.environ, OPENIMAGEIO_THREADS=str(threads))
    out = subprocess.run([sys.executable, "-c", code, sys.executable, "-m", "pyramid_cli.cli", *args],
                         capture_output=True, text=True, env=env, check=True)
    kib, rc = out.stdout.split()
    if rc != "0":
        raise RuntimeError(f"pyramid {' '.join(args)} failed")
    return int(kib) / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--compressions", default=",".join(COMPRESSIONS))
    ap.add_argument("--widths", default="1920,3840")
    ap.add_argument("--threads", default="1,2,8,16")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--source", default=str(SOURCE), help="a half RGBA EXR to resize (16:9; made if missing)")
    ap.add_argument("--json", help="write every figure here")
    a = ap.parse_args()
    import numpy as np
    import OpenImageIO as oiio

    oiiotool = Path(sys.executable).with_name("oiiotool")  # the OpenImageIO wheel's
    comps = ["none"] + [c for c in a.compressions.split(",") if c != "none"]
    threads = [int(t) for t in a.threads.split(",")]
    result: dict[str, dict] = {}
    with tempfile.TemporaryDirectory(prefix="pyramid-codec-memory-") as tmp:
        source = a.source
        if not Path(source).is_file():  # smooth colour plus noise, as the bench's inputs
            source = str(Path(tmp) / "source.exr")
            y, x = np.mgrid[0:2160, 0:3840] / 2160.0
            rng = np.random.default_rng(1)
            px = np.stack([x / 2, y, (x + y) / 3, np.ones_like(x)], axis=2) + rng.normal(0, 0.02, (2160, 3840, 4))
            out = oiio.ImageOutput.create(source)
            out.open(source, oiio.ImageSpec(3840, 2160, 4, "half"))
            out.write_image(px.astype(np.float16))
            out.close()
        for width in (int(w) for w in a.widths.split(",")):
            base = {}
            for comp in comps:
                src = Path(tmp) / f"w{width}_{comp}.exr"
                subprocess.run([str(oiiotool), source, "--resize", f"{width}x{width * 9 // 16}", "--compression",
                                comp, "-o", str(src)], check=True)
                for t in threads:
                    args = ["blur", "--levels", "5", str(src), str(Path(tmp) / "out.exr"), "--backend", "cpu", "-q"]
                    peak = min(peak_mib(args, t) for _ in range(a.repeat))
                    if comp == "none":
                        base[t] = peak
                    per_file = (peak - base[t]) / 2
                    result[f"{width} {comp} {t}"] = {"peak_mib": round(peak, 1), "per_file_mib": round(per_file, 1)}
                    print(f"{width:5d} {comp:6s} {t:3d} threads: peak {peak:6.1f} MiB, "
                          f"one file's codec {per_file:5.1f} MiB", flush=True)
    if a.json:
        Path(a.json).write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
