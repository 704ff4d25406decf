"""Bounds inference (pyramid_cli.plan.bounds): each intermediate of a named filter stores the guard band that later
passes of the filter read; the filter's input is a boundary and gets none."""

from fractions import Fraction

from pyramid_cli.plan.bounds import infer_guards
from pyramid_cli.plan.model import Image, Pass, Tap


def one_phase(label: str, target: int, *taps: tuple[int, int, int]) -> Pass:
    """A pass at the target's resolution reading ``(source, row offset, column offset)``: source pixel R − t."""
    return Pass(label, target, (1, 1), (1, 1),
                {(0, 0): [Tap(s, (Fraction(r), Fraction(c)), Fraction(1, len(taps)), False) for s, r, c in taps]})


def test_an_intermediate_stores_what_the_next_pass_reads_and_the_input_nothing():
    images = [Image((8, 8)), Image((8, 8)), Image((8, 8))]
    passes = [one_phase("a", 1, (0, 3, 3)), one_phase("b", 2, (1, 2, 0), (1, 0, 1), (1, 0, -1))]
    infer_guards(images, passes, first=1)
    assert images[1].guard == [2, 1, 0, 1]  # rows R − 2, columns C ∓ 1
    assert images[0].guard == [0, 0, 0, 0] and images[2].guard == [0, 0, 0, 0]


def test_guards_grow_backwards_through_a_chain():
    images = [Image((8, 8)), Image((8, 8)), Image((8, 8)), Image((8, 8))]
    passes = [one_phase("a", 1, (0, 0, 0)), one_phase("b", 2, (1, 0, 1), (1, 0, -1)),
              one_phase("c", 3, (2, 0, -2))]
    infer_guards(images, passes, first=1)
    assert images[2].guard == [0, 0, 0, 2]
    assert images[1].guard == [0, 1, 0, 3]  # what b reads over image 2's stored extent, columns 1..10
    assert images[3].guard == [0, 0, 0, 0]
