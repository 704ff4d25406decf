"""The ``pyramid`` command line: one click group, one function per command.

Command bodies only translate options; the work happens in the modules they
call. Heavy modules (numpy, OpenImageIO, moderngl) are imported inside the
commands so that ``pyramid --help`` stays fast.
"""

from __future__ import annotations

import json
import os
import sys

import click

from .errors import EXIT_CODES, ExpressionError, PyramidError, UsageError

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
        except KeyboardInterrupt as e:  # Ctrl-C, and SIGTERM/SIGHUP after signals.install()
            from .signals import describe, exit_code
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
@click.option("--strategy", type=click.Choice(["cost", "paper"]), default="cost", show_default=True,
              help="cost: per filter, the paper's decomposition or one fused pass, whichever is faster by the "
                   "cost model calibrated by bench/calibrate.py (pyramid_cli/cost_model.json); paper: always "
                   "the paper's.")
def plan_command(expression, size, as_json: bool, strategy: str) -> None:
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
    p = plan(expression, (h, w), strategy)
    check(p)
    click.echo(json.dumps(to_json(p), ensure_ascii=False) if as_json else render(p))


def io_options(f):
    """Options every command that reads and writes images shares."""
    options = [
        click.option("--backend", type=click.Choice(["auto", "gl", "cpu"]), default="auto", show_default=True,
                     help="gl: OpenGL through headless EGL; cpu: numpy (for apply and blur the reference of "
                          "the paper's formulas, slow and exact); auto: gl, else cpu with a warning."),
        click.option("--precision", type=click.Choice(["float", "half"]), default="float", show_default=True,
                     help="GL intermediate textures: RGBA32F, or RGBA16F (faster, ~1e-3 relative, max 65504). "
                          "Half files travel as half either way (upload, read-back), losing nothing."),
        click.option("--type", "pixel_type", type=click.Choice(["uint8", "uint16", "half", "float"]),
                     help="Output pixel type (default: the input's, as the output format allows)."),
        click.option("--colorspace", type=click.Choice(["auto", "linear", "srgb"]), default="auto",
                     show_default=True, help="Encoding of integer inputs; filtering is always in linear light."),
        click.option("--alpha", type=click.Choice(["auto", "straight", "premultiplied", "none"]), default="auto",
                     show_default=True, help="How the input stores alpha (RGBA is filtered premultiplied)."),
        click.option("--nan", "nan_policy", type=click.Choice(["keep", "zero", "fail"]), default="keep",
                     show_default=True, help="What to do with NaN/Inf pixels in float input."),
        click.option("--dither", is_flag=True, help="Dither 8-bit output."),
        click.option("--compression", metavar="C", help="Output compression: EXR none|zip|zips|piz|dwaa|... "
                     "(default: the input's), PNG zlib level 0-9 (default 6)."),
        click.option("--force", is_flag=True, help="Allow OUTPUT to overwrite INPUT."),
        click.option("-v", "--verbose", is_flag=True, help="Say which backend, colour and alpha rules are in force."),
        click.option("-q", "--quiet", is_flag=True, help="Print nothing but errors."),
    ]
    for option in reversed(options):
        f = option(f)
    return f


def batch_options(f):
    """Many inputs in one process: an output template, failure and freshness policies, I/O overlap."""
    options = [
        click.option("-o", "--output", "template", metavar="TEMPLATE",
                     help="Output path template for several inputs: {stem} {name} {ext} {dir}."),
        click.option("--keep-going", is_flag=True, help="Go on past a bad file; report failures at the end."),
        click.option("--skip-existing", is_flag=True, help="Skip inputs whose output is newer (like make)."),
        click.option("-j", "--jobs", type=click.IntRange(1, 64), default=2, show_default=True,
                     help="Threads decoding/encoding images while the GPU works on another."),
    ]
    for option in reversed(options):
        f = option(f)
    return f


