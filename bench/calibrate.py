#!/usr/bin/env python3
"""Calibrate the planner's cost model (``pyramid_cli/plan/cost.py``) on this machine's GL.

    python bench/calibrate.py              # measure, fit, print; writes nothing
    python bench/calibrate.py --write      # and write pyramid_cli/plan/cost_model.json (+ the raw points
                                           #   to bench/results/calibration-latest.json)
    python bench/calibrate.py --quick      # two sizes, few repetitions: a smoke run (seconds)

Then what ``auto`` weighs (``bench/calibrate_backends.py``): both backends' fixed and per-pixel costs,
stored by ``--write`` in the cache folder for ``auto`` on this machine (with the pass model just
fitted), and by ``--ship`` also as the package's defaults (``pyramid_cli/plan/backend_costs.json``);
``--no-backends`` skips them.

Method. Synthetic single passes run on the real :class:`~pyramid_cli.exec.gl.GLExecutor`,
built with :class:`pyramid_cli.plan.Builder` from literal masks whose taps are
k bilinear (2×2 blocks of equal weights, like ``[1 1; 1 1]/4``) or k single-texel
fetches (isolated weights, like ``[1 0 1]/2``): ⊗ (stride 1), ⊗↓ (stride 2, reading
a source four times the output) and ⊗↑ (four phases, reading a quarter-size source),
k = 1, 2, 4, 8, at output sizes 16² … 2048². A pass's time is the difference between
a plan of 1 + n copies of the pass (each reading the input) and a plan of one, over n,
so upload and read-back cancel and the executor's own per-pass work (uniforms,
targets, the draw call) is included; each plan is warm (compiled, pool filled), the
read-back syncs, and of interleaved repetitions the fastest is kept (the least
disturbed). The five constants of :class:`~pyramid_cli.plan.cost.CostModel` are fitted by
least squares on relative error with non-negative constants (every subset of
constants is tried; the best non-negative solution wins). When bilinear and
single-texel fetches come out within 10 % of each other they are merged into one.

Validation: for every named filter where the planner chooses, the paper's recipe and
the fused pass are timed whole at a small and a large size, beside the model's
estimate, and the report says whether the model picks the measured faster one.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as _dt
import json
import os
import platform
import sys
import time
from dataclasses import replace
from fractions import Fraction
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:  # run from a checkout even without the editable install
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from pyramid_cli import plan as planner  # noqa: E402
from pyramid_cli.core.expr import Named, Op  # noqa: E402
from pyramid_cli.plan import cost  # noqa: E402

MODEL_JSON = ROOT / "pyramid_cli" / "plan" / cost.MODEL_FILE
RAW_JSON = ROOT / "bench" / "results" / "calibration-latest.json"
PHASES = [(0, 0), (0, 1), (1, 0), (1, 1)]
MERGE_WITHIN = 0.10
DEP_WEIGHT = Fraction(1, 2 ** 20)
KINDS = ("conv", "down", "up", "up-branch")
LIN, NEAR = cost.CONSTANTS.index("fetch_linear_s"), cost.CONSTANTS.index("fetch_nearest_s")
# Named filters the planner chooses a recipe for (paper's passes or one fused pass).
CHOICES = [(Op.CONV, "bartlett"), (Op.CONV, "gauss5"), (Op.CONV, "gauss7"), (Op.CONV, "quasi"),
           (Op.DOWN, "box4"), (Op.DOWN, "quadratic"), (Op.DOWN, "cubic"), (Op.DOWN, "bartlett"),
           (Op.UP, "cubic"), (Op.UP, "fourpoint")]
perf = time.perf_counter


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


# ---------------------------------------------------------------- synthetic passes
def tap_weights(k: int, linear: bool) -> dict:
    """Weights fitted by exactly k bilinear taps (2×2 blocks 3 columns apart) or k texel reads."""
    w = {}
    for i in range(k):
        if linear:
            for a in (0, 1):
                for b in (0, 1):
                    w[(a, 3 * i + b)] = Fraction(1, 4 * k)
        else:
            w[(0, 2 * i)] = Fraction(1, k)
    return w


def synthetic(kind: str, k: int, linear: bool, out: int) -> tuple[list[planner.Stage], tuple[int, int]]:
    """One pass of ``kind`` with k fetches per fragment, writing out × out; and its input size.

    conv: ⊗, stride 1; down: ⊗↓, stride 2; up: ⊗↑ with the same taps in every phase (the
    shader indexes phase tables); up-branch: ⊗↑ whose last phase has one tap more (the shader
    branches on the phase, and SIMD runs every branch: 4k + 1 fetches executed).
    """
    w = tap_weights(k, linear)
    if kind == "conv":
        return [planner.conv(w)], (out, out)
    if kind == "down":
        return [planner.down(w)], (2 * out, 2 * out)
    phases = {p: w for p in PHASES}
    if kind == "up-branch":
        phases[PHASES[-1]] = tap_weights(k + 1, linear)
    return [planner.up(phases)], (max(1, out // 2), max(1, out // 2))


def recipe_plan(stages, size: tuple[int, int], copies: int) -> tuple[planner.Plan, list[int]]:
    """``copies`` applications of a recipe to the input, and the index of each one's first pass.

    Each copy after the first depends on the one before, as every pass of a real plan but the
    first reads an earlier pass (and llvmpipe must then finish rendering that one): its first
    pass also reads the previous copy's result, with one tap of weight 2⁻²⁰ of the kind of
    its own first tap in each phase (so phase tables stay phase tables). The model counts it.
    """
    b = planner.Builder(size)
    firsts: list[int] = []
    last = None
    for _ in range(copies):
        firsts.append(len(b.passes))
        out = b.add_stages(0, stages, "calibrate")
        if last is not None:
            for taps in b.passes[firsts[-1]].phases.values():
                linear = taps[0].linear
                offset = (Fraction(1, 2), Fraction(1, 2)) if linear else (Fraction(0), Fraction(0))
                taps.append(planner.Tap(last, offset, DEP_WEIGHT, linear))
        last = out
    p = b.build("calibrate")
    planner.check(p)
    return p, firsts


def copy_measures(p: planner.Plan, firsts: list[int], copy: int) -> list[list]:
    """What the model weighs for each pass of one copy (:func:`pyramid_cli.plan.pass_measures`)."""
    end = firsts[copy + 1] if copy + 1 < len(firsts) else len(p.passes)
    return [[taps, list(size), lin, near, read] for taps, size, lin, near, read in
            (planner.pass_measures(p.images, ps) for ps in p.passes[firsts[copy]:end])]


def features(model: cost.CostModel, rows: list[list]) -> list[float]:
    """The model's features of a recipe: the sum over its passes (its time is their dot product with
    the constants)."""
    return [float(v) for v in np.sum([model.features(taps, tuple(size), lin, near, read)
                                      for taps, size, lin, near, read in rows], axis=0)]


def repeats(out: int) -> tuple[int, int]:
    """(extra copies n, repetitions) by output size: enough work to time, little enough to be quick."""
    if out <= 64:
        return 16, 7
    if out <= 256:
        return 8, 5
    if out <= 1024:
        return 2, 4
    return 2, 3


def time_recipe(ex, stages, size: tuple[int, int], n: int, reps: int, rng) -> tuple[float, list[list]]:
    """Seconds of one dependent application of ``stages`` on an input of ``size``, (T(1 + n) − T(1)) / n;
    with the model's measures of that application's passes."""
    one, _ = recipe_plan(stages, size, 1)
    many, firsts = recipe_plan(stages, size, 1 + n)
    img = rng.random(size + (4,), dtype=np.float32)
    ex.run(one, img)    # compile, fill the pool
    ex.run(many, img)
    t1, tn = [], []
    for _ in range(reps):  # interleaved
        t0 = perf()
        ex.run(one, img)   # read-back inside: synchronises with the GL
        t1.append(perf() - t0)
        t0 = perf()
        ex.run(many, img)
        tn.append(perf() - t0)
    return max(1e-7, (min(tn) - min(t1)) / n), copy_measures(many, firsts, 1)


# ---------------------------------------------------------------- fit
def fit(x: np.ndarray, t: np.ndarray, columns: list[int]) -> tuple[np.ndarray, float]:
    """Non-negative least squares on relative error over ``columns`` (every subset tried)."""
    a = x / t[:, None]
    b = np.ones(len(t))
    best: tuple[float, np.ndarray] | None = None
    for mask in range(1, 2 ** len(columns)):
        cols = [c for i, c in enumerate(columns) if mask >> i & 1]
        if 0 not in cols:
            continue  # a pass always costs something
        coef, *_ = np.linalg.lstsq(a[:, cols], b, rcond=None)
        if (coef < 0).any():
            continue
        full = np.zeros(x.shape[1])
        full[cols] = coef
        err = float(np.sum((a @ full - b) ** 2))
        if best is None or err < best[0]:
            best = (err, full)
    assert best is not None
    return best[1], best[0]


def fit_model(x: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, bool]:
    """The model's constants; bilinear and single-texel fetch costs merged when within 10 %."""
    columns = list(range(len(cost.CONSTANTS)))
    coef, _ = fit(x, t, columns)
    lin, near = coef[LIN], coef[NEAR]
    if max(lin, near) > 0 and abs(lin - near) <= MERGE_WITHIN * max(lin, near):
        merged = x.copy()
        merged[:, LIN] += merged[:, NEAR]
        merged[:, NEAR] = 0
        coef, _ = fit(merged, t, [c for c in columns if c != NEAR])
        coef[NEAR] = coef[LIN]
        return coef, True
    return coef, False


