"""Bilinear taps for exact weights (pyramid_cli.plan.taps)."""

from fractions import Fraction as F

from pyramid_cli.plan import taps


def test_a_2x2_box_is_one_linear_fetch_between_four_texels():
    (tap,) = taps.taps_for({(0, 0): F(1, 4), (0, 1): F(1, 4), (1, 0): F(1, 4), (1, 1): F(1, 4)}, 0)
    assert tap.linear and tap.offset == (F(1, 2), F(1, 2)) and tap.weight == 1 and tap.source == 0


def test_taps_reproduce_the_weights_they_replace():
    weights = {(0, 0): F(1, 16), (0, 1): F(3, 16), (1, 0): F(3, 16), (1, 1): F(9, 16)}
    total = sum(t.weight for t in taps.taps_for(weights, 2))
    assert total == 1


def test_the_same_weights_read_each_source_given_and_the_caller_owns_the_list():
    """The fit is kept per weights (plans ask for the same masks again and again); each call still gets the
    taps of its own source, in a list of its own, whatever order the weights came in."""
    weights = {(0, 0): F(1, 16), (0, 1): F(3, 16), (1, 0): F(3, 16), (1, 1): F(9, 16), (2, 2): F(-1, 8)}
    first = taps.taps_for(weights, 1)
    first.clear()
    again = taps.taps_for(dict(reversed(weights.items())), 3)
    assert again and {t.source for t in again} == {3}
    assert [(t.offset, t.weight, t.linear) for t in again] == [
        (t.offset, t.weight, t.linear) for t in taps.taps_for(weights, 1)]
    assert sum(t.weight for t in again) == sum(weights.values())
