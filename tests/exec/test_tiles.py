"""Tiled execution (issue 18): every executor gives the untiled run's pixels, exactly, for any tile."""

from __future__ import annotations

import numpy as np
import pytest

from helpers.cases import CHAINS, NAMED, several_inputs_and_outputs
from helpers.marks import slow_beyond
from pyramid_cli.core.geometry import level_sizes
from pyramid_cli.core.parse import parse
from pyramid_cli.exec import tiles
from pyramid_cli.exec.emulate import Emulator
from pyramid_cli.jobs.work import Blur, Collapse, Filter, Laplacian, Levels
from pyramid_cli.plan import plan

SIZE = (19, 13)                      # not a multiple of any tile below
TILES = [(1, 1), (4, 3), (7, 100), (100, 100)]  # 1×1 output pixels … larger than the image
BORDERS = ["clamp", "mirror", "wrap", "zero"]


def image(size, channels=3, seed=0, dtype=np.float32):
    rng = np.random.default_rng(seed)
    return rng.standard_normal(tuple(size) + ((channels,) if channels else ())).astype(dtype)


def works():
    """Every job kind: pyramids of several levels, several inputs and outputs."""
    sizes = tuple(level_sizes(SIZE, 2))
    return {"blur3": (Blur(levels=3), (SIZE,)), "blur1": (Blur(levels=1), (SIZE,)),
            "levels": (Levels(levels=3), (SIZE,)), "levels-all": (Levels(), (SIZE,)),
            "laplacian": (Laplacian(levels=2), (SIZE,)), "collapse": (Collapse(bands=3), sizes)}


def assert_same_tiled(executor, p, inputs, tile, dtype=np.float32):
    want = executor.run_outputs(p, inputs)
    got = tiles.run_arrays(executor, p, inputs, band=tile[0], width=tile[1], dtype=dtype)
    assert len(got) == len(want)
    for k, (w, g) in enumerate(zip(want, got, strict=True)):
        assert g.shape == w.shape
        bad = np.argwhere(w != g)
        assert not len(bad), f"output {k}: {len(bad)} pixels differ, first at {bad[0].tolist()}"


def run_grid(executor, dtype, texts, tiles_, borders):
    for text in texts:
        for border in borders:
            p = plan(parse(text), SIZE, border=border)
            for tile in tiles_:
                assert_same_tiled(executor, p, image(SIZE), tile, dtype)


# ------------------------------------------------------------------ the emulator
EMU = Emulator()


@pytest.mark.parametrize("text", slow_beyond(NAMED + CHAINS, 2))
def test_emulator_tiled_equals_untiled_every_filter(text):
    run_grid(EMU, np.float64, [text], TILES, ["clamp"])


@pytest.mark.slow
@pytest.mark.parametrize("border", BORDERS[1:])
def test_emulator_tiled_equals_untiled_every_border(border):
    run_grid(EMU, np.float64, ["gauss5", "bartlett * (bartlett * g)", "doosabin *^ (box4 *v g)", "box *v^2 g",
                               "fourpoint"], [(1, 1), (4, 3)], [border])


@pytest.mark.parametrize("name", slow_beyond(list(works()), 3))
@pytest.mark.parametrize("border", slow_beyond(["clamp", "mirror", "wrap"]))
def test_emulator_tiled_pyramids(name, border):
    work, sizes = works()[name]
    work = type(work)(**{**work.__dict__, "border": border})
    p = work.plan(sizes)
    inputs = [image(s, 2, seed=k) for k, s in enumerate(sizes)]
    for tile in TILES:
        assert_same_tiled(EMU, p, inputs, tile, np.float64)


def test_emulator_several_inputs_and_outputs():
    p = several_inputs_and_outputs(SIZE)
    for tile in TILES:
        assert_same_tiled(EMU, p, [image(SIZE, None, 1), image(SIZE, None, 2)], tile, np.float64)


def test_the_band_is_bounded():
    """A tall image in bands of 8 rows keeps a few bands of rows per level, not the picture."""
    p = Blur(levels=3).plan(((400, 16),))
    got = []
    s = tiles.Scheduler(EMU, p, lambda k, r, c: image((400, 16), 1)[r[0]:r[1], c[0]:c[1]].astype(np.float64),
                        lambda k, r, c, px: got.append(px), band=8, dtype=np.float64)
    s.run()
    assert sum(len(g) for g in got) == 400
    assert s.peak_pixels < 400 * 16 / 4, s.peak_pixels


