"""The ``pyramid`` command line: one click group, one function per command.

Command bodies only translate options; the work happens in the modules they
call. Heavy modules (numpy, OpenImageIO, moderngl) are imported inside the
commands so that ``pyramid --help`` stays fast.
"""

from __future__ import annotations

import json
import sys

import click

from .errors import EXIT_CODES, ExpressionError, PyramidError

EXIT_CODE_HELP = "\b\nExit codes:\n" + "\n".join(f"  {code}  {text}" for code, text in EXIT_CODES.values())


class ExpressionType(click.ParamType):
    """A filter expression; parse errors print with a caret under the column."""

    name = "EXPR"

    def convert(self, value, param, ctx):
        from .parse import parse

        if not isinstance(value, str):
            return value
        try:
            return parse(value)
        except ExpressionError as e:
            self.fail(str(e), param, ctx)


EXPR = ExpressionType()


class Group(click.Group):
    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except PyramidError as e:
            click.echo(f"pyramid: error: {e}", err=True)
            ctx.exit(e.exit_code)
        except KeyboardInterrupt:
            click.echo("pyramid: interrupted", err=True)
            ctx.exit(130)


@click.group(cls=Group, epilog=EXIT_CODE_HELP,
             context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="bilinear-pyramid", prog_name="pyramid")
def main() -> None:
    """Image pyramids from bilinear texture passes (Kraus & Strengert, GRAPP 2007).

    \b
    Expressions use the paper's notation or an ASCII spelling:
      ⊗  *  (x)     convolution           h_Bartlett ⊗ g      bartlett * g
      ⊗↓ *v (x)v    analysis (reduce)     h_quadratic ⊗↓ g    quadratic *v g
      ⊗↓ᵐ *v^m      one step of stride 2ᵐ h_box ⊗↓² g         box *v^2 g
      ⊗↑ *^ (x)^    synthesis (expand)    h_Doo-Sabin ⊗↑ g    doosabin *^ g
      (h)ᵐ (h)^m    m repeated steps      (h_box^{4×4})² ⊗↓ g (box4)^2 *v g
      box↘ box\\ box^se, box↖ box^nw; 1/4 [1 1; 1 1] is a written mask.
    Chains are right-associative: 'box\\ *v bartlett' is box↘ ⊗↓ (bartlett ⊗ g).

    \b
    Filters: box box↖ bartlett gauss5 gauss7 quasi (⊗); box box4 quadratic
    cubic (⊗↓); nearest midpoint doosabin cubic fourpoint (⊗↑).

    \b
    Example:
      pyramid explain 'h_box^↘ ⊗↓ (h_Bartlett ⊗ g)'
      pyramid apply 'quadratic *v g' in.exr half.exr
      pyramid blur --levels 5 in.exr soft.exr
    """


@main.command()
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
    from .explain import describe, plot_powers, render

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


@main.command("plan")
@click.argument("expression", type=EXPR)
@click.option("--size", required=True, callback=_size, metavar="WxH", help="Input image size, e.g. 1920x1080.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the report.")
def plan_command(expression, size, as_json: bool) -> None:
    """Show the render passes and bilinear taps that compute EXPRESSION.

    \b
    Example:
      pyramid plan 'quadratic *v g' --size 1920x1080
      pyramid plan --json 'h_Doo-Sabin ⊗↑ g' --size 64x64

    \b
    Tap positions are [x, y] in source texels relative to the source pixel the
    output fragment maps to (R = S·⌈r/P⌉); all are multiples of ¼ texel.
    """
    from .plan import check, plan, render, to_json

    w, h = size
    p = plan(expression, (h, w))
    check(p)
    click.echo(json.dumps(to_json(p), ensure_ascii=False) if as_json else render(p))


