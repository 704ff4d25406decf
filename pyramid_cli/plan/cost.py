"""The planner's cost model: seconds of a render pass, calibrated by ``bench/calibrate.py``.

The paper counts bilinear fetches per fragment (§3–§5); what a pass really costs
on a given GL is a fixed overhead (a draw call, a render-target switch, the
executor's own bookkeeping) that grows with the length of the pass's shader,
plus work per written pixel and per fetch, plus the bytes the pass reads from
its sources. :class:`CostModel` says so linearly::

    seconds = pass_s + taps · shader_tap_s
            + share · written · (pixel_s + linear · fetch_linear_s + nearest · fetch_nearest_s)
            + share · read · source_pixel_s

with ``taps`` the texture reads written in the pass's shader (all phases),
``written`` the target's stored pixels (logical size plus guard band),
``linear`` / ``nearest`` the bilinear / single-texel fetches each fragment
executes (:func:`executed_fetches`) and ``read`` the stored pixels of the
pass's sources. Per-pixel work is spread over ``threads`` workers in tiles of
``tile``² pixels (llvmpipe: 64² tiles, one thread per core), so a target of
fewer tiles than threads leaves workers idle: ``share = threads / min(threads,
tiles)`` (1 with ``tile`` 0). Tiny pyramid levels are all overhead, big ones
all fetches, so the cheaper of the paper's decomposition and a fused pass can
change with the image size (docs/design.md §5).

The constants live in ``cost_model.json`` beside this module (shipped as
package data), with the GL renderer they were measured on, the date, the
command that produced them and the fit's residual. This module is pure
Python: no GL, no numpy.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache

from pyramid_cli.core import resources

MODEL_FILE = "cost_model.json"
CONSTANTS = ("pass_s", "shader_tap_s", "pixel_s", "fetch_linear_s", "fetch_nearest_s", "source_pixel_s")
FIELDS = CONSTANTS + ("tile", "threads", "fetch_costs_merged", "renderer", "date", "command", "residual",
                      "samples")


@dataclass(frozen=True)
class CostModel:
    """Seconds of a render pass as a linear function of its size, fetches and reads (see the module)."""

    pass_s: float           # fixed per pass: draw call, target switch, uniforms
    shader_tap_s: float     # per pass, per texture read in the shader's code (all phases)
    pixel_s: float          # per written pixel (stored extent of the target)
    fetch_linear_s: float   # per bilinear fetch (textureLod) per written pixel
    fetch_nearest_s: float  # per single-texel fetch (texelFetch) per written pixel
    source_pixel_s: float   # per stored pixel of each source the pass reads (bytes moved)
    tile: int = 0           # side of the renderer's tiles, in pixels (0: no tiling)
    threads: int = 1        # workers sharing the tiles
    renderer: str = "uncalibrated"
    date: str = ""

    def share(self, size: tuple[int, int]) -> float:
        """How many times longer per-pixel work takes on a target of ``size`` (rows, columns) than
        with every worker busy: ``threads / min(threads, tiles)``."""
        if not self.tile or self.threads <= 1:
            return 1.0
        tiles = -(-size[0] // self.tile) * -(-size[1] // self.tile)
        return self.threads / min(self.threads, tiles)

    def features(self, taps: int, size: tuple[int, int], linear: float, nearest: float,
                 read: int) -> tuple[float, ...]:
        """What each constant of :data:`CONSTANTS` multiplies, for one pass with ``taps`` reads in
        its shader writing a target of ``size`` (rows, columns) with ``linear`` + ``nearest``
        fetches per fragment, reading sources of ``read`` stored pixels in all."""
        written = size[0] * size[1] * self.share(size)
        return (1.0, float(taps), written, written * linear, written * nearest, read * self.share(size))

    def pass_seconds(self, taps: int, size: tuple[int, int], linear: float, nearest: float, read: int) -> float:
        """Estimated seconds of one pass (arguments as for :meth:`features`)."""
        return sum(c * v for c, v in zip(self.constants, self.features(taps, size, linear, nearest, read),
                                         strict=True))

    @property
    def constants(self) -> tuple[float, ...]:
        """The constants in the order of :data:`CONSTANTS` (and of :meth:`features`)."""
        return tuple(getattr(self, k) for k in CONSTANTS)

    @property
    def name(self) -> str:
        """One-line provenance for reports: the renderer measured on and when."""
        return f"cost model: {self.renderer}" + (f", {self.date}" if self.date else "")


def executed_fetches(phases: Sequence[Sequence[tuple[int, bool]]]) -> tuple[float, float]:
    """(bilinear, single-texel) fetches a fragment executes, given each phase's taps as
    ``(source, linear)`` in shader order.

    When every phase has the same layout and one kind of tap, the generated shader
    indexes per-phase tables and a fragment runs one phase's taps (the mean, as the
    paper counts, §5). Otherwise it branches on the phase, and since neighbouring
    fragments have different phases, SIMD hardware (llvmpipe, any GPU warp) runs
    every branch: the sum over phases. This mirrors ``exec/gl/shaders.py``.
    """
    layouts = {tuple(p) for p in phases}
    kinds = {lin for p in phases for _, lin in p}
    linear = sum(lin for p in phases for _, lin in p)
    nearest = sum(not lin for p in phases for _, lin in p)
    if len(phases) > 1 and len(layouts) == 1 and len(kinds) <= 1:
        return linear / len(phases), nearest / len(phases)
    return float(linear), float(nearest)


def from_dict(d: dict) -> CostModel:
    """A :class:`CostModel` from the JSON object ``bench/calibrate.py --write`` produces."""
    missing = [k for k in FIELDS if k not in d]
    if missing:
        raise ValueError(f"{MODEL_FILE} lacks {', '.join(missing)}")
    values = {k: float(d[k]) for k in CONSTANTS}
    bad = [k for k, v in values.items() if not v >= 0]
    if bad or values["pass_s"] <= 0:
        raise ValueError(f"{MODEL_FILE}: constants must be non-negative and pass_s positive ({values})")
    tile, threads = d["tile"], d["threads"]
    if not (isinstance(tile, int) and tile >= 0 and isinstance(threads, int) and threads >= 1):
        raise ValueError(f"{MODEL_FILE}: tile must be an integer >= 0 and threads >= 1, not {tile!r}, {threads!r}")
    return CostModel(**values, tile=tile, threads=threads, renderer=str(d["renderer"]), date=str(d["date"]))


def load_dict() -> dict:
    """The committed ``cost_model.json`` as a dict."""
    return resources.json_file(__package__, MODEL_FILE)


@cache
def model() -> CostModel:
    """The calibrated model, loaded once per process (the planner stays deterministic given the file)."""
    return from_dict(load_dict())


def format_seconds(s: float) -> str:
    """14.1 ms, 352 µs: three significant figures in a readable unit."""
    if s >= 1:
        return f"{s:.3g} s"
    if s >= 1e-3:
        return f"{s * 1e3:.3g} ms"
    return f"{s * 1e6:.3g} µs"


__all__ = ["CostModel", "executed_fetches", "model", "from_dict", "load_dict", "format_seconds", "CONSTANTS",
           "FIELDS", "MODEL_FILE"]