@pytest.mark.parametrize("kind", ["levels", "mip"])
def test_a_chain_down_to_one_pixel_is_bounded_too(kind):
    """Levels down to 1×1 (and MIP chains) in bands: the coarse levels follow the finest instead of
    pulling the whole picture in for the one row of the 1×1 level at the first band."""
    from pyramid_cli.workflows.pyramids import mip_plan

    size = (512, 16)
    p = Levels().plan((size,)) if kind == "levels" else mip_plan(size)
    got = {}
    s = tiles.Scheduler(EMU, p, lambda k, r, c: image(size, 1)[r[0]:r[1], c[0]:c[1]].astype(np.float64),
                        lambda k, r, c, px: got.setdefault(k, []).append(px), band=8, dtype=np.float64)
    s.run()
    assert {k: sum(len(g) for g in v) for k, v in got.items()} == {k: p.images[k].size[0] for k in p.outputs}
    assert s.peak_pixels < size[0] * size[1] / 4, s.peak_pixels


def test_reads_of_a_pass_include_the_guard_band():
    p = plan(parse("gauss5"), (9, 9))
    first = p.passes[0]
    reads = first.reads((-p.images[first.target].guard[0], 1), (0, 1))
    assert reads[0][0][0] < 0  # rows above the image: folded by the input's border mode
    step = p.passes[-1].tile((3, 5), (2, 4))
    assert step.rows[0] <= 3 and step.run is p.passes[-1]


# ------------------------------------------------------------------ the compiled CPU executor
# The fast tier compiles a few kernel shapes (one per kind of pass: polyphase reduce, convolution, expand,
# a chain); the slow tier every named filter and chain.
CPU_FAST = {"box4 *v g", "gauss5", "doosabin", "fourpoint *^ (cubic *v g)"}


@pytest.mark.parametrize("text", [t if t in CPU_FAST else pytest.param(t, marks=pytest.mark.slow)
                                  for t in NAMED + CHAINS])
def test_cpu_tiled_equals_untiled_every_filter(cpu_executor, text):
    run_grid(cpu_executor, np.float32, [text], [(1, 1), (4, 3), (100, 100)], ["clamp"])


@pytest.mark.slow
@pytest.mark.parametrize("border", BORDERS[1:])
def test_cpu_tiled_equals_untiled_every_border(cpu_executor, border):
    run_grid(cpu_executor, np.float32, ["gauss5", "bartlett * (bartlett * g)", "doosabin *^ (box4 *v g)", "box *v^2 g"],
             [(1, 1), (4, 3)], [border])


@pytest.mark.parametrize("name", slow_beyond(list(works()), 2))
def test_cpu_tiled_pyramids(cpu_executor, name):
    work, sizes = works()[name]
    p = work.plan(sizes)
    inputs = [image(s, 4, seed=k) for k, s in enumerate(sizes)]
    for tile in TILES:
        assert_same_tiled(cpu_executor, p, inputs, tile)


def test_cpu_tiled_half_inputs_and_outputs(cpu_executor):
    """Half inputs are read as half in every window; half outputs round like the untiled run's."""
    p = Blur(levels=2).plan((SIZE,))
    x = image(SIZE, 4, dtype=np.float16)
    want = cpu_executor.run_outputs(p, [x], np.float16)[0]
    got = tiles.run_arrays(cpu_executor, p, [x], band=5, width=4, dtype=np.float16)[0]
    assert got.dtype == np.float16 and np.array_equal(want, got)


def test_cpu_tiles_into_a_memmap(cpu_executor, tmp_path):
    """Arrays larger than RAM: a memory-mapped input read band by band, the result written into a memmap."""
    size = (40, 24)
    src = np.lib.format.open_memmap(tmp_path / "in.npy", "w+", np.float32, size + (3,))
    src[...] = image(size)
    src.flush()
    src = np.load(tmp_path / "in.npy", mmap_mode="r")
    dst = np.lib.format.open_memmap(tmp_path / "out.npy", "w+", np.float32, size + (3,))
    p = Blur(levels=3).plan((size,))
    tiles.run_arrays(cpu_executor, p, [src], band=8, out=[dst])
    dst.flush()
    assert np.array_equal(np.load(tmp_path / "out.npy"), cpu_executor.run(p, np.asarray(src)))


