"""What auto weighs (pyramid_cli/plan/backend_cost.py): the shipped constants, the estimates' shape, the
machine's calibration in the cache folder and when it is passed over."""

from __future__ import annotations

import json

import pytest

from pyramid_cli.jobs.work import Blur
from pyramid_cli.plan import backend_cost, cost


@pytest.fixture
def cache_home(monkeypatch, tmp_path):
    monkeypatch.setenv("PYRAMID_CACHE_HOME", str(tmp_path))
    return tmp_path


def test_the_shipped_constants_load_and_say_where_they_were_measured():
    d = backend_cost.shipped_dict()
    c = backend_cost.from_dict(d)
    assert c.source == "shipped" and c.renderer and c.cpu.import_s > 0 and c.gl.context_s > 0
    assert c.cpu.threads >= 1 and c.passes == cost.model()  # the planner's pass model unless calibrated here
    assert "calibrate" in d["command"] and d["date"]


@pytest.mark.parametrize("change", [{"cpu": {"import_s": -1}}, {"gl": {"upload_s": "fast"}}, {"gl": None},
                                    {"cpu": {"threads": 0}}, {"renderer": None}])
def test_malformed_constants_are_refused(change):
    d = json.loads(json.dumps(backend_cost.shipped_dict()))
    for part, values in change.items():
        if values is None:
            del d[part]
        else:
            d[part].update(values)
    with pytest.raises(ValueError, match=backend_cost.COSTS_FILE):
        backend_cost.from_dict(d)


def test_estimates_grow_with_size_jobs_and_channels_and_fixed_costs_come_once():
    c = backend_cost.load()
    small, big = Blur(levels=5).plan([(256, 256)], "fused"), Blur(levels=5).plan([(2160, 3840)], "fused")
    e1 = backend_cost.cpu_estimate(c.cpu, small, 4)
    e50 = backend_cost.cpu_estimate(c.cpu, small, 4, jobs=50)
    assert e50.fixed_s == e1.fixed_s and e50.seconds == pytest.approx(e1.seconds + 49 * e1.job_s)
    assert backend_cost.cpu_estimate(c.cpu, big, 4).job_s > e1.job_s
    assert backend_cost.cpu_estimate(c.cpu, big, 1).job_s < backend_cost.cpu_estimate(c.cpu, big, 4).job_s
    warm = backend_cost.cpu_estimate(c.cpu, small, 4, imported=True)
    assert warm.fixed_s == pytest.approx(e1.fixed_s - c.cpu.import_s)
    assert backend_cost.cpu_estimate(c.cpu, small, 4, compiles=2).fixed_s == pytest.approx(
        e1.fixed_s + 2 * c.cpu.kernel_compile_s)
    gl_plan = Blur(levels=5).plan([(256, 256)], "cost")
    g1 = backend_cost.gl_estimate(c.gl, c.passes, gl_plan, 4)
    assert backend_cost.gl_estimate(c.gl, c.passes, gl_plan, 8).job_s == pytest.approx(2 * g1.job_s)  # two RGBA groups
    assert backend_cost.gl_estimate(c.gl, c.passes, gl_plan, 4, opened=True).fixed_s == pytest.approx(
        g1.fixed_s - c.gl.context_s)


def test_the_texture_pool_reuses_released_textures():
    p = Blur(levels=3).plan([(64, 64)], "cost")
    each = sum(im.stored[0] * im.stored[1] * 16 for im in p.images)
    pooled = backend_cost.pool_bytes(p, lambda stored: stored[0] * stored[1] * 16)
    assert 0 < pooled < each


def test_the_machines_calibration_is_used_for_its_driver_only(cache_home):
    d = json.loads(json.dumps(backend_cost.shipped_dict()))
    d["cpu"]["import_s"] = 9.0
    d["driver_key"] = "this-driver"
    backend_cost.machine_file().parent.mkdir(parents=True)
    backend_cost.machine_file().write_text(json.dumps(d))
    assert backend_cost.load("this-driver").cpu.import_s == 9.0
    assert backend_cost.load("this-driver").source == str(backend_cost.machine_file())
    assert backend_cost.load("another-driver").source == "shipped"
    backend_cost.machine_file().write_text("{corrupt")
    assert backend_cost._load(str(backend_cost.machine_file()), "x").source == "shipped"
