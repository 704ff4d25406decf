"""Expression trees and their written steps (pyramid_cli.core.expr); parsing is tests/core/test_parse.py."""

from pyramid_cli.core.expr import Op, steps, sup
from pyramid_cli.core.parse import parse


def test_steps_list_a_chain_innermost_first():
    ops = [(op, stride) for op, _, stride in steps(parse("doosabin *^ (box4 *v^2 g)"))]
    assert ops == [(Op.DOWN, 2), (Op.UP, 1)]


def test_superscripts():
    assert sup(2) == "²" and sup(16) == "¹⁶"