# ------------------------------------------------------------------ GL
gl_mark = pytest.mark.gl


GL_TILED = ["gauss5", "box4 *v g", "doosabin", "fourpoint", "bartlett * (bartlett * g)",
            "(doosabin)^2 *^ ((box4)^2 *v g)",
            "box *v^2 g"]


@gl_mark
@pytest.mark.parametrize("text", slow_beyond(GL_TILED, 2))
def test_gl_tiled_equals_untiled(gl, text):
    run_grid(gl, np.float32, [text], [(1, 1), (4, 3), (100, 100)], ["clamp"])


@gl_mark
@pytest.mark.slow
@pytest.mark.parametrize("border", BORDERS[1:])
def test_gl_tiled_equals_untiled_every_border(gl, border):
    run_grid(gl, np.float32, ["bartlett * (bartlett * g)", "doosabin *^ (box4 *v g)"], [(1, 1), (4, 3)], [border])


@gl_mark
@pytest.mark.parametrize("name", slow_beyond(list(works()), 2))
def test_gl_tiled_pyramids(gl, name):
    work, sizes = works()[name]
    p = work.plan(sizes)
    inputs = [image(s, 4, seed=k) for k, s in enumerate(sizes)]
    for tile in [(1, 1), (5, 4)]:
        assert_same_tiled(gl, p, inputs, tile)


@gl_mark
@pytest.mark.slow
def test_gl_strip_beyond_the_texture_limit(gl):
    """A 20000×64 strip is wider than llvmpipe's 16384: GL runs it in tiles and matches the reference."""
    from pyramid_cli.reference.pyramids import blur_reference

    size = (64, 20000)
    work = Blur(levels=3)
    p = work.plan((size,))
    x = image(size, 4, seed=3)
    assert not gl.fits(p) or gl.max_texture_size > 16384
    got = gl.run(p, x)
    ref = blur_reference(x.astype(np.float64), 3, work.analysis, work.synthesis, False, "clamp")
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-5)


@gl_mark
def test_gl_filter_work_applies_tiled(gl):
    work = Filter(expr=parse("quadratic *v g"))
    p = work.plan((SIZE,))
    assert_same_tiled(gl, p, [image(SIZE, 3)], (3, 3))


# ------------------------------------------------------------------ the Python API: arrays larger than RAM
def memmapped_input(tmp_path, seed: int, size=(70, 45, 3)) -> np.ndarray:
    """A 70×45 RGB float32 image in a .npy file, opened read-only as a memmap (numba required: the CPU runs)."""
    pytest.importorskip("numba")
    src = np.lib.format.open_memmap(tmp_path / "in.npy", "w+", np.float32, size)
    src[...] = image(size[:2], size[2], seed=seed)
    src.flush()
    return np.load(tmp_path / "in.npy", mmap_mode="r")


@pytest.mark.parametrize("fn", ["blur", "apply"])
def test_api_memmap_in_memmap_out(tmp_path, fn):
    """A memory-mapped input runs band by band into a memory-mapped ``out=``; the pixels of the whole run."""
    import pyramid_cli as pyr

    mm = memmapped_input(tmp_path, seed=9)
    call = (lambda a, **kw: pyr.blur(a, 3, backend="cpu", **kw)) if fn == "blur" else \
        (lambda a, **kw: pyr.apply("quadratic *v g", a, backend="cpu", **kw))
    want = call(np.array(mm))
    dst = np.lib.format.open_memmap(tmp_path / "out.npy", "w+", np.float32, want.shape)
    got = call(mm, out=dst, memory="128K")
    assert got is dst
    dst.flush()
    assert np.array_equal(np.load(tmp_path / "out.npy"), want)
    assert np.array_equal(call(mm), want)  # a memmap alone: banded, into a new array
    codes = (np.asarray(mm) * 255).astype(np.uint8)  # integer codes are normalised band by band
    assert np.array_equal(call(codes, memory=1 << 17), call(codes))
    with pytest.raises(ValueError, match="out: expected a float array of shape"):
        call(mm, out=np.empty((3, 3), np.float32))


