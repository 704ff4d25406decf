"""The ``pyramid`` command line: one click group, one function per command.

Command bodies only translate options; the work happens in the modules they
call. Heavy modules (numpy, OpenImageIO, moderngl) are imported inside the
commands so that ``pyramid --help`` stays fast.
"""

from __future__ import annotations

import json
import sys

import click

from pyramid_cli.core import catalogue
from pyramid_cli.core.errors import EXIT_CODES, ExpressionError, PyramidError, UsageError
from pyramid_cli.core.options import BORDERS, STRATEGIES


def _choice(values) -> click.Choice:
    return click.Choice(list(values))


EXIT_CODE_HELP = "\b\nExit codes:\n" + "\n".join(f"  {code}  {text}" for code, text in EXIT_CODES.values())


class ExpressionType(click.ParamType):
    """A filter expression; parse errors print with a caret under the column."""

    name = "EXPR"

    def convert(self, value, param, ctx):
        from pyramid_cli.core.parse import parse

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
        except KeyboardInterrupt as e:  # Ctrl-C, and SIGTERM/SIGHUP after signals.install()
            from pyramid_cli.core.signals import describe, exit_code
            click.echo(f"pyramid: {describe(e)}", err=True)
            ctx.exit(exit_code(e))


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
    from pyramid_cli.run.explain import check_plot_path, describe, plot_powers, render

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


@main.command("plan")
@click.argument("expression", type=EXPR)
@click.option("--size", required=True, callback=_size, metavar="WxH", help="Input image size, e.g. 1920x1080.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of the report.")
@click.option("--strategy", type=_choice(STRATEGIES), default="cost", show_default=True,
              help="cost: per filter, the paper's decomposition or one fused pass, whichever is faster by the "
                   "cost model calibrated by bench/calibrate.py (pyramid_cli/plan/cost_model.json); paper: always "
                   "the paper's; fused: always one pass per filter (what the CPU executor runs).")
@click.option("--mipmap", "mip_round", type=click.Choice(["down", "up"]), default=None,
              help="Plan `pyramid mipmap --round ROUND` with EXPRESSION (a one-step ⊗↓) as its --analysis: "
                   "every level's passes, the paper's where a level halves exactly, resampling tables elsewhere.")