def _process(paths: tuple[str, ...], work, opts: dict, mip_tile: int | None = None, plan_for=None) -> None:
    """Read each input, ``work(runner, pixels, dtype)``, write atomically; one runner for the whole batch.

    ``dtype`` is float16 where the output stores the result as half unchanged (the input
    was half too), else float32. With ``mip_tile``, ``work`` returns every MIP level and
    they go into one tiled file. ``plan_for(shape)``, when given, names the plan ``work``
    will run, so that the GL executor prepares it while the first image decodes.
    """
    import numpy as np

    from . import batch, io
    from .run import Runner

    jobs = batch.plan_jobs(list(paths), opts["template"])
    quiet = opts["quiet"]
    runner = Runner(opts["backend"], opts["precision"])

    def prepare(job):
        shape = io.read_shape(job.input)
        p = plan_for(shape) if shape is not None else None
        if p is not None:
            runner.prepare(p)

    def read(job):
        image = io.read_image(job.input, colorspace=opts["colorspace"], alpha=opts["alpha"], nan=opts["nan_policy"],
                              keep_half=not mip_tile)
        bad = io.count_nonfinite(image.pixels) if opts["nan_policy"] == "keep" else 0
        if bad and not quiet:
            click.echo(f"pyramid: warning: {job.input}: {bad} NaN/Inf value(s) kept; they spread through the "
                       "filter (--nan zero or --nan fail to change that)", err=True)
        if opts["verbose"]:
            click.echo(f"pyramid: {io.describe_rules(image.spec)}; backend {runner.name}", err=True)
        return job, image

    def compute(job_image):
        job, image = job_image
        if mip_tile:
            return [io.Image(px, image.spec) for px in work(runner, image.pixels, np.float32)]
        half = image.pixels.dtype == np.float16 and io.stores_half_unchanged(
            job.output, image.spec, pixel_type=opts["pixel_type"])
        return [io.Image(work(runner, image.pixels, np.float16 if half else np.float32), image.spec)]

    def write(job, images):
        out_dir = os.path.dirname(job.output)
        if out_dir and len(jobs) > 1:
            os.makedirs(out_dir, exist_ok=True)
        options = {"pixel_type": opts["pixel_type"], "dither": opts["dither"], "compression": opts["compression"],
                   "force": opts["force"], "inputs": (job.input,)}
        if mip_tile:
            io.write_levels(job.output, images, mode="mipmap", tile=mip_tile, **options)
        else:
            io.write_image(job.output, images[0], **options)
        if not quiet and not show_bar:
            h, w = images[0].pixels.shape[:2]
            levels = f", {len(images)} MIP levels" if mip_tile else ""
            click.echo(f"wrote {job.output} ({w}×{h}{levels}, {runner.name})")

    show_bar = len(jobs) > 1 and not quiet and sys.stderr.isatty()
    run_options = {"keep_going": opts["keep_going"], "skip_existing": opts["skip_existing"], "workers": opts["jobs"],
                   "prepare": prepare if plan_for is not None and runner.on_gl else None}
    try:
        if show_bar:
            with click.progressbar(length=len(jobs), label="pyramid", file=sys.stderr) as bar:
                report = batch.run(jobs, read, compute, write, progress=lambda job: bar.update(1), **run_options)
        else:
            report = batch.run(jobs, read, compute, write, **run_options)
    finally:
        runner.close()
    if len(jobs) == 1 and report.failed:
        raise report.failed[0][1]
    if not quiet and len(jobs) > 1:
        click.echo(f"pyramid: {len(report.done)} written, {len(report.skipped)} up to date, "
                   f"{len(report.failed)} failed", err=True)
    for _job, err in report.failed:
        click.echo(f"pyramid: error: {err}", err=True)
    if report.failed:
        sys.exit(report.exit_code)


@main.command()
@click.argument("expression", type=EXPR)
@click.argument("paths", metavar="INPUT OUTPUT | INPUT... -o TEMPLATE", nargs=-1, required=True)
@click.option("--border", type=click.Choice(["clamp", "mirror", "wrap", "zero"]), default="clamp",
              show_default=True, help="How pixels outside the image are read (non-clamp borders run on the CPU).")
@io_options
@batch_options
def apply(expression, paths, border: str, **opts) -> None:
    """Apply EXPRESSION to INPUT and write OUTPUT (format from its extension).

    \b
    Example:
      pyramid apply 'box4 *v g' render.exr render_half.exr
      pyramid apply --backend cpu 'h_Doo-Sabin ⊗↑ g' small.png big.png
      pyramid apply 'quadratic *v g' 'frames/*.exr' -o 'half/{stem}.exr'
    """
    from .plan import plan

    _process(paths, lambda runner, px, dtype: runner.run_expr(expression, px, border, dtype), opts,
             plan_for=(lambda shape: plan(expression, shape[:2])) if border == "clamp" else None)


@main.command()
@click.argument("paths", metavar="INPUT OUTPUT | INPUT... -o TEMPLATE", nargs=-1, required=True)
@click.option("--levels", "-m", type=click.IntRange(1, 16), default=4, show_default=True,
              help="Analysis steps down (and synthesis steps back up).")
@click.option("--analysis", default="box4", show_default=True,
              help="box, box4, quadratic, cubic, or a ⊗↓ expression.")
@click.option("--synthesis", default="doosabin", show_default=True,
              help="nearest, midpoint, doosabin, cubic, fourpoint, or a ⊗↑ expression.")
@click.option("--quasi", is_flag=True, help="Apply the §5.5 quasi-interpolation prefilter at the coarsest level.")
@click.option("--sigma", type=float, help="Blur strength as a Gaussian sigma in input pixels: picks the levels "
              "and blends two neighbouring level counts, so the strength changes continuously.")