@pytest.mark.parametrize("fn", ["pyramid", "laplacian", "mipmap"])
def test_api_memmap_in_memmap_outs_for_every_level(tmp_path, fn):
    """Jobs of several outputs too: a memory-mapped input runs band by band into one memory-mapped ``out=``
    per level (after level 0, which is the input, for the pyramid and the MIP map); the whole run's pixels."""
    import pyramid_cli as pyr

    mm = memmapped_input(tmp_path, seed=4)
    call = {"pyramid": lambda a, **kw: list(pyr.pyramid(a, backend="cpu", **kw)),
            "laplacian": lambda a, **kw: pyr.laplacian(a, 3, backend="cpu", **kw),
            "mipmap": lambda a, **kw: pyr.mipmap(a, backend="cpu", border="mirror", **kw)}[fn]
    want = call(np.array(mm))
    made = want if fn == "laplacian" else want[1:]  # level 0 of a pyramid or MIP map is the input itself
    dst = [np.lib.format.open_memmap(tmp_path / f"out{k}.npy", "w+", np.float32, w.shape) for k, w in enumerate(made)]
    got = call(mm, out=dst, memory="256K")
    assert all(g is d for g, d in zip(got[-len(dst):], dst, strict=True))
    for k, w in enumerate(made):
        dst[k].flush()
        assert np.array_equal(np.load(tmp_path / f"out{k}.npy"), w), k
    assert all(np.array_equal(g, w) for g, w in zip(call(mm), want, strict=True))  # a memmap alone: new arrays
    with pytest.raises(ValueError, match=f"out: expected {len(made)} arrays"):
        call(mm, out=dst[:1])
    with pytest.raises(ValueError, match=r"out\[1\]: expected a float array of shape"):
        call(mm, out=[dst[0], np.empty((3, 3), np.float32), *dst[2:]])


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["fill", "blend"])
def test_pointwise_plans_tile(kind, cpu_executor):
    """Plans with PointwisePass (issue 17's fill and blend, several levels) tile to the untiled pixels."""
    from pyramid_cli.jobs.work import Blend, Fill

    rng = np.random.default_rng(5)
    if kind == "fill":
        work = Fill(levels=3)
        weight = (rng.random(SIZE + (1,)) > 0.6).astype(np.float32)
        inputs = [image(SIZE, 3, seed=1) * weight, np.repeat(weight, 3, axis=2)]
    else:
        work = Blend(levels=3)
        inputs = [image(SIZE, 3, seed=1), image(SIZE, 3, seed=2), rng.random(SIZE + (3,)).astype(np.float32)]
    p = work.plan(tuple(a.shape[:2] for a in inputs))
    assert tiles.tileable(p)
    for tile in [(1, 1), (4, 3), (100, 100)]:
        assert_same_tiled(EMU, p, [a.astype(np.float64) for a in inputs], tile, np.float64)
        assert_same_tiled(cpu_executor, p, inputs, tile)


def mip_plans():
    """MIP chains (issue 14) whose odd levels run ResamplePass tables: maketx's sizes, --resize, 1×N."""
    from pyramid_cli.workflows.pyramids import mip_plan

    for size, resize in [(SIZE, False), ((7, 1), False), ((1, 9), False), ((11, 6), True)]:
        for border in BORDERS:
            yield mip_plan(size, border=border, resize=resize), size


@pytest.mark.slow
@pytest.mark.parametrize("tile", [(1, 1), (3, 2), (100, 100)])
def test_mip_plans_with_resample_passes_tile(tile, cpu_executor):
    """Tiled MIP plans (ResamplePass: sliced tables over windows placed by a guard band) equal untiled."""
    from pyramid_cli.plan import ResamplePass

    for p, size in mip_plans():
        assert tiles.tileable(p)
        assert any(isinstance(ps, ResamplePass) for ps in p.passes)
        assert_same_tiled(EMU, p, image(size).astype(np.float64), tile, np.float64)
        assert_same_tiled(cpu_executor, p, image(size), tile)


@gl_mark
@pytest.mark.slow
def test_gl_mip_plans_with_resample_passes_tile(gl):
    for p, size in mip_plans():
        for tile in [(1, 1), (4, 3)]:
            assert_same_tiled(gl, p, image(size), tile)


