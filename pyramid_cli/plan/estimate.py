"""What a plan costs by the calibrated cost model (:mod:`pyramid_cli.plan.cost`)."""

from __future__ import annotations

from pyramid_cli.plan import cost
from pyramid_cli.plan.model import Image, Pass, Plan, PointwisePass, ResamplePass


def pass_measures(images: list[Image],
                  ps: Pass | ResamplePass | PointwisePass) -> tuple[int, tuple[int, int], float, float, int]:
    """What the cost model weighs for one pass: (texture reads in its shader, the target's stored
    size, bilinear and single-texel fetches each fragment executes, stored pixels of the sources read)."""
    if isinstance(ps, ResamplePass):  # a table row of single-texel reads per fragment
        src = images[ps.source].stored
        return ps.width, images[ps.target].stored, 0.0, float(ps.width), src[0] * src[1]
    if isinstance(ps, PointwisePass):  # one single-texel read per operand
        read = sum(images[s].stored[0] * images[s].stored[1] for s in ps.sources())
        return len(ps.srcs), images[ps.target].stored, 0.0, float(len(ps.srcs)), read
    in_shader = sum(len(taps) for taps in ps.phases.values())
    linear, nearest = cost.executed_fetches([[(t.source, t.linear) for t in taps] for _, taps in
                                             sorted(ps.phases.items())])
    read = sum(images[s].stored[0] * images[s].stored[1] for s in ps.sources())
    return in_shader, images[ps.target].stored, linear, nearest, read


def pass_seconds(images: list[Image], ps: Pass | ResamplePass | PointwisePass,
                 model: cost.CostModel | None = None) -> float:
    """The cost model's seconds for one pass: its stored target, executed fetches and sources read."""
    return (model or cost.model()).pass_seconds(*pass_measures(images, ps))


def estimate_seconds(p: Plan, model: cost.CostModel | None = None) -> float:
    """The cost model's seconds for a whole plan (passes only: no upload, read-back or compile)."""
    return sum(pass_seconds(p.images, ps, model) for ps in p.passes)
