"""Cost checks made before any work starts: refuse at once what would run for minutes or fill memory.

Every check is cheap (interval arithmetic on the written steps) and raises a
:class:`~pyramid_cli.core.errors.PyramidError` with a one-line reason:

- :func:`check_kernel_cost` (``pyramid explain``): the exact kernel of a chain has at most
  :data:`MAX_KERNEL_ENTRIES` weights and its exact evaluation at most
  :data:`MAX_EVALUATION_WORK` rational multiply-adds, else :class:`UsageError` (exit 2).
- :func:`check_image_cost` (commands that filter an image): no intermediate or output image
  of the chain is larger than :data:`MAX_PIXELS` pixels, else :class:`DataError` (exit 5).

``blur --sigma``'s check, :func:`pyramid_cli.core.sigma.check_sigma`, lives with the closed form it uses.

The limits are set so that work that passes them finishes in seconds on a 2-core machine:
explain's slowest allowed kernels take about 2 s there; an image of :data:`MAX_PIXELS`
pixels is an 8192×8192 texture (1 GiB as RGBA32F).
"""

from __future__ import annotations

import math

from pyramid_cli.core.errors import DataError, UsageError
from pyramid_cli.core.expr import Expr, Op, steps
from pyramid_cli.core.geometry import reduced

MAX_KERNEL_ENTRIES = 65_536          # weights in all phases of an exact kernel (e.g. 256×256)
MAX_EVALUATION_WORK = 500_000        # rational multiply-adds to evaluate it exactly (estimated)
MAX_PIXELS = 1 << 26                 # pixels in any intermediate or output image (8192×8192)


# ---------------------------------------------------------------- exact kernels
def _offset_ranges(op: Op, f) -> tuple[tuple[int, int], tuple[int, int], int]:
    """Per axis (lo, hi) of the offsets d a step reads (``R − d``), and its non-zero weights."""
    from pyramid_cli.core.algebra import step_of

    step = step_of(op, f)
    masks = [dict(w) for _, w in step.weights] if op is Op.UP else [dict(step.weights)]
    ds = [d for w in masks for d in w] or [(0, 0)]
    nnz = max(len(w) for w in masks)
    return (min(d[0] for d in ds), max(d[0] for d in ds)), (min(d[1] for d in ds), max(d[1] for d in ds)), nnz


def _back(op: Op, stride: int, a: int, b: int, lo: int, hi: int) -> tuple[int, int]:
    """Input index range that outputs ``a..b`` of one step read (the paper's index formulas)."""
    if op is Op.DOWN:
        s = 2 ** stride
        return s * a - hi, s * b - lo
    if op is Op.UP:
        return (a + 1) // 2 - hi, (b + 1) // 2 - lo
    return a - hi, b - lo


def kernel_cost(expr: Expr) -> tuple[int, int]:
    """(weights, work): an upper bound on the number of weights of ``expr``'s exact kernel (all
    phases) and an estimate of the rational multiply-adds :func:`algebra.kernel` spends on it.

    Found by interval arithmetic on the written steps, in microseconds, however large the kernel.
    """
    from pyramid_cli.core.algebra import split_step, step_of

    stps = steps(expr)
    if not stps:
        return 1, 1
    info = [(op, s, *_offset_ranges(op, f)) for op, f, s in stps]
    ups = sum(op is Op.UP for op, _, _ in stps)
    period = 2 ** ups
    n = len(info)

    def extent(level: int, count: int, axis: int) -> int:
        """Width at level 0 of what ``count`` neighbouring pixels of level ``level`` read."""
        a, b = 8 * period + 1, 8 * period + count
        for op, s, rr, rc, _ in reversed(info[:level]):
            lo, hi = (rr, rc)[axis]
            a, b = _back(op, s, a, b, lo, hi)
        return b - a + 1

    width = [extent(n, period, axis) for axis in (0, 1)]
    entries = period * period * width[0] * width[1]
    separable = all(split_step(step_of(op, f, s)) is not None for op, f, s in stps)
    work = 0
    for level in range(1, n + 1):
        # pixels of this level the evaluation visits × weights of the step × size of each input's value
        span = [1, 1]
        for axis in (0, 1):
            a, b = 8 * period + 1, 8 * period + period
            for op, s, rr, rc, _ in reversed(info[level:]):
                lo, hi = (rr, rc)[axis]
                a, b = _back(op, s, a, b, lo, hi)
            span[axis] = b - a + 1
        below = [extent(level - 1, 1, axis) for axis in (0, 1)]
        nnz = info[level - 1][4]
        if separable:
            taps = max(1, round(math.sqrt(nnz)))
            work += sum(span[axis] * taps * below[axis] for axis in (0, 1))
        else:
            work += span[0] * span[1] * nnz * below[0] * below[1]
    if separable:
        work += entries
    return entries, work


def check_kernel_cost(expr: Expr, text: str | None = None) -> None:
    """Refuse (exit 2) a chain whose exact kernel is too large or too slow to evaluate."""
    entries, work = kernel_cost(expr)
    what = f"'{text}'" if text else "the expression"
    if entries > MAX_KERNEL_ENTRIES:
        raise UsageError(f"{what} has an exact kernel of up to {entries:,} weights, more than the limit of "
                         f"{MAX_KERNEL_ENTRIES:,}: use fewer repeated steps")
    if work > MAX_EVALUATION_WORK:
        raise UsageError(f"{what} needs about {work:,} exact operations to evaluate, more than the limit of "
                         f"{MAX_EVALUATION_WORK:,}: use fewer repeated steps")


# ---------------------------------------------------------------- images
def step_sizes(expr_or_steps, size: tuple[int, int]) -> list[tuple[int, int]]:
    """(rows, cols) of the input and after every written step (docs/design.md §1 sizes)."""
    stps = steps(expr_or_steps) if not isinstance(expr_or_steps, list) else expr_or_steps
    h, w = size
    out = [(h, w)]
    for op, _, m in stps:
        if op is Op.DOWN:
            h, w = reduced(h, m), reduced(w, m)
        elif op is Op.UP:
            h, w = 2 * h, 2 * w
        out.append((h, w))
    return out


def check_image_cost(expr_or_steps, size: tuple[int, int], *, where: str = "") -> None:
    """Refuse (exit 5) a chain that would make an image of more than :data:`MAX_PIXELS` pixels.

    ``size`` is the input's (rows, cols); ``where`` (the input's path) starts the message.
    """
    sizes = step_sizes(expr_or_steps, size)
    for k, (h, w) in enumerate(sizes[1:], 1):
        if h * w > MAX_PIXELS:
            prefix = f"{where}: " if where else ""
            what = "the result" if k == len(sizes) - 1 else f"step {k} of {len(sizes) - 1}"
            raise DataError(f"{prefix}{what} would be {w}×{h} pixels, more than the limit of {MAX_PIXELS:,} "
                            f"({int(math.isqrt(MAX_PIXELS))}×{int(math.isqrt(MAX_PIXELS))})")
