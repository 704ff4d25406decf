"""``pyramid diff``: a drop-in for OpenImageIO's ``idiff``, for one pair or many.

The command is a standalone :class:`click.Command`; the CLI registers it with
``main.add_command(diff)``. It does not rely on the group's error handling:
every outcome leaves through an explicit exit code, idiff's (0 match,
1 warning, 2 failure, 3 size/channel mismatch, 4 file error), not the rest of
the tool's table. idiff's single-dash spellings (``-fail 0.004``, ``-od``,
``-abs``...) are rewritten to this command's options before click parses them
(:func:`idiff_argv`).
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Sequence
from typing import Any

import click

from pyramid_cli.cli.group import collector_on
from pyramid_cli.core.options import ALPHA_MODES
from pyramid_cli.diff.idiff import DEFAULT_FAIL, DEFAULT_WARN, EXIT_CODES, format_value

_NONNEG = click.FloatRange(min=0.0)

# idiff's single-dash long options -> ours. -a, -o, -p, -q, -v are ordinary short options.
IDIFF_SPELLINGS: dict[str, str] = {
    "-fail": "--fail", "-failpercent": "--failpercent", "-hardfail": "--hardfail",
    "-failrelative": "--failrelative", "-warn": "--warn", "-warnpercent": "--warnpercent",
    "-hardwarn": "--hardwarn", "-warnrelative": "--warnrelative", "-allowfailures": "--allowfailures",
    "-od": "--od", "-abs": "--abs", "-scale": "--scale",
}
_TAKES_VALUE = frozenset({
    "--fail", "--failpercent", "--hardfail", "--failrelative", "--warn", "--warnpercent", "--hardwarn",
    "--warnrelative", "--allowfailures", "--scale", "-o", "--out", "--colorspace", "--alpha", "--junit",
    "--html", "--metric", "--flip-fail", "--tocolorspace", "--colorconfig",
})


def idiff_argv(args: Sequence[str]) -> list[str]:
    """Rewrite idiff's single-dash long options (``-fail 0.004``) to ours (``--fail 0.004``).

    Only tokens in option position are rewritten: not the value that follows an
    option taking one, and nothing after ``--``.

    Parameters
    ----------
    args : sequence of str
        The command's arguments (after ``diff``).

    Returns
    -------
    list of str
    """
    out: list[str] = []
    expect_value = False
    for i, tok in enumerate(args):
        if expect_value:
            out.append(tok)
            expect_value = False
            continue
        if tok == "--":
            out.extend(args[i:])
            break
        tok = IDIFF_SPELLINGS.get(tok, tok)
        out.append(tok)
        expect_value = tok in _TAKES_VALUE
    return out


class IdiffCommand(click.Command):
    """A click command that also takes idiff's single-dash spellings."""

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        return super().parse_args(ctx, idiff_argv(args))


DIFF_EPILOG = """\b
Exit codes (OpenImageIO idiff's, not the rest of pyramid's table; folders and
globs: the largest over all pairs):
  0  match: no pixel over --fail (beyond --allowfailures), or failing pixels
     within --failpercent and nothing over the warn tests
  1  warning: failing pixels within --failpercent, but over --warnpercent or
     --hardwarn
  2  failure: over the fail thresholds; NaN/Inf against a number; a missing
     or extra golden (folders/globs); a bad command line; -p
  3  the images differ in size, channel count or MIP level count
  4  file error: A or B cannot be read (missing, truncated, not an image), or
     an output (--out, --junit, --html, --update) cannot be written

\b
idiff spellings accepted: -fail -failpercent -hardfail -failrelative -warn
-warnpercent -hardwarn -warnrelative -allowfailures -a -o -od -abs -scale -v -q
"""