def io_options(f):
    """Options every command that reads and writes images shares."""
    options = [
        click.option("--backend", type=click.Choice(["auto", "gl", "cpu"]), default="auto", show_default=True,
                     help="gl: OpenGL through headless EGL; cpu: numpy; auto: gl, else cpu with a warning."),
        click.option("--type", "pixel_type", type=click.Choice(["uint8", "uint16", "half", "float"]),
                     help="Output pixel type (default: the input's, as the output format allows)."),
        click.option("--colorspace", type=click.Choice(["auto", "linear", "srgb"]), default="auto",
                     show_default=True, help="Encoding of integer inputs; filtering is always in linear light."),
        click.option("--alpha", type=click.Choice(["auto", "straight", "premultiplied", "none"]), default="auto",
                     show_default=True, help="How the input stores alpha (RGBA is filtered premultiplied)."),
        click.option("--nan", "nan_policy", type=click.Choice(["keep", "zero", "fail"]), default="keep",
                     show_default=True, help="What to do with NaN/Inf pixels in float input."),
        click.option("--dither", is_flag=True, help="Dither 8-bit output."),
        click.option("--force", is_flag=True, help="Allow OUTPUT to overwrite INPUT."),
        click.option("-v", "--verbose", is_flag=True, help="Say which backend, colour and alpha rules are in force."),
        click.option("-q", "--quiet", is_flag=True, help="Print nothing but errors."),
    ]
    for option in reversed(options):
        f = option(f)
    return f


def _process(input_path: str, output_path: str, work, opts: dict) -> None:
    """Read, transform with ``work(runner, pixels)``, write atomically; report unless --quiet."""
    from . import io
    from .run import Runner

    image = io.read_image(input_path, colorspace=opts["colorspace"], alpha=opts["alpha"], nan=opts["nan_policy"])
    runner = Runner(opts["backend"])
    try:
        if opts["verbose"]:
            click.echo(f"pyramid: {io.describe_rules(image.spec)}; backend {runner.name}", err=True)
        image.pixels = work(runner, image.pixels)
    finally:
        runner.close()
    io.write_image(output_path, image, pixel_type=opts["pixel_type"], dither=opts["dither"], force=opts["force"],
                   inputs=(input_path,))
    if not opts["quiet"]:
        h, w = image.pixels.shape[:2]
        click.echo(f"wrote {output_path} ({w}×{h}, {runner.name})")


@main.command()
@click.argument("expression", type=EXPR)
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.argument("output_path", metavar="OUTPUT", type=click.Path(dir_okay=False))
@click.option("--border", type=click.Choice(["clamp", "mirror", "wrap", "zero"]), default="clamp",
              show_default=True, help="How pixels outside the image are read (non-clamp borders run on the CPU).")
@io_options
def apply(expression, input_path: str, output_path: str, border: str, **opts) -> None:
    """Apply EXPRESSION to INPUT and write OUTPUT (format from its extension).

    \b
    Example:
      pyramid apply 'box4 *v g' render.exr render_half.exr
      pyramid apply --backend cpu 'h_Doo-Sabin ⊗↑ g' small.png big.png
    """
    _process(input_path, output_path, lambda runner, px: runner.run_expr(expression, px, border), opts)


@main.command()
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.argument("output_path", metavar="OUTPUT", type=click.Path(dir_okay=False))
@click.option("--levels", "-m", type=click.IntRange(1, 16), default=4, show_default=True,
              help="Analysis steps down (and synthesis steps back up).")
@click.option("--analysis", default="box4", show_default=True,
              help="box, box4, quadratic, cubic, or a ⊗↓ expression.")
@click.option("--synthesis", default="doosabin", show_default=True,
              help="nearest, midpoint, doosabin, cubic, fourpoint, or a ⊗↑ expression.")
@click.option("--quasi", is_flag=True, help="Apply the §5.5 quasi-interpolation prefilter at the coarsest level.")
@click.option("--allow-mixed-lattice", is_flag=True, help="Do not warn when analysis and synthesis lattices differ.")
@io_options
def blur(input_path: str, output_path: str, levels: int, analysis: str, synthesis: str, quasi: bool,
         allow_mixed_lattice: bool, **opts) -> None:
    """Pyramidal blur: LEVELS analysis steps, then synthesis back to the input size.

    Defaults are the paper's Figure 3b: 4×4 box analysis, Doo-Sabin synthesis.

    \b
    Example:
      pyramid blur --levels 5 render.exr soft.exr
      pyramid blur --analysis box --synthesis doosabin photo.png blocky.png
    """
    from .pyramids import blur_plan, lattice_mismatch

    warning = None if allow_mixed_lattice else lattice_mismatch(analysis, synthesis)
    if warning and not opts["quiet"]:
        click.echo(f"pyramid: warning: {warning}", err=True)

    def work(runner, px):
        return runner.run_plan(blur_plan(px.shape[:2], levels, analysis, synthesis, quasi), px)

    _process(input_path, output_path, work, opts)


def _register() -> None:
    from .diff_cli import diff

    main.add_command(diff)


_register()


def run() -> None:  # console-script entry point
    main(prog_name="pyramid")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(run())
