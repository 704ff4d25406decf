"""Commands that read no image: ``explain`` (an expression's kernel, lattice and continuity) and ``plan``
(its render passes and taps, a MIP map's levels, a working-set budget)."""

from __future__ import annotations

import json

import click

from pyramid_cli.cli.group import collector_on
from pyramid_cli.cli.params import EXPR, choice
from pyramid_cli.core.errors import UsageError
from pyramid_cli.core.options import BORDERS, STRATEGIES


@click.command()
@click.argument("expression", type=EXPR)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the report.")
@click.option("--plot", type=click.Path(dir_okay=False), help="Draw the 1-D powers of an analysis filter "
              "(the paper's Figure 2) to this PNG.")
def explain(expression, as_json: bool, plot: str | None) -> None:
    """Show the exact equivalent kernel of EXPRESSION, its continuity and lattice.

    \b
    Example:
      pyramid explain 'box\\ *v bartlett'
      pyramid explain --json 'h_Doo-Sabin ⊗↑ g'
      pyramid explain --plot box4.png 'box4 *v g'

    \b
    JSON: output pixel (r, c) of phase [r mod P, c mod P] receives
    weights[i][j]/denominator × input pixel (R − (i − i0), C − (j − j0)),
    R = stride·⌈r/period⌉ (r for ⊗, 2ᵐr for ⊗↓ᵐ, ⌊(r+1)/2⌋ for ⊗↑), anchor = [i0, j0].
    """
    from pyramid_cli.run.explain import check_plot_path, describe, plot_powers, render

    collector_on()

    if plot:
        check_plot_path(plot)  # refused before any work
    info = describe(expression)
    if plot:
        plot_powers(expression, plot)
    click.echo(json.dumps(info, ensure_ascii=False) if as_json else render(info))



def _size(ctx, param, value):
    import re

    if value is None:
        return None
    m = re.fullmatch(r"\s*(\d+)\s*[x×X]\s*(\d+)\s*", value)
    if not m or not int(m.group(1)) or not int(m.group(2)):
        raise click.BadParameter(f"expected WIDTHxHEIGHT such as 1920x1080, not {value!r}")
    return int(m.group(1)), int(m.group(2))



@click.command("plan")
@click.argument("expression", type=EXPR)
@click.option("--size", required=True, callback=_size, metavar="WxH", help="Input image size, e.g. 1920x1080.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the report.")
@click.option("--strategy", type=choice(STRATEGIES), default="cost", show_default=True,
              help="cost: per filter, the paper's decomposition or one fused pass, whichever is faster by the "
                   "cost model calibrated by bench/calibrate.py (pyramid_cli/plan/cost_model.json); paper: always "
                   "the paper's; fused: always one pass per filter (what the CPU executor runs).")
@click.option("--mipmap", "mip_round", type=click.Choice(["down", "up"]), default=None,
              help="Plan `pyramid mipmap --round ROUND` with EXPRESSION (a one-step ⊗↓) as its --analysis: "
                   "every level's passes, the paper's where a level halves exactly, resampling tables elsewhere.")
@click.option("--border", type=choice(BORDERS), default="clamp", show_default=True,
              help="How written operators read past their input's edges (mipmap: the --wrap mode).")
@click.option("--memory", metavar="SIZE", default=None,
              help="Also say how a file of this size runs in this working-set budget (e.g. 512M): whole, or "
                   "streamed in bands of how many rows (RGBA float; see pyramid apply --memory).")
@click.option("--backend", "memory_backend", type=click.Choice(["cpu", "gl"]), default=None,
              help="Whose memory --memory estimates (default cpu; gl: GL on a software renderer such as Mesa's "
                   "llvmpipe, whose power-of-two textures are host memory and pad bands, not pictures).")
def plan_command(expression, size, as_json: bool, strategy: str, mip_round: str | None, border: str,
                 memory: str | None, memory_backend: str | None) -> None:
    """Show the render passes and bilinear taps that compute EXPRESSION.

    \b
    Example:
      pyramid plan 'quadratic *v g' --size 1920x1080
      pyramid plan --json 'h_Doo-Sabin ⊗↑ g' --size 64x64
      pyramid plan --mipmap down 'quadratic *v g' --size 1001x777
      pyramid plan 'gauss7' --size 32768x32768 --memory 1G
      pyramid plan 'gauss7' --size 5000x3000 --memory 1G --backend gl

    \b
    Tap positions are [x, y] in source texels relative to the source pixel the
    output fragment maps to (R = S·⌈r/P⌉); all are multiples of ¼ texel.
    """
    from pyramid_cli.plan import check, plan, render, to_json

    collector_on()

    w, h = size
    if mip_round is not None:
        from pyramid_cli.core.expr import Apply, Input, Named, Op, to_text
        from pyramid_cli.jobs.texture import TextureLevels

        named = (isinstance(expression, Apply) and expression.op is Op.DOWN and isinstance(expression.filter, Named)
                 and isinstance(expression.arg, Input) and expression.stride == 1 and expression.power == 1)
        analysis = expression.filter.key if named else to_text(expression)
        p = TextureLevels(analysis=analysis, border=border, rounding=mip_round).plan(((h, w),), strategy)
        if p is None:
            raise UsageError(f"a {w}x{h} image is its own MIP map: there are no levels to plan")
    else:
        p = plan(expression, (h, w), strategy, border)
    check(p)
    choice = None
    if memory_backend is not None and memory is None:
        raise UsageError("--backend says whose memory --memory estimates: give --memory too")
    if memory is not None:
        from pyramid_cli.run.stream import choose, choose_mip, parse_size

        texture = None
        if memory_backend == "gl":
            from pyramid_cli.exec.gl import GLExecutor

            texture = GLExecutor.texture_bytes
        if mip_round is not None:  # level 0 kept in memory, the input read once, where it fits (RGBA float)
            choice = choose_mip(p, 4, parse_size(memory), level0=h * w * 4 * 4, texture=texture)
        else:
            choice = choose(p, 4, parse_size(memory), texture=texture)
    if as_json:
        doc = to_json(p)
        if choice is not None:
            doc["memory"] = choice.to_json()
        click.echo(json.dumps(doc, ensure_ascii=False))
        return
    click.echo(render(p))
    if choice is not None:
        click.echo(f"memory: {choice.describe()}")


__all__ = ['explain', 'plan_command']
