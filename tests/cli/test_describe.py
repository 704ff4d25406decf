"""``pyramid explain`` and ``pyramid plan`` (pyramid_cli.cli.describe): the commands that read no image."""

import json

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.cli import invoke
from pyramid_cli.core.parse import parse
from pyramid_cli.reference import filters as reference

pytestmark = pytest.mark.cli


def test_explain_json_fields_for_quadratic():
    r = invoke("explain", "--json", "h_box^↘ ⊗↓ (h_Bartlett ⊗ g)")
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["expression"] == "h_box^↘ ⊗↓ (h_Bartlett ⊗ g)"
    assert d["kind"] == "analysis" and d["stride"] == 2
    (ph,) = d["phases"]
    assert ph["phase"] == [0, 0] and ph["denominator"] == 64
    assert ph["weights"] == [[1, 3, 3, 1], [3, 9, 9, 3], [3, 9, 9, 3], [1, 3, 3, 1]]
    assert ph["anchor"] == [1, 1]
    assert d["continuity"] == "C^1" and d["lattice"] == "dual" and d["fetches"] == 3


def test_explain_json_synthesis_has_four_phases_that_match_the_reference():
    d = json.loads(invoke("explain", "--json", "doosabin").output)
    assert d["kind"] == "synthesis" and len(d["phases"]) == 4
    # Apply the JSON's own weights with its documented index rule and compare to the reference.
    g = np.random.default_rng(0).random((6, 5))
    want = reference.run(parse("doosabin"), g)
    got = np.zeros_like(want)
    for ph in d["phases"]:
        w = np.array(ph["weights"]) / ph["denominator"]
        i0, j0 = ph["anchor"]
        for r in range(1, want.shape[0] + 1):
            for c in range(1, want.shape[1] + 1):
                if [r % 2, c % 2] != ph["phase"]:
                    continue
                R, C = (r + 1) // 2, (c + 1) // 2
                for i in range(w.shape[0]):
                    for j in range(w.shape[1]):
                        rr = min(max(R - (i - i0), 1), g.shape[0])
                        cc = min(max(C - (j - j0), 1), g.shape[1])
                        got[r - 1, c - 1] += w[i, j] * g[rr - 1, cc - 1]
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_explain_report_prints_the_kernel_like_the_paper():
    r = invoke("explain", "bartlett")
    assert "1/16 ⎡1 2 1⎤" in r.output
    assert "= 1/4 [1 2 1]ᵀ · 1/4 [1 2 1]" in r.output


@pytest.mark.slow
def test_explain_plot_writes_a_png(tmp_path):
    out = tmp_path / "box4.png"
    r = invoke("explain", "--plot", str(out), "box4 *v g")
    assert r.exit_code == 0, r.output
    assert oiio.ImageInput.open(str(out)) is not None


@pytest.mark.parametrize("size", ["1920x1080", "1920×1080", " 64 X 32 "])
def test_plan_reads_every_spelling_of_a_size(size):
    r = invoke("plan", "--json", "quadratic *v g", "--size", size)
    assert r.exit_code == 0, r.output
    assert json.loads(r.output) == json.loads(invoke("plan", "--json", "quadratic *v g", "--size",
                                                     size.replace("×", "x").replace("X", "x").replace(" ", "")).output)


@pytest.mark.parametrize("size", ["1920", "0x1080", "1920x", "axb"])
def test_plan_refuses_a_bad_size_with_exit_2(size):
    r = invoke("plan", "box *v g", "--size", size)
    assert r.exit_code == 2 and "expected WIDTHxHEIGHT" in r.output


def test_plan_backend_without_memory_is_a_usage_error():
    r = invoke("plan", "gauss7", "--size", "64x64", "--backend", "gl")
    assert r.exit_code == 2 and "give --memory too" in r.output


def test_plan_memory_adds_a_memory_line_and_a_json_field():
    r = invoke("plan", "gauss7", "--size", "256x256", "--memory", "1G")
    assert r.exit_code == 0, r.output
    assert r.output.splitlines()[-1].startswith("memory: ")
    d = json.loads(invoke("plan", "--json", "gauss7", "--size", "256x256", "--memory", "1G").output)
    assert "memory" in d
    assert "memory" not in json.loads(invoke("plan", "--json", "gauss7", "--size", "256x256").output)


def test_plan_mipmap_of_a_single_pixel_has_no_levels():
    r = invoke("plan", "--mipmap", "down", "box *v g", "--size", "1x1")
    assert r.exit_code == 2 and "its own MIP map" in r.output
    r = invoke("plan", "--mipmap", "down", "quadratic *v g", "--size", "33x17")
    assert r.exit_code == 0, r.output
