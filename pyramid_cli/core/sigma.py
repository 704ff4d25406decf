"""The pyramid blur's written steps and its Gaussian-equivalent sigma, in closed form (pure Python).

An m-level blur (paper §2, Figure 3) is m analysis steps (⊗↓) and m synthesis steps (⊗↑) back
up, each cropped to its level's size (:func:`blur_steps`). Its strength is the standard deviation
of its equivalent kernel (:func:`impulse_sigma`, exact but 4× dearer per level); variances add
under the cascade and level k's filters act 2ᵏ input pixels apart, so the variance is a geometric
series in 4 (:func:`levels_sigma`, microseconds). ``blur --sigma`` blends the m- and (m+1)-level
blurs (:func:`sigma_blend`) after :func:`check_sigma` refuses what no image of the size can express.
"""

from __future__ import annotations

import json
import math
from fractions import Fraction
from functools import lru_cache

from pyramid_cli.core import algebra, cache
from pyramid_cli.core.catalogue import DEFAULT_ANALYSIS, DEFAULT_SYNTHESIS
from pyramid_cli.core.errors import UsageError
from pyramid_cli.core.expr import Apply, Expr, Input, Named, Op, steps
from pyramid_cli.core.fingerprint import sources
from pyramid_cli.core.geometry import level_sizes, mip_levels
from pyramid_cli.core.options import MAX_LEVELS
from pyramid_cli.core.parse import one_step

A0, S0 = DEFAULT_ANALYSIS, DEFAULT_SYNTHESIS


def blur_steps(size: tuple[int, int], levels: int, analysis: str = A0, synthesis: str = S0,
               quasi: bool = False):
    """Written steps and crops of an m-level pyramid blur back to ``size``.

    Returns ``(steps, crops)``: the ``(op, filter, stride)`` list in the order they run, and
    ``{step index: (rows, cols)}`` for each synthesis step cropped to its level's size.
    """
    if levels < 1:
        raise UsageError("--levels must be at least 1")
    down = steps(one_step(analysis, Op.DOWN))
    up = steps(one_step(synthesis, Op.UP))
    sizes = level_sizes(size, levels)
    step_list, crops = [], {}
    for _ in range(levels):
        step_list += down
    if quasi:
        step_list.append((Op.CONV, Named("quasi"), 1))
    for k in range(levels, 0, -1):
        step_list += up
        crops[len(step_list) - 1] = sizes[k - 1]
    return step_list, crops


def blur_expression(levels: int, analysis: str, synthesis: str) -> Expr:
    """The blur without crops, as an expression (used to describe its equivalent kernel)."""
    expr: Expr = Input()
    for op, f, s in blur_steps((2 ** levels, 2 ** levels), levels, analysis, synthesis)[0]:
        expr = Apply(op, f, expr, 1, s)
    return expr


def impulse_sigma(levels: int, analysis: str, synthesis: str) -> float:
    """Standard deviation (input pixels) of the blur's equivalent kernel along a row, mean over phases."""
    split = algebra.axis_kernels(algebra.chain_steps(blur_expression(levels, analysis, synthesis)))
    if split is None:
        raise UsageError("the blur's filters are not separable")
    _, _, phases = split[1]
    total = 0.0
    for w in phases.values():
        s = sum(w.values())
        mean = sum(v * d for d, v in w.items()) / s
        total += float(sum(v * (d - mean) ** 2 for d, v in w.items()) / s)
    return (total / len(phases)) ** 0.5


FORM_FORMAT = 1  # the layout of a variance form's cache entry


@lru_cache(maxsize=32)
def variance_form(analysis: str, synthesis: str) -> tuple[Fraction, Fraction] | None:
    """(A, B) with variance(m levels) = A·4ᵐ + B, from 1 and 2 levels, checked at 3; None if it does not fit.

    Variances add under the pyramid's cascade and level k's filters act 2ᵏ input pixels apart,
    so the blur's variance is a geometric series in 4. The three impulse responses are exact
    kernel algebra (tens of milliseconds), so the form is kept in the cache folder's ``plans``
    (:mod:`pyramid_cli.core.cache`), keyed by the filters and the core's sources
    (:func:`pyramid_cli.core.fingerprint.sources`); an entry that is not exactly one is recomputed.
    """
    key = repr(("variance_form", FORM_FORMAT, sources("core"), analysis, synthesis))
    name = f"sigma-{cache.key(key)}.json"
    try:
        doc = json.loads((cache.read("plans", name) or b"").decode("utf-8"))
        if doc["key"] == key:
            if doc["form"] is None:
                return None
            (a, b), (c, d) = doc["form"]
            if all(type(n) is int for n in (a, b, c, d)) and b > 0 and d > 0:
                return Fraction(a, b), Fraction(c, d)
    except (ValueError, KeyError, TypeError, UnicodeDecodeError):
        pass  # none yet, or not one: computed below
    form = _variance_form(analysis, synthesis)
    data = None if form is None else [[f.numerator, f.denominator] for f in form]
    cache.write("plans", name, json.dumps({"key": key, "form": data}).encode("utf-8"))
    return form


