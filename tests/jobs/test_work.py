"""The Work values: what to compute, planned for any input size (pyramid_cli.jobs.work)."""

import numpy as np

from pyramid_cli.core.border import Border
from pyramid_cli.core.parse import parse
from pyramid_cli.exec import emulate
from pyramid_cli.jobs.work import Blur, Filter, same_setting
from pyramid_cli.reference import filters as reference


def test_a_filter_plans_its_expression_and_its_reference_is_the_oracle():
    work = Filter(expr=parse("quadratic *v g"), border="mirror")
    image = np.random.default_rng(1).random((9, 7, 3))
    p = work.plan([image.shape], "cost")
    assert p.border == "mirror" and work.n_inputs == 1
    (want,) = work.reference([image])
    oracle = reference.run(parse("quadratic *v g"), image, Border("mirror"))
    np.testing.assert_allclose(want, oracle, rtol=0, atol=1e-12)
    np.testing.assert_allclose(emulate.run(p, image), want, rtol=0, atol=1e-9)


def test_a_blur_keeps_the_size_and_says_what_it_is():
    work = Blur(levels=2)
    p = work.plan([(20, 30, 3)], "cost")
    assert p.output.size[:2] == (20, 30) and work.label == "blur"


def test_same_setting_reads_spellings():
    assert same_setting("synthesis", "doosabin", "h_Doo-Sabin")
    assert not same_setting("synthesis", "doosabin", "cubic")
    assert same_setting("border", "wrap", "wrap") and not same_setting("border", "wrap", "clamp")
