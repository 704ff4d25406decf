"""The CPU executor's float64 kernels: the conformance suite's idea at float64, and float32 left as it was.

A float64 run (``run_outputs(..., dtype=float64)``) computes in float64 throughout on kernels generated at that
width, so it equals the float64 reference to float64 rounding (1e-12 relative here), on odd sizes and every
border, for pass plans (a blur), resampling plans (MIP levels at odd sizes) and pointwise plans (fill, blend).
Few kernel shapes on purpose: each float64 shape compiles once per machine (about a second on 2 cores), into the
tests' kernel cache (tests/exec/cpu/conftest.py), so a rerun loads them.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from pyramid_cli.exec.cpu import CPUExecutor, codegen  # noqa: E402
from pyramid_cli.exec.cpu.compile import loaded, source_digest  # noqa: E402
from pyramid_cli.exec.cpu.executor import kernel_digest  # noqa: E402
from pyramid_cli.jobs.texture import TextureLevels  # noqa: E402
from pyramid_cli.jobs.work import Blend, Blur, Fill  # noqa: E402
from pyramid_cli.plan.shapes import shape  # noqa: E402

BORDERS = ["clamp", "mirror", "wrap", "zero"]
SIZES = [(5, 3), (67, 91)]  # windows only; an interior with border strips (over TINY floats at 3 channels)
RTOL = 1e-12


@pytest.fixture(scope="module")
def ex(cache_folder):
    with CPUExecutor(threads=2, cache=cache_folder) as executor:
        yield executor


def close(got: list[np.ndarray], want: list[np.ndarray]) -> None:
    """Every output float64 and within :data:`RTOL` of the reference, relative to its largest value."""
    assert len(got) == len(want)
    for g, w in zip(got, want, strict=True):
        assert g.dtype == np.float64 and g.shape == np.shape(w)
        np.testing.assert_allclose(g, w, rtol=0, atol=RTOL * max(1.0, float(np.max(np.abs(w)))))


def run(ex, work, images) -> list[np.ndarray]:
    p = work.plan(tuple(im.shape[:2] for im in images), ex.strategy)
    return ex.run_outputs(p, images, np.float64)


def picture(size, seed, channels=3) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal(size + (channels,))


def test_the_float32_text_is_unchanged_and_float64_is_its_own_kernel():
    p = Blur(levels=1).plan(((9, 7),), "fused")
    s = shape(p.passes[0])
    f32, f64 = codegen.kernel_source(s), codegen.kernel_source(s, np.float64)
    assert codegen.kernel_source(s, np.float32) == f32 and "float64" not in f32
    assert "float32" not in f64 and f64.replace("float64", "float32").count("\n") == f32.count("\n")
    for make in (codegen.resample_source, codegen.pointwise_source):
        assert "float64" not in make() and "float32" not in make(np.float64)
    assert codegen.signature(1, 1, np.float64) == codegen.signature(1, 1).replace("float32", "float64")
    digests = {source_digest(f32), source_digest(f64)}
    assert kernel_digest(p.passes[0]) == source_digest(f32) and kernel_digest(p.passes[0], np.float64) in digests
    assert len(digests) == 2
    with pytest.raises(ValueError, match="float32 or float64"):
        codegen.kernel_source(s, np.float16)


@pytest.mark.parametrize("border", BORDERS)
def test_a_blur_equals_the_float64_reference(ex, border):
    work = Blur(levels=2, border=border)
    for seed, size in enumerate(SIZES):
        a = picture(size, seed)
        close(run(ex, work, [a]), work.reference([a]))


@pytest.mark.parametrize("border", BORDERS)
def test_mip_levels_at_odd_sizes_equal_the_float64_reference(ex, border):
    work = TextureLevels(levels=None, border=border)
    for seed, size in enumerate([(5, 3), (37, 23), (1, 7)]):
        a = picture(size, seed, channels=4)
        close(run(ex, work, [a]), work.reference([a]))  # levels 1 and on (level 0 is the input)


@pytest.mark.parametrize("border", ["clamp", "wrap"])
def test_fill_and_blend_equal_the_float64_reference(ex, border):
    rng = np.random.default_rng(7)
    for size in SIZES:
        weight = np.repeat((rng.random(size + (1,)) < 0.4).astype(np.float64), 3, axis=2)
        weight[0, 0] = 1.0
        colour = picture(size, 1) * weight  # premultiplied
        fill = Fill(border=border)
        close(run(ex, fill, [colour, weight]), fill.reference([colour, weight]))
        a, b, mask = picture(size, 2), picture(size, 3), np.repeat(rng.random(size + (1,)), 3, axis=2)
        blend = Blend(levels=2, border=border)
        close(run(ex, blend, [a, b, mask]), blend.reference([a, b, mask]))


def test_float64_runs_use_their_own_kernels_and_float32_runs_are_unchanged(ex):
    work = Blur(levels=2)
    a = picture((13, 11), 4)
    p = work.plan(((13, 11),), ex.strategy)
    f32, f64 = ex.kernel_digests(p), ex.kernel_digests(p, np.float64)
    assert not f32 & f64 and f32 == ex.kernel_digests(p, np.float16)
    (wide,) = ex.run_outputs(p, [a], np.float64)
    assert all(loaded(d) for d in f64) and ex.uncached(p, np.float64) == 0
    (narrow,) = ex.run_outputs(p, [a.astype(np.float32)])
    np.testing.assert_array_equal(narrow, ex.run(p, a))  # float64 pixels into a float32 run: as before
    np.testing.assert_allclose(narrow, wide, rtol=0, atol=1e-5)
    half = a.astype(np.float16)
    np.testing.assert_array_equal(ex.run_outputs(p, [half], np.float64)[0], ex.run_outputs(p, [half.astype(
        np.float64)], np.float64)[0])  # half pixels in a float64 run: read exactly, computed in float64


def test_a_float32_run_generates_no_float64_kernel(cache_folder, monkeypatch):
    """A fresh executor's float32 runs make (compile or load) their float32 kernels only: the float64 text is not
    even written for them."""
    from pyramid_cli.exec.cpu import executor as module

    made = []

    def spy(real, typed_at: int):  # the working type is argument ``typed_at`` (float32 when not given)
        def generate(*args):
            made.append(np.dtype(args[typed_at]).name if len(args) > typed_at else "float32")
            return real(*args)
        return generate

    for name, typed_at in (("kernel_source", 1), ("resample_source", 0), ("pointwise_source", 0)):
        monkeypatch.setattr(module, name, spy(getattr(module, name), typed_at))
    with CPUExecutor(threads=1, cache=cache_folder) as fresh:
        a = picture((13, 11), 4)
        for work in (Blur(levels=2), TextureLevels(levels=None)):
            fresh.run_outputs(work.plan(((13, 11),), fresh.strategy), [a.astype(np.float32)])
        fresh.run_outputs(Fill().plan(((13, 11),), fresh.strategy), [a, np.ones_like(a)], np.float16)
    assert made and set(made) == {"float32"}
