"""GLSL for the GL executor: the templates beside this file, specialised per pass shape.

This module is ``pyramid_cli.exec.gl.shaders``, next to its templates in the package
``pyramid_cli.exec.gl`` (installed with them as package data, see ``pyproject.toml``).

A pass of a :class:`~pyramid_cli.plan.model.Plan` becomes a :class:`~pyramid_cli.plan.shapes.PassShape`
(:mod:`pyramid_cli.plan.shapes`): everything a fragment shader needs except sizes and guard bands (those are
uniforms), so one compiled program serves every image size and every plan that has a pass of the same shape.
The shape's taps are
written into the fragment shader as constants (``#define`` for the period and
stride, one generated line per tap), which keeps the program free of loops and
dynamic indexing.

This module has no GL dependency: it only produces text, so it can be tested
without a context.
"""

from __future__ import annotations

from fractions import Fraction
from functools import cache

import numpy as np

from pyramid_cli.core import resources
from pyramid_cli.core.errors import BackendError
from pyramid_cli.plan.shapes import PassShape, PointwiseShape, ShapeTap, pointwise_shape, shape, sources

VERTEX = "fullscreen.vert.glsl"
FRAGMENT = "pass.frag.glsl"
RESAMPLE = "resample.frag.glsl"


class ShaderCompileError(BackendError):
    """A generated program failed to compile or link; the message carries a numbered listing."""


@cache
def load(name: str) -> str:
    """Text of the template ``name`` from the package ``pyramid_cli.exec.gl`` (this folder)."""
    return resources.text(__package__, name)


# ------------------------------------------------------------------ GLSL text
def _float(x) -> str:
    """A GLSL float literal: the float32 nearest to ``x``, written so that it parses back to it."""
    text = f"{float(np.float32(float(x))):.9g}"
    return text if any(ch in text for ch in ".en") else text + ".0"


def _vec2(col, row) -> str:
    return f"vec2({_float(col)}, {_float(row)})"


def _tap_line(t: ShapeTap) -> str:
    tr, tc = t.offset
    if t.exact_texel:
        read = f"nearest{t.slot}(R - ivec2({int(tc)}, {int(tr)}))"
    else:
        read = f"linear{t.slot}(Rf - {_vec2(tc, tr)})"
    if t.weight == 1:
        return f"acc += {read};"
    if t.weight == -1:
        return f"acc -= {read};"
    return f"acc += {_float(t.weight)} * {read};"


def _source_lines(k: int, border: str = "clamp") -> list[str]:
    head = [
        f"uniform sampler2D u_src{k};",
        f"uniform ivec2 u_guard{k};   // (left, top) guard band of source {k}",
        f"uniform ivec2 u_extent{k};  // stored (columns, rows) of source {k}",
    ]
    if border == "clamp":
        return head + [
            f"uniform vec2 u_inv{k};      // 1 / texture size (a power of two: exact)",
            f"vec4 linear{k}(vec2 pos) {{ return bilinear(u_src{k}, pos, u_guard{k}, u_extent{k}, u_inv{k}); }}",
            f"vec4 nearest{k}(ivec2 pos) {{ return nearest(u_src{k}, pos, u_guard{k}, u_extent{k}); }}",
        ]
    # Mirror, wrap and zero fold each integer neighbour of a read (plan.py's border contract),
    # so bilinear reads are four folded texelFetches mixed by the fraction.
    fetch = {"mirror": f"texelFetch(u_src{k}, fold_mirror(q, u_extent{k}), 0)",
             "wrap": f"texelFetch(u_src{k}, fold_wrap(q, u_extent{k}), 0)",
             "zero": f"read_zero(u_src{k}, q, u_extent{k})"}[border]
    return head + [
        f"vec4 fetch{k}(ivec2 q) {{ return {fetch}; }}",
        f"vec4 nearest{k}(ivec2 pos) {{ return fetch{k}(pos - 1 + u_guard{k}); }}",
        f"vec4 linear{k}(vec2 pos) {{",
        f"    vec2 q = pos - 1.0 + vec2(u_guard{k});",
        "    vec2 i = floor(q);",
        "    vec2 f = q - i;",
        "    ivec2 j = ivec2(i);",
        f"    return mix(mix(fetch{k}(j), fetch{k}(j + ivec2(1, 0)), f.x),",
        f"               mix(fetch{k}(j + ivec2(0, 1)), fetch{k}(j + ivec2(1, 1)), f.x), f.y);",
        "}",
    ]