@click.option("--border", type=_choice(BORDERS), default="clamp", show_default=True,
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

    w, h = size
    if mip_round is not None:
        from pyramid_cli.core.expr import Apply, Input, Named, Op, to_text
        from pyramid_cli.workflows.mip import TextureLevels

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


def io_options(f):
    """Options every command that reads and writes images shares."""
    from pyramid_cli.core.options import (
        ALPHA_MODES,
        BACKEND_HELP,
        BACKENDS,
        COLORSPACES,
        NAN_POLICIES,
        PIXEL_TYPES,
        PRECISIONS,
    )

    options = [
        click.option("--backend", type=_choice(BACKENDS), default="auto", show_default=True,
                     help="; ".join(f"{name}: {BACKEND_HELP[name]}" for name in BACKENDS) + " (-v says which ran)."),
        click.option("--threads", type=click.IntRange(1, 1024), default=None, metavar="N",
                     help="CPU executor threads (default: the cores this process may use)."),
        click.option("--precision", type=_choice(PRECISIONS), default="float", show_default=True,
                     help="GL intermediate textures: RGBA32F, or RGBA16F (faster, ~1e-3 relative, max 65504). "
                          "Half files travel as half either way (upload, read-back), losing nothing."),
        click.option("--type", "pixel_type", type=_choice(PIXEL_TYPES),
                     help="Output pixel type (default: the input's, as the output format allows)."),
        click.option("--colorspace", type=_choice(COLORSPACES), default="auto",
                     show_default=True, help="Encoding of integer inputs; filtering is always in linear light."),
        click.option("--alpha", type=_choice(ALPHA_MODES), default="auto",
                     show_default=True, help="How the input stores alpha (RGBA is filtered premultiplied)."),
        click.option("--nan", "nan_policy", type=_choice(NAN_POLICIES), default="keep",
                     show_default=True, help="What to do with NaN/Inf pixels in float input."),
        click.option("--dither", is_flag=True, help="Dither 8-bit output."),
        click.option("--compression", metavar="C", help="Output compression: EXR none|zip|zips|piz|dwaa|... "
                     "(default: the input's), PNG zlib level 0-9 (default 6)."),
        click.option("--force", is_flag=True, help="Allow OUTPUT to overwrite INPUT."),
        click.option("-v", "--verbose", is_flag=True, help="Say which executor runs and why, and the colour and "
                     "alpha rules in force for each image."),
        click.option("-q", "--quiet", is_flag=True, help="Print nothing but errors."),
    ]
    for option in reversed(options):
        f = option(f)
    return f


def border_option(f):
    from pyramid_cli.core.options import BORDERS

    return click.option("--border", type=_choice(BORDERS), default="clamp", show_default=True,
                        help="How every written operator reads past its input's edges: clamp (repeat the edge), "
                             "mirror (… 2 1 | 1 2 …), wrap (periodic), zero. Runs on every backend.")(f)


def batch_options(f):
    """Many inputs in one process: an output template, failure and freshness policies, I/O overlap."""
    options = [
        click.option("-o", "--output", "template", metavar="TEMPLATE",
                     help="Output path template: {stem} {name} {ext} (with its dot, e.g. '.exr') {dir} of each "
                          "input, and for sequences {frame} ({frame:05d}) or one frame token (####, %04d, @, $F4, "
                          "<UDIM>), in any combination: 'out/{stem}_blur_{frame:05d}{ext}'. Without fields or a "
                          "token it is a path as it is. Output folders are created."),
        click.option("--keep-going", is_flag=True, help="Go on past a bad file; report failures at the end."),
        click.option("--skip-existing", is_flag=True, help="Skip inputs whose output is newer (like make)."),
        click.option("-j", "--jobs", type=click.IntRange(1, 64), default=2, show_default=True,
                     help="Threads decoding/encoding images while the executor works on another."),
        *sequence_options(),
    ]
    for option in reversed(options):
        f = option(f)
    return f


def sequence_options() -> list:
    """--frames, --shard, --cluster, --chunk, --cluster-timeout (frame sequences, array jobs, a Dask cluster)."""
    return [
        click.option("--frames", metavar="RANGE", help="Frames of sequence inputs (plate.####.exr, plate.%04d.exr, "
                     "plate.1001-1240#.exr, tex.<UDIM>.exr) to process: 1001-1240, 1001-1240x2 or 1001-1240:2 (both "
                     "every other frame), 1,5-9, -5--1; descending ranges are the same frames; run in ascending "
                     "order (default: the pattern's range, else every frame on disk)."),
        click.option("--shard", metavar="K/N|auto", help="Process only the K-th (from 1) "
                     "of N contiguous chunks of the jobs. auto reads the array task from Slurm, SGE, AWS Batch, "
                     "Kubernetes, LSF, PBS or Torque; give what the scheduler does not publish: auto/N the task "
                     "count (Kubernetes), auto/FIRST-LAST[:STEP] the array's range as submitted (LSF, PBS, Torque: "
                     "auto/5-9 for bsub -J 'x[5-9]'), or PYRAMID_SHARD_COUNT / PYRAMID_SHARD_ARRAY. A task that "
                     "cannot be placed exits 2 before any work."),
        click.option("--cluster", metavar="ADDRESS", help="Run on a Dask cluster: a scheduler address "
                     "(tcp://HOST:8786, HOST:PORT, tls://, ws://, ...), a scheduler file (dask scheduler "
                     "--scheduler-file), or local:N for N worker processes on this machine (needs pip install "
                     "'bilinear-pyramid[cluster]')."),
        click.option("--chunk", type=click.IntRange(1), metavar="N", help="Jobs per cluster task (default: about "
                     "four tasks per worker, at most 16 jobs)."),
        click.option("--cluster-timeout", type=click.FloatRange(0, min_open=True), metavar="SECONDS",
                     help="How long --cluster waits to connect (or for its scheduler file), and with no worker "
                          "connected before the frames not done fail (default 30)."),
    ]


class _Bar:
    """click's progress bar as the pipeline's progress (shown at a terminal only)."""

    def __init__(self, total: int):
        self.bar = click.progressbar(length=total, label="pyramid", file=sys.stderr)

    def __enter__(self):
        return self.bar.__enter__()

    def __exit__(self, *exc):
        return self.bar.__exit__(*exc)


def _reporter(opts: dict):
    from pyramid_cli.run.report import Reporter

    return Reporter(quiet=opts["quiet"], verbose=opts["verbose"], interactive=sys.stderr.isatty(), out=click.echo,
                    err=lambda msg: click.echo(msg, err=True), progress=_Bar if sys.stderr.isatty() else None)


def _drop(msg: str) -> None:
    """A Reporter's ``out`` where a command prints its own result (--json)."""


def _session(opts: dict, reporter):
    from pyramid_cli.exec.session import Session

    session = Session(opts["backend"], opts["precision"], threads=opts["threads"], warn=reporter.warn)
    reporter.detail(f"executor {session.name} ({session.why})")
    return session


def _read_write(opts: dict):
    from pyramid_cli.run.settings import ReadOptions, WriteOptions

    return (ReadOptions(opts["colorspace"], opts["alpha"], opts["nan_policy"]),
            WriteOptions(opts["pixel_type"], opts["dither"], opts["compression"], opts["force"]))


def memory_option(f):
    """--memory: the working-set budget of a streamed single-image job (pyramid_cli.run.stream)."""
    return click.option("--memory", metavar="SIZE", default=None,
                        help="Working-set budget, e.g. 512M or 2G (default: a quarter of the available memory). "
                             "A picture whose whole run would not fit streams from file to file in bands of rows "
                             "chosen from it; -v says which. Work that cannot fit is refused before it starts.")(f)


def mixed_lattice_option(f):
    return click.option("--allow-mixed-lattice", is_flag=True,
                        help="Do not warn when the analysis and synthesis filters sit on different lattices (the "
                             "result shifts by half a fine pixel per level; `pyramid explain` shows a filter's "
                             "lattice).")(f)


def _process(paths, work, opts: dict, mip_tile: int | None = None) -> None:
    from pyramid_cli.run.pipeline import process

    reporter = _reporter(opts)
    ro, wo = _read_write(opts)
    batch = {"read": ro, "write": wo, "reporter": reporter, "keep_going": opts["keep_going"],
             "skip_existing": opts["skip_existing"], "jobs": opts["jobs"], "mip_tile": mip_tile,
             "frames": opts["frames"], "shard": opts["shard"], "cluster": opts["cluster"], "chunk": opts["chunk"],
             "cluster_timeout": opts["cluster_timeout"]}
    if opts.get("memory") is not None:
        from pyramid_cli.run.stream import parse_size

        batch["memory"] = parse_size(opts["memory"])
    if opts["cluster"]:  # every worker opens its own session; none is needed here
        from pyramid_cli.run.cluster import SessionSpec

        spec = SessionSpec(opts["backend"], opts["precision"], opts["threads"])
        report = process(list(paths), opts["template"], work, spec, **batch)
    else:
        with _session(opts, reporter) as session:
            report = process(list(paths), opts["template"], work, session, **batch)
    if report.failed:
        sys.exit(report.exit_code)


@main.command()
@click.argument("expression", type=EXPR)
@click.argument("paths", metavar="INPUT OUTPUT | INPUT... -o TEMPLATE", nargs=-1, required=True)
@border_option
@io_options
@batch_options
@memory_option
def apply(expression, paths, border: str, **opts) -> None:
    """Apply EXPRESSION to INPUT and write OUTPUT (format from its extension).

    \b
    Example:
      pyramid apply 'box4 *v g' render.exr render_half.exr
      pyramid apply --border mirror 'h_Doo-Sabin ⊗↑ g' small.png big.png
      pyramid apply 'quadratic *v g' 'frames/*.exr' -o 'half/{stem}.exr'
      pyramid apply 'quadratic *v g' 'plate.%04d.exr' -o 'half/plate.%04d.exr' --shard 3/10
      pyramid apply --memory 1G 'gauss7' matte_32k.exr matte_soft.exr
    """
    from pyramid_cli.jobs.work import Filter

    _process(paths, Filter(expr=expression, border=border), opts)


@main.command()
@click.argument("paths", metavar="INPUT OUTPUT | INPUT... -o TEMPLATE", nargs=-1, required=True)
@click.option("--levels", "-m", type=click.IntRange(1, 16), default=4, show_default=True,
              help="Analysis steps down (and synthesis steps back up).")
@click.option("--analysis", default=catalogue.ANALYSIS_DEFAULT, show_default=True,
              help=f"{', '.join(catalogue.ANALYSIS_FILTERS)}, or a ⊗↓ expression.")
@click.option("--synthesis", default=catalogue.SYNTHESIS_DEFAULT, show_default=True,
              help=f"{', '.join(catalogue.SYNTHESIS_FILTERS)}, or a ⊗↑ expression.")
@click.option("--quasi", is_flag=True, help="Apply the §5.5 quasi-interpolation prefilter at the coarsest level.")
@click.option("--sigma", type=float, help="Blur strength as a Gaussian sigma in input pixels: picks the levels "
              "and blends two neighbouring level counts, so the strength changes continuously.")
@mixed_lattice_option
@border_option
@io_options
@batch_options
@memory_option
def blur(paths, levels: int, analysis: str, synthesis: str, quasi: bool, sigma: float | None,
         allow_mixed_lattice: bool, border: str, **opts) -> None:
    """Pyramidal blur: LEVELS analysis steps, then synthesis back to the input size.

    Defaults are the paper's Figure 3b: 4×4 box analysis, Doo-Sabin synthesis.

    \b
    Example:
      pyramid blur --levels 5 render.exr soft.exr
      pyramid blur --analysis box --synthesis doosabin photo.png blocky.png
      pyramid blur --levels 4 'in/*.exr' -o 'out/{stem}_blur.exr' --keep-going
      pyramid blur 'plate.####.exr' -o 'soft/soft.####.exr' --frames 1001-1240x2
      pyramid blur 'plate.1001-1240#.exr' -o 'soft.%04d.exr' --shard auto --skip-existing
      pyramid blur 'plate.####.exr' -o 'soft.####.exr' --cluster local:4
      pyramid blur --levels 5 --memory 2G -v painting_32k.exr soft_32k.exr
    """
    from pyramid_cli.jobs.work import Blur, SigmaBlur

    if sigma is None:
        work = Blur(levels=levels, analysis=analysis, synthesis=synthesis, quasi=quasi, border=border,
                    allow_mixed_lattice=allow_mixed_lattice)
    else:
        from pyramid_cli.workflows.pyramids import sigma_blend

        if quasi:
            raise UsageError("--quasi and --sigma cannot be combined")
        m, t = sigma_blend(sigma, analysis, synthesis)
        if not opts["quiet"]:
            click.echo(f"pyramid: sigma {sigma:g}: {1 - t:.3f} × {m} level(s) + {t:.3f} × {m + 1} "
                       f"(the blend's equivalent kernel has standard deviation {sigma:g} px)", err=True)
        work = SigmaBlur(sigma=sigma, analysis=analysis, synthesis=synthesis, border=border,
                         allow_mixed_lattice=allow_mixed_lattice)
    _process(paths, work, opts)


@main.command()
@click.argument("input_path", metavar="INPUT")
@click.argument("pattern", metavar="OUTPUT_PATTERN")
@click.option("--levels", "-m", type=click.IntRange(1, 16), default=4, show_default=True)
@click.option("--analysis", default=catalogue.ANALYSIS_DEFAULT, show_default=True,
              help=f"{', '.join(catalogue.ANALYSIS_FILTERS)} or a ⊗↓ expression.")
@click.option("--laplacian", is_flag=True, help="Write band-pass levels L_k = G_k − expand(G_k+1) and the coarsest "
              "G_m, which `pyramid collapse` sums back to the input.")
@click.option("--synthesis", default=catalogue.SYNTHESIS_DEFAULT, show_default=True,
              help="Expansion used by --laplacian.")
@click.option("--multipart", is_flag=True, help="Write one multi-part EXR (OUTPUT_PATTERN is its path).")
@click.option("--sheet", type=click.Path(dir_okay=False), help="Also draw all levels side by side (Figure 1a).")
@border_option
@io_options
@memory_option
def levels(input_path, pattern, levels, analysis, laplacian, synthesis, multipart, sheet, border, **opts) -> None:
    """Write every level of the analysis pyramid (level 0 is the input).

    Output folders are created.

    \b
    Example:
      pyramid levels render.exr 'pyr/render_{level}.exr' --levels 5
      pyramid levels --laplacian --multipart render.exr bands.exr
      pyramid collapse bands.exr rebuilt.exr
      pyramid levels --memory 1G -v painting_32k.exr 'pyr/painting_{level}.exr'
    """
    from pyramid_cli.jobs.work import Laplacian, Levels
    from pyramid_cli.run.pipeline import write_levels_files

    work = (Laplacian(levels=levels, analysis=analysis, synthesis=synthesis, border=border) if laplacian
            else Levels(levels=levels, analysis=analysis, border=border))
    reporter = _reporter(opts)
    ro, wo = _read_write(opts)
    memory = None
    if opts.get("memory") is not None:
        from pyramid_cli.run.stream import parse_size

        memory = parse_size(opts["memory"])
    with _session(opts, reporter) as session:
        write_levels_files(input_path, pattern, work, session, read=ro, write=wo, reporter=reporter,
                           multipart=multipart, sheet=sheet, memory=memory)


@main.command()
@click.argument("inputs", nargs=-1, required=True, metavar="BANDS... | BANDS.exr")
@click.argument("output_path", metavar="OUTPUT")
@click.option("--synthesis", default=None, help="Expansion the bands were made with (default: as recorded, "
              f"else {catalogue.SYNTHESIS_DEFAULT}).")
@click.option("--border", type=_choice(BORDERS), default=None,
              help="The border the bands were made with (default: as recorded, else clamp).")
@io_options
def collapse(inputs, output_path, synthesis, border, **opts) -> None:
    """Sum Laplacian bands back to the image: G_k = L_k + expand(G_k+1).

    INPUT is the multi-part EXR of `pyramid levels --laplacian --multipart`, or the
    level files L_0 … L_m-1, G_m in order. Use the --border the bands were made with.

    \b
    Example:
      pyramid collapse bands.exr rebuilt.exr
      pyramid collapse 'pyr/band_*.exr' rebuilt.exr
    """
    from pyramid_cli.run.pipeline import collapse_files

    reporter = _reporter(opts)
    ro, wo = _read_write(opts)
    with _session(opts, reporter) as session:
        collapse_files(list(inputs), output_path, session, synthesis=synthesis, border=border, read=ro, write=wo,
                       reporter=reporter)


@main.command()
@click.argument("paths", metavar="INPUT OUTPUT | INPUT... -o TEMPLATE", nargs=-1, required=True)
@click.option("--analysis", default=catalogue.MIP_ANALYSIS_DEFAULT, show_default=True,
              help=f"{', '.join(catalogue.ANALYSIS_FILTERS)} or a ⊗↓ expression.")
@click.option("--tile", type=click.IntRange(8, 4096), default=64, show_default=True,
              help="Tile size (TIFF/.tx tiles must be a multiple of 16).")
@click.option("--wrap", metavar="MODE[,MODE]",
              help="maketx's wrap modes, black|clamp|periodic|mirror (s,t): how the filters read past the edges "
                   "and the file's wrapmodes. Sets --border (black=zero, periodic=wrap).")
@click.option("--swrap", metavar="MODE", help="The s (horizontal) wrap mode; must equal t's.")
@click.option("--twrap", metavar="MODE", help="The t (vertical) wrap mode; must equal s's.")
@click.option("--constant-color-detect", "constant_detect", is_flag=True,
              help="A constant-colour image becomes one tile of that colour, as maketx's flag does.")
@click.option("--fill", "fill_holes", is_flag=True, help="Fill the texels of alpha < 1 (empty space around UV "
              "islands) by pull-push first, so no level darkens toward the empty colour; the texture becomes opaque "
              "and its texels of alpha 1 stay as they are (pyramid fill).")
@click.option("--round", "rounding", type=click.Choice(["down", "up"]), default="down", show_default=True,
              help="Level sizes. down: maketx's and OpenEXR's max(1, ⌊n/2⌋); a level that is not exactly half "
                   "the one above is resampled with the --analysis filter's own kernel stretched to the ratio, "
                   "so every level covers the whole texture domain and keeps the mean (exactly under --wrap "
                   "periodic or mirror). up: ⌈n/2⌉, the analysis pyramid's levels (an odd size is padded by the "
                   "border, so coarse levels cover a little more than the image and lookups drift toward the "
                   "top left).")
@click.option("--resize", is_flag=True, help="maketx's --resize: level 0 resampled up to the next power of two "
              "on each axis first (as a bilinear lookup of the source reads it), then the levels from it.")
@click.option("--nchannels", type=click.IntRange(1, 64), metavar="N", help="maketx's --nchannels: keep the first N "
              "channels, or append channels of zeros up to N.")
@click.option("--monochrome-detect", "monochrome_detect", is_flag=True, help="maketx's flag: an RGB image (no "
              "alpha) whose three channels are equal at every pixel becomes a one-channel (Y) texture.")
@border_option
@io_options
@batch_options
@memory_option
@click.pass_context
def mipmap(ctx: click.Context, paths, analysis, tile, wrap, swrap, twrap, constant_detect, fill_holes, rounding,
           resize, nchannels, monochrome_detect, border, **opts) -> None:
    """Write a tiled MIP-mapped texture down to 1×1 (what maketx makes, with better filters).

    OpenEXR (.exr) holds the levels as its own MIP levels, TIFF (.tx, .tif) as
    subimages marked "Plain Texture", as maketx writes them; both read as MIP-mapped
    in OpenImageIO's TextureSystem. Filtering is in linear light on premultiplied
    alpha; the output keeps the source's type and encoding where the format can
    (8-bit sRGB PNG → 8-bit sRGB .tx; in EXR 8-bit becomes half), --type overrides. Level 0
    carries maketx's metadata: oiio:AverageColor, oiio:ConstantColor (constant
    images), oiio:SHA-1 of the source pixels, wrapmodes, textureformat.

    Level sizes are maketx's max(1, ⌊n/2⌋): a level that halves exactly runs the
    paper's filter, any other is resampled with the same filter's kernel so that it
    covers the whole texture domain (see `pyramid plan --mipmap`); --round up keeps the
    analysis pyramid's ⌈n/2⌉ instead. --wrap (maketx's names) and --border (ours) say
    the same thing; different s and t modes are refused.

    \b
    Example:
      pyramid mipmap albedo.exr albedo.tx.exr
      pyramid mipmap albedo.png albedo.tx                       # 8-bit sRGB .tx, like maketx
      pyramid mipmap --wrap periodic --analysis box4 'tex/*.png' -o 'tx/{stem}.tx'
      pyramid mipmap --constant-color-detect --tile 64 'tex/*.exr' -o 'tx/{stem}.tx.exr'
      pyramid mipmap --monochrome-detect --resize mask.png mask.tx      # 1 channel, powers of two
      pyramid mipmap 'tex/albedo.<UDIM>.exr' -o 'tx/albedo.<UDIM>.tx.exr'
      pyramid mipmap --fill bake.png bake.tx                    # pad UV islands first: no dark bleeding
      pyramid mipmap --memory 2G -v matte_32k.exr matte_32k.tx.exr   # streamed: level 0 band by band
    """
    from pyramid_cli.workflows.mip import TextureLevels, border_for_wrap, parse_wrap

    modes = parse_wrap(wrap, swrap, twrap)
    if modes is not None:
        wanted = border_for_wrap(*modes)
        explicit = ctx.get_parameter_source("border") is click.core.ParameterSource.COMMANDLINE
        if explicit and border != wanted:
            raise UsageError(f"--border {border} contradicts --wrap {','.join(modes)} (which reads as --border "
                             f"{wanted}); give one of them")
        border = wanted
    output = opts.get("template") or (paths[-1] if len(paths) > 1 else "")
    if tile % 16 and output.lower().endswith((".tx", ".tif", ".tiff")):
        raise UsageError(f"--tile {tile}: TIFF tiles must be a multiple of 16 ({output})")
    work = TextureLevels(levels=None, analysis=analysis, border=border, constant_detect=constant_detect,
                         rounding=rounding, resize=resize, nchannels=nchannels, monochrome_detect=monochrome_detect,
                         fill=fill_holes)
    _process(paths, work, opts, mip_tile=tile)


@main.command()
@click.argument("input_path", metavar="INPUT")
@click.argument("output_path", metavar="OUTPUT")
@click.option("--mask", type=click.Path(dir_okay=False), help="Weight image: 1 known, 0 a hole, between partly "
              "known (one channel, one per channel, else its alpha channel; stored values, no sRGB decoding; NaN/Inf "
              "kept with a warning as in an image, values outside 0 … 1 clipped with one). Implies --holes mask.")
@click.option("--holes", type=_choice(["alpha", "mask", "nan"]), default=None,
              help="Where the weights come from: the alpha channel (default without --mask), --mask, or every "
                   "pixel with a NaN/Inf is a hole.")
@click.option("--levels", "-m", type=click.IntRange(0, 16), default=None,
              help="Pull steps (default: down to 1×1, so every hole is filled).")
@click.option("--analysis", default="box4", show_default=True,
              help=f"The pull's filter: {', '.join(catalogue.ANALYSIS_FILTERS)}, or a ⊗↓ expression.")
@click.option("--synthesis", default="doosabin", show_default=True,
              help=f"The push's filter: {', '.join(catalogue.SYNTHESIS_FILTERS)}, or a ⊗↑ expression.")
@click.option("--keep-alpha", is_flag=True, help="Keep the input's alpha and store the filled colours beside it "
              "unassociated (straight), instead of an opaque image: a PNG keeps its cut-out with colour under it.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (pixels filled, levels, executor).")
@mixed_lattice_option
@border_option
@io_options
def fill(input_path, output_path, mask, holes, levels, analysis, synthesis, keep_alpha, as_json, allow_mixed_lattice,
         border, **opts) -> None:
    """Fill holes from the pixels around them by pull-push (Kraus, GRAPP 2009).

    The known pixels are pulled down the analysis pyramid as premultiplied colours with
    their weights, then every level is composited over the expanded coarser one: holes of
    any size get a smooth fill, pixels of full weight stay bit for bit. The output is
    opaque (alpha 1, as oiiotool --fillholes writes it) unless --keep-alpha. An image
    without a known pixel is bad pixel data (exit 5). Filters
    on two lattices fill from beside the holes and are warned about.

    \b
    Example:
      pyramid fill bake.png bake_padded.png                 # holes where alpha < 1
      pyramid fill --mask valid.png plate.exr patched.exr    # holes where the mask is 0
      pyramid fill --holes nan depth.exr depth_filled.exr    # holes at NaN/Inf pixels
      pyramid fill --analysis box --json in.exr out.exr
      pyramid fill --keep-alpha decal.png decal_dilated.png    # colour under the cut-out
    """
    from pyramid_cli.run.methods_files import fill_file

    reporter = _reporter(opts)
    if as_json:  # the JSON object is the result; warnings still go to stderr
        reporter.out = _drop
    ro, wo = _read_write(opts)
    with _session(opts, reporter) as session:
        info = fill_file(input_path, output_path, session, mask=mask, holes=holes, levels=levels, analysis=analysis,
                         synthesis=synthesis, keep_alpha=keep_alpha, border=border,
                         allow_mixed_lattice=allow_mixed_lattice, read=ro, write=wo, reporter=reporter)
    if as_json:
        click.echo(json.dumps(info, ensure_ascii=False))


@main.command()
@click.argument("a_path", metavar="A")
@click.argument("b_path", metavar="B")
@click.argument("mask_path", metavar="MASK")
@click.argument("output_path", metavar="OUTPUT")
@click.option("--levels", "-m", type=click.IntRange(0, 16), default=None,
              help="Laplacian levels (default: as many as the size allows while the coarsest level keeps 16 "
                   "pixels on its shorter side: 4 at 256×256, 7 at 3840×2160).")
@click.option("--analysis", default=catalogue.ANALYSIS_DEFAULT, show_default=True,
              help=f"{', '.join(catalogue.ANALYSIS_FILTERS)}, or a ⊗↓ expression.")
@click.option("--synthesis", default=catalogue.SYNTHESIS_DEFAULT, show_default=True,
              help=f"{', '.join(catalogue.SYNTHESIS_FILTERS)}, or a ⊗↑ expression.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (size, levels, executor).")
@mixed_lattice_option
@border_option
@io_options
def blend(a_path, b_path, mask_path, output_path, levels, analysis, synthesis, as_json, allow_mixed_lattice, border,
          **opts) -> None:
    """Join A and B along MASK without a seam (Burt & Adelson's multiresolution spline, 1983).

    Each Laplacian band of A and B is blended with the same level of the mask's analysis
    pyramid, and the bands are collapsed: fine detail meets over a narrow seam, coarse
    shading over a wide one. MASK is 1 where A shows and 0 where B shows: one channel,
    one per channel, else its alpha channel; stored values, no sRGB decoding; NaN/Inf
    kept with a warning (as in an image; --nan), values outside 0 … 1 clipped with one. A, B and MASK have
    one size. Filters on two lattices move the seam and are warned about.

    \b
    Example:
      pyramid blend apple.png orange.png left_half.png orapple.png
      pyramid blend --levels 5 plate.exr patch.exr matte.exr comp.exr
      pyramid blend --analysis cubic --synthesis cubic --json a.exr b.exr m.png out.exr
    """
    from pyramid_cli.run.methods_files import blend_files

    reporter = _reporter(opts)
    if as_json:  # the JSON object is the result; warnings still go to stderr
        reporter.out = _drop
    ro, wo = _read_write(opts)
    with _session(opts, reporter) as session:
        info = blend_files(a_path, b_path, mask_path, output_path, session, levels=levels, analysis=analysis,
                           synthesis=synthesis, border=border, allow_mixed_lattice=allow_mixed_lattice, read=ro,
                           write=wo, reporter=reporter)
    if as_json:
        click.echo(json.dumps(info, ensure_ascii=False))


@main.command("farm-template", context_settings={"ignore_unknown_options": True, "allow_interspersed_args": False})
@click.option("--frames", required=True, metavar="RANGE", help="The job's frames: 1001-1240, 1001-1240x2 or "
              "1001-1240:2 (every other frame), 1,5-9; written to the template ascending, as Open Job Description "
              "requires (1010-1001 becomes 1001-1010).")
@click.option("--chunk", type=click.IntRange(1), default=10, show_default=True,
              help="Frames per task, at most, whatever the range's shape (one process, one warm executor each; "
                   "OpenJD evens the sizes: 10 frames at 4 are tasks of 4, 3, 3).")
@click.option("--target-seconds", type=click.IntRange(1), help="Target task run time, for schedulers that adapt "
              "the chunk size to it (targetRuntimeSeconds).")
@click.option("--name", help="Job name (default: the command).")
@click.option("--executable", default="pyramid", show_default=True, help="The pyramid program on the workers.")
@click.option("-o", "--output", "out_path", default="-", show_default=True, type=click.Path(dir_okay=False),
              help="Where to write the template (- for standard output).")
@click.argument("command", nargs=-1, required=True, type=click.UNPROCESSED, metavar="-- COMMAND ARGS...")
@click.pass_context
def farm_template(ctx: click.Context, frames, chunk, target_seconds, name, executable, out_path, command) -> None:
    """Write an Open Job Description job template (AWS Deadline Cloud's format) running COMMAND over frames.

    Each task runs COMMAND on a chunk of frames with --frames CHUNK (an OpenJD range
    such as 1001-1007:2, which --frames reads with the same meaning); the template
    validates with `openjd check` and runs locally with `openjd run`. COMMAND is
    planned over all the frames when the template is written: what its tasks would
    refuse (a bad option, an output template giving two frames one file, frames
    outside the pattern's range) is refused now. --frames, --shard, --cluster and
    --chunk cannot be in COMMAND (farm-template sets the frames; the tasks are the split).

    \b
    Example:
      pyramid farm-template --frames 1001-1240 --chunk 20 -o blur.json -- \\
          blur --levels 4 --skip-existing '/shots/sh010/plate.####.exr' -o '/shots/sh010/soft.####.exr'
      pyramid farm-template --frames 1001-1240x2 --chunk 8 -o half.json -- \\
          apply 'quadratic *v g' '/shots/sh010/plate.####.exr' -o '/shots/sh010/half/{stem}_half{ext}'
      openjd check blur.json && openjd run blur.json
      deadline bundle submit ...   # a job bundle holding template.json
    """
    from pyramid_cli.run.farm import check_plan, dumps, job_template

    template = job_template(list(command), frames, chunk=chunk, name=name, executable=executable,
                            target_seconds=target_seconds)
    sub = main.get_command(ctx, command[0])
    try:
        parsed = sub.make_context(command[0], list(command[1:]), parent=ctx)
    except click.ClickException as e:
        raise UsageError(f"the command after --: {e.format_message().splitlines()[0]}") from None
    check_plan(parsed.params["paths"], parsed.params.get("template"), frames)
    text = dumps(template)
    if out_path == "-":
        click.echo(text, nl=False)
        return
    from pyramid_cli.run.farm import write

    write(out_path, text)
    click.echo(f"wrote {out_path}", err=True)


def _register() -> None:
    from pyramid_cli.cli.diff import diff

    main.add_command(diff)


_register()


def run() -> None:  # console-script entry point
    from pyramid_cli.core.signals import guard_streams, install
    install()  # SIGTERM/SIGHUP clean up like Ctrl-C (exit 143/129); SIGXFSZ ignored
    guard_streams()  # a reader closing stdout (| head) drops the lines, not the frames
    main(prog_name="pyramid")

