"""The ``pyramid plan`` report: text and JSON."""

from __future__ import annotations

from pyramid_cli.plan import cost
from pyramid_cli.plan.estimate import estimate_seconds, pass_seconds
from pyramid_cli.plan.model import Plan, PointwisePass, ResamplePass, Tap


def _tap_json(t: Tap) -> dict:
    return {"pos": [float(-t.offset[1]), float(-t.offset[0])], "weight": float(t.weight),
            "exact": str(t.weight), "sampler": t.sampler, "source": t.source}


def to_json(p: Plan) -> dict:
    """The ``pyramid plan --json`` object. ``pos`` is [x, y] in source texels relative to the
    source pixel ``R = S·⌈r/P⌉`` the output fragment maps to; sizes are [width, height].
    ``estimate_s`` is the calibrated cost model's time (per pass and in all; passes only, no
    upload, read-back or compile), ``cost_model`` where it was measured."""
    model = cost.model()
    passes = []
    for ps in p.passes:
        img = p.images[ps.target]
        if isinstance(ps, ResamplePass):
            passes.append(_resample_json(p, ps, model))
            continue
        if isinstance(ps, PointwisePass):
            passes.append({"label": ps.label, "size": [img.size[1], img.size[0]], "pointwise": ps.op,
                           "sources": list(ps.srcs), "param": str(ps.param), "fetches": ps.fetches,
                           "estimate_s": pass_seconds(p.images, ps, model)})
            continue
        entry = {"label": ps.label, "size": [img.size[1], img.size[0]], "guard": list(img.guard),
                 "period": [ps.period[1], ps.period[0]], "stride": [ps.stride[1], ps.stride[0]],
                 "fetches": ps.fetches, "estimate_s": pass_seconds(p.images, ps, model)}
        if ps.why:
            entry["why"] = ps.why
        if len(ps.phases) == 1:
            entry["taps"] = [_tap_json(t) for t in next(iter(ps.phases.values()))]
        else:
            entry["phases"] = [{"phase": list(ph), "taps": [_tap_json(t) for t in taps]}
                               for ph, taps in sorted(ps.phases.items(), reverse=True)]
        passes.append(entry)
    return {"expression": p.expression, "input": [p.images[0].size[1], p.images[0].size[0]],
            "output": [p.output.size[1], p.output.size[0]], "passes": passes, "fetches": p.fetches,
            "fetches_per_output_pixel": p.fetches_per_output_pixel, "paper_fetches": p.paper_fetches,
            "estimate_s": estimate_seconds(p, model), "cost_model": model.name}


def _resample_json(p: Plan, ps: ResamplePass, model) -> dict:
    """A :class:`ResamplePass` in ``pyramid plan --json``: its axis, sizes and exact weight table
    (output j reads source index ``starts[j] + k``, 0-based along ``axis``, with ``weights[j][k]``)."""
    img = p.images[ps.target]
    return {"label": ps.label, "kind": "resample", "size": [img.size[1], img.size[0]], "guard": [0, 0, 0, 0],
            "axis": ["rows", "columns"][ps.axis], "from": p.images[ps.source].size[ps.axis],
            "to": img.size[ps.axis], "fetches": ps.fetches, "estimate_s": pass_seconds(p.images, ps, model),
            "starts": list(ps.starts), "weights": [[str(w) for w in row] for row in ps.weights]}


def _name(p: Plan, image: int) -> str:
    """How the report names an image: the input (``input k`` of several), else the pass that writes it."""
    if image in p.inputs:
        return "input" if len(p.inputs) == 1 else f"input {p.inputs.index(image) + 1}"
    return f"pass {next(n for n, ps in enumerate(p.passes, 1) if ps.target == image)}"


def _resample_lines(p: Plan, ps: ResamplePass, n: int) -> list[str]:
    img = p.images[ps.target]
    src = _name(p, ps.source)
    lines = [f"pass {n}  {ps.label}: {img.size[1]}×{img.size[0]}, reads {src}, "
             f"{ps.fetches:g} texel(s) per fragment from a table of {len(ps.starts)}×{ps.width} weights"]
    shown = sorted({0, len(ps.starts) // 2, len(ps.starts) - 1})
    for j in shown:
        ws = " ".join(str(w) for w in ps.weights[j])
        lines.append(f"  out {j:<5} ← src {ps.starts[j]}..{ps.starts[j] + ps.width - 1} × [{ws}]")
    return lines


def render(p: Plan) -> str:
    """The human-readable ``pyramid plan`` report."""
    h, w = p.images[0].size
    oh, ow = p.output.size
    lines = [f"plan   {p.expression}", f"input  {w}×{h} → output {ow}×{oh}, {len(p.passes)} pass(es)"]
    for n, ps in enumerate(p.passes, 1):
        if isinstance(ps, ResamplePass):
            lines += _resample_lines(p, ps, n)
            continue
        img = p.images[ps.target]
        t, l, b, r = img.guard
        guard = f" + guard t{t} l{l} b{b} r{r}" if any(img.guard) else ""
        srcs = ", ".join(_name(p, s) for s in sorted(ps.sources()))
        if isinstance(ps, PointwisePass):
            operands = ", ".join(_name(p, s) for s in ps.srcs)
            lines.append(f"pass {n}  {ps.label}: {img.size[1]}×{img.size[0]}, pointwise {ps.op}({operands})"
                         + (f", K = {ps.param}" if ps.op.startswith("pull") else ""))
            continue
        lines.append(f"pass {n}  {ps.label}: {img.size[1]}×{img.size[0]}{guard}, reads {srcs}, "
                     f"{ps.fetches:g} fetch(es) per fragment")
        if ps.why:
            lines.append(f"        chosen: {ps.why}")
        for ph, taps in sorted(ps.phases.items(), reverse=True):
            head = f"  phase {ph[0]},{ph[1]}" if len(ps.phases) > 1 else "  "
            for i, tap in enumerate(taps):
                src = "" if len(ps.sources()) == 1 else f" {_name(p, tap.source)}"
                lines.append(f"{head if i == 0 else ' ' * len(head)}  {tap.sampler:<7} at "
                             f"({float(-tap.offset[1]):+.2f}, {float(-tap.offset[0]):+.2f}) × {tap.weight}{src}")
    paper = "n/a" if p.paper_fetches is None else f"{p.paper_fetches:g}"
    lines.append(f"fetches {p.fetches:g} (paper: {paper}); per output pixel {p.fetches_per_output_pixel:.2f}")
    model = cost.model()
    lines.append(f"estimate {cost.format_seconds(estimate_seconds(p, model))} for the passes "
                 f"(no upload, read-back or compile; {model.name})")
    return "\n".join(lines)