def _report(r: Any, path_a: str, path_b: str, title: str | None = None) -> str:
    """The human-readable report of one level: one aligned line per statistic."""
    head = title or f'Comparing "{path_a}" and "{path_b}"'
    lines = [f'{head} ({r.width}x{r.height}, {r.channels} channel{"s" if r.channels != 1 else ""})']

    def row(label: str, text: str) -> None:
        lines.append(f"  {label:<12} {text}")

    if r.max_x is None:
        row("max error", "0")
    else:
        values = (", ".join(format_value(v) for v in r.a_values) + " vs "
                  + ", ".join(format_value(v) for v in r.b_values))
        row("max error", f"{format_value(r.max_error)} @ (x={r.max_x}, y={r.max_y}, {r.max_channel_name})"
                         f"  values {values}")
    row("mean error", format_value(r.mean_error))
    row("RMS error", format_value(r.rms_error))
    row("PSNR", "inf dB (identical)" if math.isinf(r.psnr) else f"{r.psnr:.2f} dB")
    t = r.thresholds
    row("over warn", f"{r.n_warn} pixels ({r.percent(r.n_warn):.3g}%) over {format_value(t['warn'])}"
                     + (f", relative {format_value(t['warnrelative'])}" if t["warnrelative"] else ""))
    row("over fail", f"{r.n_fail} pixels ({r.percent(r.n_fail):.3g}%) over {format_value(t['fail'])}"
                     + (f", relative {format_value(t['failrelative'])}" if t["failrelative"] else ""))
    if math.isfinite(t["hardfail"]):
        row("hardfail", f"{r.n_hardfail} pixels over {format_value(t['hardfail'])}")
    if math.isfinite(t["hardwarn"]):
        row("hardwarn", f"{r.n_hardwarn} pixels over {format_value(t['hardwarn'])}")
    if r.n_nonfinite:
        row("NaN/Inf", f"{r.n_nonfinite} pixels where NaN/Inf meets a different value")
    row("verdict", f"{r.verdict.upper()} (rule: {r.rule})")
    return "\n".join(lines)


_LABEL = {"match": "PASS", "warning": "WARN", "failure": "FAIL", "missing": "MISSING", "extra": "EXTRA",
          "size": "SIZE", "file": "ERROR"}


def _single_json(pr: Any) -> dict[str, Any]:
    """One pair under --json: the worst level's statistics at top level (as before), plus the pair."""
    worst = pr.worst
    d: dict[str, Any] = worst.to_dict() if worst is not None else {"verdict": None}
    d.update({"verdict": pr.status if pr.status in ("match", "warning", "failure") else d.get("verdict"),
              "status": pr.status, "exit_code": pr.exit_code, "rule": pr.rule, "path_a": pr.path_a,
              "path_b": pr.path_b})
    if pr.status in ("size", "file"):
        d["error"] = pr.message
    if len(pr.levels) > 1 or any(lv.flip is not None for lv in pr.levels):
        d["levels"] = pr.to_dict()["levels"]
    return d


def _summary(results: Sequence[Any]) -> dict[str, int]:
    counts = {k: 0 for k in ("match", "warning", "failure", "size", "file", "missing", "extra")}
    for r in results:
        counts[r.status] += 1
    return counts


@click.command("diff", cls=IdiffCommand, epilog=DIFF_EPILOG,
               context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.argument("path_a", metavar="A", type=click.Path())
@click.argument("path_b", metavar="B", type=click.Path())
@click.option("--fail", type=_NONNEG, default=DEFAULT_FAIL, show_default=True,
              help="A pixel fails if any channel's |A-B| is > this (stored values; idiff: -fail).")
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
              help="Also require |A-B|/mean(|A|,|B|) > R for a pixel to fail (0: off).")
@click.option("--warnrelative", type=_NONNEG, default=0.0, show_default=True, metavar="R",
              help="Also require |A-B|/mean(|A|,|B|) > R for a pixel to warn (0: off).")
@click.option("--allowfailures", type=click.IntRange(min=0), default=0, show_default=True, metavar="N",
              help="Up to N pixels may differ by any amount and the images still match.")
@click.option("-a", "--all", "all_levels", is_flag=True, help="Compare every subimage and MIP level (idiff -a).")
@click.option("--linear", is_flag=True,
              help="Compare decoded linear light (8/16-bit sRGB decoded, alpha premultiplied) instead of "
                   "the stored values.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object (statistics, verdict, exit_code, the deciding rule); "
                   "infinities are null.")
@click.option("-o", "--out", "out_path", type=click.Path(), default=None,
              help="Write the signed difference A-B (x --scale) to this image, atomically (idiff -o).")
@click.option("--abs", "absolute", is_flag=True, help="With --out: |A-B| instead of A-B (idiff -abs).")
@click.option("--od", "out_if_differ", is_flag=True,
              help="With --out: write it only if the images differ at all (idiff -od).")
