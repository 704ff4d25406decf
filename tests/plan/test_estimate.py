"""Seconds a plan should take, by the cost model (pyramid_cli.plan.estimate)."""

from pyramid_cli.core.parse import parse
from pyramid_cli.plan import estimate, plan


def test_the_estimate_is_the_sum_over_passes_and_grows_with_the_picture():
    small = plan(parse("gauss5"), (16, 16))
    large = plan(parse("gauss5"), (1024, 1024))
    assert estimate.estimate_seconds(small) > 0
    assert estimate.estimate_seconds(large) > estimate.estimate_seconds(small)
    total = sum(estimate.pass_seconds(small.images, ps) for ps in small.passes)
    assert abs(total - estimate.estimate_seconds(small)) < 1e-12
