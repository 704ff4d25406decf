"""The moderngl executor: a :class:`~pyramid_cli.plan.model.Plan` as hardware bilinear texture passes.

Every GL call of the project lives here and in :mod:`pyramid_cli.exec.gl.context` (moderngl is imported nowhere
else). One
headless EGL context per :class:`GLExecutor`, made on first use; one program per
pass shape (:mod:`pyramid_cli.exec.gl.shaders`), compiled once and cached; textures,
framebuffers and numpy staging buffers pooled by size and reused across passes,
plans and images. The input is uploaded once per image (and channel group); only
the final image is read back.

Coordinates (the contract of :mod:`pyramid_cli.exec.emulate`, which this must equal):

- numpy row 0 is texture row 0 (y = 0) on upload and read-back: nothing is flipped;
- every texture has the smallest power-of-two dimensions that hold its stored extent
  (logical size plus guard), so that the normalized coordinate ``(q + ½) / size`` of a
  quarter-texel position ``q`` is an exact binary fraction, and the filtering unit gets
  ``q`` and its fraction back without rounding (with non-power-of-two sizes the
  coordinate carries an error of about size·2⁻²⁴ texel on llvmpipe, docs/design.md §6);
  nothing here depends on llvmpipe: any GPU converts such coordinates exactly;
- the shader clamps each read position to the source's stored extent, which is the
  emulator's clamp. Bilinear reads at the clamped last position also touch the next
  texel (with weight 0); that texel repeats the edge: every pass renders one extra row
  and column that copy its last ones (and the upload repeats the input's edge) where the
  texture has room, and CLAMP_TO_EDGE gives the same where it has none, so stale pool
  contents (a NaN left there, say) never leak in;
- taps with integral offsets read one texel with ``texelFetch``; others use LINEAR
  filtering with ``textureLod(…, 0)`` (no derivatives needed inside phase branches).

Precision: the input texture is always RGBA32F (exact); intermediates and the target
are RGBA32F (``precision="float"``, exact and unclamped) or RGBA16F (``"half"``,
saturating at 65504 on llvmpipe). Inputs may be float16 arrays (half files, kept half
by :mod:`pyramid_cli.imageio`): they are converted band by band while uploading, so no
full-size float32 copy is made. Outputs read back as float32, or as float16 when the
caller will store half anyway, rounded to nearest even, the rounding of numpy and OpenEXR
(``test_half_read_back_rounds_like_numpy``). glReadPixels converts to half where the driver
rounds so (llvmpipe: :func:`half_read_rounds_even`, probed once per context on every tie);
elsewhere the floats are read in bands and numpy rounds them: NVIDIA's driver (580, H100)
rounds ties away from zero and subnormals toward it (1 ulp off at about half the ties), and
its conversion took 7× as long as reading floats. Rendering
into RGBA16F does not round that way on llvmpipe, which is why targets stay RGBA32F.

Pictures that do not fit (a texture beyond GL_MAX_TEXTURE_SIZE or of 2 GiB) run in tiles
(:meth:`GLExecutor.run_tiled`, :mod:`pyramid_cli.exec.tiles`): every pass on windows of its
images, each window's texture padded to powers of two (the tile, not the picture), with
the same exact coordinates and the same pixels. Single files that fit but whose textures
would be padded stream in bands for the same reason (:func:`pyramid_cli.run.stream.choose`,
which counts :meth:`GLExecutor.texture_bytes`).

Memory is the cost of a cold run (page faults: about 1 s per GB on the 2-core machines
of docs/design.md §6), so uploads go through a reused band and read-backs straight into the
output array instead of full-size staging copies, and :meth:`GLExecutor.prepare` can compile the programs and
allocate the textures of a plan while the image is still being decoded.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pyramid_cli.core.errors import BackendError, DataError
from pyramid_cli.core.geometry import check_size
from pyramid_cli.exec import tiles
from pyramid_cli.exec.emulate import plan_inputs, resample_table
from pyramid_cli.exec.gl import shaders as generate
from pyramid_cli.exec.gl.context import context_info, create_context, is_software_renderer
from pyramid_cli.exec.gl.textures import texture_bytes, texture_size
from pyramid_cli.plan.model import Plan, ResamplePass
from pyramid_cli.plan.shapes import PassShape, PointwiseShape, shape, sources

PRECISIONS = {"float": "f4", "half": "f2"}  # intermediate and target texture formats
READ_DTYPES = (np.dtype(np.float32), np.dtype(np.float16))  # what outputs can be
INPUT_POOL = "-input"  # the pool of inputs' textures that are never render targets (GLExecutor._input_texture)
BAND_BYTES = 8 << 20  # upload staging: rows of RGBA32F per texture write
MAX_TEXTURE_BYTES = 2 << 30  # llvmpipe fails to attach a texture of 2 GiB (8193², 12000×6000: docs/design.md §6)
TILE_TEXELS = 1 << 24        # a tile's largest texture, about (256 MiB of RGBA32F), when a plan runs in tiles


def half_probe() -> np.ndarray:
    """Float32 values, (rows, 64, 4), whose float16 rounding tells a read-back's rounding apart: every tie between
    two neighbouring finite halves of either sign (nearest even decides), the float32 neighbours of each tie,
    three quarters of the way, and subnormal, overflowing, infinite and NaN values."""
    h = np.arange(0x7BFF, dtype=np.uint16).view(np.float16).astype(np.float32)
    up = np.arange(1, 0x7C00, dtype=np.uint16).view(np.float16).astype(np.float32)
    ties = (h + up) / 2
    values = [ties, np.nextafter(ties, np.float32(np.inf)), np.nextafter(ties, np.float32(0)), h + (up - h) * 0.75,
              np.array([65504, 65519.99, 65520, 1e6, 2.9e-8, 3e-8, 6e-8, np.inf, np.nan, 0.0], np.float32)]
    flat = np.concatenate(values + [-v for v in values])
    return np.resize(flat, (-(-len(flat) // 256) * 256,)).reshape(-1, 64, 4)


def half_read_rounds_even(values: np.ndarray, read: np.ndarray) -> bool:
    """Whether ``read`` (float16) is ``values`` (float32) rounded as numpy and OpenEXR round: to nearest even,
    overflow to infinity, NaN kept (its payload aside)."""
    with np.errstate(over="ignore"):
        want = values.astype(np.float16)
    same = (read.view(np.uint16) == want.view(np.uint16)) | (np.isnan(read) & np.isnan(want))
    return bool(same.all())


def _written(stored: tuple[int, int], tex: tuple[int, int]) -> tuple[int, int]:
    """Rows and columns a pass writes: the extent plus the repeated edge where the texture has room."""
    return min(stored[0] + 1, tex[0]), min(stored[1] + 1, tex[1])


@dataclass
class _Target:
    texture: Any
    fbo: Any                # None for an input's texture on a GPU (GLExecutor._input_texture)
    size: tuple[int, int]  # texture (rows, columns)
    dtype: str              # its pool: the texture's dtype, + INPUT_POOL for those inputs' textures


@dataclass
class _Program:
    program: Any
    vao: Any
    uniforms: set[str] = field(default_factory=set)

    def set(self, name: str, value) -> None:
        if name in self.uniforms:  # the compiler drops unused uniforms
            self.program[name].value = value


class _Clock:
    """Laps between ``ctx.finish()`` calls, by name (:meth:`GLExecutor.profile`)."""

    def __init__(self, per_pass: bool):
        import time

        self.per_pass = per_pass
        self.now = time.perf_counter
        self.laps: dict[str, list[float]] = {"upload": [], "passes": [], "readback": []}
        self.t = 0.0

    def start(self, ctx) -> None:
        ctx.finish()
        self.t = self.now()

    def lap(self, ctx, name: str) -> None:
        ctx.finish()
        t = self.now()
        self.laps[name].append(t - self.t)
        self.t = t


class GLExecutor:
    """Runs plans on one headless EGL context.

    Parameters
    ----------
    precision : {"float", "half"}
        Format of intermediate and target textures: RGBA32F (exact, default) or
        RGBA16F (half the memory traffic; saturates at 65504).
    info : dict, optional
        What the context will say of itself (:func:`~pyramid_cli.exec.gl.context.machine_gl`, cached):
        then :attr:`name`, :attr:`renderer` and :attr:`max_texture_size` answer without making it.

    The context is created on first use; :meth:`close` (or ``with``) releases it. It is an
    :class:`~pyramid_cli.exec.base.Executor`.
    """

    backend = "gl"
    strategy = "cost"  # the calibrated cost model's plans (pyramid_cli.plan.lower)
    work_dtype = np.dtype(np.float32)
    writes_into = False  # run_outputs reads its outputs back into arrays of its own

    def __init__(self, precision: str = "float", info: dict | None = None):
        if precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {sorted(PRECISIONS)}, not {precision!r}")
        self.precision = precision
        self._ctx = None
        # a pass's shape, or ("resample", axis) for the table-driven program of either axis
        self._programs: dict[PassShape | PointwiseShape | tuple[str, int], _Program] = {}
        self._plan_programs: dict[int, tuple[Plan, list[_Program]]] = {}
        self._tables: dict[tuple[int, int], tuple[ResamplePass, Any]] = {}
        self._free: dict[tuple[tuple[int, int], str], list[_Target]] = {}
        self._buffers: dict[tuple[tuple[int, ...], str, int], np.ndarray] = {}  # (shape, dtype, slot)
        self._tiling = False  # inside run_tiled: its one-pass plans are not tiled again
        self.compiles = 0  # programs built so far (the cache's misses)
        self._clock: _Clock | None = None
        self._info: dict = dict(info) if info else {}
        self._depth = 0
        self._half_even: bool | None = None  # half_rounds_even(), once the context is asked

    # ------------------------------------------------------------ context
    @property
    def ctx(self):
        """The executor's context (created on first use). GL work on it must run inside :meth:`current`."""
        return self.open()

    def open(self):
        """Create the context now if it does not exist yet (BackendError if it cannot be made); returns it."""
        if self._ctx is None:
            ctx = create_context()
            with ctx:
                self._info = context_info(ctx)
            self._ctx = ctx
        return self._ctx

    @property
    def opened(self) -> bool:
        """Whether the context exists (made by :meth:`open` or the first GL work)."""
        return self._ctx is not None

    @contextmanager
    def current(self):
        """Make the executor's context current for the block (re-entrant).

        moderngl does not switch contexts by itself: with two executors (or a context
        made by :func:`~pyramid_cli.exec.gl.context.available`) in one process, GL calls go to whichever context was
        made current last, and leaving ``with ctx`` leaves none current. Every public
        method therefore runs its GL calls inside this.
        """
        ctx = self.ctx
        if self._depth:
            yield ctx
            return
        self._depth += 1
        try:
            with ctx:
                yield ctx
        finally:
            self._depth -= 1

    @property
    def max_texture_size(self) -> int:
        """GL_MAX_TEXTURE_SIZE of the context (made now if there is none yet and ``info`` did not say)."""
        if "max_texture_size" not in self._info:
            self.open()
        return self._info["max_texture_size"]

    def info(self) -> dict:
        """What the context says of itself (:func:`~pyramid_cli.exec.gl.context.context_info`; made now)."""
        self.open()
        return dict(self._info)

    @property
    def renderer(self) -> str:
        """GL_RENDERER of the context (remembered after :meth:`close`)."""
        if not self._info:
            self.open()
        return self._info.get("renderer", "OpenGL")

    @property
    def name(self) -> str:
        """What runs the plans, for messages: ``gl (GL_RENDERER)``."""
        return f"gl ({self.renderer})"

    def uncached(self, plan: Plan, dtype=np.float32) -> int:
        """Programs are compiled in milliseconds: nothing to warn of (0)."""
        return 0

    @property
    def error(self) -> str:
        """``ctx.error`` of this executor's context (reading it clears the GL error flag)."""
        with self.current() as ctx:
            return ctx.error

    def close(self) -> None:
        """Release every GL object and the context (the executor can be used again afterwards)."""
        if self._ctx is not None:
            self._ctx.release()
        self._ctx = None
        self._programs.clear()
        self._plan_programs.clear()
        self._tables.clear()
        self._free.clear()
        self._buffers.clear()
        self._half_even = None

    def __enter__(self) -> GLExecutor:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------ programs
    def program(self, ps, images=None) -> _Program:
        """The compiled program of a pass's shape (cached for the executor's lifetime);
        ``images`` (the plan's) give the sources' border modes."""
        key = shape(ps, images)
        prog = self._programs.get(key)
        if prog is None:
            with self.current():
                prog = self._programs[key] = self._build(key)
        return prog

    def programs(self, plan: Plan) -> list[_Program]:
        """The programs of ``plan``'s passes, remembered per plan (batches run one plan per size many times)."""
        hit = self._plan_programs.get(id(plan))
        if hit is not None and hit[0] is plan:
            return hit[1]
        programs = [self.resample_program(ps.axis) if isinstance(ps, ResamplePass) else self.program(ps, plan.images)
                    for ps in plan.passes]
        if len(self._plan_programs) >= 64:
            self._plan_programs.pop(next(iter(self._plan_programs)))
        self._plan_programs[id(plan)] = (plan, programs)  # holds the plan: its id stays unique
        return programs

    def resample_program(self, axis: int) -> _Program:
        """The table-driven program of a :class:`ResamplePass` along ``axis`` (one per axis, any table)."""
        key = ("resample", axis)
        prog = self._programs.get(key)
        if prog is None:
            with self.current():
                prog = self._programs[key] = self._build(key, generate.resample_fragment_source(axis))
                prog.set("u_src", 0)
                prog.set("u_table", 1)
        return prog

    def _table(self, plan: Plan, ps: ResamplePass):
        """The pass's (index, weight) table as an RG32F texture (width × outputs), made once per plan and pass."""
        key = (id(plan), id(ps))
        hit = self._tables.get(key)
        if hit is not None and hit[0] is ps:
            return hit[1]
        idx, weights = resample_table(ps, plan.images[ps.source], np.float32)
        data = np.ascontiguousarray(np.stack([idx.astype(np.float32), weights], axis=-1))
        tex = self.ctx.texture((ps.width, len(ps.starts)), 2, data.tobytes(), dtype="f4")
        if len(self._tables) >= 256:
            _, old = self._tables.pop(next(iter(self._tables)))
            old.release()
        self._tables[key] = (ps, tex)  # holds the pass: its id stays unique
        return tex

    def _build(self, key, frag: str | None = None) -> _Program:
        import moderngl

        ctx = self.ctx
        vert = generate.vertex_source()
        frag = frag if frag is not None else generate.fragment_source(key)
        try:
            program = ctx.program(vertex_shader=vert, fragment_shader=frag)
        except moderngl.Error as e:
            log = str(e)
            stage, source = ("vertex", vert) if "vertex_shader" in log.split("\n", 1)[0] else ("fragment", frag)
            raise generate.compile_error(log, stage, source) from e
        self.compiles += 1
        uniforms = {name for name in program if isinstance(program[name], moderngl.Uniform)}
        prog = _Program(program, ctx.vertex_array(program, []), uniforms)
        for k in range(getattr(key, "n_sources", 0)):
            prog.set(f"u_src{k}", k)  # slot k reads texture unit k
        return prog

    # ------------------------------------------------------------ pools
    def _acquire(self, size: tuple[int, int], dtype: str, target: bool = True) -> _Target:
        """A texture of ``size`` (rows, columns) and ``dtype`` from the pool, or a new one; with a framebuffer to
        render into unless ``target`` is False (an input's texture, pooled apart: :meth:`_input_texture`)."""
        key = dtype if target else dtype + INPUT_POOL
        free = self._free.get((size, key))
        if free:
            return free.pop()
        import moderngl

        ctx = self.ctx
        tex = None
        try:
            tex = ctx.texture((size[1], size[0]), 4, dtype=dtype)
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = False  # clamp to edge: the texture's own last texel
            return _Target(tex, ctx.framebuffer(color_attachments=[tex]) if target else None, size, key)
        except moderngl.Error as e:  # out of memory, an incomplete framebuffer: whatever the driver says
            if tex is not None:
                tex.release()
            ctx.error  # noqa: B018 - reading it clears the GL error flag the failure left
            reason = " ".join(str(e).split())
            raise DataError(f"the GL cannot allocate a {size[1]}x{size[0]} RGBA {dtype} texture ({reason})") from None

    def _input_texture(self, size: tuple[int, int]) -> _Target:
        """The RGBA32F texture an input is uploaded into. On a software renderer, one of the pool's render targets
        (a later pass reuses it: no more memory). On a GPU, one that is never rendered into, pooled apart:
        NVIDIA's driver (580, H100) wrote a 4K picture into a texture that had been a framebuffer's attachment
        in 67–75 ms against 24–25 ms (a half EXR's banded upload took 0.5 s), while llvmpipe took the same
        either way."""
        return self._acquire(size, "f4", target=self.host_textures)

    def _release(self, t: _Target) -> None:
        self._free.setdefault((t.size, t.dtype), []).append(t)

    def clear_pool(self) -> None:
        """Release pooled textures and staging buffers (programs stay compiled)."""
        if self._ctx is not None:
            with self.current() as ctx:
                # moderngl re-binds the last bound framebuffer after making a new one: a deleted
                # one would be GL_INVALID_OPERATION, so bind the default (0) before deleting.
                ctx.detect_framebuffer(0).use()
                for free in self._free.values():
                    for t in free:
                        if t.fbo is not None:
                            t.fbo.release()
                        t.texture.release()
        self._free.clear()
        self._buffers.clear()

    def _buffer(self, shape: tuple[int, ...], dtype, slot: int = 0) -> np.ndarray:
        """A reused staging array; ``slot`` tells apart buffers of one shape needed at once."""
        key = (shape, np.dtype(dtype).str, slot)
        buf = self._buffers.get(key)
        if buf is None:
            buf = self._buffers[key] = np.zeros(shape, dtype=dtype)
        return buf

    # ------------------------------------------------------------ running
    def check(self, plan: Plan) -> None:
        """DataError if an image of ``plan`` or its texture exceeds GL_MAX_TEXTURE_SIZE, or a texture
        would reach 2 GiB (Mesa cannot attach one: "framebuffer is not complete")."""
        limit = self.max_texture_size
        for k in plan.inputs:
            rows, cols = plan.images[k].size
            check_size(cols, rows, limit, where="input image" if len(plan.inputs) == 1 else f"input image {k}")
        for k, im in enumerate(plan.images):
            h, w = im.stored
            check_size(w, h, limit, where=f"image {k} of the plan (logical {im.size[0]}x{im.size[1]} plus guard)")
            th, tw = texture_size(im.stored)
            if th > limit or tw > limit:
                raise DataError(f"image {k} of the plan needs a {tw}x{th} texture (power-of-two sides), "
                                f"over the GL limit of {limit}x{limit}")
            if th * tw * 16 >= MAX_TEXTURE_BYTES:
                raise DataError(f"image {k} of the plan needs a {tw}x{th} RGBA32F texture (power-of-two sides) "
                                f"of {th * tw * 16 / 2 ** 30:.0f} GiB; GL textures stay under 2 GiB")

    @property
    def host_textures(self) -> bool:
        """Whether textures live in host memory (a software renderer such as Mesa's llvmpipe): then ``--memory``
        counts them (:meth:`texture_bytes`) and single files they would pad run in bands
        (:func:`pyramid_cli.run.stream.costs`). A GPU's textures live in its own memory, and whole runs stay whole."""
        return is_software_renderer(self.renderer)

    texture_bytes = staticmethod(texture_bytes)

    def fits(self, plan: Plan) -> bool:
        """Whether ``plan`` runs whole: every image's power-of-two texture within GL_MAX_TEXTURE_SIZE and 2 GiB.

        Plans that do not fit run in tiles (:meth:`run_tiled`)."""
        try:
            self.check(plan)
        except DataError:
            return False
        return True

    def tile_size(self, plan: Plan, texels: int = TILE_TEXELS) -> tuple[int, int]:
        """Rows and columns of a tile (in pixels of the largest output) whose textures stay within half the
        texture limit on a side and about ``texels`` texels (guard bands included)."""
        anchor = (max(plan.images[k].size[0] for k in plan.outputs), max(plan.images[k].size[1] for k in plan.outputs))
        side = self.max_texture_size // 2
        scale = [max(im.size[a] / anchor[a] for im in plan.images) for a in (0, 1)]
        guard = [max(im.guard[a] + im.guard[a + 2] for im in plan.images) + 64 for a in (0, 1)]
        width = max(1, int((side - guard[1]) / scale[1]))
        band = max(1, min(int((side - guard[0]) / scale[0]), int(texels / (width * scale[1]) / scale[0])))
        return band, width

    def run_tiled(self, plan: Plan, images, dtype=np.float32, tile: tuple[int, int] | None = None) -> list[np.ndarray]:
        """:meth:`run_outputs` in tiles (:mod:`pyramid_cli.exec.tiles`): each pass runs on windows of its images, so
        textures are the tile's size padded to powers of two, not the picture's, and images beyond
        GL_MAX_TEXTURE_SIZE run; the pixels are those of the untiled run. ``tile``: (rows, columns) of the
        largest output per tile; default :meth:`tile_size`."""
        dtype = np.dtype(dtype)
        if dtype not in READ_DTYPES:
            raise ValueError(f"outputs are float32 or float16, not {dtype}")
        arrays = self._inputs(plan, images)
        band, width = tile or self.tile_size(plan)
        # A tile's one-pass plans run whole or not at all: a window that still does not fit (a MIP
        # chain's coarse levels read the whole width of the one above) is refused by check(), not
        # tiled again.
        self._tiling, outer = True, self._tiling
        try:
            return tiles.run_arrays(self, plan, arrays, band=band, width=width, dtype=dtype)
        finally:
            self._tiling = outer

    def run(self, plan: Plan, image) -> np.ndarray:
        """Execute ``plan`` on ``image`` (H, W) or (H, W, C); returns the output's logical pixels, float32.

        ``image`` may also be a list with one array per ``plan.inputs``. The result is the
        last of ``plan.outputs`` (:meth:`run_outputs` returns them all). More than four
        channels run in groups of four through the same programs.
        """
        return self.run_outputs(plan, image)[-1]

    def run_outputs(self, plan: Plan, images, dtype=np.float32) -> list[np.ndarray]:
        """Execute ``plan`` with one image per ``plan.inputs``; the logical pixels of every ``plan.outputs``.

        Inputs are float32 or float16 arrays (others are converted to float32). Outputs have
        the inputs' channel layout, (H, W) for 2-D inputs, else (H, W, C), and ``dtype``:
        float32, or float16 (rounded to nearest even: by the read-back or by numpy). Only these images
        are read back, after the last pass.
        """
        dtype = np.dtype(dtype)
        if dtype not in READ_DTYPES:
            raise ValueError(f"outputs are float32 or float16, not {dtype}")
        arrays = self._inputs(plan, images)
        if not self.fits(plan) and not self._tiling:
            if tiles.tileable(plan):
                return self.run_tiled(plan, arrays, dtype)
        flat = arrays[0].ndim == 2
        arrays = [a[:, :, None] if flat else a for a in arrays]
        self.check(plan)
        channels = arrays[0].shape[2]
        outs = [np.empty(plan.images[k].size + (channels,), dtype=dtype) for k in plan.outputs]
        with self.current() as ctx:
            programs = self.programs(plan)
            for c0 in range(0, channels, 4):
                n = min(4, channels - c0)
                group = slice(c0, c0 + n)
                self._run_group(plan, programs, [a[:, :, group] for a in arrays], [o[:, :, group] for o in outs])
            err = ctx.error
        if err != "GL_NO_ERROR":
            raise BackendError(f"OpenGL reported {err} while running {plan.expression!r}")
        return [np.ascontiguousarray(o[:, :, 0]) for o in outs] if flat else outs

    @staticmethod
    def _inputs(plan: Plan, images) -> list[np.ndarray]:
        return plan_inputs(plan, images)

    def _upload(self, img: np.ndarray) -> _Target:
        """The input in an RGBA32F texture, its edge repeated into the spare row and column.

        RGBA float32 goes straight from the array; anything else (float16, fewer channels,
        a channel group of a wider image) through a reused staging band of about BAND_BYTES.
        """
        rows, cols, n = img.shape
        tex_size = texture_size((rows, cols))
        wr, wc = _written((rows, cols), tex_size)
        t = self._input_texture(tex_size)
        if n == 4 and img.dtype == np.float32 and img.flags.c_contiguous:  # no staging copy at all
            t.texture.write(img, viewport=(0, 0, cols, rows))
            if wc > cols:
                t.texture.write(np.ascontiguousarray(img[:, cols - 1:]), viewport=(cols, 0, 1, rows))
            if wr > rows:
                edge = img[rows - 1:, np.minimum(np.arange(wc), cols - 1)]
                t.texture.write(np.ascontiguousarray(edge), viewport=(0, rows, wc, 1))
            return t
        band = max(1, min(wr, BAND_BYTES // (16 * wc)))
        buf = self._buffer((band, wc, 4), np.float32)
        for y0 in range(0, wr, band):
            b = buf[: min(band, wr - y0)]
            src = img[y0:y0 + len(b)]
            b[: len(src), :cols, :n] = src
            b[len(src):, :cols, :n] = img[rows - 1]  # the spare edge row repeats the last one
            # Channels n: keep whatever they hold: channels never mix, and they are not read back.
            if wc > cols:
                b[:, cols] = b[:, cols - 1]
            t.texture.write(b, viewport=(0, y0, wc, len(b)))
        return t

    def _read_back(self, target: _Target, viewport: tuple[int, int, int, int], out: np.ndarray, slot: int) -> None:
        """Read a viewport of ``target`` into ``out`` (rows, columns, ≤ 4 channels), float32 or float16 rounded
        to nearest even: by GL where :meth:`half_rounds_even`, else by numpy from float32 bands of about
        :data:`BAND_BYTES`."""
        n = out.shape[2]
        gl_dtype = "f2" if out.dtype == np.float16 and self.half_rounds_even() else "f4"
        if out.flags.c_contiguous and out.dtype == (np.float16 if gl_dtype == "f2" else np.float32):
            target.fbo.read_into(out, viewport=viewport, components=n, dtype=gl_dtype)  # GL_RED / RG / RGB / RGBA
            return
        x, y, cols, rows = viewport
        staged = np.float16 if gl_dtype == "f2" else np.float32
        band = max(1, min(rows, BAND_BYTES // (4 * n * cols)))
        buf = self._buffer((band, cols, n), staged, slot=slot)
        for r0 in range(0, rows, band):
            b = buf[: min(band, rows - r0)]
            target.fbo.read_into(b, viewport=(x, y + r0, cols, len(b)), components=n, dtype=gl_dtype)
            out[r0:r0 + len(b)] = b

    def half_rounds_even(self) -> bool:
        """Whether this context's glReadPixels rounds float → half as numpy does (:func:`half_read_rounds_even`
        on a texture of :func:`half_probe`; asked once per context)."""
        if self._half_even is None:
            values = half_probe()
            with self.current() as ctx:
                tex = ctx.texture((values.shape[1], values.shape[0]), 4, values.tobytes(), dtype="f4")
                fbo = ctx.framebuffer([tex])
                try:
                    got = np.empty(values.shape, np.float16)
                    fbo.read_into(got, components=4, dtype="f2")
                finally:
                    fbo.release()
                    tex.release()
            self._half_even = half_read_rounds_even(values, got)
        return self._half_even

    def profile(self, plan: Plan, images, dtype=np.float32, per_pass: bool = True) -> dict:
        """Run ``plan`` once, timed: upload, the passes and read-back, with ``ctx.finish()`` between.

        The timing hook of the benchmarks. With ``per_pass`` every pass is followed by a
        finish and timed alone (``passes`` lists them, channel group after group); without,
        the passes of a group run back to back between two finishes (``passes`` holds one
        span per group). ``device`` is their sum; ``total`` the whole call.
        """
        import time

        self._clock = _Clock(per_pass)
        try:
            t0 = time.perf_counter()
            self.run_outputs(plan, images, dtype)
            total = time.perf_counter() - t0
        finally:
            clock, self._clock = self._clock, None
        laps = clock.laps
        return {"upload": sum(laps["upload"]), "passes": laps["passes"], "device": sum(laps["passes"]),
                "readback": sum(laps["readback"]), "total": total}

    def prepare(self, plan: Plan) -> None:
        """Compile ``plan``'s programs and put the textures one run takes into the pool.

        Nothing is rendered. Called while the image is still being decoded, it moves the
        shader compiles and the page faults of fresh textures off the critical path.
        """
        if not self.fits(plan) and tiles.tileable(plan):  # runs in tiles: the programs are all there is to prepare
            with self.current():
                self.programs(plan)
            return
        self.check(plan)
        dtype = PRECISIONS[self.precision]
        with self.current():
            self.programs(plan)
            held = {k: self._input_texture(texture_size(plan.images[k].stored)) for k in plan.inputs}
            for ps, done in zip(plan.passes, plan.releases(), strict=True):
                held[ps.target] = self._acquire(texture_size(plan.images[ps.target].stored), dtype)
                for s in done:
                    self._release(held.pop(s))
            for t in held.values():
                self._release(t)

    def _run_group(self, plan: Plan, programs: list[_Program], inputs: list[np.ndarray],
                   outs: list[np.ndarray]) -> None:
        """All passes for one group of ≤ 4 channels; writes the read-back images into ``outs``."""
        ctx = self.ctx
        dtype = PRECISIONS[self.precision]
        clock = self._clock
        if clock:
            clock.start(ctx)
        held: dict[int, _Target] = {k: self._upload(a) for k, a in zip(plan.inputs, inputs, strict=True)}
        if clock:
            clock.lap(ctx, "upload")
        for ps, prog, done in zip(plan.passes, programs, plan.releases(), strict=True):
            target_image = plan.images[ps.target]
            stored = target_image.stored
            tex_size = texture_size(stored)
            target = self._acquire(tex_size, dtype)
            if isinstance(ps, ResamplePass):
                held[ps.source].texture.use(location=0)
                self._table(plan, ps).use(location=1)
                prog.set("u_width", ps.width)
            else:
                for k, src in enumerate(sources(ps)):
                    im, t = plan.images[src], held[src]
                    t.texture.use(location=k)
                    prog.set(f"u_guard{k}", (im.guard[1], im.guard[0]))
                    prog.set(f"u_extent{k}", (im.stored[1], im.stored[0]))
                    prog.set(f"u_inv{k}", (1.0 / t.size[1], 1.0 / t.size[0]))
                prog.set("u_out_guard", (target_image.guard[1], target_image.guard[0]))
            prog.set("u_out_extent", (stored[1], stored[0]))
            wr, wc = _written(stored, tex_size)
            target.fbo.use()                  # bind first: ctx.viewport is stored with the bound framebuffer
            ctx.viewport = (0, 0, wc, wr)
            prog.vao.render(vertices=3)
            if clock and clock.per_pass:
                clock.lap(ctx, "passes")
            held[ps.target] = target
            for s in done:
                self._release(held.pop(s))
        if clock and not clock.per_pass:
            clock.lap(ctx, "passes")
        inputs_by_index = dict(zip(plan.inputs, inputs, strict=True))
        for j, (k, out) in enumerate(zip(plan.outputs, outs, strict=True)):
            if k in inputs_by_index:  # an input read back as given (e.g. level 0 of a pyramid)
                out[...] = inputs_by_index[k]
                continue
            im = plan.images[k]
            rows, cols = im.size
            self._read_back(held[k], (im.guard[1], im.guard[0], cols, rows), out, slot=j)
        if clock:
            clock.lap(ctx, "readback")
        for t in held.values():
            self._release(t)


__all__ = ["GLExecutor", "half_probe", "half_read_rounds_even", "texture_size"]
