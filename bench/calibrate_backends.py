"""Measure what ``auto`` weighs (:mod:`pyramid_cli.plan.backend_cost`): each backend's fixed and per-pixel costs.

Called by ``bench/calibrate.py`` (``make calibrate``); on its own::

    python bench/calibrate_backends.py            # measure and print; writes nothing
    python bench/calibrate_backends.py --write    # and store them for auto on this machine (the cache folder)
    python bench/calibrate_backends.py --ship     # and write them as the package's defaults (backend_costs.json)

Fixed costs are timed in fresh processes (the fastest of a few: the least disturbed): importing numba; loading kernels
from numba's disk cache and compiling them (a temporary cache folder); importing moderngl and
making an EGL context; compiling GL programs. Per-pixel costs are timed warm: the CPU executor on
real jobs (pyramids, filters, reductions; 1–4 channels, half and float; fitted like the GL
model, by non-negative least squares on relative error), GL's upload of half RGBA and read-back,
and the page faults of fresh memory (GL's texture pool). The CPU executor's ``fresh_byte_s`` is
a fresh process's first run of a 2048² half blur over its warm runs, per byte its passes write.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from pyramid_cli.plan import backend_cost  # noqa: E402

SHIPPED = ROOT / "pyramid_cli" / "plan" / backend_cost.COSTS_FILE
perf = time.perf_counter

# A fresh process that prints the seconds of one step after its imports (argv: what to time, a folder).
CHILD = r"""
import sys, time, json
what, folder = sys.argv[1], sys.argv[2]
import numpy as np
from pyramid_cli.jobs.work import Blur, Filter
from pyramid_cli.core.parse import parse
jobs = [Blur(levels=3), Filter(expr=parse("gauss5 * g")), Filter(expr=parse("cubic *v g"))]
out = {}
if what == "numba":
    t = time.perf_counter(); import numba; out["s"] = time.perf_counter() - t
elif what == "kernels":
    import numba
    from pyramid_cli.exec.cpu import CPUExecutor
    ex = CPUExecutor(cache=folder)
    t = time.perf_counter()
    for j in jobs:
        ex.prepare(j.plan([(64, 64)], "fused"))
    out["s"] = time.perf_counter() - t
    out["compiles"], out["loads"] = ex.compiles, ex.cache_loads
elif what == "first":  # a fresh process's first run of a 2048² half blur over its warm runs (kernels loaded)
    from pyramid_cli.exec.cpu import CPUExecutor
    ex = CPUExecutor()
    p = Blur(levels=5).plan([(2048, 2048)], "fused")
    img = np.random.default_rng(0).random((2048, 2048, 4)).astype(np.float16)
    ex.prepare(p)
    t = time.perf_counter(); ex.run_outputs(p, [img], np.float16); first = time.perf_counter() - t
    warm = []
    for _ in range(2):
        t = time.perf_counter(); ex.run_outputs(p, [img], np.float16); warm.append(time.perf_counter() - t)
    values = sum(im.stored[0] * im.stored[1] * 4 for im in (p.images[ps.target] for ps in p.passes))
    out["s"] = max(0.0, first - min(warm)) / (values * 4)
elif what == "gl":
    from pyramid_cli.exec.gl import GLExecutor
    t = time.perf_counter()
    import moderngl
    ex = GLExecutor(); ex.open()
    out["context_s"] = time.perf_counter() - t
    t = time.perf_counter()
    for j in jobs:
        ex.programs(j.plan([(64, 64)], "cost"))
    out["programs_s"] = time.perf_counter() - t
    out["programs"] = ex.compiles
