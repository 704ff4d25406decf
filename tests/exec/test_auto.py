"""What auto compares (pyramid_cli/exec/auto.py): kernels and programs a job needs, the -v line, which
calibration stands for which renderer."""

from __future__ import annotations

import pytest

from pyramid_cli.exec import auto
from pyramid_cli.jobs.work import Blur
from pyramid_cli.plan import backend_cost
from pyramid_cli.plan.backend_cost import Estimate
from pyramid_cli.plan.shapes import shape


def test_kernels_missing_from_an_empty_cache_are_compiles(monkeypatch, tmp_path):
    monkeypatch.setenv("PYRAMID_CACHE_DIR", str(tmp_path))
    p = Blur(levels=3).plan([(64, 64)], "fused")
    from pyramid_cli.exec.cpu import codegen
    from pyramid_cli.exec.cpu.compile import loaded, source_digest

    loads, compiles = auto.cpu_kernels(p)
    distinct = {source_digest(codegen.kernel_source(shape(ps))) for ps in p.passes}
    assert loads == 0 and compiles == sum(not loaded(d) for d in distinct)  # loaded in this process: neither


def test_programs_are_counted_once_per_pass_shape():
    p = Blur(levels=5).plan([(1080, 1920)], "cost")
    assert 0 < auto.gl_programs(p) < len(p.passes)


def test_estimates_name_both_backends_and_grow_with_the_batch():
    costs = backend_cost.load()
    cpu_plan, gl_plan = Blur(levels=2).plan([(64, 64)], "fused"), Blur(levels=2).plan([(64, 64)], "cost")
    one = auto.estimates(cpu_plan, gl_plan, 3, costs=costs)
    many = auto.estimates(cpu_plan, gl_plan, 3, jobs=10, costs=costs)
    assert set(one) == {"cpu", "gl"} and all(many[b].seconds > one[b].seconds for b in one)
    assert set(auto.estimates(None, gl_plan, 3, costs=costs)) == {"gl"}


def test_the_line_gives_each_estimate_and_the_choice():
    found = {"gl": Estimate("gl", 1.31, 0, 0), "cpu": Estimate("cpu", 1.92, 0, 0)}
    assert auto.line(found, {"gl": "gl (llvmpipe …)"}, "gl") == "auto: cpu 1.92 s, gl (llvmpipe …) 1.31 s (est.) → gl"


@pytest.mark.parametrize("measured, here, stands", [("llvmpipe (LLVM 15)", "llvmpipe (LLVM 17)", True),
                                                    ("NVIDIA A100", "NVIDIA A100", True),
                                                    ("llvmpipe (LLVM 15)", "NVIDIA H100", False),
                                                    ("NVIDIA A100", "llvmpipe (LLVM 15)", False)])
def test_a_calibration_stands_for_its_renderer_or_another_software_one(measured, here, stands):
    costs = backend_cost.from_dict({**backend_cost.shipped_dict(), "renderer": measured})
    assert auto.calibrated_for(costs, here) is stands