def _uniform_phases(s: PassShape) -> bool:
    """Every phase has the same taps but for offsets and weights, all bilinear or all single texels."""
    layouts = {tuple((t.slot, t.exact_texel) for t in taps) for _, taps in s.phases}
    kinds = {t.exact_texel for _, taps in s.phases for t in taps}
    return len(layouts) == 1 and len(kinds) == 1 and len(s.phases) == s.period[0] * s.period[1]


def _phase_table_lines(s: PassShape) -> list[str]:
    """Branch-free taps: per-phase offsets and weights in constant arrays indexed by the phase.

    Neighbouring fragments have different phases, so branching on the phase makes SIMD
    hardware (and llvmpipe) run every branch; indexing runs one.
    """
    pr, pc = s.period
    table = dict(s.phases)
    order = [(i, j) for i in range(pr) for j in range(pc)]
    n = len(order)
    lines = ["int idx = phase.y * PERIOD.x + phase.x;"]
    for k, first in enumerate(table[order[0]]):
        offs = [table[ph][k].offset for ph in order]
        weights = [table[ph][k].weight for ph in order]
        w = ", ".join(_float(x) for x in weights)
        if first.exact_texel:
            o = ", ".join(f"ivec2({int(tc)}, {int(tr)})" for tr, tc in offs)
            lines.append(f"const ivec2 OFF{k}[{n}] = ivec2[]({o});")
            read = f"nearest{first.slot}(R - OFF{k}[idx])"
        else:
            o = ", ".join(_vec2(tc, tr) for tr, tc in offs)
            lines.append(f"const vec2 OFF{k}[{n}] = vec2[]({o});")
            read = f"linear{first.slot}(Rf - OFF{k}[idx])"
        lines.append(f"const float W{k}[{n}] = float[]({w});")
        lines.append(f"acc += W{k}[idx] * {read};")
    return lines


def affine_taps(s: PassShape) -> list[ShapeTap] | None:
    """The pass's taps as offsets from ``r · STRIDE / PERIOD`` when they are the same in every phase.

    A tap with offset ``t`` in phase ``p`` reads logical index ``S·⌈r/P⌉ − t``, which for
    ``r ≡ p (mod P)`` is ``r·S/P + c`` with ``c = S·([p > 0] − p/P) − t``. When each tap
    has one ``c`` and one weight across all phases (box⊗↓, Doo-Sabin ⊗↑, the midpoint ⊗↑
    and every single-phase pass), the shader needs no phase arithmetic, and ``c`` is
    returned in each tap's ``offset`` (rows, columns). None otherwise.
    """
    (pr, pc), (sr, sc) = s.period, s.stride
    if len(s.phases) != pr * pc:
        return None

    def c(n: int, p: int, stride: int, t: Fraction) -> Fraction:
        return stride * ((1 if n else 0) - Fraction(n, p)) - t

    found: list[ShapeTap] | None = None
    for (nr, nc), taps in s.phases:
        these = [ShapeTap(t.slot, (c(nr, pr, sr, t.offset[0]), c(nc, pc, sc, t.offset[1])), t.weight)
                 for t in taps]
        if found is None:
            found = these
        elif these != found:
            return None
    if found is None or any(t.exact_texel and (sr % pr or sc % pc) for t in found):
        return None
    return found


def _affine_lines(taps: list[ShapeTap]) -> list[str]:
    lines = []
    for t in taps:
        tr, tc = t.offset
        pos = f"base + {_vec2(tc, tr)}"
        read = f"nearest{t.slot}(ivec2({pos}))" if t.exact_texel else f"linear{t.slot}({pos})"
        lines.append(f"acc += {_float(t.weight)} * {read};" if t.weight != 1 else f"acc += {read};")
    return lines


def _tap_lines(s: PassShape) -> list[str]:
    if s.period != (1, 1) and _uniform_phases(s):
        return _phase_table_lines(s)
    lines: list[str] = []
    single = s.period == (1, 1)
    for (pr, pc), taps in s.phases:
        body = [_tap_line(t) for t in taps]
        if single:
            lines += body
        else:
            lines.append(f"if (phase == ivec2({pc}, {pr})) {{")
            lines += ["    " + b for b in body]
            lines.append("}")
    return lines


