"""Cost checks: refused at once with a one-line reason, cheap to compute, and equal to the slow truth."""

import math

import pytest

from helpers.marks import slow_beyond
from pyramid_cli.core import sigma as sigmas
from pyramid_cli.core.errors import DataError, ExpressionError, UsageError
from pyramid_cli.core.parse import parse
from pyramid_cli.core.sigma import impulse_sigma
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


@pytest.mark.parametrize("analysis, synthesis", slow_beyond(
    [("box4", "doosabin"), ("quadratic", "cubic"), ("box", "nearest"), ("cubic", "fourpoint")], unpack=True))
def test_levels_sigma_equals_the_kernel_evaluation(analysis, synthesis):
    for m in range(1, 6):
        assert math.isclose(sigmas.levels_sigma(m, analysis, synthesis), impulse_sigma(m, analysis, synthesis),
                            rel_tol=1e-12)


def test_sigma_blend_matches_the_kernel_evaluation():
    """The closed-form (m, t) equals the one found from the evaluated kernels (the planner's only source
    before the closed form: the first level count at or past sigma, blended with the one below)."""
    for sigma in (0.5, 1.4, 3.5, 10.0, 40.0):
        m, t = sigmas.sigma_blend(sigma)
        sig = [0.0]
        while sig[-1] < sigma:
            sig.append(impulse_sigma(len(sig), "box4", "doosabin"))
        m2 = len(sig) - 2
        t2 = (sigma ** 2 - sig[m2] ** 2) / (sig[m2 + 1] ** 2 - sig[m2] ** 2)
        assert m == m2 and math.isclose(t, t2, rel_tol=1e-9, abs_tol=1e-12)


@pytest.mark.parametrize("sigma", [float("inf"), float("nan"), -1.0, 0.0, 1e6])
def test_bad_sigmas_are_refused(sigma):
    with pytest.raises(UsageError):
        sigmas.check_sigma(sigma)


def test_sigma_beyond_the_image_is_refused_and_names_the_limit():
    top = sigmas.max_sigma((256, 320))
    sigmas.check_sigma(top * 0.99, (256, 320))
    with pytest.raises(UsageError, match=r"320×256 image.*9 levels"):
        sigmas.check_sigma(1000.0, (256, 320))


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