def residuals(x: np.ndarray, t: np.ndarray, coef: np.ndarray) -> np.ndarray:
    return x @ coef / t - 1


def fit_tiles(points: list[dict], cores: int) -> tuple[cost.CostModel, bool, np.ndarray, np.ndarray]:
    """Fit the constants for each candidate tiling (no tiles, or tiles of 16…128 pixels shared by
    2…16 workers) and keep the one with the smallest residual. Returns the model (constants,
    tile, threads), whether the fetch costs were merged, the features and the times."""
    t = np.array([p["seconds"] for p in points])
    best = None
    for tile, threads in [(0, 1)] + [(tl, n) for tl in (16, 32, 64, 128) for n in sorted({2, 4, 8, 16, cores})]:
        shape = cost.CostModel(*[0.0] * len(cost.CONSTANTS), tile=tile, threads=threads)
        x = np.array([features(shape, p["measures"]) for p in points])
        coef, merged = fit_model(x, t)
        err = float(np.sum(residuals(x, t, coef) ** 2))
        if best is None or err < best[0] - 1e-12:
            best = (err, cost.CostModel(*(float(c) for c in coef), tile=tile, threads=threads), merged, x)
    _, model, merged, x = best
    return model, merged, x, t


# ---------------------------------------------------------------- report
def fmt(s: float) -> str:
    return cost.format_seconds(s)


