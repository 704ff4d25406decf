"""The option groups the commands share, and the parameter types they parse: one definition each, so every
command spells ``--backend``, ``--border``, ``-o TEMPLATE`` or ``--memory`` alike."""

from __future__ import annotations

import click

from pyramid_cli.core.errors import ExpressionError


def choice(values) -> click.Choice:
    """A click choice of ``values`` (a tuple from :mod:`pyramid_cli.core.options`)."""
    return click.Choice(list(values))


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


def io_options(f):
    """Options every command that reads and writes images shares."""
    from pyramid_cli.core.options import (
        ALPHA_MODES,
        BACKEND_HELP,
        BACKENDS,
        NAN_POLICIES,
        PIXEL_TYPES,
        PRECISIONS,
    )

    options = [
        click.option("--backend", type=choice(BACKENDS), default="auto", show_default=True,
                     help="; ".join(f"{name}: {BACKEND_HELP[name]}" for name in BACKENDS) + " (-v says which ran)."),
        click.option("--threads", type=click.IntRange(1, 1024), default=None, metavar="N",
                     help="CPU executor threads (default: the cores this process may use: its affinity, within its "
                          "container's CPU quota)."),
        click.option("--precision", type=choice(PRECISIONS), default="float", show_default=True,
                     help="GL intermediate textures: RGBA32F, or RGBA16F (faster, ~1e-3 relative, max 65504). "
                          "Half files travel as half either way (upload, read-back), losing nothing."),
        click.option("--type", "pixel_type", type=choice(PIXEL_TYPES),
                     help="Output pixel type (default: the input's, as the output format allows)."),
        click.option("--colorspace", metavar="NAME", default="auto", show_default=True,
                     help="The input's colour space: any space, alias or role of the colour config (linear, srgb, "
                          "ACEScg, ACEScct, g22_rec709, data, ...); auto reads oiio:ColorSpace, then the config's "
                          "file rules, then the type (integers sRGB, floats linear). Filtering is in linear light."),
        click.option("--tocolorspace", metavar="NAME", help="The output's colour space (default: the input's when "
                     "the output format holds it, else what it conventionally holds: sRGB for 8/16-bit PNG/JPEG)."),
        click.option("--colorconfig", metavar="FILE", help="OpenColorIO config (default: $OCIO, else OpenImageIO's "
                     "built-in ACES config)."),
        click.option("--alpha", type=choice(ALPHA_MODES), default="auto",
                     show_default=True, help="How the input stores alpha (RGBA is filtered premultiplied)."),
        click.option("--nan", "nan_policy", type=choice(NAN_POLICIES), default="keep",
                     show_default=True, help="What to do with NaN/Inf pixels in float input."),
        click.option("--dither", is_flag=True, help="Dither 8-bit output."),
        click.option("--compression", metavar="C", help="Output compression: EXR none|zip|zips|piz|dwaa|... "
                     "(default: the input's), PNG zlib level 0-9 (default 6), with :none for rows unfiltered as "
                     "libvips writes them (6:none: a quarter of the time, twice the bytes) or :sub+up… for libpng's "
                     "filters."),
        click.option("--force", is_flag=True, help="Allow OUTPUT to overwrite INPUT."),
        click.option("-v", "--verbose", is_flag=True, help="Say which executor runs and why, and the colour and "
                     "alpha rules in force for each image."),
        click.option("-q", "--quiet", is_flag=True, help="Print nothing but errors."),
    ]
    for option in reversed(options):
        f = option(f)
    return f


def border_option(f):
    """--border: how written operators read past their input's edges."""
    from pyramid_cli.core.options import BORDERS

    return click.option("--border", type=choice(BORDERS), default="clamp", show_default=True,
                        help="How every written operator reads past its input's edges: clamp (repeat the edge), "
                             "mirror (… 2 1 | 1 2 …), wrap (periodic), zero. Runs on every backend.")(f)


def batch_options(f):
    """Many inputs in one process: an output template, failure and freshness policies, I/O overlap."""
    return batch_options_of()(f)


def batch_options_of(jobs: bool = True, cluster: bool = True):
    """:func:`batch_options` as a decorator, without ``-j/--jobs`` or the --cluster options when a command has no
    use for them (``pyramid tiles`` streams one input at a time)."""
    options = [
        click.option("-o", "--output", "template", metavar="TEMPLATE",
                     help="Output path template: {stem} {name} {ext} (with its dot, e.g. '.exr') {dir} of each "
                          "input, and for sequences {frame} ({frame:05d}) or one frame token (####, %04d, @, $F4, "
                          "<UDIM>), in any combination: 'out/{stem}_blur_{frame:05d}{ext}'. Without fields or a "
                          "token it is a path as it is. Output folders are created."),
        click.option("--keep-going", is_flag=True, help="Go on past a bad file; report failures at the end."),
        click.option("--skip-existing", is_flag=True, help="Skip inputs whose output is newer (like make)."),
        *([click.option("-j", "--jobs", type=click.IntRange(1, 64), default=2, show_default=True,
                        help="Threads decoding/encoding images while the executor works on another.")] if jobs else []),
        *sequence_options(cluster),
    ]

    def decorate(f):
        for option in reversed(options):
            f = option(f)
        return f

    return decorate


def sequence_options(cluster: bool = True) -> list:
    """--frames, --shard, --cluster, --chunk, --cluster-timeout (frame sequences, array jobs, a Dask cluster);
    without ``cluster`` the first two."""
    options = [
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
    ]
    if not cluster:
        return options
    return options + [
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


def memory_option(f):
    """--memory: the working-set budget of a run on this machine (pyramid_cli.run.stream, pyramid_cli.run.local)."""
    return click.option("--memory", metavar="SIZE", default=None,
                        help="Working-set budget, e.g. 512M or 2G (default: the smallest that the container's memory "
                             "limit, the rlimits and a quarter of the available memory allow). "
                             "A picture whose whole run would not fit streams from file to file in bands of rows "
                             "chosen from it; in a batch, one too large to be held beside the others runs alone. "
                             "-v says which. Work that cannot fit is refused before it starts.")(f)


def mixed_lattice_option(f):
    """--allow-mixed-lattice: no warning for an analysis and synthesis on two lattices."""
    return click.option("--allow-mixed-lattice", is_flag=True,
                        help="Do not warn when the analysis and synthesis filters sit on different lattices (the "
                             "result shifts by half a fine pixel per level; `pyramid explain` shows a filter's "
                             "lattice).")(f)


__all__ = ["choice", "ExpressionType", "EXPR", "io_options", "border_option", "batch_options", "batch_options_of",
           "sequence_options", "memory_option", "mixed_lattice_option"]
