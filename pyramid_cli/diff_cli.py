"""``pyramid diff``: compare two images with idiff's thresholds and exit codes.

The command is a standalone :class:`click.Command`; the CLI registers it with
``main.add_command(diff)``. It does not rely on the group's error handling:
every outcome leaves through an explicit exit code, idiff's (0 match,
1 warning, 2 failure, 3 size/channel mismatch, 4 file error), not the rest of
the tool's table.
"""

from __future__ import annotations

import json
import math

import click

from .idiff import DEFAULT_FAIL, DEFAULT_WARN, EXIT_CODES

_NONNEG = click.FloatRange(min=0.0)

DIFF_EPILOG = """\b
Exit codes (those of OpenImageIO's idiff, not the rest of pyramid's table):
  0  match: no more pixels over the thresholds than allowed
  1  warning: over the warn thresholds, within the fail thresholds
  2  failure: over the fail thresholds (a bad command line also exits 2)
  3  the images differ in size or channel count
  4  file error: A or B cannot be read (missing, unreadable, truncated, not an
     image), or --out cannot be written; one line on stderr names the file
"""


def _fmt(v: float | None) -> str:
    if v is None:
        return "-"
    if math.isinf(v):
        return "inf"
    return f"{v:.6g}"


def _report(r, path_a: str, path_b: str) -> str:
    """The human-readable report: one aligned line per statistic."""
    lines = [f'Comparing "{path_a}" and "{path_b}" ({r.width}x{r.height}, {r.channels} channel'
             f'{"s" if r.channels != 1 else ""})']

    def row(label: str, text: str) -> None:
        lines.append(f"  {label:<12} {text}")

    if r.max_x is None:
        row("max error", "0")
    else:
        values = (", ".join(_fmt(v) for v in r.a_values) + " vs " + ", ".join(_fmt(v) for v in r.b_values))
        row("max error", f"{_fmt(r.max_error)} @ (x={r.max_x}, y={r.max_y}, {r.max_channel_name})"
                         f"  values {values}")
    row("mean error", _fmt(r.mean_error))
    row("RMS error", _fmt(r.rms_error))
    row("PSNR", "inf dB (identical)" if math.isinf(r.psnr) else f"{r.psnr:.2f} dB")
    t = r.thresholds
    row("over warn", f"{r.n_warn} pixels ({r.percent(r.n_warn):.3g}%) over {_fmt(t['warn'])}"
                     + (f", relative {_fmt(t['warnrelative'])}" if t["warnrelative"] else ""))
    row("over fail", f"{r.n_fail} pixels ({r.percent(r.n_fail):.3g}%) over {_fmt(t['fail'])}"
                     + (f", relative {_fmt(t['failrelative'])}" if t["failrelative"] else ""))
    if math.isfinite(t["hardfail"]):
        row("hardfail", f"{r.n_hardfail} pixels over {_fmt(t['hardfail'])}")
    if math.isfinite(t["hardwarn"]):
        row("hardwarn", f"{r.n_hardwarn} pixels over {_fmt(t['hardwarn'])}")
    if r.n_nonfinite:
        row("NaN/Inf", f"{r.n_nonfinite} pixels where NaN/Inf meets a different value")
    row("verdict", r.verdict.upper())
    return "\n".join(lines)


def _finish(ctx: click.Context, code: int, message: str, as_json: bool) -> None:
    """Leave with ``code`` after a one-line error (and a JSON object under --json)."""
    click.echo(f"pyramid diff: error: {message}", err=True)
    if as_json:
        click.echo(json.dumps({"verdict": None, "exit_code": code, "error": message}))
    ctx.exit(code)


