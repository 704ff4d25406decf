"""The plan emulator, the plan's living definition (pyramid_cli.exec.emulate). Every executor against it:
tests/exec/test_conformance.py."""

import numpy as np

from pyramid_cli.core.parse import parse
from pyramid_cli.exec import emulate
from pyramid_cli.plan import plan
from pyramid_cli.reference import filters as reference


def test_emulate_runs_a_plan_in_float64_like_the_reference():
    image = np.random.default_rng(2).random((13, 11, 3))
    p = plan(parse("doosabin *^ (box4 *v g)"), (13, 11))
    out = emulate.run(p, image)
    assert out.dtype == np.float64
    np.testing.assert_allclose(out, reference.run(parse("doosabin *^ (box4 *v g)"), image), rtol=0, atol=1e-12)


def test_pointwise_combines_sources():
    a, b = np.full((2, 2), 3.0), np.full((2, 2), 1.0)
    np.testing.assert_array_equal(emulate.pointwise("mul", [a, b]), a * b)
