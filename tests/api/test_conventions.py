"""The Python API in the conventions of numpy's neighbours (scikit-image, OpenCV, scipy.ndimage): result dtypes,
single reduce/expand steps, border names, checks before returning, warnings and logging, the exported job values."""

from __future__ import annotations

import logging
import warnings

import numpy as np
import pytest

import pyramid_cli as pyr
from pyramid_cli.core import catalogue
from pyramid_cli.core.border import BORDER_ALIASES, BORDER_REFUSED
from pyramid_cli.core.errors import BackendWarning, MaskWarning, MixedLatticeWarning, PyramidWarning
from pyramid_cli.reference import pyramids

DTYPES = [np.uint8, np.uint16, np.float16, np.float32, np.float64]


def picture(dtype, shape=(13, 11, 3), seed=0) -> np.ndarray:
    x = np.random.default_rng(seed).random(shape)
    if np.dtype(dtype).kind == "u":
        return np.rint(x * np.iinfo(dtype).max).astype(dtype)
    return x.astype(dtype)


@pytest.mark.parametrize("dtype", DTYPES, ids=lambda d: np.dtype(d).name)
def test_results_keep_the_input_dtype_and_levels_are_copies(dtype):
    a = picture(dtype)
    calls = {
        "apply": [pyr.apply("quadratic *v g", a, backend="cpu")], "blur": [pyr.blur(a, 2, backend="cpu")],
        "reduce": [pyr.reduce(a, backend="cpu")], "expand": [pyr.expand(a, backend="cpu")],
        "pyramid": list(pyr.pyramid(a, backend="cpu")), "mipmap": pyr.mipmap(a, backend="cpu"),
        "fill": [pyr.fill(a, mask=np.ones(a.shape[:2]), backend="cpu")],
        "blend": [pyr.blend(a, a, np.ones(a.shape[:2]), levels=2, backend="cpu")],
    }
    for name, outs in calls.items():
        assert [o.dtype for o in outs] == [np.dtype(dtype)] * len(outs), name
        assert not any(np.shares_memory(o, a) for o in outs), name
    levels = calls["pyramid"]
    np.testing.assert_array_equal(levels[0], a)
    np.testing.assert_array_equal(calls["fill"][0], a)  # known pixels come back bit for bit, as codes too
    bands = pyr.laplacian(a, 2, backend="cpu")  # bands are signed: integer inputs give float32 bands
    assert {b.dtype for b in bands} == {np.dtype(dtype) if np.dtype(dtype).kind == "f" else np.dtype(np.float32)}


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_integer_results_are_the_float_results_rounded_to_codes(dtype):
    a = picture(dtype)
    top = np.iinfo(dtype).max
    as_float = pyr.blur(a, 2, dtype=np.float32, backend="cpu")
    assert as_float.dtype == np.float32
    np.testing.assert_array_equal(pyr.blur(a, 2, backend="cpu"), np.rint(as_float.astype(np.float64) * top))
    flat = np.full((9, 7), top // 3, dtype=dtype)
    np.testing.assert_array_equal(pyr.blur(flat, 3, backend="cpu"), flat)  # a constant round-trips exactly
    over = pyr.apply("1/2 [-1 3] * g", np.full((3, 4), top, dtype=dtype), backend="cpu")  # 1.5·max: clipped
    np.testing.assert_array_equal(over[:, 1:], top)
    asked = pyr.blur(np.linspace(0, 1, 12).reshape(3, 4), 1, dtype=dtype, backend="cpu")
    assert asked.dtype == dtype


def test_float64_is_computed_in_float64_and_float16_rounded_from_float32():
    a = picture(np.float64, (17, 13))
    want = pyramids.blur_reference(a, 3)
    np.testing.assert_array_equal(pyr.blur(a, 3, backend="reference"), want)  # the float64 oracle itself
    np.testing.assert_allclose(pyr.blur(a, 3, backend="cpu"), want, rtol=0, atol=1e-14)  # float64 on the CPU
    for backend in ("cpu", "auto"):  # on the compiled CPU executor's float64 kernels, not the numpy emulator
        with pyr.Session(backend=backend) as s:
            np.testing.assert_allclose(pyr.blur(a, 3, session=s), want, rtol=0, atol=1e-14)
            assert s.ran.startswith("cpu (numba")
    from pyramid_cli.exec.cpu.compile import loaded
    from pyramid_cli.exec.cpu.executor import kernel_digest

    plan = pyr.Blur(levels=3).plan(((17, 13),), "fused")
    assert all(loaded(kernel_digest(ps, np.float64)) for ps in plan.passes)
    fast = pyr.blur(a, 3, dtype=np.float32, backend="cpu")  # the fast path: the executor's float32
    assert fast.dtype == np.float32 and 0 < np.abs(fast - want).max() < 1e-6
    np.testing.assert_array_equal(fast, pyr.blur(a.astype(np.float32), 3, backend="cpu"))
    half = pyr.blur(a.astype(np.float16), 3, backend="cpu")
    np.testing.assert_array_equal(half, pyr.blur(a.astype(np.float16), 3, dtype=np.float32,
                                                 backend="cpu").astype(np.float16))
    np.testing.assert_allclose(pyr.collapse(pyr.laplacian(a, 3, backend="cpu"), backend="cpu"), a, rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match="dtype must be a float or integer type"):
        pyr.blur(a, 1, dtype=bool)


@pytest.mark.parametrize("analysis", catalogue.ANALYSIS_FILTERS)
def test_reduce_is_apply_of_one_analysis_step(analysis):
    a = picture(np.float32, (9, 14, 2), seed=1)
    np.testing.assert_array_equal(pyr.reduce(a, analysis=analysis, border="wrap", backend="cpu"),
                                  pyr.apply(f"{analysis} *v g", a, border="wrap", backend="cpu"))


@pytest.mark.parametrize("synthesis", catalogue.SYNTHESIS_FILTERS)
def test_expand_is_apply_of_one_synthesis_step(synthesis):
    a = picture(np.float32, (5, 4), seed=2)
    got = pyr.expand(a, synthesis=synthesis, border="mirror", backend="cpu")
    assert got.shape == (10, 8)
    np.testing.assert_array_equal(got, pyr.apply(f"{synthesis} *^ g", a, border="mirror", backend="cpu"))


@pytest.fixture(scope="module")
def modes():
    """Each of our border modes on one picture, and the picture."""
    a = picture(np.float64, (7, 6), seed=3)
    return a, {m: pyr.apply("gauss7 * g", a, border=m, backend="reference") for m in set(BORDER_ALIASES.values())}


@pytest.mark.parametrize("alias", sorted(BORDER_ALIASES))
def test_each_border_alias_equals_its_mode(modes, alias):
    a, ours = modes
    np.testing.assert_array_equal(pyr.apply("gauss7 * g", a, border=alias, backend="reference"),
                                  ours[BORDER_ALIASES[alias]])
    if alias in ("edge", "symmetric", "wrap", "constant"):  # numpy.pad's own mode of that name reads the same
        padded = pyr.apply("gauss7 * g", np.pad(a, 3, mode=alias), backend="reference")[3:-3, 3:-3]
        np.testing.assert_allclose(padded, ours[BORDER_ALIASES[alias]], rtol=0, atol=1e-15)


def test_reflect_is_refused_because_no_mode_equals_numpys(modes):
    a, ours = modes
    numpy_reflect = pyr.apply("gauss7 * g", np.pad(a, 3, mode="reflect"), backend="reference")[3:-3, 3:-3]
    assert all(np.abs(numpy_reflect - v).max() > 1e-3 for v in ours.values())
    for name in BORDER_REFUSED:
        with pytest.raises(ValueError, match=f"border '{name}'"):
            pyr.blur(a, 1, border=name)


def test_every_border_docstring_lists_the_aliases():
    for f in (pyr.apply, pyr.reduce, pyr.expand, pyr.blur, pyr.pyramid, pyr.laplacian, pyr.collapse, pyr.mipmap,
              pyr.fill, pyr.blend):
        for name in ("clamp", "edge", "nearest", "symmetric", "periodic", "constant"):
            assert name in " ".join(f.__doc__.split()), (f.__name__, name)
    assert "pyramid_laplacian" in pyr.laplacian.__doc__ and "smoothed at the same" in pyr.laplacian.__doc__


@pytest.mark.parametrize("call", [
    lambda: pyr.pyramid(np.ones(5)), lambda: pyr.pyramid(np.ones((4, 4)), levels=99),
    lambda: pyr.pyramid(np.ones((4, 4)), border="reflect"), lambda: pyr.pyramid(np.ones((4, 4)), analysis="doosabin"),
    lambda: pyr.mipmap(np.ones((4, 4)), dtype="complex64"), lambda: pyr.reduce(np.ones((4, 4)), analysis="nearest"),
], ids=["shape", "levels", "border", "filter", "dtype", "role"])
def test_every_function_checks_before_it_returns(call):
    with pytest.raises(ValueError):
        call()  # not at the first next()


@pytest.mark.parametrize("keep_alpha", [False, True])
def test_a_float64_fill_from_alpha_keeps_its_known_pixels_bit_for_bit(keep_alpha):
    a = picture(np.float64, (9, 8, 4), seed=5)
    a[:, :, 3] = 1.0
    a[3:6, 2:5] = 0.0  # a premultiplied hole
    filled = pyr.fill(a, keep_alpha=keep_alpha, backend="cpu")
    assert filled.dtype == np.float64
    np.testing.assert_array_equal(filled[a[:, :, 3] == 1], a[a[:, :, 3] == 1])


def test_collapse_of_integer_input_gives_codes_back():
    a = picture(np.uint8, (12, 9))
    np.testing.assert_array_equal(pyr.collapse(pyr.laplacian(a, 3, backend="cpu"), dtype=np.uint8, backend="cpu"), a)
    assert pyr.collapse(pyr.laplacian(a, 2, backend="cpu"), border="edge", backend="cpu").dtype == np.float32


def test_warnings_are_pyramid_warnings_at_the_callers_line(caplog):
    a = np.random.default_rng(4).random((16, 16)).astype(np.float32)  # float32: no float64 kernels to compile
    with pytest.warns(MixedLatticeWarning, match="half a fine pixel per level") as caught:
        pyr.blur(a, 2, analysis="quadratic", synthesis="cubic", backend="cpu")
    assert caught[0].filename == __file__ and issubclass(caught[0].category, PyramidWarning)
    with pytest.warns(MaskWarning, match=r"outside \[0, 1\]") as caught:
        pyr.fill(a, mask=np.full((16, 16), 1.5), backend="cpu")
    assert caught[0].filename == __file__
    with pytest.warns(BackendWarning, match="no GL") as caught:
        pyr.Session("cpu")._warn("no GL here; running on the CPU")
    assert caught[0].filename == __file__
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", category=PyramidWarning)  # one filter silences them all
        pyr.blur(a, 2, analysis="quadratic", synthesis="cubic", backend="cpu")
    with caplog.at_level(logging.INFO, logger="pyramid_cli"):
        pyr.blur(a, sigma=2.0, backend="cpu")
    assert any("sigma 2" in r.getMessage() for r in caplog.records if r.name == "pyramid_cli")


def test_job_values_are_exported_and_process_files_reports_each_file(tmp_path):
    from pyramid_cli.jobs import texture, work

    assert (pyr.Fill, pyr.Blend, pyr.TextureLevels, pyr.Filter) == (work.Fill, work.Blend, texture.TextureLevels,
                                                                     work.Filter)
    good = tmp_path / "good.exr"
    pyr.write_image(good, np.full((6, 5, 3), 0.5, np.float32))
    (tmp_path / "bad.exr").write_text("not an image")
    with pytest.warns(MixedLatticeWarning):
        report = pyr.process_files(pyr.Blur(levels=1, analysis="quadratic", synthesis="cubic"),
                                   [str(good), str(tmp_path / "bad.exr")], template=str(tmp_path / "o" / "{stem}.exr"),
                                   backend="cpu", keep_going=True)
    assert [j.input for j in report.done] == [str(good)] and not report.skipped
    [(job, error)] = report.failed
    assert job.input.endswith("bad.exr") and isinstance(error, OSError) and "bad.exr" in str(error)
    assert report.exit_code == error.exit_code == 3
