"""The GL executor (``pyramid_cli.exec.gl.executor``) against the float64 oracle (``reference``) and the plan's
living definition (``emulate``)."""

from functools import cache

import numpy as np
import pytest

import pyramid_cli.exec.gl.shaders as generate
from helpers.marks import slow_beyond
from pyramid_cli.core.errors import DataError
from pyramid_cli.core.parse import parse
from pyramid_cli.exec import emulate
from pyramid_cli.plan import plan
from pyramid_cli.reference import filters as reference

gl_mark = pytest.mark.gl


@cache
def planned(text: str, size: tuple[int, int], strategy: str = "cost"):
    return parse(text), plan(parse(text), size, strategy)


def random_image(size, channels, seed):
    rng = np.random.default_rng(seed)
    return rng.random(size if channels is None else size + (channels,)).astype(np.float32)


@gl_mark
def test_row_zero_is_numpy_row_zero(gl):
    """The identity copies a non-symmetric image bit for bit: no flip, no transpose."""
    image = np.arange(6 * 9 * 2, dtype=np.float32).reshape(6, 9, 2)
    _, p = planned("g", (6, 9))
    np.testing.assert_array_equal(gl.run(p, image), image)


@gl_mark
def test_box_se_moves_a_bright_pixel_down_right(gl):
    """box↘ = ¼[[0,0,0],[0,1,1],[0,1,1]]: f[r,c] = ¼(g[r,c] + g[r−1,c] + g[r,c−1] + g[r−1,c−1])."""
    image = np.zeros((6, 9), dtype=np.float32)
    image[2, 5] = 1.0
    expr, p = planned("box\\ * g", (6, 9))
    out = gl.run(p, image)
    expected = np.zeros_like(image)
    expected[2:4, 5:7] = 0.25
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-7)
    np.testing.assert_allclose(out, reference.run(expr, image), rtol=0, atol=1e-7)


@gl_mark
def test_more_than_four_channels_run_in_groups(gl):
    image = random_image((17, 13), 6, seed=7)
    expr, p = planned("doosabin *^ (box4 *v g)", (17, 13))
    out = gl.run(p, image)
    assert out.shape == (18, 14, 6)
    np.testing.assert_allclose(out, reference.run(expr, image), rtol=0, atol=1e-5)
    for c in range(6):  # each channel as if alone
        np.testing.assert_allclose(out[:, :, c], gl.run(p, image[:, :, c]), rtol=0, atol=0)


@gl_mark
@pytest.mark.parametrize("text", slow_beyond(["cubic *^ g", "fourpoint", "box *v g", "gauss5"], 1))
def test_quarter_taps_are_exact_at_non_power_of_two_sizes(gl, text):
    """Normalized coordinates of non-power-of-two textures would be off by ~width·2⁻²⁴ texel (≈6e-5 here)."""
    size = (600, 1001)
    image = random_image(size, None, seed=3)
    _, p = planned(text, size)
    np.testing.assert_allclose(gl.run(p, image), emulate.run(p, image), rtol=0, atol=1e-6)


@gl_mark
@pytest.mark.parametrize("text", ["gauss7", "(doosabin)^2 *^ ((box4)^2 *v g)", "fourpoint", "box4 *v g"])
def test_half_precision_within_half_tolerance(gl, text):
    from pyramid_cli.exec.gl import GLExecutor

    size = (33, 20)
    image = random_image(size, 3, seed=11)
    expr, p = planned(text, size)
    with GLExecutor(precision="half") as half:
        out = half.run(p, image)
        assert half.error == "GL_NO_ERROR"
    assert out.dtype == np.float32
    ref = reference.run(expr, image)
    # each RGBA16F pass rounds to 11 significant bits: at most 2⁻¹¹ relative per pass
    np.testing.assert_allclose(out, ref, rtol=0, atol=len(p.passes) * 2.0 ** -11 * 1.5)
    assert np.abs(out - ref).max() > 1e-7  # it really stored halves


@gl_mark
def test_half_precision_does_not_hold_values_above_65504(gl):
    from pyramid_cli.exec.gl import GLExecutor

    image = np.full((2, 3), 1e5, dtype=np.float32)
    _, p = planned("g", (2, 3))
    with GLExecutor(precision="half") as half:
        out = half.run(p, image)
        assert half.error == "GL_NO_ERROR"  # saturation is not a GL error
    assert np.all(out >= 65504) and not np.any(np.isclose(out, 1e5))
    np.testing.assert_array_equal(gl.run(p, image), image)  # RGBA32F is unclamped


