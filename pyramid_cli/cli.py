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


@main.command()
@click.argument("expression", type=EXPR)
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.argument("output_path", metavar="OUTPUT", type=click.Path(dir_okay=False))
@click.option("--backend", type=click.Choice(["auto", "gl", "cpu"]), default="auto", show_default=True,
              help="gl: OpenGL through headless EGL; cpu: the numpy reference; auto: gl, else cpu.")
@click.option("--border", type=click.Choice(["clamp", "mirror", "wrap", "zero"]), default="clamp",
              show_default=True, help="How pixels outside the image are read.")
@click.option("--type", "pixel_type", type=click.Choice(["uint8", "uint16", "half", "float"]),
              help="Output pixel type (default: the input's).")
@click.option("--colorspace", type=click.Choice(["auto", "linear", "srgb"]), default="auto", show_default=True,
              help="Encoding of integer inputs; filtering is always in linear light.")
@click.option("--alpha", type=click.Choice(["auto", "straight", "premultiplied", "none"]), default="auto",
              show_default=True, help="How the input stores alpha.")
@click.option("--nan", "nan_policy", type=click.Choice(["keep", "zero", "fail"]), default="keep",
              show_default=True, help="What to do with NaN/Inf pixels in float input.")
@click.option("--dither", is_flag=True, help="Dither 8-bit output.")
@click.option("--force", is_flag=True, help="Allow OUTPUT to overwrite INPUT.")
@click.option("-v", "--verbose", is_flag=True, help="Say which colour and alpha rules are in force.")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing but errors.")
def apply(expression, input_path: str, output_path: str, backend: str, border: str, pixel_type, colorspace,
          alpha, nan_policy, dither, force, verbose, quiet) -> None:
    """Apply EXPRESSION to INPUT and write OUTPUT (format from its extension).

    \b
    Example:
      pyramid apply 'box4 *v g' render.exr render_half.exr
      pyramid apply --backend cpu 'h_Doo-Sabin ⊗↑ g' small.png big.png
    """
    from . import io
    from .run import execute

    image = io.read_image(input_path, colorspace=colorspace, alpha=alpha, nan=nan_policy)
    if verbose:
        click.echo(io.describe_rules(image.spec), err=True)
    pixels, used = execute(expression, image.pixels, backend=backend, border=border)
    image.pixels = pixels
    io.write_image(output_path, image, pixel_type=pixel_type, dither=dither, force=force, inputs=(input_path,))
    if not quiet:
        h, w = pixels.shape[:2]
        click.echo(f"wrote {output_path} ({w}×{h}, {used})", err=False)


def run() -> None:  # console-script entry point
    main(prog_name="pyramid")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(run())
