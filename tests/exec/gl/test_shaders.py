"""The generated GLSL (``pyramid_cli.exec.gl.shaders``): one canonical source per pass shape, the affine fast
path, and compile errors that show the numbered source."""

from functools import cache

import numpy as np
import pytest

import pyramid_cli.exec.gl.shaders as generate
from pyramid_cli.core.parse import parse
from pyramid_cli.plan import plan

CHAINS = [
    "box *v g", "box^nw *v g", "box4 *v g", "quadratic *v g", "cubic *v g", "bartlett *v g",
    "gauss5 *v g", "box * g", "box^nw * g", "bartlett", "gauss5", "gauss7", "quasi", "nearest",
    "midpoint", "doosabin", "cubic *^ g", "fourpoint", "box\\ *v bartlett", "bartlett * (bartlett * g)",
    "(box4)^3 *v g", "doosabin *^ (box4 *v g)", "box\\ * (doosabin *^ g)", "quasi * g", "box *v^2 g",
    "1/8 [1 2 1; 0 2 0; 1 0 1] *v g", "[1 -1] * g", "(doosabin)^2 *^ ((box4)^2 *v g)",
    "fourpoint *^ (cubic *v g)", "box *v (midpoint *^ g)",
]

gl_mark = pytest.mark.gl


@cache
def planned(text: str, size: tuple[int, int], strategy: str = "cost"):
    return parse(text), plan(parse(text), size, strategy)


@gl_mark
def test_compile_error_shows_numbered_source(gl, monkeypatch):
    monkeypatch.setattr(generate, "fragment_source", lambda s: "#version 330 core\nvoid main() { oops; }\n")
    _, p = planned("1/3 [1 1 1] * g", (4, 4))
    with pytest.raises(generate.ShaderCompileError) as info:
        gl.run(p, np.zeros((4, 4), dtype=np.float32))
    assert "fragment shader failed to compile" in str(info.value)
    assert "2: void main() { oops; }" in str(info.value)


def test_generated_source_is_canonical_per_shape():
    _, a = planned("gauss7", (9, 9), "paper")  # the paper's passes: the cost model fuses tiny images
    _, b = planned("bartlett", (40, 3), "paper")
    sources = {generate.fragment_source(generate.shape(ps)) for ps in a.passes + b.passes}
    assert len(sources) == 2
    text = generate.fragment_source(generate.shape(planned("fourpoint", (3, 3), "paper")[1].passes[0]))
    assert text.startswith("#version 330 core\n")
    assert "#define PERIOD ivec2(1, 2)" in text and "if (phase == ivec2(0, 1))" in text
    assert "acc += -0.0625 * nearest0(R - ivec2(0, -1));" in text
    assert "acc += 1.125 * linear0(Rf - vec2(0.0, 0.5));" in text


@pytest.mark.parametrize("text", CHAINS)
def test_affine_taps_read_where_the_phase_formula_reads(text):
    """Where the generator drops the phase arithmetic, every phase's reads must be r·S/P + c."""
    from fractions import Fraction

    _, p = planned(text, (17, 13))
    for ps in p.passes:
        s = generate.shape(ps)
        affine = generate.affine_taps(s)
        if affine is None:
            continue
        table = dict(s.phases)
        for r in range(-3, 9):
            for c in range(-3, 9):
                taps = table[(r % s.period[0], c % s.period[1])]
                base = (s.stride[0] * -(-r // s.period[0]), s.stride[1] * -(-c // s.period[1]))
                indexed = [(t.slot, (base[0] - t.offset[0], base[1] - t.offset[1]), t.weight) for t in taps]
                slope = (Fraction(s.stride[0], s.period[0]), Fraction(s.stride[1], s.period[1]))
                direct = [(t.slot, (r * slope[0] + t.offset[0], c * slope[1] + t.offset[1]), t.weight)
                          for t in affine]
                assert indexed == direct


def test_affine_passes_skip_the_phase_arithmetic():
    def sources(text):
        return [generate.fragment_source(generate.shape(ps)) for ps in planned(text, (9, 9))[1].passes]

    for text in ["doosabin", "box4 *v g", "quadratic", "gauss7"]:
        assert all("#define AFFINE" in src for src in sources(text)), text
    for text in ["fourpoint", "nearest", "midpoint"]:  # phases read at different offsets from r·S/P
        assert not any("#define AFFINE" in src for src in sources(text)), text
    (ds,) = sources("doosabin")
    assert "#define SLOPE vec2(0.5, 0.5)" in ds and "acc += linear0(base + vec2(0.25, 0.25));" in ds
