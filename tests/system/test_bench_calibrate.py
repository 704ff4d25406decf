"""bench/calibrate.py: the fit recovers a known model, and a quick run on the GL prints one."""

import importlib.util
import json
import subprocess
import sys

import numpy as np
import pytest

from helpers.paths import ROOT
from pyramid_cli.plan import cost

_spec = importlib.util.spec_from_file_location("bench_calibrate", ROOT / "bench" / "calibrate.py")
calibrate = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(calibrate)


def synthetic_points(truth: cost.CostModel, noise: float = 0.0) -> list[dict]:
    """Points shaped like the calibration's, timed by ``truth`` (times a little noise)."""
    rng = np.random.default_rng(0)
    points = []
    for out in (16, 64, 256, 1024):
        for kind in calibrate.KINDS:
            for linear in (True, False):
                for k in (1, 2, 4, 8):
                    stages, size = calibrate.synthetic(kind, k, linear, out)
                    p, firsts = calibrate.recipe_plan(stages, size, 2)
                    rows = calibrate.copy_measures(p, firsts, 1)
                    seconds = float(np.dot(truth.constants, calibrate.features(truth, rows)))
                    points.append({"kind": kind, "k": k, "out": out, "measures": rows,
                                   "seconds": seconds * (1 + noise * rng.standard_normal())})
    return points


@pytest.mark.slow
def test_fit_recovers_the_constants_and_the_tiling():
    truth = cost.CostModel(pass_s=8e-5, shader_tap_s=8e-6, pixel_s=6e-9, fetch_linear_s=3e-9,
                           fetch_nearest_s=1.5e-9, source_pixel_s=0.0, tile=64, threads=2)
    model, merged, x, t = calibrate.fit_tiles(synthetic_points(truth), cores=2)
    assert (model.tile, model.threads) == (64, 2) and not merged
    np.testing.assert_allclose(model.constants, truth.constants, rtol=1e-6, atol=1e-15)
    assert np.abs(calibrate.residuals(x, t, np.array(model.constants))).max() < 1e-9


@pytest.mark.slow
def test_fit_merges_equal_fetch_costs_and_keeps_constants_non_negative():
    truth = cost.CostModel(pass_s=5e-5, shader_tap_s=0.0, pixel_s=4e-9, fetch_linear_s=2e-9,
                           fetch_nearest_s=2.05e-9, source_pixel_s=0.0)
    model, merged, _, _ = calibrate.fit_tiles(synthetic_points(truth, noise=0.05), cores=2)
    assert merged and model.fetch_linear_s == model.fetch_nearest_s
    assert all(c >= 0 for c in model.constants) and model.pass_s > 0
    assert model.fetch_linear_s == pytest.approx(2e-9, rel=0.2)


def test_synthetic_passes_have_the_fetches_they_claim():
    for kind in calibrate.KINDS:
        for linear in (True, False):
            stages, size = calibrate.synthetic(kind, 4, linear, 64)
            p, firsts = calibrate.recipe_plan(stages, size, 2)
            (first,) = calibrate.copy_measures(p, firsts, 0)
            (second,) = calibrate.copy_measures(p, firsts, 1)
            _, shape, lin, near, _ = second
            # up-branch: phases of 4, 4, 4 and 5 taps, all run; the second copy also reads the first
            # with one tap of its kind in every phase (a dependency, as passes have in real plans)
            alone, dependency = (4 * 4 + 1, 4) if kind == "up-branch" else (4, 1)
            assert ((lin, near) if linear else (near, lin)) == (alone + dependency, 0), (kind, linear)
            assert first[2] + first[3] == alone and tuple(shape) == (64, 64)


@pytest.mark.slow
@pytest.mark.gl
def test_quick_calibration_prints_a_model_and_writes_nothing(gl_executor):
    before = (ROOT / "pyramid_cli" / "plan" / cost.MODEL_FILE).read_text()
    r = subprocess.run([sys.executable, str(ROOT / "bench" / "calibrate.py"), "--quick", "--no-validate",
                        "--no-backends"],
                       capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-2000:]
    doc = json.loads(r.stdout[r.stdout.index("\n{") + 1:])
    assert cost.from_dict(doc).pass_s > 0 and set(cost.FIELDS) <= set(doc)
    assert "residual: rms" in r.stdout and "not written" in r.stdout
    assert (ROOT / "pyramid_cli" / "plan" / cost.MODEL_FILE).read_text() == before


_spec_b = importlib.util.spec_from_file_location("bench_calibrate_backends", ROOT / "bench" / "calibrate_backends.py")
calibrate_backends = importlib.util.module_from_spec(_spec_b)
_spec_b.loader.exec_module(calibrate_backends)


def test_backend_constants_are_stored_for_auto_in_the_cache_folder(monkeypatch, tmp_path):
    """What ``make calibrate`` stores is what auto reads on this machine (for this driver), and the jobs the CPU
    constants are fitted on all plan."""
    from pyramid_cli.exec.gl.context import driver_key
    from pyramid_cli.plan import backend_cost

    monkeypatch.setenv("PYRAMID_CACHE_HOME", str(tmp_path))
    doc = {**backend_cost.shipped_dict(), "driver_key": driver_key()}
    doc["gl"] = {**doc["gl"], "program_s": 0.5}
    written = calibrate_backends.store(doc, ship=False)
    assert written == [str(backend_cost.machine_file())] and backend_cost.machine_file().is_relative_to(tmp_path)
    assert backend_cost.load(driver_key()).gl.program_s == 0.5
    jobs = calibrate_backends.real_jobs(quick=True)
    assert {c for *_, c, _ in jobs} == {1, 3, 4} and all(w.plan([(h, wd)], "fused") for w, h, wd, _, _ in jobs)