@click.option("--allow-mixed-lattice", is_flag=True, help="Do not warn when analysis and synthesis lattices differ.")
@io_options
@batch_options
def blur(paths, levels: int, analysis: str, synthesis: str, quasi: bool, sigma: float | None,
         allow_mixed_lattice: bool, **opts) -> None:
    """Pyramidal blur: LEVELS analysis steps, then synthesis back to the input size.

    Defaults are the paper's Figure 3b: 4×4 box analysis, Doo-Sabin synthesis.

    \b
    Example:
      pyramid blur --levels 5 render.exr soft.exr
      pyramid blur --analysis box --synthesis doosabin photo.png blocky.png
      pyramid blur --levels 4 'in/*.exr' -o 'out/{stem}_blur.exr' --keep-going
    """
    from .pyramids import lattice_mismatch

    warning = None if allow_mixed_lattice else lattice_mismatch(analysis, synthesis)
    if warning and not opts["quiet"]:
        click.echo(f"pyramid: warning: {warning}", err=True)

    if sigma is not None:
        from .pyramids import blur_plan_sigma, sigma_blend

        if quasi:
            raise UsageError("--quasi and --sigma cannot be combined")
        m, t = sigma_blend(sigma, analysis, synthesis)
        if not opts["quiet"]:
            click.echo(f"pyramid: sigma {sigma:g}: {1 - t:.3f} × {m} level(s) + {t:.3f} × {m + 1} "
                       f"(the blend's equivalent kernel has standard deviation {sigma:g} px)", err=True)

        def plan_for(shape):
            return blur_plan_sigma(shape[:2], sigma, analysis, synthesis)[0]

        def work(runner, px, dtype):
            return runner.run_plan(plan_for(px.shape), px, dtype)
    else:
        from .pyramids import blur_plan

        def plan_for(shape):
            return blur_plan(shape[:2], levels, analysis, synthesis, quasi)

        def work(runner, px, dtype):
            return runner.run_blur(px, levels, analysis, synthesis, quasi, dtype)

    _process(paths, work, opts, plan_for=plan_for)


def _level_path(pattern: str, level: int) -> str:
    if "{level}" not in pattern:
        raise UsageError(f"output pattern {pattern!r} needs {{level}}, e.g. out_{{level}}.exr "
                         "(or use --multipart)")
    return pattern.replace("{level}", str(level))


def _read_one(path: str, opts: dict):
    from . import io

    return io.read_image(path, colorspace=opts["colorspace"], alpha=opts["alpha"], nan=opts["nan_policy"])


@main.command()
@click.argument("input_path", metavar="INPUT")
@click.argument("pattern", metavar="OUTPUT_PATTERN")
@click.option("--levels", "-m", type=click.IntRange(1, 16), default=4, show_default=True)
@click.option("--analysis", default="box4", show_default=True, help="box, box4, quadratic, cubic or a ⊗↓ expression.")
@click.option("--laplacian", is_flag=True, help="Write band-pass levels L_k = G_k − expand(G_k+1) and the coarsest "
              "G_m, which `pyramid collapse` sums back to the input.")
@click.option("--synthesis", default="doosabin", show_default=True, help="Expansion used by --laplacian.")
@click.option("--multipart", is_flag=True, help="Write one multi-part EXR (OUTPUT_PATTERN is its path).")
@click.option("--sheet", type=click.Path(dir_okay=False), help="Also draw all levels side by side (Figure 1a).")
@io_options
def levels(input_path, pattern, levels, analysis, laplacian, synthesis, multipart, sheet, **opts) -> None:
    """Write every level of the analysis pyramid (level 0 is the input).

    \b
    Example:
      pyramid levels render.exr 'pyr/render_{level}.exr' --levels 5
      pyramid levels --laplacian --multipart render.exr bands.exr
      pyramid collapse bands.exr rebuilt.exr
    """
    from . import io
    from .pyramids import levels_plan
    from .run import Runner

    image = _read_one(input_path, opts)
    runner = Runner(opts["backend"], opts["precision"])
    try:
        outs = runner.run_outputs(levels_plan(image.pixels.shape[:2], levels, analysis, laplacian, synthesis),
                                  image.pixels)
    finally:
        runner.close()
    stack = outs if laplacian else [image.pixels] + outs
    images = [io.Image(px, image.spec) for px in stack]
    write = {"pixel_type": opts["pixel_type"] or ("float" if laplacian else None), "dither": opts["dither"],
             "compression": opts["compression"], "force": opts["force"], "inputs": (input_path,)}
    if laplacian:
        for im in images:
            im.spec.attributes["pyramid:synthesis"] = synthesis
    if multipart:
        io.write_levels(pattern, images, mode="multipart", **write)
        written = [pattern]
    else:
        written = [_level_path(pattern, k) for k in range(len(images))]
        for path, im in zip(written, images, strict=True):
            io.write_image(path, im, **write)
    if sheet:
        from .demo import sheet as draw

        panel = draw([im.pixels if not laplacian or k == len(images) - 1 else im.pixels + 0.5
                      for k, im in enumerate(images)])
        info = io.ImageInfo(path=sheet, format="png", pixel_type="uint8", channel_names=["R", "G", "B"],
                            alpha_channel=-1, colorspace="srgb", alpha_mode="none")
        io.write_image(sheet, io.Image(panel, info), pixel_type="uint8")
        written.append(sheet)
    if not opts["quiet"]:
        for path in written:
            click.echo(f"wrote {path}")


