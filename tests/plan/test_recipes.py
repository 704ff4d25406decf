"""The paper's recipes: each named step as bilinear stages (pyramid_cli.plan.recipes)."""

import pytest

from pyramid_cli.core.expr import steps
from pyramid_cli.core.parse import parse
from pyramid_cli.plan import recipes


@pytest.mark.parametrize("text", ["box4 *v g", "quadratic *v g", "gauss5", "doosabin", "cubic *^ g", "box *v^2 g"])
def test_recipes_compute_the_step_they_stand_for(text):
    ((op, f, stride),) = steps(parse(text))
    stages = recipes.recipe(op, f, stride)
    assert stages and recipes.recipe_kernel_matches(stages, op, f, stride)