@click.option("--scale", type=float, default=1.0, show_default=True, help="Multiply the --out difference by this.")
@click.option("--heatmap", is_flag=True,
              help="With --out: a false-colour RGB picture of each pixel's largest error, log scale "
                   "1e-8 (dark) to 1 (yellow); black = identical, white = NaN/Inf mismatch.")
@click.option("--colorspace", metavar="NAME", default="auto", show_default=True,
              help="With --linear: the inputs' colour space (any name of the colour config; auto reads "
                   "oiio:ColorSpace, then the config's file rules, then the type).")
@click.option("--tocolorspace", metavar="NAME", help="Compare both decoded and converted to this colour space "
              "(implies --linear): pyramid diff --tocolorspace srgb a.exr b.png.")
@click.option("--colorconfig", metavar="FILE", help="OpenColorIO config (default: $OCIO, else OpenImageIO's "
              "built-in one).")
@click.option("--alpha", type=click.Choice(ALPHA_MODES), default="auto",
              show_default=True, help="With --linear: how the inputs store alpha.")
@click.option("--metric", type=click.Choice(["idiff", "flip"]), default="idiff", show_default=True,
              help="flip: also NVIDIA's FLIP (pip install 'bilinear-pyramid[flip]'); failure when the mean "
                   "FLIP error is over --flip-fail.")
@click.option("--flip-fail", type=_NONNEG, default=0.05, show_default=True, help="Mean FLIP error threshold.")
@click.option("--update", is_flag=True,
              help="Copy A over each golden B that fails or is missing (byte for byte, atomically); "
                   "the exit code is then that of the comparison before the update.")
@click.option("--dry-run", is_flag=True, help="With --update: list what would be copied, copy nothing.")
@click.option("--junit", "junit_path", type=click.Path(), default=None,
              help="Write a JUnit XML report (one testcase per pair).")
@click.option("--html", "html_dir", type=click.Path(), default=None,
              help="Write a self-contained HTML report (index.html and PNGs) into this folder.")
@click.option("-p", "--perceptual", is_flag=True, hidden=True)
@click.option("-v", "--verbose", is_flag=True, help="Folders: a full report for every pair, passing ones too.")
@click.option("-q", "--quiet", is_flag=True,
              help="No report; one line on stderr per warning or failure (--json still prints).")