@click.command("diff", epilog=DIFF_EPILOG,
               context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.argument("path_a", metavar="A", type=click.Path())
@click.argument("path_b", metavar="B", type=click.Path())
@click.option("--fail", type=_NONNEG, default=DEFAULT_FAIL, show_default=True,
              help="A pixel fails if any channel's |A-B| is > this (linear light).")
@click.option("--warn", type=_NONNEG, default=DEFAULT_WARN, show_default=True,
              help="A pixel warns if any channel's |A-B| is > this.")
@click.option("--failpercent", type=click.FloatRange(0.0, 100.0), default=0.0, show_default=True,
              help="Failure only if more than this % of pixels fail.")
@click.option("--warnpercent", type=click.FloatRange(0.0, 100.0), default=0.0, show_default=True,
              help="Warning only if more than this % of pixels warn.")
@click.option("--hardfail", type=_NONNEG, default=math.inf, show_default="inf",
              help="Failure if any pixel's |A-B| is > this, whatever --failpercent.")
@click.option("--hardwarn", type=_NONNEG, default=math.inf, show_default="inf",
              help="Warning if any pixel's |A-B| is > this, whatever --warnpercent.")
@click.option("--failrelative", type=_NONNEG, default=0.0, show_default=True, metavar="R",
              help="Also require |A-B|/mean(|A|,|B|) > R for a pixel to fail (idiff's -failrelative; 0: off).")
@click.option("--warnrelative", type=_NONNEG, default=0.0, show_default=True, metavar="R",
              help="Also require |A-B|/mean(|A|,|B|) > R for a pixel to warn (0: off).")
@click.option("--allowfailures", type=click.IntRange(min=0), default=0, show_default=True, metavar="N",
              help="Up to N pixels may differ by any amount and the images still match.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object (all statistics, verdict, exit_code); infinities are null.")
@click.option("-o", "--out", "out_path", type=click.Path(), default=None,
              help="Write |A-B| x --scale (or the --heatmap) to this image, atomically.")
@click.option("--heatmap", is_flag=True,
              help="With --out: write a false-colour RGB picture of each pixel's largest error, log scale "
                   "1e-8 (dark) to 1 (yellow); black = identical, white = NaN/Inf mismatch.")
@click.option("--scale", type=float, default=1.0, show_default=True, help="Multiply the --out difference by this.")
@click.option("--colorspace", type=click.Choice(["auto", "linear", "srgb"]), default="auto", show_default=True,
              help="Encoding of integer inputs (both files are read alike, into linear light).")
@click.option("--alpha", type=click.Choice(["auto", "straight", "premultiplied", "none"]), default="auto",
              show_default=True, help="How the inputs store alpha (both are compared premultiplied).")
@click.option("-q", "--quiet", is_flag=True,
              help="No report; one line on stderr for a warning or failure (--json still prints).")
@click.pass_context
def diff(ctx: click.Context, path_a: str, path_b: str, fail: float, warn: float, failpercent: float,
         warnpercent: float, hardfail: float, hardwarn: float, failrelative: float, warnrelative: float,
         allowfailures: int, as_json: bool, out_path: str | None, heatmap: bool, scale: float,
         colorspace: str, alpha: str, quiet: bool) -> None:
    """Compare images A and B as read (linear float) with idiff's rules.

    A pixel fails when any channel differs by more than --fail (and, with
    --failrelative R, by more than R relative to the mean of the two |values|);
    an error equal to a threshold does not count. NaN against NaN matches; NaN
    or Inf against anything else is an infinite error: a failure unless
    --allowfailures covers it. Reports the largest error and
    where, mean and RMS error, PSNR (peak 1.0) and the pixels over warn / fail.

    \b
    Defaults: --fail 1e-3 passes half-precision rounding (at most 2^-11 |v|,
    < 1e-3 for |v| < 4) and catches real bugs (errors of 1e-2 and more);
    --warn 1e-5 is silent for float32 against the float64 reference (~1e-6)
    and flags anything coarser. 8-bit outputs: use --fail 5e-3. HDR values
    of 4 and over against half: add --failrelative 1e-3.

    \b
    Example:
      pyramid diff gpu.exr reference.exr
      pyramid diff --fail 0.004 --failpercent 1 --hardfail 0.25 a.png b.png
      pyramid diff --json --out diff.png --heatmap half.exr float.exr
    """
    from . import io
    from .diff import ShapeMismatchError, compare, difference_image
    from .diff import heatmap as make_heatmap
    from .errors import PyramidError

    if heatmap and not out_path:
        raise click.UsageError("--heatmap needs --out FILE", ctx=ctx)

    images = []
    for path in (path_a, path_b):
        try:
            images.append(io.read_image(path, colorspace=colorspace, alpha=alpha, nan="keep"))
        except PyramidError as e:  # InputError, or DataError for an image too large to hold
            _finish(ctx, EXIT_CODES["file"], e.message, as_json)
    img_a, img_b = images

    try:
        result = compare(img_a.pixels, img_b.pixels, fail=fail, warn=warn, failpercent=failpercent,
                         warnpercent=warnpercent, hardfail=hardfail, hardwarn=hardwarn,
                         failrelative=failrelative, warnrelative=warnrelative,
                         allowfailures=allowfailures, channel_names=img_a.spec.channel_names)
    except ShapeMismatchError as e:
        _finish(ctx, EXIT_CODES["size"], f"{path_a} and {path_b}: {e}", as_json)

    if out_path:
        if heatmap:
            rgb = make_heatmap(img_a.pixels, img_b.pixels)
            # Colour-map values are display (sRGB) colours: hand them over in
            # linear light so that the sRGB encoding on write stores them as is.
            pixels = io.srgb_to_linear(rgb).astype("float32")
            spec = io.ImageInfo(path=out_path, format="", pixel_type="uint8", channel_names=["R", "G", "B"],
                                alpha_channel=-1, colorspace="srgb", alpha_mode="none")
        else:
            pixels = difference_image(img_a.pixels, img_b.pixels, scale)
            spec = io.ImageInfo(path=out_path, format="", pixel_type="float",
                                channel_names=list(img_a.spec.channel_names), alpha_channel=-1,
                                colorspace="linear", alpha_mode="none")
        try:
            io.write_image(out_path, io.Image(pixels=pixels, spec=spec), inputs=(path_a, path_b))
        except PyramidError as e:
            _finish(ctx, EXIT_CODES["file"], e.message, as_json)

    if as_json:
        click.echo(json.dumps(result.to_dict(), allow_nan=False))
    elif not quiet:
        click.echo(_report(result, path_a, path_b))
    if quiet and result.verdict != "match":
        where = (f", max error {_fmt(result.max_error)} @ (x={result.max_x}, y={result.max_y}, "
                 f"{result.max_channel_name})") if result.max_x is not None else ""
        click.echo(f"pyramid diff: {result.verdict.upper()}: {result.n_fail} pixels over fail, "
                   f"{result.n_warn} over warn{where}", err=True)
    ctx.exit(result.exit_code)