print(json.dumps(out))
"""


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def child(what: str, folder: str, reps: int) -> list[dict]:
    """``reps`` fresh processes of :data:`CHILD` timing ``what``."""
    out = []
    for _ in range(reps):
        r = subprocess.run([sys.executable, "-c", CHILD, what, folder], capture_output=True, text=True, check=True,
                           cwd=ROOT)
        out.append(json.loads(r.stdout.strip().splitlines()[-1]))
    return out


def fixed_costs(reps: int) -> dict:
    """Fresh-process fixed costs of both backends (medians of ``reps``)."""
    numba_s = min(d["s"] for d in child("numba", "-", reps))
    with tempfile.TemporaryDirectory() as folder:
        first = child("kernels", folder, 1)[0]  # an empty cache: every kernel compiles
        loads = child("kernels", folder, reps)
    compile_s = first["s"] / max(1, first["compiles"])
    load_s = min(d["s"] / max(1, d["loads"]) for d in loads)
    gl = child("gl", "-", reps)
    first = sorted(d["s"] for d in child("first", "-", reps))[reps // 2]
    return {"first_byte_s": first, "import_s": numba_s, "kernel_load_s": load_s, "kernel_compile_s": compile_s,
            "context_s": min(d["context_s"] for d in gl),
            "program_s": min(d["programs_s"] / max(1, d["programs"]) for d in gl)}


def fresh_byte_s(reps: int = 3) -> float:
    """Seconds per byte of touching new memory (page faults), over reusing it."""
    n = 64 << 20
    fresh, reused = [], []
    for _ in range(reps):
        t = perf()
        a = np.empty(n // 4, dtype=np.float32)
        a.fill(1)
        fresh.append(perf() - t)
        t = perf()
        a.fill(2)
        reused.append(perf() - t)
        del a
    return max(0.0, (min(fresh) - min(reused)) / n)


def real_jobs(quick: bool) -> list[tuple]:
    """(work, rows, columns, channels, dtype) of the jobs the CPU constants are fitted on: pyramids, filters,
    reductions and MIP chains at small to 4K sizes, one to four channels, half and float inputs."""
    from pyramid_cli.core.parse import parse
    from pyramid_cli.jobs.work import Blur, Filter

    works = [Blur(levels=5), Blur(levels=2), Filter(expr=parse("gauss5 * g")), Filter(expr=parse("cubic *v g")),
             Filter(expr=parse("box4 *v box4 *v g"))]
    sizes = [(256, 256), (1080, 1920)] if quick else [(256, 256), (720, 1280), (1080, 1920), (2160, 3840)]
    out = []
    for w in works:
        for h, wd in sizes:
            for channels, dtype in ((4, np.float16), (3, np.float32), (1, np.float32)):
                out.append((w, h, wd, channels, dtype))
    return out


def cpu_passes(calibrate, quick: bool, rng) -> dict:
    """The CPU executor's pass constants, fitted (non-negative least squares on relative error) on real jobs
    (:func:`real_jobs`) run warm: each job's fastest of three, its new arrays' page faults included, as in a run."""
    from pyramid_cli.exec.cpu import CPUExecutor
    from pyramid_cli.plan import pass_measures

    rows, times = [], []
    with CPUExecutor() as ex:
        for work, h, w, channels, dtype in real_jobs(quick):
            p = work.plan([(h, w)], "fused")
            img = rng.random((h, w, channels)).astype(dtype)
            ex.prepare(p)  # the kernels: not part of a run
            out = np.float16 if dtype == np.float16 else np.float32  # a half file is written half
            ex.run_outputs(p, [img], out)
            best = float("inf")
            for _ in range(3):
                t = perf()
                ex.run_outputs(p, [img], out)
                best = min(best, perf() - t)
            feats = np.zeros(4)
            for ps in p.passes:
                _, (ph, pw), lin, near, _ = pass_measures(p.images, ps)
                values = ph * pw * channels
                feats += [1.0, values, values * lin, values * near]
            rows.append(feats)
            times.append(best)
        threads = ex.threads
    coef, _ = calibrate.fit(np.array(rows), np.array(times), [0, 1, 2, 3])
    return {"pass_s": float(coef[0]), "value_s": float(coef[1]), "linear_s": float(coef[2]),
            "nearest_s": float(coef[3]), "threads": int(threads)}


def gl_transfers(reps: int = 3) -> dict:
    """GL's upload of a half RGBA picture and read-back of a float one, per texel (warm, 2048²)."""
    from pyramid_cli.core.parse import parse
    from pyramid_cli.exec.gl import GLExecutor
    from pyramid_cli.jobs.work import Filter

    n = 2048
    img = np.random.default_rng(3).random((n, n, 4)).astype(np.float16)
    p = Filter(expr=parse("box * g")).plan([(n, n)], "cost")
    with GLExecutor() as ex:
        ex.run_outputs(p, [img])
        prof = [ex.profile(p, [img], per_pass=False) for _ in range(reps)]
        renderer = ex.renderer
    return {"upload_s": min(d["upload"] for d in prof) / (n * n),
            "readback_s": min(d["readback"] for d in prof) / (n * n), "renderer": renderer}