@gl_mark
def test_program_cache_compiles_each_shape_once(gl):
    from pyramid_cli.exec.gl import GLExecutor

    _, p = planned("gauss5", (17, 13), "paper")  # the paper's passes: the cost model fuses tiny images
    shapes = {generate.shape(ps) for ps in p.passes}
    assert len(shapes) == 2 < len(p.passes)  # box↖ and box↘ alternate
    with GLExecutor() as fresh:
        fresh.run(p, random_image((17, 13), None, 0))
        assert fresh.compiles == 2
        pooled = sum(len(v) for v in fresh._free.values())
        fresh.run(p, random_image((17, 13), 4, 1))
        _, other = planned("gauss5", (64, 129), "paper")
        fresh.run(other, random_image((64, 129), 6, 2))
        assert fresh.compiles == 2
        fresh.run(p, random_image((17, 13), 3, 3))
        assert sum(len(v) for v in fresh._free.values()) >= pooled
        assert fresh.compiles == 2
        _, box = planned("box\\ * g", (5, 3))  # the second shape of gauss5: nothing new
        fresh.run(box, random_image((5, 3), None, 4))
        assert fresh.compiles == 2
        assert fresh.error == "GL_NO_ERROR"


@gl_mark
def test_executors_and_probes_interleave(gl):
    """Each executor makes its own context current: another context, or available(), cannot steal its calls."""
    from pyramid_cli.exec.gl import GLExecutor, available

    image = random_image((9, 5), 3, seed=5)
    expr, p = planned("cubic *^ g", (9, 5))
    ref = reference.run(expr, image)
    with GLExecutor() as other:
        np.testing.assert_allclose(other.run(p, image), ref, rtol=0, atol=1e-5)
        np.testing.assert_allclose(gl.run(p, image), ref, rtol=0, atol=1e-5)
        assert available()[0]
        np.testing.assert_allclose(other.run(p, image), ref, rtol=0, atol=1e-5)
    np.testing.assert_allclose(gl.run(p, image), ref, rtol=0, atol=1e-5)
    info = gl.info()
    assert info["max_texture_size"] >= 4096 and info["renderer"]