def _variance_form(analysis: str, synthesis: str) -> tuple[Fraction, Fraction] | None:
    v = [Fraction(impulse_sigma(m, analysis, synthesis) ** 2).limit_denominator(1 << 20) for m in (1, 2, 3)]
    a = (v[1] - v[0]) / 12
    b = v[0] - 4 * a
    if abs(float(a * 64 + b - v[2])) > 1e-9 * max(1.0, float(v[2])):
        return None
    return a, b


def levels_sigma(levels: int, analysis: str = A0, synthesis: str = S0) -> float:
    """The Gaussian-equivalent sigma (input pixels) of a ``levels``-level blur, in microseconds.

    Equal to :func:`impulse_sigma` (tested up to 5 levels), which costs 4× more per level.
    """
    form = variance_form(analysis, synthesis)
    if form is None:
        return impulse_sigma(levels, analysis, synthesis)
    a, b = form
    return math.sqrt(float(a * 4 ** levels + b))


def max_levels(size: tuple[int, int] | None) -> int:
    """Most pyramid levels an image of ``size`` (rows, cols) has: halvings until 1×1 (at most
    :data:`~pyramid_cli.core.options.MAX_LEVELS`)."""
    if size is None:
        return MAX_LEVELS
    rows, cols = size
    return max(1, min(mip_levels((rows, cols)), MAX_LEVELS))


def max_sigma(size: tuple[int, int] | None, analysis: str = A0, synthesis: str = S0) -> float:
    """Largest ``--sigma`` an image of ``size`` can express: the blur down to 1×1 (:func:`max_levels`)."""
    return levels_sigma(max_levels(size), analysis, synthesis)


def sigma_blend(sigma: float, analysis: str = A0, synthesis: str = S0,
                size: tuple[int, int] | None = None) -> tuple[int, float]:
    """(m, t): blending (1 − t) × the m-level blur with t × the (m+1)-level one has variance sigma².

    Refuses (exit 2) what :func:`check_sigma` refuses; the variances come in closed form
    (:func:`levels_sigma`), no kernel is evaluated beyond 3 levels.
    """
    check_sigma(sigma, size, analysis, synthesis)
    sig = [0.0]
    while sig[-1] < sigma:
        sig.append(levels_sigma(len(sig), analysis, synthesis))
    m = len(sig) - 2
    return m, (sigma ** 2 - sig[m] ** 2) / (sig[m + 1] ** 2 - sig[m] ** 2)


def check_sigma(sigma: float, size: tuple[int, int] | None = None, analysis: str = A0,
                synthesis: str = S0, *, where: str = "") -> None:
    """Refuse (exit 2) a ``--sigma`` that is not a positive number or that needs more levels than an
    image of ``size`` (rows, cols) has (``size`` None: the :data:`MAX_LEVELS` limit only)."""
    if not (isinstance(sigma, (int, float)) and sigma > 0 and math.isfinite(sigma)):
        raise UsageError(f"--sigma must be a positive finite number, not {sigma!r}")
    top = max_sigma(size, analysis, synthesis)
    if sigma > top:
        prefix = f"{where}: " if where else ""
        if size is None:
            raise UsageError(f"{prefix}--sigma {sigma:g} needs more than {MAX_LEVELS} levels "
                             f"(at most {top:.4g} with {analysis}/{synthesis})")
        h, w = size
        raise UsageError(f"{prefix}--sigma {sigma:g} is more than a {w}×{h} image can express: "
                         f"{max_levels(size)} levels reach 1×1 at sigma {top:.4g}")


__all__ = ["blur_steps", "blur_expression", "impulse_sigma", "variance_form", "levels_sigma", "max_levels",
           "max_sigma", "sigma_blend", "check_sigma"]
