"""The expression language: the paper's notation verbatim, ASCII spellings, caret errors."""

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pyramid_cli.core.errors import ExpressionError
from pyramid_cli.core.expr import Apply, Input, Named, Op, to_text
from pyramid_cli.core.parse import parse

G = Input()


def _node(op):
    def make(key, x=G, **kw):
        return Apply(op, Named(key), x, **kw)
    return make


conv, down, up = _node(Op.CONV), _node(Op.DOWN), _node(Op.UP)


@pytest.mark.parametrize("text, expected", [
    ("h_box^↘ ⊗↓ (h_Bartlett^{3×3} ⊗ g)", down("box", conv("bartlett"))),
    ("h_quadratic ⊗↓ g", down("quadratic")),
    ("(h_box^{4×4})^2 ⊗↓ g", down("box4", power=2)),
    ("(h_box^{4×4})² ⊗↓ g", down("box4", power=2)),
    ("h_box ⊗↓^3 g", down("box", stride=3)),
    ("h_box ⊗↓³ g", down("box", stride=3)),
    ("h_Doo-Sabin ⊗↑ g", up("doosabin")),
    ("h_box⁴ˣ⁴ ⊗↓ g", down("box4")),
    ("h_cubic^{5×5} ⊗↓ g", down("cubic")),
    ("h_Gauss^{7×7} ⊗ g", conv("gauss7")),
    ("h_box^↙ ⊗ g", conv("box_nw")),          # the paper's printed arrow for box↖
    ("h_box^↖ ⊗ (h_midpoint ⊗↑ g)", conv("box_nw", up("midpoint"))),
    ("box\\ ⊗↓ bartlett", down("box", conv("bartlett"))),
    ("box\\ *v bartlett", down("box", conv("bartlett"))),
    ("box (x)v (bartlett (x) g)", down("box", conv("bartlett"))),
    ("box^nw * g", conv("box_nw")),
    ("box4 *v box4 *v g", down("box4", down("box4"))),
    ("doosabin *^ (box4 *v g)", up("doosabin", down("box4"))),
    ("quadratic", down("quadratic")),           # a lone filter runs with its own operator
    ("doosabin", up("doosabin")),
    ("bartlett", conv("bartlett")),
    ("H_BARTLETT ⊗ G", conv("bartlett")),
])
def test_accepted_spellings(text, expected):
    assert parse(text) == expected


def test_chains_are_right_associative():
    assert parse("box\\ *v quadratic *v bartlett") == down("box", down("quadratic", conv("bartlett")))


def test_written_masks():
    e = parse("1/4 [1 1; 1 1] *v g")
    assert e.op is Op.DOWN and len(e.filter.mask) == 2
    assert parse("[1 2 1]/4 * g").filter.mask[0][1] * 4 == 2


@pytest.mark.parametrize("text, message, column, length", [
    ("bartlet ⊗ g", "unknown filter 'bartlet' (did you mean 'bartlett'?)", 0, 7),
    ("h_quadratc ⊗↓ g", "did you mean 'quadratic'?", 0, 10),
    ("doosabin ⊗↓ g", "'doosabin' is a synthesis filter (four phase masks): use it with ⊗↑, not ⊗↓", 0, 8),
    ("box4 ⊗↑ g", "'box4' is a single mask for ⊗ and ⊗↓; ⊗↑ needs a synthesis filter", 0, 4),
    ("box ⊗↓", "expected a filter or g after ⊗↓", 6, 1),
    ("(box ⊗ g", "'(' at column 1 is never closed", 8, 1),
    ("box ⊗ g)", "unmatched ')'", 7, 1),
    ("g ⊗ box", "a filter must stand left of ⊗, not the image g", 0, 1),
    ("box ⊗↑² g", "only ⊗↓ takes a stride exponent", 6, 1),
    ("box ⊗↓^99 g", "exponent must be between 1 and 16, not 99", 6, 3),
    ("bartlett^{4×4} ⊗ g", "'bartlett' has no size 4×4 (sizes: 3×3)", 8, 6),
    ("cubic", "'cubic' alone is ambiguous", 0, 5),
    ("box $ g", "unexpected character '$'", 4, 1),
])
def test_errors_name_the_problem_and_point_at_it(text, message, column, length):
    with pytest.raises(ExpressionError) as err:
        parse(text)
    e = err.value
    assert message in e.problem
    assert (e.column, e.length) == (column, length)
    assert str(e).splitlines()[2] == "  " + " " * column + "^" * length


ALPHABET = st.sampled_from(list("⊗↓↑↘↖↙*v^()[];/,-_ {}×x²³⁴ˣ\\hgab0123456789") + [
    "box", "box4", "bartlett", "quadratic", "cubic", "doosabin", "midpoint", "g", " ", "h_", "(x)", "^{4×4}"])


@pytest.mark.slow
@settings(max_examples=3000, deadline=None)
@given(st.lists(ALPHABET, max_size=14).map("".join) | st.text(max_size=30))
def test_fuzz_any_string_parses_or_points_inside_it(text):
    try:
        parse(text)
    except ExpressionError as e:
        assert 0 <= e.column <= len(text)
        assert e.problem and "\n" not in e.problem


NAMES = {Op.CONV: ["box", "box_nw", "bartlett", "gauss5", "quasi", "box4", "quadratic", "cubic"],
         Op.DOWN: ["box", "box_nw", "bartlett", "gauss7", "box4", "quadratic", "cubic"],
         Op.UP: ["nearest", "midpoint", "doosabin", "cubic", "fourpoint"]}


@st.composite
def expressions(draw, depth=0):
    if depth > 3 or draw(st.booleans()) and depth:
        return G
    op = draw(st.sampled_from(list(Op)))
    key = draw(st.sampled_from(NAMES[op]))
    power = draw(st.integers(1, 3))
    stride = draw(st.integers(1, 3)) if op is Op.DOWN else 1
    return Apply(op, Named(key), draw(expressions(depth + 1)), power, stride)


@settings(max_examples=300, deadline=None)
@given(expressions())
@pytest.mark.slow
def test_canonical_texts_parse_back(expr):
    if isinstance(expr, Input):
        return
    assert parse(to_text(expr)) == expr
    assert parse(to_text(expr, "ascii")) == expr
