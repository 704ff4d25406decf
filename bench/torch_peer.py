"""The PyTorch peer: pyramid's written operators as ``torch.nn.functional.conv2d`` passes.

Used by ``bench/run.py --only gpu`` as the GPU peer of the GL executor, and by
``tests/system/test_torch_peer.py``, which checks it against the numpy reference at every pixel.

It computes the same thing as :mod:`pyramid_cli.reference.filters` with the clamp border, on NCHW
tensors of any device and floating dtype (float64, float32, float16):

- every weight comes from the project's exact masks (:func:`pyramid_cli.core.algebra.step_of`, i.e.
  the catalogue's matrices through the paper's offsets ``⌊i − n/2⌋``), not typed in here;
- ``h ⊗↓ᵐ g`` (§4) is one ``conv2d`` of stride 2ᵐ: with 0-based indices, output ``r`` reads
  input ``2ᵐ·r + 2ᵐ − 1 − d`` for each mask offset ``d`` (the 1-based ``g[2ᵐr − d]``);
- ``h ⊗↑ g`` (§5) is one ``conv2d`` on the coarse grid with four output channels, one per
  phase, then ``pixel_shuffle(2)``: fine rows ``2k`` and ``2k + 1`` (0-based) are the 1-based
  odd and even rows, phases 1 and 0, both reading coarse ``k − d``;
- ``h ⊗ g`` (§3) is one ``conv2d`` of stride 1 reading ``r − d``;
- the clamp-to-edge border is ``F.pad(mode="replicate")`` before each step, as wide as that
  step's taps reach outside the image (replicate padding is exactly the reference's clamped
  index, at any width, even for a 1×1 image);
- channels never mix: an (N, C, H, W) tensor runs as (N·C, 1, H, W);
- the pyramid blur takes its steps and crops from :func:`pyramid_cli.core.sigma.blur_steps`,
  the function :func:`pyramid_cli.workflows.pyramids.blur_plan` plans from, so odd sizes are cropped
  the same way (each synthesis back to its level's size).

Each step reads the result of the one before it, as the reference does (a written operator
is a boundary, docs/design.md §1); nothing is fused. The pad is a full copy of the level, as in
the usual PyTorch idiom; the peer is meant to be the straightforward PyTorch program, not a
hand-tuned kernel.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from pathlib import Path

import torch
import torch.nn.functional as F

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:  # run from a checkout even without the editable install
    sys.path.insert(0, str(ROOT))

from pyramid_cli.core import algebra  # noqa: E402
from pyramid_cli.core.expr import Expr, Filter, Named, Op, steps  # noqa: E402
from pyramid_cli.core.sigma import blur_steps  # noqa: E402

Size = tuple[int, int]


# ====================================================================== one written step
def _phase_channel(phase: tuple[int, int]) -> int:
    """Output channel of a ⊗↑ phase (r mod 2, c mod 2), 1-based r, for ``pixel_shuffle(2)``.

    pixel_shuffle puts channel ``2a + b`` at fine (2k + a, 2l + b), 0-based; a = 0 is the
    1-based odd row, phase 1.
    """
    return 2 * (1 - phase[0]) + (1 - phase[1])


@dataclass(frozen=True)
class ConvStep:
    """One written operator as a conv2d: exact weights, stride, and the left pad of each axis.

    ``weights[ch][kr][kc]`` (Fractions): ``out[ch][r][c] = Σ w · xpad[s·r + kr][s·c + kc]`` with
    ``xpad`` the input replicated by ``pad_before`` rows/columns in front. The pad behind depends
    on the input's size (:meth:`pads`).
    """

    op: Op
    stride: int                       # input pixels per output pixel: 2ᵐ for ⊗↓ᵐ, else 1
    weights: tuple                    # (channels, rows, columns) of Fractions
    pad_before: tuple[int, int]       # (rows, columns)

    @property
    def kernel_size(self) -> tuple[int, int]:
        return len(self.weights[0]), len(self.weights[0][0])

    def out_size(self, size: Size) -> Size:
        """Size of the result: ⌈n/2ᵐ⌉ for ⊗↓ᵐ, 2n for ⊗↑, n for ⊗ (docs/design.md §1)."""
        if self.op is Op.DOWN:
            return (-(-size[0] // self.stride), -(-size[1] // self.stride))
        if self.op is Op.UP:
            return (2 * size[0], 2 * size[1])
        return size

    def pads(self, size: Size) -> tuple[int, int, int, int]:
        """``F.pad`` widths (left, right, top, bottom) for an input of ``size`` (rows, columns)."""
        coarse = (size if self.op is Op.UP else self.out_size(size))  # conv2d outputs per axis
        out = []
        for axis in (1, 0):
            k, before = self.kernel_size[axis], self.pad_before[axis]
            needed = self.stride * (coarse[axis] - 1) + k  # padded length the last output reads
            out += [before, max(0, needed - before - size[axis])]
        return out[0], out[1], out[2], out[3]

    def weight_tensor(self, device, dtype) -> torch.Tensor:
        return _weight_tensor(self, str(device), dtype)

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        """Apply the step to ``x`` (N, C, H, W); channels never mix."""
        n, c, h, w = x.shape
        y = x.reshape(n * c, 1, h, w)
        y = F.pad(y, self.pads((h, w)), mode="replicate")
        y = F.conv2d(y, self.weight_tensor(x.device, x.dtype), stride=self.stride)
        if self.op is Op.UP:
            y = F.pixel_shuffle(y[:, :, :h, :w], 2)
        else:
            oh, ow = self.out_size((h, w))
            y = y[:, :, :oh, :ow]
        return y.reshape(n, c, y.shape[-2], y.shape[-1])


@lru_cache(maxsize=64)
def _weight_tensor(st: ConvStep, device: str, dtype) -> torch.Tensor:
    w = [[[float(v) for v in row] for row in ch] for ch in st.weights]
    return torch.tensor(w, dtype=torch.float64).to(device=device, dtype=dtype).unsqueeze(1)


@lru_cache(maxsize=64)
def conv_step(op: Op, f: Filter, stride: int = 1) -> ConvStep:
    """The conv2d form of ``f op ·`` (stride = the m of ⊗↓ᵐ), from the exact mask of :func:`algebra.step_of`."""
    st = algebra.step_of(op, f, stride)
    s = 2 ** stride if op is Op.DOWN else 1
    if op is Op.UP:
        phases = {phase: dict(w) for phase, w in st.weights}
    else:
        phases = {(1, 1): dict(st.weights)}  # one channel
    # 0-based input offset read by output r, per tap: s·r + o with o = s − 1 − d (⊗↓ᵐ) or −d (⊗, ⊗↑).
    taps = {phase: {(s - 1 - dr, s - 1 - dc) if op is Op.DOWN else (-dr, -dc): v for (dr, dc), v in w.items()}
            for phase, w in phases.items()}
    offs = [o for t in taps.values() for o in t]
    lo = (min(o[0] for o in offs), min(o[1] for o in offs))
    hi = (max(o[0] for o in offs), max(o[1] for o in offs))
    before = (max(0, -lo[0]), max(0, -lo[1]))
    shape = (hi[0] + before[0] + 1, hi[1] + before[1] + 1)
    channels = [[[Fraction(0)] * shape[1] for _ in range(shape[0])] for _ in phases]
    for phase, t in taps.items():
        ch = _phase_channel(phase) if op is Op.UP else 0
        for (orow, ocol), v in t.items():
            channels[ch][orow + before[0]][ocol + before[1]] += Fraction(v)
    frozen = tuple(tuple(tuple(row) for row in ch) for ch in channels)
    return ConvStep(op, s, frozen, before)


# ====================================================================== chains
def run_steps(x: torch.Tensor, step_list, crops: dict[int, Size] | None = None) -> torch.Tensor:
    """Written steps ``(op, filter, stride)`` in order on ``x`` (N, C, H, W); ``crops[i]`` crops after step i."""
    crops = crops or {}
    for i, (op, f, m) in enumerate(step_list):
        x = conv_step(op, f, m)(x)
        if i in crops:
            x = x[:, :, :crops[i][0], :crops[i][1]]
    return x


def run_expr(expr: Expr, x: torch.Tensor) -> torch.Tensor:
    """An expression's written steps on ``x``: the reference's ``run`` with the clamp border."""
    return run_steps(x, steps(expr))


def blur(x: torch.Tensor, levels: int = 5, analysis: str = "box4", synthesis: str = "doosabin",
         quasi: bool = False) -> torch.Tensor:
    """The m-level pyramid blur of ``x`` (N, C, H, W) back to its size: ``pyramids.blur_reference`` in torch."""
    step_list, crops = blur_steps(tuple(x.shape[-2:]), levels, analysis, synthesis, quasi)
    return run_steps(x, step_list, crops)


def box4_down(x: torch.Tensor) -> torch.Tensor:
    """``box4 ⊗↓ x`` (4×4 box analysis, the tool's default)."""
    return conv_step(Op.DOWN, Named("box4"), 1)(x)


def doosabin_up(x: torch.Tensor) -> torch.Tensor:
    """``doosabin ⊗↑ x`` (Doo-Sabin synthesis, the tool's default), 2n per axis, uncropped."""
    return conv_step(Op.UP, Named("doosabin"), 1)(x)


# ====================================================================== floor, layout
def copy_floor(src: torch.Tensor, dst: torch.Tensor) -> torch.Tensor:
    """The floor: a device-to-device copy of the image into a preallocated tensor."""
    return dst.copy_(src)


def to_nchw(pixels, device="cpu", dtype=torch.float32) -> torch.Tensor:
    """A numpy (H, W) or (H, W, C) image as a contiguous (1, C, H, W) tensor on ``device``."""
    t = torch.as_tensor(pixels)
    t = t[:, :, None] if t.ndim == 2 else t
    return t.permute(2, 0, 1).unsqueeze(0).to(device=device, dtype=dtype).contiguous()


def from_nchw(t: torch.Tensor, flat: bool = False):
    """A (1, C, H, W) tensor as a numpy (H, W, C) array, or (H, W) with ``flat``."""
    a = t[0].permute(1, 2, 0).detach().cpu().numpy()
    return a[:, :, 0] if flat else a


__all__ = ["ConvStep", "conv_step", "run_steps", "run_expr", "blur", "box4_down", "doosabin_up", "copy_floor",
           "to_nchw", "from_nchw"]
