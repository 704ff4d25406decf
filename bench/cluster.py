#!/usr/bin/env python3
"""Scale measurements for frame sequences, shards and the Dask runner (the ``cluster`` scenario).

    python bench/cluster.py [--quick] [--json OUT.json]       # alone
    python bench/run.py --only cluster                         # inside the suite

What it measures (nothing is asserted):

- ``per_frame``: a frame's cost in one process with one warm session
  (``pipeline.process`` over a sequence), for 4K-class half EXR frames (512² with
  ``--quick``) and for 32² frames (the per-job floor of the batch machinery);
- ``dask``: on a ``LocalCluster(n_workers=2, processes=True, threads_per_worker=1)``
  on 127.0.0.1: the cluster's start, the round trip of an empty chunk task (submit,
  plugin, report back), and a 64-frame 32² sequence at chunk 1 and chunk 16 against
  the same in one process, whence the overhead per task;
- ``shard``: the wall time of a fresh ``pyramid blur --shard 1/1`` process on one 32²
  frame (interpreter, imports, session, sequence planning: what every array task pays
  once), with the GL and CPU executors, beside ``pyramid --help``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for p in (str(ROOT), str(HERE)):
    if p not in sys.path:
        sys.path.insert(0, p)

import numpy as np  # noqa: E402

perf = time.perf_counter


def _sequence(folder: Path, n: int, rows: int, cols: int, half: bool) -> str:
    import OpenImageIO as oiio
    from run import _write, gradient_noise

    folder.mkdir(parents=True, exist_ok=True)
    base = gradient_noise(rows, cols, 4, seed=11)
    for f in range(1001, 1001 + n):
        spec = oiio.ImageSpec(cols, rows, 4, "half" if half else "float")
        spec.channelnames = ("R", "G", "B", "A")
        spec.alpha_channel = 3
        spec.attribute("compression", "zip")
        px = np.roll(base, f, axis=1)
        _write(oiio, folder / f"plate.{f}.exr", spec, px.astype(np.float16 if half else np.float32))
    return str(folder / "plate.####.exr")


def _process(pattern: str, out: str, session, **kw) -> float:
    from pyramid_cli.jobs.work import Blur
    from pyramid_cli.run import pipeline
    from pyramid_cli.run.report import Reporter

    t0 = perf()
    report = pipeline.process([pattern], out, Blur(levels=5), session, reporter=Reporter(quiet=True), **kw)
    dt = perf() - t0
    if report.failed:
        raise RuntimeError(str(report.failed[0][1]))
    return dt


def per_frame(tmp: Path, quick: bool) -> dict:
    from pyramid_cli.exec.session import Session

    side = (512, 512) if quick else (2160, 3840)
    n_big = 3 if quick else 4
    out = {}
    for label, (rows, cols), n, half in (("4K-class half EXR (zip), RGBA" if not quick else "512² half EXR, RGBA",
                                          side, n_big, True),
                                         ("32² float EXR, RGBA", (32, 32), 64, False)):
        folder = tmp / f"pf_{rows}"
        pattern = _sequence(folder, n, rows, cols, half)
        sizes = [os.path.getsize(folder / f"plate.{f}.exr") for f in range(1001, 1001 + n)]
        with Session("auto") as s:
            first = _process(pattern, str(folder / "warm" / "o.####.exr"), s, frames="1001")
            total = _process(pattern, str(folder / "out" / "o.####.exr"), s)
            executor = s.name
        out_size = statistics.mean(os.path.getsize(p) for p in (folder / "out").iterdir())
        out[label] = {"frames": n, "size": f"{cols}×{rows}", "executor": executor,
                      "first_frame_cold_s": first, "per_frame_warm_s": total / n,
                      "input_bytes_per_frame": statistics.mean(sizes), "output_bytes_per_frame": out_size}
        print(f"cluster: per frame, {label}: {total / n * 1e3:.1f} ms warm ({executor}); first frame "
              f"{first * 1e3:.0f} ms", file=sys.stderr)
    return out


def dask(tmp: Path, quick: bool) -> dict:
    try:
        import distributed
    except ImportError:
        return {"skipped": "distributed is not installed (pip install 'bilinear-pyramid[cluster]')"}
    from pyramid_cli.exec.session import Session
    from pyramid_cli.jobs.work import Blur
    from pyramid_cli.run import batch, cluster, pipeline, settings
    from pyramid_cli.run.report import Reporter

    n_empty = 100 if quick else 400
    pattern = _sequence(tmp / "dask", 64, 32, 32, False)
    res: dict = {"workers": 2, "host": "127.0.0.1"}
    t0 = perf()
    local_cluster = distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1",
                                             dashboard_address=None, silence_logs=40)
    with local_cluster as local, distributed.Client(local) as client:
        res["cluster_start_s"] = perf() - t0
        spec = cluster.SessionSpec("cpu")
        client.register_plugin(cluster.SessionPlugin(spec), name=spec.plugin_name)
        ro, wo = settings.ReadOptions(), settings.WriteOptions()
        kw = {"keep_going": False, "skip_existing": False, "threads": 1, "mip_tile": None, "started": time.time(),
              "quiet": True, "verbose": False, "bar": False, "plugin": spec.plugin_name}
        client.gather([client.submit(cluster.run_chunk, [], Blur(), ro, wo, pure=False, **kw) for _ in range(4)])
        t0 = perf()
        futures = [client.submit(cluster.run_chunk, [], Blur(), ro, wo, pure=False, **kw) for _ in range(n_empty)]
        client.gather(futures)
        wall = perf() - t0
        res["empty_tasks"] = n_empty
        res["empty_task_wall_per_task_s"] = wall / n_empty
        res["empty_task_worker_s_per_task"] = wall * 2 / n_empty
        t0 = perf()
        client.gather(client.submit(cluster.run_chunk, [], Blur(), ro, wo, pure=False, **kw))
        res["one_task_round_trip_s"] = perf() - t0
        jobs = batch.plan_jobs([pattern], str(tmp / "dask" / "x.####.exr"))
        for chunk in (1, 16):
            timings = []
            for rep in range(2 if quick else 3):
                out = str(tmp / "dask" / f"c{chunk}_{rep}" / "o.####.exr")
                t0 = perf()
                pipeline.process([pattern], out, Blur(levels=5), cluster.SessionSpec("cpu"),
                                 reporter=Reporter(quiet=True), cluster=client, chunk=chunk)
                timings.append(perf() - t0)
            res[f"64 frames, chunk {chunk}_s"] = statistics.median(timings)
    with Session("cpu") as s:
        timings = [_process(pattern, str(tmp / "dask" / f"one_{rep}" / "o.####.exr"), s) for rep in range(3)]
    res["64 frames, one process (cpu)_s"] = statistics.median(timings)
    one = res["64 frames, one process (cpu)_s"]
    res["overhead_per_task_chunk1_s"] = (res["64 frames, chunk 1_s"] * 2 - one) / len(jobs)
    res["overhead_per_task_chunk16_s"] = (res["64 frames, chunk 16_s"] * 2 - one) / (len(jobs) / 16)
    res["notes"] = ["overhead per task = (2 workers × cluster wall − one-process wall) / tasks: the worker time a "
                    "task costs beyond its frames' work (serialisation, scheduling, the client's round trip), and "
                    "an upper bound: it also holds each worker's first-frame cold start and any idle worker at the "
                    "end (64 / 16 = 4 tasks on 2 workers)",
                    "both sides use the cpu executor so that the two workers and the one process run the same code"]
    print(f"cluster: dask start {res['cluster_start_s']:.2f} s; empty task {res['empty_task_wall_per_task_s']*1e3:.1f}"
          f" ms wall/task over 2 workers; overhead/task chunk 1 {res['overhead_per_task_chunk1_s']*1e3:.1f} ms",
          file=sys.stderr)
    return res


def shard_start(tmp: Path, quick: bool) -> dict:
    from run import cmd_time, interleaved, pyramid_cmd

    pattern = _sequence(tmp / "shard", 1, 32, 32, False)
    pyr = pyramid_cmd()
    out = str(tmp / "shard" / "out" / "o.####.exr")
    fns = {
        "pyramid --help": lambda: cmd_time([*pyr, "--help"]),
        "pyramid blur --shard 1/1 (1 frame 32², auto)": lambda: cmd_time([*pyr, "blur", "-q", "--shard", "1/1",
                                                                           pattern, "-o", out]),
        "pyramid blur --shard 1/1 (1 frame 32², cpu)": lambda: cmd_time([*pyr, "blur", "-q", "--backend", "cpu",
                                                                          "--shard", "1/1", pattern, "-o", out]),
    }
    res = interleaved(fns, 3 if quick else 5)
    print("cluster: shard start " + ", ".join(f"{k}: {v['median_s']:.2f} s" for k, v in res.items()), file=sys.stderr)
    return res


def scenario_cluster(args, report: dict, tmp: Path) -> None:
    """The ``cluster`` scenario of bench/run.py (see the module notes)."""
    sc = report["scenarios"]["cluster"] = {}
    sc["per_frame"] = per_frame(tmp, args.quick)
    sc["dask"] = dask(tmp, args.quick)
    sc["shard_start"] = shard_start(tmp, args.quick)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small frames, few repetitions")
    ap.add_argument("--json", default=str(HERE / "results" / "cluster-latest.json"), help="where to write JSON")
    args = ap.parse_args(argv)
    from run import machine_info

    report = {"machine": machine_info(), "quick": args.quick, "scenarios": {}}
    with tempfile.TemporaryDirectory(prefix="pyramid-bench-cluster-") as td:
        scenario_cluster(args, report, Path(td))
    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=1, default=str) + "\n")
    print(json.dumps(report["scenarios"]["cluster"], indent=1, default=str))
    print(f"wrote {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