def _inject(template: str, marker: str, lines: list[str]) -> str:
    token = f"// {{{{{marker}}}}}"
    for raw in template.splitlines():
        if raw.strip() == token:
            indent = raw[: len(raw) - len(raw.lstrip())]
            return template.replace(raw, "\n".join(indent + ln for ln in lines), 1)
    raise ValueError(f"template has no {token} line")  # a broken template is a packaging bug


def vertex_source() -> str:
    return load(VERTEX)


def fragment_source(s: PassShape) -> str:
    """The fragment shader of one pass shape (or of a :class:`PointwiseShape`)."""
    if isinstance(s, PointwiseShape):
        return pointwise_fragment_source(s)
    pr, pc = s.period
    sr, sc = s.stride
    defines = [
        f"#define N_SOURCES {s.n_sources}",
        f"#define PERIOD ivec2({pc}, {pr})",
        f"#define STRIDE ivec2({sc}, {sr})",
    ]
    affine = affine_taps(s)
    if affine is not None:
        defines += ["#define AFFINE", f"#define SLOPE {_vec2(Fraction(sc, pc), Fraction(sr, pr))}"]
    text = _inject(load(FRAGMENT), "DEFINES", defines)
    text = _inject(text, "SOURCES", [ln for k in range(s.n_sources) for ln in _source_lines(k, s.border(k))])
    if affine is not None:
        return _inject(_inject(text, "AFFINE_TAPS", _affine_lines(affine)), "TAPS", [])
    return _inject(_inject(text, "TAPS", _tap_lines(s)), "AFFINE_TAPS", [])


def resample_fragment_source(axis: int) -> str:
    """The fragment shader of a :class:`~pyramid_cli.plan.ResamplePass` along ``axis`` (0 rows, 1 columns):
    one table-driven loop for every table (the weights are a texture, not code)."""
    return _inject(load(RESAMPLE), "DEFINES", [f"#define AXIS {1 - axis}  // GL vectors are (column, row)"])


# ------------------------------------------------------------------ pointwise passes
POINTWISE = "pointwise.frag.glsl"

# The formulas of plan.model.POINTWISE_OPS on vec4 operands a, b, c (K the param); divisions are
# guarded by a select so that no 0/0 is ever mixed in.
POINTWISE_GLSL = {
    "mul": ["frag_color = a * b;"],
    "pull_colour": ["bvec4 pos = greaterThan(b, vec4(0.0));",
                    "vec4 v = a * (min(vec4(1.0), K * b) / mix(vec4(1.0), b, pos));",
                    "frag_color = mix(vec4(0.0), v, pos);"],
    "pull_weight": ["frag_color = min(vec4(1.0), K * a);"],
    "divide": ["bvec4 pos = greaterThan(b, vec4(0.0));",
               "frag_color = mix(vec4(0.0), a / mix(vec4(1.0), b, pos), pos);"],
    "over": ["frag_color = a + (1.0 - b) * c;"],
    "blend": ["frag_color = c * a + (1.0 - c) * b;"],
}


def pointwise_fragment_source(s: PointwiseShape) -> str:
    """The fragment shader of one pointwise op."""
    text = _inject(load(POINTWISE), "DEFINES", [f"#define K {_float(s.param)}"])
    text = _inject(text, "SOURCES", [f"uniform sampler2D u_src{k};" for k in range(s.n_sources)])
    text = _inject(text, "OPERANDS", [f"vec4 {'abc'[k]} = texelFetch(u_src{k}, q, 0);" for k in range(s.n_sources)])
    return _inject(text, "OP", POINTWISE_GLSL[s.op])


def numbered(source: str) -> str:
    """``source`` with 1-based line numbers, as compilers report them."""
    lines = source.splitlines()
    width = len(str(len(lines)))
    return "\n".join(f"{i:>{width}}: {ln}" for i, ln in enumerate(lines, 1))


def compile_error(log: str, stage: str, source: str) -> ShaderCompileError:
    """An error that carries the compiler's log and the numbered listing of the generated source."""
    return ShaderCompileError(f"{stage} shader failed to compile: {log.strip()}\n{numbered(source)}")


__all__ = ["PointwiseShape", "pointwise_shape", "pointwise_fragment_source",
           "PassShape", "ShapeTap", "affine_taps", "ShaderCompileError", "shape", "sources", "vertex_source",
           "fragment_source", "resample_fragment_source", "numbered", "compile_error", "load"]
