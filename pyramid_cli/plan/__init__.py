"""From expressions to render passes of bilinear texture taps (paper §3–§5, docs/design.md §5).

Read in processing order: :mod:`.model` (the Plan every executor runs),
:mod:`.recipes` (the paper's decompositions and their check against the masks),
:mod:`.taps` (weights as bilinear fetches), :mod:`.bounds` (guard bands),
:mod:`.estimate` (the cost model's view), :mod:`.lower` (steps to passes),
:mod:`.report` (what ``pyramid plan`` prints) and :mod:`.cache` (plans kept in the process and on disk,
which every job's :meth:`~pyramid_cli.jobs.work.Work.plan` reads first).
"""

from __future__ import annotations

from pyramid_cli.plan.estimate import estimate_seconds, pass_measures, pass_seconds
from pyramid_cli.plan.lower import Builder, choose_recipe, plan, plan_steps, recipe_seconds
from pyramid_cli.plan.model import POINTWISE_OPS, Half, Image, Pass, Plan, PointwisePass, ResamplePass, Tap, check
from pyramid_cli.plan.recipes import (
    Stage,
    chain,
    checked_recipe,
    conv,
    direct_recipe,
    down,
    recipe,
    recipe_kernel_matches,
    up,
)
from pyramid_cli.plan.report import render, to_json
from pyramid_cli.plan.taps import taps_for

__all__ = ["PointwisePass", "POINTWISE_OPS",
           "Plan", "Pass", "Tap", "Image", "Half", "Builder", "plan", "plan_steps", "check", "estimate_seconds",
           "pass_seconds", "pass_measures", "choose_recipe", "recipe_seconds", "Stage", "recipe", "direct_recipe",
           "checked_recipe", "recipe_kernel_matches", "conv", "down", "up", "chain", "taps_for", "render", "to_json",
           "ResamplePass"]