def machine(ex) -> dict:
    info = {"python": platform.python_version(), "cores": len(os.sched_getaffinity(0))
            if hasattr(os, "sched_getaffinity") else os.cpu_count(), "cpu": "unknown",
            "LP_NUM_THREADS": os.environ.get("LP_NUM_THREADS")}
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                info["cpu"] = line.split(":", 1)[1].strip()
                break
    gi = ex.info()
    info["renderer"], info["gl_version"] = gi["renderer"], gi["version"]
    return info


def sig(v: float) -> float:
    """Four significant figures: the file stays readable and the fit's noise is far larger."""
    return float(f"{v:.4g}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--write", action="store_true", help=f"write {MODEL_JSON.relative_to(ROOT)} "
                    f"and {RAW_JSON.relative_to(ROOT)}")
    ap.add_argument("--quick", action="store_true", help="two sizes, few repetitions (a smoke run)")
    ap.add_argument("--no-validate", action="store_true", help="skip timing the named filters' recipes")
    ap.add_argument("--no-backends", action="store_true", help="skip measuring what auto weighs")
    ap.add_argument("--ship", action="store_true", help="with --write: also write auto's constants as the "
                    "package's defaults")
    args = ap.parse_args(argv)

    from pyramid_cli.exec.gl import GLExecutor

    started = perf()
    rng = np.random.default_rng(7)
    sizes = [16, 256] if args.quick else [16, 64, 256, 1024, 2048]
    counts = [1, 4] if args.quick else [1, 2, 4, 8]
    points = []
    with GLExecutor() as ex:
        info = machine(ex)
        log(f"calibrating on {info['renderer']} ({info['cpu']}, {info['cores']} cores)")
        for out in sizes:
            n, reps = repeats(out)
            if args.quick:
                n, reps = min(n, 4), 3
            for kind in KINDS:
                for linear in (True, False):
                    for k in counts:
                        if out >= 2048 and k != 1:
                            continue  # the largest size only checks that the slope holds
                        stages, size = synthetic(kind, k, linear, out)
                        s, rows = time_recipe(ex, stages, size, n, reps, rng)
                        points.append({"kind": kind, "fetch": "linear" if linear else "nearest", "k": k,
                                       "out": out, "measures": rows, "seconds": s})
            log(f"  {out}²: done ({perf() - started:.0f} s)")
        model, merged, x, t = fit_tiles(points, info["cores"])
        # A disturbed measurement is only ever too slow: time the passes the first fit finds
        # more than 30 % slower than it predicts once more, keep the faster, and fit again.
        slow = [i for i, r in enumerate(residuals(x, t, np.array(model.constants))) if r < -0.3]
        for i in slow:
            p = points[i]
            stages, size = synthetic(p["kind"], p["k"], p["fetch"] == "linear", p["out"])
            p["seconds"] = min(p["seconds"], time_recipe(ex, stages, size, *repeats(p["out"]), rng)[0])
        if slow:
            log(f"  re-timed {len(slow)} pass(es) measured > 30 % slower than the first fit")
            model, merged, x, t = fit_tiles(points, info["cores"])
        coef = np.array(model.constants)
        res = residuals(x, t, coef)
        model = replace(model, renderer=info["renderer"], date=_dt.date.today().isoformat())

        print(f"\n{'kind':<9} {'fetch':<8} {'k':>2} {'out':>5}  {'measured':>9}  {'model':>9}  error")
        for p, r in zip(points, res, strict=True):
            print(f"{p['kind']:<9} {p['fetch']:<8} {p['k']:>2} {p['out']:>5}  {fmt(p['seconds']):>9}  "
                  f"{fmt(p['seconds'] * (1 + r)):>9}  {r:+.0%}")
        groups = {}
        for p, r in zip(points, res, strict=True):
            groups.setdefault(p["kind"], []).append(r)
        rms = float(np.sqrt(np.mean(res ** 2)))
        print(f"\nfit ({len(points)} passes, relative least squares, non-negative):")
        for name, c in zip(cost.CONSTANTS, coef, strict=True):
            print(f"  {name:<16} {c:.4g} s")
        print(f"  tiles            {model.tile}² pixels, {model.threads} workers" if model.tile else
              "  tiles            none (no tiling fits better)")
        if merged:
            print(f"  (bilinear and single-texel fetch costs within {MERGE_WITHIN:.0%}: merged into one)")
        print(f"  residual: rms {rms:.1%}, max {np.max(np.abs(res)):.1%}; by kind: "
              + ", ".join(f"{k} rms {np.sqrt(np.mean(np.square(v))):.1%}" for k, v in groups.items()))

        validation = [] if args.no_validate else validate(ex, model, rng, [64, 256] if args.quick else [64, 1024])

    elapsed = perf() - started
    print(f"\n{elapsed:.0f} s")
    residual = {"rms_relative": sig(rms), "max_relative": sig(float(np.max(np.abs(res)))),
                "by_kind_rms_relative": {k: sig(float(np.sqrt(np.mean(np.square(v))))) for k, v in groups.items()},
                "method": "least squares on relative error, constants >= 0, fastest of interleaved repetitions"}
    if validation:
        agree = sum(v["model_choice"] == v["measured_choice"] for v in validation)
        residual["validation"] = f"model picks the measured faster recipe in {agree} of {len(validation)} cases"
        print(residual["validation"])
    doc = {**{k: sig(float(c)) for k, c in zip(cost.CONSTANTS, coef, strict=True)},
           "tile": model.tile, "threads": model.threads, "fetch_costs_merged": merged,
           "renderer": info["renderer"], "gl_version": info["gl_version"], "cpu": info["cpu"],
           "cores": info["cores"], "date": model.date,
           "command": "python bench/calibrate.py --write" + (" --quick" if args.quick else ""),
           "residual": residual, "samples": len(points)}
    backends = None
    if not args.no_backends:
        import calibrate_backends

        backends = calibrate_backends.measure(sys.modules[__name__], args.quick, passes=doc)
        calibrate_backends.report(backends)
    if not args.write:
        print("\n(not written: pass --write to update the model)")
        print(json.dumps(doc, indent=1, ensure_ascii=False))
        return 0
    if args.quick:
        log("calibrate: a --quick fit is a smoke run; writing it anyway as asked")
    cost.from_dict(doc)  # refuse to write a model the planner would reject
    MODEL_JSON.write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    RAW_JSON.parent.mkdir(parents=True, exist_ok=True)
    RAW_JSON.write_text(json.dumps({"model": doc, "machine": info, "points": points, "validation": validation},
                                   indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    print(f"\nwrote {MODEL_JSON.relative_to(ROOT)} and {RAW_JSON.relative_to(ROOT)}")
    if backends is not None:
        print("wrote " + " and ".join(calibrate_backends.store(backends, args.ship)))
    return 0


def validate(ex, model: cost.CostModel, rng, sizes: list[int]) -> list[dict]:
    """Time both candidates of every planner choice whole; compare with the model's estimates."""
    out = []
    print(f"\n{'filter':<14} {'input':>5}  {'paper: measured':>15} {'model':>9}  {'fused: measured':>15} "
          f"{'model':>9}  model picks / faster")
    for op, key in CHOICES:
        f = Named(key)
        paper, fused = planner.checked_recipe(op, f), planner.direct_recipe(op, f)
        for n in sizes:
            size = (n, n)
            row = {"filter": f"{key} {op.unicode}", "input": n}
            for name, stages in (("paper", paper), ("fused", fused)):
                row[name], rows = time_recipe(ex, stages, size, *repeats(n), rng)
                row[name + "_model"] = float(np.dot(model.constants, features(model, rows)))
            row["model_choice"] = "fused" if row["fused_model"] < row["paper_model"] else "paper"
            if (row["fused"] < row["paper"]) != (row["model_choice"] == "fused"):  # once more, keep the faster
                for name, stages in (("paper", paper), ("fused", fused)):
                    row[name] = min(row[name], time_recipe(ex, stages, size, *repeats(n), rng)[0])
            row["measured_choice"] = "fused" if row["fused"] < row["paper"] else "paper"
            out.append(row)
            print(f"{row['filter']:<14} {n:>5}  {fmt(row['paper']):>15} {fmt(row['paper_model']):>9}  "
                  f"{fmt(row['fused']):>15} {fmt(row['fused_model']):>9}  {row['model_choice']} / "
                  f"{row['measured_choice']}")
    return out


if __name__ == "__main__":
    sys.exit(main())