def sig(v: float) -> float:
    return float(f"{v:.4g}")


def measure(calibrate, quick: bool = False, passes: dict | None = None) -> dict:
    """Every constant of :class:`~pyramid_cli.plan.backend_cost.BackendCosts`, as the JSON object stored.
    ``passes``: the GL pass model just fitted (the planner's model when None)."""
    from pyramid_cli.exec.gl.context import driver_key

    reps = 3 if quick else 5
    started = perf()
    log("backends: fixed costs in fresh processes …")
    fixed = fixed_costs(reps)
    log("backends: the CPU executor's passes …")
    cpu = cpu_passes(calibrate, quick, np.random.default_rng(11))
    fault = fresh_byte_s()
    gl = gl_transfers()
    doc = {"cpu": {"import_s": sig(fixed["import_s"]), "kernel_load_s": sig(fixed["kernel_load_s"]),
                   "kernel_compile_s": sig(fixed["kernel_compile_s"]),
                   **{k: sig(cpu[k]) for k in ("pass_s", "value_s", "linear_s", "nearest_s")},
                   "fresh_byte_s": sig(fixed["first_byte_s"]), "threads": cpu["threads"]},
           "gl": {"context_s": sig(fixed["context_s"]), "program_s": sig(fixed["program_s"]),
                  "upload_s": sig(gl["upload_s"]), "readback_s": sig(gl["readback_s"]), "fresh_byte_s": sig(fault)},
           "renderer": gl["renderer"], "date": _dt.date.today().isoformat(),
           "command": "python bench/calibrate.py --write" + (" --quick" if quick else ""),
           "driver_key": driver_key()}
    if passes is not None:
        doc["passes"] = passes
    backend_cost.from_dict(doc)  # refuse to store what auto would reject
    log(f"backends: {perf() - started:.0f} s")
    return doc


def report(doc: dict) -> None:
    print("\nbackends (what auto weighs):")
    for part in ("cpu", "gl"):
        print(f"  {part}: " + ", ".join(f"{k} {v:.4g}" for k, v in doc[part].items()))


def store(doc: dict, ship: bool = False) -> list[str]:
    """Write ``doc`` to the cache folder (auto on this machine) and, with ``ship``, as the package's defaults."""
    written = []
    path = backend_cost.machine_file()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    written.append(str(path))
    if ship:
        shipped = {k: v for k, v in doc.items() if k not in ("driver_key", "passes")}
        SHIPPED.write_text(json.dumps(shipped, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
        written.append(str(SHIPPED.relative_to(ROOT)))
    return written


def main(argv=None) -> int:
    import importlib.util

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--write", action="store_true", help="store them for auto on this machine (the cache folder)")
    ap.add_argument("--ship", action="store_true", help="and write them as the package's defaults")
    ap.add_argument("--quick", action="store_true", help="fewer sizes and repetitions")
    args = ap.parse_args(argv)
    spec = importlib.util.spec_from_file_location("bench_calibrate", ROOT / "bench" / "calibrate.py")
    calibrate = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(calibrate)
    doc = measure(calibrate, args.quick)
    report(doc)
    if args.write or args.ship:
        print("wrote " + " and ".join(store(doc, args.ship)))
    else:
        print("\n(not written: pass --write to store them for auto here)")
        print(json.dumps(doc, indent=1, ensure_ascii=False))
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