@gl_mark
def test_too_large_for_one_texture_runs_in_tiles(gl):
    """Beyond GL_MAX_TEXTURE_SIZE the check refuses the whole picture, and the run goes tile by tile (issue 18)."""
    limit = gl.max_texture_size
    _, wide = planned("box *v g", (1, limit + 1))
    with pytest.raises(DataError, match=f"{limit + 1}x1 exceeds the limit of {limit}x{limit}"):
        gl.check(wide)
    x = random_image((1, limit + 1), None, 2)
    assert not gl.fits(wide)
    np.testing.assert_allclose(gl.run(wide, x), emulate.run(wide, x), rtol=0, atol=1e-6)
    _, up = planned("nearest", (limit // 2 + 1, 1))  # the input fits, the output does not
    assert not gl.fits(up)
    x = random_image((limit // 2 + 1, 1), None, 3)
    np.testing.assert_allclose(gl.run(up, x), emulate.run(up, x), rtol=0, atol=1e-6)


@gl_mark
@pytest.mark.parametrize("channels", [None, 4], ids=["staged", "rgba-direct"])
@pytest.mark.parametrize("text", ["cubic *^ g", "box *v g", "bartlett"])
def test_stale_pool_contents_never_leak(gl, text, channels):
    """A NaN image leaves NaN in pooled textures; the next, smaller image must not read it at its edges."""
    _, dirty = planned(text, (7, 7))
    gl.run(dirty, np.full((7, 7) + ((channels,) if channels else ()), np.nan, dtype=np.float32))
    expr, p = planned(text, (5, 6))  # the same power-of-two textures
    image = random_image((5, 6), channels, seed=9)
    out = gl.run(p, image)
    np.testing.assert_allclose(out, reference.run(expr, image), rtol=0, atol=1e-5)


@gl_mark
def test_half_read_back_rounds_like_numpy(gl):
    """Ties, subnormals, overflow and NaN: the read-back's float → half equals numpy's, bit for bit."""
    rng = np.random.default_rng(3)
    h = rng.integers(0, 0x7C00, size=4096, dtype=np.uint16).view(np.float16)
    up = np.nextafter(h, np.float16(np.inf))
    ties = (h.astype(np.float32) + up.astype(np.float32)) / 2  # exactly halfway: nearest even decides
    special = np.array([65504, 65520, 65519.99, 1e6, -1e6, 6e-8, 2.9e-8, 3e-8, np.inf, -np.inf, np.nan, -0.0],
                       dtype=np.float32)
    values = np.concatenate([ties, -ties, rng.standard_normal(4096).astype(np.float32) * 100, special])
    values = np.resize(values, 64 * 64 * 4).reshape(64, 64, 4).astype(np.float32)
    _, p = planned("g", (64, 64))
    (half,) = gl.run_outputs(p, [values], dtype=np.float16)
    with np.errstate(over="ignore"):
        want = values.astype(np.float16)
    same = (half.view(np.uint16) == want.view(np.uint16)) | (np.isnan(half) & np.isnan(want))
    assert same.all(), values[~same][:5]


def _round_ties_away(values: np.ndarray) -> np.ndarray:
    """float32 → float16 as NVIDIA's glReadPixels did (driver 580, H100): ties away from zero."""
    rne = values.astype(np.float16)
    away = np.nextafter(rne, np.copysign(np.float16(np.inf), rne))
    tie = np.abs(values.astype(np.float64) - rne) == np.abs(away.astype(np.float64) - values)
    return np.where(tie & (np.abs(rne) < np.abs(values)), away, rne)


def test_half_probe_tells_a_driver_that_rounds_ties_away_apart():
    """The probe's values tell nearest-even from the roundings NVIDIA's read-back used: ties away from zero,
    subnormals toward zero. Only nearest even passes."""
    from pyramid_cli.exec.gl.executor import half_probe, half_read_rounds_even

    values = half_probe()
    with np.errstate(over="ignore", invalid="ignore"):
        assert half_read_rounds_even(values, values.astype(np.float16))
        assert not half_read_rounds_even(values, _round_ties_away(values))
        flushed = values.astype(np.float16)
        flushed[np.abs(flushed) < np.float16(2.0 ** -14)] = 0  # subnormals flushed to zero
        assert not half_read_rounds_even(values, flushed)


@gl_mark
@pytest.mark.parametrize("channels", [None, 3, 4, 6])
def test_half_outputs_are_rounded_by_numpy_where_the_driver_does_not(gl, monkeypatch, channels):
    """Where the read-back would not round as numpy does, float16 outputs are read as float32 and rounded by
    numpy (no half read-back asked of GL), bit for bit the float32 outputs rounded; a 2-D image, channel
    groups that are not contiguous and one band after another included."""
    import moderngl

    from pyramid_cli.exec.gl import executor as gl_executor

    asked = []
    read_into = moderngl.Framebuffer.read_into

    def spy(self, buffer, *args, **kwargs):
        asked.append(kwargs.get("dtype", "f1"))
        return read_into(self, buffer, *args, **kwargs)

    image = random_image((67, 45), channels, 5) * 3 - 1
    image.flat[::7] = np.float32(2.0 ** -20)  # subnormal as half
    _, p = planned("doosabin *^ (box4 *v g)", (67, 45))
    want = [o.astype(np.float16) for o in gl.run_outputs(p, [image], dtype=np.float32)]
    monkeypatch.setattr(moderngl.Framebuffer, "read_into", spy)
    monkeypatch.setattr(gl, "_half_even", False)
    monkeypatch.setattr(gl_executor, "BAND_BYTES", 4 * 4 * 45 * 5)  # bands of 5 rows
    got = gl.run_outputs(p, [image], dtype=np.float16)
    assert set(asked) == {"f4"}
    for g, w in zip(got, want, strict=True):
        assert g.dtype == np.float16 and g.shape == w.shape
        np.testing.assert_array_equal(g.view(np.uint16), w.view(np.uint16))


@gl_mark
@pytest.mark.parametrize("dtype, channels", [(np.float32, 4), (np.float16, 4), (np.float32, 3), (np.float32, None)])
def test_inputs_on_a_gpu_are_uploaded_into_textures_never_rendered_into(gl, dtype, channels):
    """On a GPU (not a host-memory renderer) an input's texture has no framebuffer and is pooled apart from the
    render targets, which never reuse it; the pixels are the shared pool's, bit for bit, run after run."""
    from pyramid_cli.exec.gl import GLExecutor
    from pyramid_cli.exec.gl.executor import INPUT_POOL

    image = random_image((45, 70), channels, 9).astype(dtype)
    _, p = planned("doosabin *^ (box4 *v g)", (45, 70))
    want = gl.run(p, image)

    class OnAGPU(GLExecutor):
        host_textures = False

    with OnAGPU() as fresh:
        for _ in range(2):
            np.testing.assert_array_equal(fresh.run(p, image), want)
            inputs = [t for (_, pool), ts in fresh._free.items() if pool.endswith(INPUT_POOL) for t in ts]
            assert len(inputs) == 1 and inputs[0].fbo is None
            assert all(t.fbo is not None for (_, pool), ts in fresh._free.items() if pool == "f4" for t in ts)
        fresh.prepare(p)
        assert sum(len(ts) for ts in fresh._free.values()) == len(inputs) + sum(
            len(ts) for (_, pool), ts in fresh._free.items() if pool == "f4")


@gl_mark
def test_prepare_compiles_and_allocates_ahead(gl):
    from pyramid_cli.exec.gl import GLExecutor
    from pyramid_cli.workflows.pyramids import blur_plan

    p = blur_plan((45, 70), 3)
    with GLExecutor() as fresh:
        fresh.prepare(p)
        compiled, pooled = fresh.compiles, sum(len(v) for v in fresh._free.values())
        assert compiled == len({generate.shape(ps) for ps in p.passes}) and pooled >= 2
        made = []
        original = fresh.ctx.texture
        fresh.ctx.texture = lambda *a, **k: made.append(a) or original(*a, **k)
        image = random_image((45, 70), 4, seed=2)
        out = fresh.run(p, image)
        assert not made and fresh.compiles == compiled  # everything came from prepare
    np.testing.assert_allclose(out, emulate.run(p, image), rtol=0, atol=1e-5)


@gl_mark
def test_runs_after_clear_pool(gl):
    """clear_pool deletes the framebuffer last bound; the next run must still make its own."""
    from pyramid_cli.exec.gl import GLExecutor

    expr, p = planned("box4 *v g", (16, 16))
    image = random_image((16, 16), 4, seed=9)
    with GLExecutor() as fresh:
        first = fresh.run(p, image)
        fresh.clear_pool()
        assert not fresh._free
        np.testing.assert_array_equal(fresh.run(p, image), first)
        assert fresh.error == "GL_NO_ERROR"
    np.testing.assert_allclose(first, reference.run(expr, image), rtol=0, atol=1e-5)


@gl_mark
@pytest.mark.parametrize("per_pass", [True, False])
def test_profile_times_a_run_and_computes_the_same(gl, per_pass):
    _, p = planned("doosabin *^ (box4 *v g)", (33, 17))
    image = random_image((33, 17), 6, 1)
    t = gl.profile(p, image, per_pass=per_pass)
    groups = 2  # six channels run as two groups of four
    assert len(t["passes"]) == (len(p.passes) * groups if per_pass else groups)
    assert all(v >= 0 for v in t["passes"]) and t["device"] == sum(t["passes"])
    assert 0 < t["upload"] + t["device"] + t["readback"] <= t["total"]
    assert gl._clock is None
    np.testing.assert_array_equal(gl.run(p, image), gl.run(p, image))


@gl_mark
@pytest.mark.parametrize("size", [(8193, 8193), (6000, 12000), (8192, 8193)])
def test_textures_of_2_gib_are_refused_before_allocating(gl, size):
    p = plan(parse("box *v g"), size)
    with pytest.raises(DataError, match="GL textures stay under 2 GiB"):
        gl.check(p)


@gl_mark
def test_allocation_failures_become_data_errors(gl, monkeypatch):
    import moderngl

    def fail(*a, **k):
        raise moderngl.Error("the framebuffer is not complete")

    monkeypatch.setattr(gl.ctx, "framebuffer", fail)
    with pytest.raises(DataError, match="cannot allocate a 65x33 RGBA f4 texture"):
        gl._acquire((33, 65), "f4")  # a size the pool never holds (textures are powers of two)