@click.pass_context
def diff(ctx: click.Context, path_a: str, path_b: str, fail: float, warn: float, failpercent: float,
         warnpercent: float, hardfail: float, hardwarn: float, failrelative: float, warnrelative: float,
         allowfailures: int, all_levels: bool, linear: bool, as_json: bool, out_path: str | None,
         absolute: bool, out_if_differ: bool, scale: float, heatmap: bool, colorspace: str,
         tocolorspace: str | None, colorconfig: str | None, alpha: str, metric: str, flip_fail: float,
         update: bool, dry_run: bool, junit_path: str | None,
         html_dir: str | None, perceptual: bool, verbose: bool, quiet: bool) -> None:
    """Compare output A with reference B the way OpenImageIO's idiff does.

    A and B are two image files; a file and a folder (B/name-of-A, as idiff);
    two folders (paired by relative path; B/name-*.ext are accepted
    alternatives); or two quoted glob patterns. Integer files are compared
    as stored, code values scaled to 0-1 (so idiff's thresholds mean what they
    meant: one 8-bit code is 0.0039); half and float files as stored.

    A pixel fails when any channel differs by more than --fail (and, with
    --failrelative R, by more than R relative to the mean of the two |values|);
    an error equal to a threshold does not count. Like idiff, images with no
    failing pixel pass (exit 0) whatever the warn thresholds say. Unlike idiff,
    NaN or Inf against a number fails, and different sizes or channel counts
    exit 3.

    \b
    Defaults (this tool's, not idiff's 1e-6): --fail 1e-3 passes half-precision
    rounding and catches real bugs; --warn 1e-5. 8-bit outputs: -fail 0.004
    (one code passes, two fail). HDR values of 4 and over against half: add
    --failrelative 1e-3.

    \b
    Examples:
      pyramid diff gpu.exr reference.exr
      pyramid diff -fail 0.004 -failpercent 1 -hardfail 0.25 a.png b.png
      pyramid diff -a out.tx golden.tx
      pyramid diff out/ golden/ --junit report.xml --html diff-report
      pyramid diff 'out/**/*.exr' 'golden/**/*.exr'
      pyramid diff out/ golden/ --update --dry-run
      pyramid diff --json -o diff.exr -abs -scale 100 half.exr float.exr
    """
    from pyramid_cli.core.errors import PyramidError
    from pyramid_cli.diff import goldens

    collector_on()

    if perceptual:
        _finish(ctx, 2, "-p (idiff's Yee perceptual test) is not implemented: use --metric flip "
                        "(NVIDIA FLIP) or numeric thresholds", as_json)
    if heatmap and not out_path:
        raise click.UsageError("--heatmap needs --out FILE", ctx=ctx)
    if dry_run and not update:
        raise click.UsageError("--dry-run goes with --update", ctx=ctx)
    if colorspace != "auto" or tocolorspace or colorconfig:
        from pyramid_cli import imageio as io

        try:
            io.check_colorspaces(colorspace, tocolorspace, colorconfig=colorconfig)
        except PyramidError as e:
            _finish(ctx, 2, e.message, as_json)
        linear = linear or tocolorspace is not None
    if metric == "flip":
        try:
            import flip_evaluator  # noqa: F401
        except ImportError:
            _finish(ctx, 2, "--metric flip needs NVIDIA's FLIP: pip install 'bilinear-pyramid[flip]' "
                            "(or pip install flip-evaluator)", as_json)

    opts = goldens.CompareOptions(
        thresholds={"fail": fail, "warn": warn, "failpercent": failpercent, "warnpercent": warnpercent,
                    "hardfail": hardfail, "hardwarn": hardwarn, "failrelative": failrelative,
                    "warnrelative": warnrelative, "allowfailures": allowfailures},
        all_levels=all_levels, linear=linear, colorspace=colorspace, alpha=alpha, metric=metric,
        tocolorspace=tocolorspace, colorconfig=colorconfig,
        flip_fail=flip_fail)
    try:
        pairing = goldens.pair_inputs(path_a, path_b)
    except PyramidError as e:
        _finish(ctx, 2 if e.kind == "usage" else EXIT_CODES["file"], e.message, as_json)
    if out_path and pairing.many:
        raise click.UsageError("--out compares one pair: use --html DIR for folders and globs", ctx=ctx)

    try:
        results = goldens.compare_pairs(pairing, opts)
    except PyramidError as e:  # --metric flip without its package
        _finish(ctx, 2, e.message, as_json)
    code = goldens.worst_code(results)

    if out_path and results[0].levels:
        _write_out(ctx, results[0], opts, out_path, absolute, out_if_differ, scale, heatmap, as_json)

    updated: list[tuple[str, str]] = []
    try:
        if update:
            updated = goldens.update_goldens(results, dry_run=dry_run)
        if junit_path:
            from pyramid_cli.diff.junit import write_junit

            write_junit(junit_path, results, suite=f"pyramid diff {path_a} {path_b}")
        if html_dir:
            from pyramid_cli.diff.html import write_html

            write_html(html_dir, results, opts, title=f"pyramid diff {path_a} {path_b}")
    except PyramidError as e:
        _finish(ctx, EXIT_CODES["file"], e.message, as_json)

    if as_json:
        if pairing.many:
            worst = max(results, key=lambda r: r.exit_code, default=None)
            obj: dict[str, Any] = {"exit_code": code, "summary": _summary(results),
                                   "decided_by": ({"name": worst.name, "status": worst.status, "rule": worst.rule}
                                                  if worst is not None and code else None),
                                   "pairs": [r.to_dict() for r in results]}
        else:
            obj = _single_json(results[0])
        if update:
            obj["updated"] = [{"output": s, "golden": d} for s, d in updated]
            obj["dry_run"] = dry_run
        from pyramid_cli.diff.compare import json_safe

        click.echo(json.dumps(json_safe(obj), allow_nan=False))
    elif not quiet:
        text = _text(results, pairing.many, verbose, path_a, path_b)
        if text:
            click.echo(text)
    if quiet:
        for r in results:
            if r.exit_code:
                click.echo(f"pyramid diff: {_LABEL[r.status]}: {r.name}: {r.message}", err=True)
    elif not pairing.many and results[0].status in ("size", "file"):
        click.echo(f"pyramid diff: error: {results[0].message}", err=True)
    if update and not as_json:
        verb = "would copy" if dry_run else "copied"
        for s, d in updated:
            click.echo(f"{verb} {s} -> {d}", err=quiet)
        if not updated:
            click.echo("no golden to update", err=quiet)
    ctx.exit(code)


