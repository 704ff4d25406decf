"""Pass shapes (``pyramid_cli.plan.shapes``): the canonical key an executor compiles once, independent of image
indices and sizes, recording non-clamp borders and pointwise ops."""

from __future__ import annotations

from fractions import Fraction

from pyramid_cli.core.parse import parse
from pyramid_cli.plan import plan
from pyramid_cli.plan.model import Image, Pass, PointwisePass, Tap
from pyramid_cli.plan.shapes import PassShape, PointwiseShape, ShapeTap, pointwise_shape, shape, sources

HALF = Fraction(1, 2)


def two_source_pass(a: int, b: int) -> Pass:
    """Half of image ``a`` at a half-texel offset plus half of image ``b`` at its texel, at stride 2."""
    return Pass("t", 9, (1, 1), (2, 2), {(0, 0): [Tap(a, (HALF, HALF), HALF, True),
                                                  Tap(b, (Fraction(0), Fraction(0)), HALF, False)]})


def test_image_indices_become_slots_in_sorted_order():
    assert sources(two_source_pass(7, 3)) == [3, 7]
    s = shape(two_source_pass(7, 3))
    assert isinstance(s, PassShape) and s.n_sources == 2 and s.period == (1, 1) and s.stride == (2, 2)
    ((phase, taps),) = s.phases
    assert phase == (0, 0)
    assert taps == (ShapeTap(1, (HALF, HALF), HALF), ShapeTap(0, (Fraction(0), Fraction(0)), HALF))
    assert [t.exact_texel for t in taps] == [False, True]
    # other images read the same way: the same shape (one compiled program)
    assert shape(two_source_pass(8, 4)) == s and hash(shape(two_source_pass(8, 4))) == hash(s)
    assert shape(two_source_pass(3, 7)) != s  # the other image at the half-texel offset


def test_one_shape_serves_every_image_size():
    def shapes(size):
        return [shape(ps) for ps in plan(parse("gauss5"), size, "paper").passes]

    assert shapes((17, 13)) == shapes((64, 129)) == shapes((5, 3))
    assert len(set(shapes((17, 13)))) == 2  # box↖ and box↘ alternate


def test_borders_are_recorded_only_when_not_all_clamp():
    ps = two_source_pass(0, 1)
    clamp = [Image((4, 4)), Image((4, 4))]
    assert shape(ps, clamp).borders == () and shape(ps, clamp) == shape(ps)
    mixed = shape(ps, [Image((4, 4), border="mirror"), Image((4, 4))])
    assert mixed.borders == ("mirror", "clamp") and mixed != shape(ps)
    assert mixed.border(0) == "mirror" and mixed.border(1) == "clamp" and shape(ps).border(1) == "clamp"


def test_pointwise_passes_keep_operand_order_and_parameter():
    ps = PointwisePass("blend", 5, "blend", (4, 2, 3))
    assert sources(ps) == [4, 2, 3]
    assert shape(ps) == pointwise_shape(ps) == PointwiseShape("blend", 3, Fraction(1))
    pulled = PointwisePass("pull", 3, "pull_weight", (1,), param=Fraction(4))
    assert shape(pulled) == PointwiseShape("pull_weight", 1, Fraction(4))
    assert shape(pulled) != shape(PointwisePass("pull", 3, "pull_weight", (1,), param=Fraction(2)))