@main.command()
@click.argument("inputs", nargs=-1, required=True, metavar="BANDS... | BANDS.exr")
@click.argument("output_path", metavar="OUTPUT")
@click.option("--synthesis", default=None, help="Expansion the bands were made with (default: as recorded, "
              "else doosabin).")
@io_options
def collapse(inputs, output_path, synthesis, **opts) -> None:
    """Sum Laplacian bands back to the image: G_k = L_k + expand(G_k+1).

    INPUT is the multi-part EXR of `pyramid levels --laplacian --multipart`, or the
    level files L_0 … L_m-1, G_m in order.

    \b
    Example:
      pyramid collapse bands.exr rebuilt.exr
      pyramid collapse 'pyr/band_*.exr' rebuilt.exr
    """
    from . import batch, io
    from .pyramids import collapse_plan
    from .run import Runner

    paths = batch.expand(list(inputs))
    if len(paths) == 1:
        bands = io.read_parts(paths[0], colorspace=opts["colorspace"], alpha=opts["alpha"], nan=opts["nan_policy"])
    else:
        bands = [_read_one(p, opts) for p in sorted(paths, key=_level_key)]
    if len(bands) < 2:
        raise UsageError(f"collapse needs at least two levels, {paths[0]} holds {len(bands)}")
    synthesis = synthesis or bands[0].spec.attributes.get("pyramid:synthesis", "doosabin")
    sizes = [b.pixels.shape[:2] for b in bands]
    runner = Runner(opts["backend"], opts["precision"])
    try:
        (out,) = runner.run_outputs(collapse_plan(tuple(sizes), synthesis), [b.pixels for b in bands])
    finally:
        runner.close()
    io.write_image(output_path, io.Image(out, bands[0].spec), pixel_type=opts["pixel_type"], dither=opts["dither"],
                   compression=opts["compression"], force=opts["force"], inputs=paths)
    if not opts["quiet"]:
        click.echo(f"wrote {output_path} ({sizes[0][1]}×{sizes[0][0]}, {runner.name})")


def _level_key(path: str):
    import re

    digits = re.findall(r"\d+", os.path.basename(path))
    return (int(digits[-1]) if digits else 0, path)


@main.command()
@click.argument("paths", metavar="INPUT OUTPUT | INPUT... -o TEMPLATE", nargs=-1, required=True)
@click.option("--analysis", default="quadratic", show_default=True,
              help="box, box4, quadratic, cubic or a ⊗↓ expression.")
@click.option("--tile", type=click.IntRange(8, 4096), default=64, show_default=True, help="Tile size.")
@io_options
@batch_options
def mipmap(paths, analysis, tile, **opts) -> None:
    """Write a tiled MIP-mapped OpenEXR down to 1×1 (what maketx makes, with better filters).

    Level sizes are ⌈n/2⌉ (OpenEXR's round-up mode), as ⊗↓ gives. OpenImageIO 3.2
    cannot write MIP-mapped TIFF; a .tif output exits 4 saying so.

    \b
    Example:
      pyramid mipmap albedo.exr albedo.tx.exr
      pyramid mipmap --analysis cubic 'tex/*.png' -o 'tx/{stem}.tx.exr'
    """
    from .pyramids import levels_plan, mip_levels

    def plan_for(shape):
        m = mip_levels(shape[:2])
        return levels_plan(shape[:2], m, analysis) if m else None

    def work(runner, px, dtype):
        p = plan_for(px.shape)
        return [px] + (runner.run_outputs(p, px, dtype) if p else [])

    _process(paths, work, opts, mip_tile=tile, plan_for=plan_for)


def _register() -> None:
    from .diff_cli import diff

    main.add_command(diff)


_register()


def run() -> None:  # console-script entry point
    from .signals import install
    install()  # SIGTERM/SIGHUP clean up like Ctrl-C (exit 143/129); SIGXFSZ ignored
    main(prog_name="pyramid")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(run())