@gl_mark
@pytest.mark.slow
def test_gl_mip_strip_beyond_the_texture_limit_is_refused(gl):
    """A MIP chain wider than GL's limit cannot run in column strips (its coarse levels read the whole
    width of the level above): GL refuses it with a DataError (exit 5; auto runs it on the CPU) instead
    of tiling the tiles, while a plain filter of the same width runs tiled (the test above)."""
    from pyramid_cli.core.errors import DataError
    from pyramid_cli.workflows.pyramids import mip_plan

    size = (5, 20001)
    p = mip_plan(size)
    if gl.max_texture_size > 20001:
        pytest.skip("this GL holds the whole strip")
    with pytest.raises(DataError, match="exceeds the limit"):
        gl.run_outputs(p, np.abs(image(size, 3, seed=4)))


# ------------------------------------------------------------ row windows (a part of a picture: tiles --cluster)
def windowed(executor, p, x, windows, band, width=None, dtype=np.float32):
    """What a Scheduler restricted to ``windows`` emits: {output: [(row, col, pixels)]}."""
    got: dict = {k: [] for k in p.outputs}

    def source(k, rows, cols):
        return np.ascontiguousarray(x[rows[0]:rows[1], cols[0]:cols[1]], dtype=dtype)

    def sink(k, r, c, px):
        got[k].append((r, c, px.copy()))

    tiles.Scheduler(executor, p, source, sink, band=band, width=width, dtype=dtype, windows=windows).run()
    return got


@pytest.mark.parametrize("border", ["clamp", "mirror", "zero"])
@pytest.mark.parametrize("analysis", ["quadratic", "cubic", "box"])
def test_a_row_window_makes_exactly_its_rows_with_the_whole_runs_pixels(border, analysis):
    """Any window of rows of each level, at odd sizes, bands and strips: the whole run's pixels, every pixel of the
    window once, nothing outside it (pyramid tiles --cluster cuts a picture into such windows)."""
    executor, rng = Emulator(), np.random.default_rng(7)
    size = (37, 23)
    p = Levels(levels=3, analysis=analysis, border=border).plan((size,))
    x = image(size, 2, dtype=np.float64)
    whole = executor.run_outputs(p, [x])
    for trial in range(6):
        windows = {}
        for k in p.outputs:
            h = p.images[k].size[0]
            a = int(rng.integers(0, h))
            windows[k] = (a, int(rng.integers(a, h + 1)))
        got = windowed(executor, p, x, windows, band=8 + 8 * (trial % 2), width=(None, 7)[trial % 2],
                       dtype=np.float64)
        for j, k in enumerate(p.outputs):
            seen = np.zeros(p.images[k].size, int)
            for r, c, px in got[k]:
                np.testing.assert_array_equal(px, whole[j][r:r + px.shape[0], c:c + px.shape[1]])
                seen[r:r + px.shape[0], c:c + px.shape[1]] += 1
            want = np.zeros_like(seen)
            want[slice(*windows[k])] = 1
            np.testing.assert_array_equal(seen, want, err_msg=f"output {k}, window {windows[k]}")


def test_reads_of_many_rows_come_from_their_first_and_last_periods():
    """The scheduler's two-lookup bounds of a tall rectangle (``_reads_of``) are the pass's own, for every phased
    pass, offset and height: what it keeps and what it waits for are unchanged."""
    for text in ("gauss5", "box4 *v g", "fourpoint *^ (cubic *v g)"):
        for ps in plan(parse(text), (61, 23)).passes:
            for r0 in range(-6, 30):
                for n in range(1, 40, 3):
                    assert tiles._reads_of(ps, (r0, r0 + n), (0, 23)) == ps._reads((r0, r0 + n), (0, 23))


def test_coarse_outputs_advance_a_band_at_a_time():
    """An output that is not the lead advances once it can make a band of its own rows (or all it has left), not
    by the row or two each band allows: a pyramid's steps stay about twice the lead's bands, the pixels unchanged
    (the equality tests above)."""
    size = (512, 40)
    p = Levels(levels=6).plan((size,))
    s = tiles.Scheduler(EMU, p, lambda k, r, c: image(size, 1)[r[0]:r[1], c[0]:c[1]].astype(np.float64),
                        lambda k, r, c, px: None, band=8, dtype=np.float64)
    s.run()
    lead_bands = p.images[p.outputs[0]].size[0] // 8
    assert s.steps <= 2 * lead_bands + len(p.outputs), s.steps


