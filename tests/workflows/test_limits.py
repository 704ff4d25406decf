"""Cost checks: refused at once with a one-line reason, cheap to compute, and equal to the slow truth."""

import pytest

from pyramid_cli.core.errors import DataError, ExpressionError, UsageError
from pyramid_cli.core.parse import parse
from pyramid_cli.workflows import limits


@pytest.mark.parametrize("text", ["(box)^16 *v g", "(box)^12 *v g", "(cubic)^6 *^ g", "(doosabin)^8 *^ g",
                                  "(box4)^8 *v g", "(quasi)^16 * g"])
def test_costly_kernels_are_refused(text):
    with pytest.raises(UsageError, match="limit"):
        limits.check_kernel_cost(parse(text), text)


@pytest.mark.parametrize("text", ["quadratic *v g", "box\\ *v bartlett", "(box4)^4 *v g", "(cubic)^4 *^ g",
                                  "fourpoint", "gauss7 * g", "(box4)^3 *v (doosabin)^3 *^ g"])
def test_ordinary_kernels_pass(text):
    limits.check_kernel_cost(parse(text), text)


def test_the_bound_holds_for_small_kernels():
    from pyramid_cli.core import algebra

    for text in ["quadratic *v g", "(box)^3 *v g", "doosabin *^ bartlett", "(cubic)^2 *^ g", "box4 *v quasi"]:
        k = algebra.kernel(parse(text))
        entries, _ = limits.kernel_cost(parse(text))
        assert sum(len(w) for w in k.phases.values()) <= entries


def test_huge_images_are_refused_before_any_work():
    with pytest.raises(DataError, match="limit"):
        limits.check_image_cost(parse("(doosabin)^8 *^ g"), (256, 320), where="in.exr")
    limits.check_image_cost(parse("doosabin *^ g"), (2160, 3840))


@pytest.mark.parametrize("text, column", [
    ("[1 " + "9" * 400 + " 1]", 3), ("[1 " + "9" * 4300 + " 1]", 3), ("1/" + "7" * 5000 + " [1 1]", 2),
    ("box^" + "9" * 5000 + " *v g", 3), ("gauss" + "9" * 5000, 0), ("[1 1] / " + "3" * 400, 8),
])
def test_oversized_numbers_point_at_the_column(text, column):
    with pytest.raises(ExpressionError) as e:
        parse(text)
    assert e.value.column == column