def _text(results: Sequence[Any], many: bool, verbose: bool, path_a: str, path_b: str) -> str:
    if not many:
        pr = results[0]
        if not pr.levels:
            return ""  # the one-line error goes to stderr
        blocks = []
        for lv in pr.levels:
            title = (f'Comparing "{path_a}" and "{pr.path_b}" subimage {lv.subimage} MIP level {lv.miplevel}'
                     if len(pr.levels) > 1 else None)
            text = _report(lv.result, path_a, pr.path_b or path_b, title)
            if lv.flip is not None:
                text += f"\n  {'mean FLIP':<12} {lv.flip:.6g}"
            blocks.append(text)
        if len(pr.levels) > 1 or pr.rule in ("subimages", "flip"):
            blocks.append(f"{_LABEL[pr.status]} ({pr.rule}{': ' + pr.message if pr.message else ''})")
        return "\n".join(blocks)
    lines = []
    order = sorted(results, key=lambda r: -r.exit_code)
    for r in order:
        lines.append(f"{_LABEL[r.status]:<8} {r.name}  {r.message}")
        if verbose or r.status in ("failure", "warning"):
            for lv in r.levels if verbose or r.exit_code else []:
                lines.append("    " + _report(lv.result, r.path_a or "", r.path_b or "").replace("\n", "\n    "))
    s = _summary(results)
    lines.append(f"{len(results)} pairs: {s['match']} passed, {s['warning']} warned, {s['failure']} failed, "
                 f"{s['size']} differ in size, {s['file']} unreadable, {s['missing']} missing, "
                 f"{s['extra']} extra")
    return "\n".join(lines)


def _write_out(ctx: click.Context, pr: Any, opts: Any, out_path: str, absolute: bool, out_if_differ: bool,
               scale: float, heatmap: bool, as_json: bool) -> None:
    """idiff's -o: the first compared level's difference (signed unless --abs), unless -od and equal."""
    import os

    from pyramid_cli.core.errors import PyramidError
    from pyramid_cli.diff.compare import difference_image
    from pyramid_cli.diff.compare import heatmap as make_heatmap
    from pyramid_cli.diff.goldens import read_pixels
    from pyramid_cli.imageio import raw as io_raw

    lv = pr.levels[0]
    for src in (pr.path_a, pr.path_b):
        if os.path.exists(out_path) and os.path.samefile(out_path, src):
            _finish(ctx, EXIT_CODES["file"], f"--out {out_path} would overwrite the input {src}", as_json)
    if out_if_differ and lv.result.max_error == 0.0:
        return
    try:
        pa, names = read_pixels(pr.path_a, opts, lv.subimage, lv.miplevel)
        pb, _ = read_pixels(pr.path_b, opts, lv.subimage, lv.miplevel)
        if heatmap:
            rgb = make_heatmap(pa, pb)
            io_raw.write_display_png(out_path, rgb) if out_path.lower().endswith(".png") else \
                io_raw.write_float(out_path, rgb, ["R", "G", "B"])
        else:
            io_raw.write_float(out_path, difference_image(pa, pb, scale, absolute=absolute), names)
    except PyramidError as e:  # usage: --heatmap without matplotlib
        _finish(ctx, 2 if e.kind == "usage" else EXIT_CODES["file"], e.message, as_json)


def _finish(ctx: click.Context, code: int, message: str, as_json: bool) -> None:
    """Leave with ``code`` after a one-line error (and a JSON object under --json)."""
    click.echo(f"pyramid diff: error: {message}", err=True)
    if as_json:
        click.echo(json.dumps({"verdict": None, "exit_code": code, "error": message}))
    ctx.exit(code)


if __name__ == "__main__":  # pragma: no cover
    diff.main(sys.argv[1:], prog_name="pyramid diff")