@pytest.mark.parametrize("border", ["clamp", "mirror"])
def test_a_sink_may_keep_the_rows_it_is_given_without_a_copy(cpu_executor, border):
    """The scheduler never writes into rows it has made (the band engine hands them to the writers without a
    copy): views kept by the sink until the end hold the whole run's pixels, at odd sizes, bands and strips, and
    are read-only."""
    size = (45, 29)
    x = image(size, 3, seed=5)
    for work in (Levels(levels=4, border=border), Blur(levels=2, border=border)):
        p = work.plan((size,))
        whole = cpu_executor.run_outputs(p, [x])
        for band, width in ((4, None), (8, 11)):
            got: dict = {k: [] for k in p.outputs}

            def sink(k, r, c, px, got=got):
                with pytest.raises(ValueError, match="read-only"):
                    px[:1, :1] = 0
                got[k].append((r, c, px))

            tiles.Scheduler(cpu_executor, p, lambda k, r, c: x[r[0]:r[1], c[0]:c[1]].copy(), sink,
                            band=band, width=width).run()
            for j, k in enumerate(p.outputs):
                seen = np.zeros(p.images[k].size, int)
                for r, c, px in got[k]:
                    np.testing.assert_array_equal(px, whole[j][r:r + px.shape[0], c:c + px.shape[1]])
                    seen[r:r + px.shape[0], c:c + px.shape[1]] += 1
                assert (seen == 1).all(), f"{work.label} output {k}: band {band}, width {width}"


def test_codes_are_kept_as_the_executor_reads_them(cpu_executor):
    """A run on 8-bit codes keeps them as uint8, as decoded: the executor reads them through its table, so
    neither the scheduler's joins nor any step converts them; the pixels are those of the floats
    ``table[codes]``, tiled or not."""
    size = (37, 29)
    codes = np.random.default_rng(3).integers(0, 256, size + (3,), dtype=np.uint8)
    table = np.linspace(0, 1, 256, dtype=np.float32) ** 2
    p = Levels(levels=3).plan((size,))
    seen = set()

    class Recording:
        def __getattr__(self, name):
            return getattr(cpu_executor, name)

        def run_outputs(self, plan_, images, dtype=np.float32, codes=None, out=None):
            seen.update(a.dtype.name for a in images if a.dtype.kind == "u")  # the codes, not the levels
            return cpu_executor.run_outputs(plan_, images, dtype, codes=codes, out=out)

    got: dict = {k: np.zeros(p.images[k].size + (3,), np.float32) for k in p.outputs}

    def sink(k, r, c, px):
        got[k][r:r + px.shape[0], c:c + px.shape[1]] = px

    tiles.Scheduler(Recording(), p, lambda k, r, c: codes[r[0]:r[1], c[0]:c[1]], sink, band=8, width=13,
                    codes=table).run()
    assert seen == {"uint8"}
    for k, want in zip(p.outputs, cpu_executor.run_outputs(p, [table[codes]]), strict=True):
        np.testing.assert_array_equal(got[k], want)


@pytest.mark.parametrize("border", ["clamp", "mirror", "wrap", "zero"])
def test_an_executor_that_writes_into_makes_each_band_in_its_place(cpu_executor, border):
    """With the CPU executor (``writes_into``), a step's rows are written by its pass into the image's new buffer,
    after the kept rows, not copied there: steps that make the rows of their kept columns are given ``out``, a view
    of the rows the scheduler then holds and hands to the sink, and the pixels are the untiled run's."""
    size = (53, 47)
    image = np.random.default_rng(4).random(size + (3,), dtype=np.float32)
    p = Levels(levels=4, border=border).plan((size,))
    given: list[np.ndarray] = []

    class Recording:
        def __getattr__(self, name):
            return getattr(cpu_executor, name)

        def run_outputs(self, plan_, images, dtype=np.float32, out=None):
            got = cpu_executor.run_outputs(plan_, images, dtype, out=out)
            if out is not None:
                given.append(out)
                assert got[-1] is out
            return got

    made: dict = {k: np.zeros(p.images[k].size + (3,), np.float32) for k in p.outputs}

    def sink(k, r, c, px):
        assert k in p.inputs or any(np.shares_memory(px, a) for a in given), "a band copied after its pass"
        made[k][r:r + px.shape[0], c:c + px.shape[1]] = px

    tiles.Scheduler(Recording(), p, lambda k, r, c: image[r[0]:r[1], c[0]:c[1]], sink, band=8).run()
    assert given
    for k, want in zip(p.outputs, cpu_executor.run_outputs(p, image), strict=True):
        np.testing.assert_array_equal(made[k], want, err_msg=f"image {k}")
