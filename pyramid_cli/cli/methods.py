"""The methods built on pyramids: ``fill`` holes by pull-push and ``blend`` two images along a mask."""

from __future__ import annotations

import json

import click

from pyramid_cli.cli.params import border_option, choice, io_options, memory_option, mixed_lattice_option
from pyramid_cli.cli.running import drop, make_reporter, open_session, read_write
from pyramid_cli.core import catalogue
from pyramid_cli.core.options import MAX_LEVELS, MAX_SWEEPS, MAX_WEIGHT_SCALE


def _pair(values: tuple[int, int]) -> str:
    return ",".join(str(v) for v in values)


class LevelPair(click.ParamType):
    """One integer (every level) or two, ``N,M`` (level 1, the coarser levels), each from ``lo`` to ``hi``."""

    name = "N[,M]"

    def __init__(self, lo: int, hi: int):
        self.lo, self.hi = lo, hi

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            v = tuple(int(x) for x in str(value).split(","))
        except ValueError:
            v = ()
        if len(v) not in (1, 2) or not all(self.lo <= x <= self.hi for x in v):
            self.fail(f"{value!r} is not one or two integers N,M from {self.lo} to {self.hi}", param, ctx)
        return v * 2 if len(v) == 1 else v


@click.command()
@click.argument("input_path", metavar="INPUT")
@click.argument("output_path", metavar="OUTPUT")
@click.option("--mask", type=click.Path(dir_okay=False), help="Weight image: 1 known, 0 a hole, between partly "
              "known (one channel, one per channel, else its alpha channel; stored values, no sRGB decoding; NaN/Inf "
              "kept with a warning as in an image, values outside 0 … 1 clipped with one). Implies --holes mask.")
@click.option("--holes", type=choice(["alpha", "mask", "nan"]), default=None,
              help="Where the weights come from: the alpha channel (default without --mask), --mask, or every "
                   "pixel with a NaN/Inf is a hole.")
@click.option("--levels", "-m", type=click.IntRange(0, MAX_LEVELS), default=None,
              help="Pull steps (default: down to 1×1, so every hole is filled).")
@click.option("--analysis", default=catalogue.FILL_ANALYSIS, show_default=True,
              help=f"The pull's filter: {', '.join(catalogue.ANALYSIS_FILTERS)}, or a ⊗↓ expression.")
@click.option("--synthesis", default=catalogue.FILL_SYNTHESIS, show_default=True,
              help=f"The push's filter: {', '.join(catalogue.SYNTHESIS_FILTERS)}, or a ⊗↑ expression.")
@click.option("--weight-scale", type=LevelPair(1, MAX_WEIGHT_SCALE), default=_pair(catalogue.FILL_SCALE),
              show_default=True, help="K: a coarse pixel's weight is K × its filtered weight, clamped to 1; at level 1 "
              "and at the coarser levels (one number: every level; Gortler's classic: 4).")
@click.option("--sweeps", type=LevelPair(0, MAX_SWEEPS), default=_pair(catalogue.FILL_SWEEPS), show_default=True,
              help="Membrane smoothing sweeps in the push at level 1 and at the coarser levels (0: the classic "
                   "pull-push). The classic fill, the former default: --analysis box4 --weight-scale 4 --sweeps 0.")
@click.option("--keep-alpha", is_flag=True, help="Keep the input's alpha and store the filled colours beside it "
              "unassociated (straight), instead of an opaque image: a PNG keeps its cut-out with colour under it.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (pixels filled, levels, executor).")
@mixed_lattice_option
@border_option
@io_options
@memory_option
def fill(input_path, output_path, mask, holes, levels, analysis, synthesis, weight_scale, sweeps, keep_alpha, as_json,
         allow_mixed_lattice, border, **opts) -> None:
    """Fill holes from the pixels around them by pull-push (Kraus, GRAPP 2009).

    The known pixels are pulled down the analysis pyramid as premultiplied colours with
    their weights, then every level is composited over the expanded coarser one and, at the
    coarse levels, smoothed by membrane sweeps: holes of any size get a smooth fill, pixels
    of full weight stay bit for bit. The output is
    opaque (alpha 1, as oiiotool --fillholes writes it) unless --keep-alpha. An image
    without a known pixel is bad pixel data (exit 5). Filters
    on two lattices fill from beside the holes and are warned about.

    With --levels whose coarsest level keeps 16 rows, the image (and mask) are read and the
    output written band by band from a megapixel on the CPU executor, or when the whole run
    would not fit --memory (the same bytes; -v says which). A fill down to 1×1 (the default)
    needs every row before its first: it runs whole, and --memory with it is refused.

    \b
    Example:
      pyramid fill bake.png bake_padded.png                 # holes where alpha < 1
      pyramid fill --mask valid.png plate.exr patched.exr    # holes where the mask is 0
      pyramid fill --holes nan depth.exr depth_filled.exr    # holes at NaN/Inf pixels
      pyramid fill --analysis box --json in.exr out.exr
      pyramid fill --analysis box4 --weight-scale 4 --sweeps 0 in.exr out.exr   # the classic fill
      pyramid fill --keep-alpha decal.png decal_dilated.png    # colour under the cut-out
      pyramid fill --levels 6 --memory 512M -v render_16k.exr render_filled.exr
    """
    from pyramid_cli.run.methods_files import fill_file
    from pyramid_cli.run.stream import parse_size

    reporter = make_reporter(opts)
    if as_json:  # the JSON object is the result; warnings still go to stderr
        reporter.out = drop
    ro, wo = read_write(opts)
    memory = parse_size(opts["memory"]) if opts.get("memory") is not None else None
    with open_session(opts, reporter) as session:
        info = fill_file(input_path, output_path, session, mask=mask, holes=holes, levels=levels, analysis=analysis,
                         synthesis=synthesis, weight_scale=weight_scale, sweeps=sweeps, keep_alpha=keep_alpha,
                         border=border, allow_mixed_lattice=allow_mixed_lattice, read=ro, write=wo, reporter=reporter,
                         memory=memory)
    if as_json:
        click.echo(json.dumps(info, ensure_ascii=False))


@click.command()
@click.argument("a_path", metavar="A")
@click.argument("b_path", metavar="B")
@click.argument("mask_path", metavar="MASK")
@click.argument("output_path", metavar="OUTPUT")
@click.option("--levels", "-m", type=click.IntRange(0, MAX_LEVELS), default=None,
              help="Laplacian levels (default: as many as the size allows while the coarsest level keeps 16 "
                   "pixels on its shorter side: 4 at 256×256, 7 at 3840×2160).")
@click.option("--analysis", default=catalogue.DEFAULT_ANALYSIS, show_default=True,
              help=f"{', '.join(catalogue.ANALYSIS_FILTERS)}, or a ⊗↓ expression.")
@click.option("--synthesis", default=catalogue.DEFAULT_SYNTHESIS, show_default=True,
              help=f"{', '.join(catalogue.SYNTHESIS_FILTERS)}, or a ⊗↑ expression.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (size, levels, executor).")
@mixed_lattice_option
@border_option
@io_options
@memory_option
def blend(a_path, b_path, mask_path, output_path, levels, analysis, synthesis, as_json, allow_mixed_lattice, border,
          **opts) -> None:
    """Join A and B along MASK without a seam (Burt & Adelson's multiresolution spline, 1983).

    Each Laplacian band of A and B is blended with the same level of the mask's analysis
    pyramid, and the bands are collapsed: fine detail meets over a narrow seam, coarse
    shading over a wide one. MASK is 1 where A shows and 0 where B shows: one channel,
    one per channel, else its alpha channel; stored values, no sRGB decoding; NaN/Inf
    kept with a warning (as in an image; --nan), values outside 0 … 1 clipped with one. A, B and MASK have
    one size. Filters on two lattices move the seam and are warned about.

    From a megapixel on the CPU executor, or when the whole run would not fit --memory, the three
    inputs are read and the output written band by band (the same bytes; -v says which).

    \b
    Example:
      pyramid blend apple.png orange.png left_half.png orapple.png
      pyramid blend --levels 5 plate.exr patch.exr matte.exr comp.exr
      pyramid blend --analysis cubic --synthesis cubic --json a.exr b.exr m.png out.exr
      pyramid blend --memory 512M -v plate_16k.exr patch_16k.exr matte_16k.exr comp_16k.exr
    """
    from pyramid_cli.run.methods_files import blend_files
    from pyramid_cli.run.stream import parse_size

    reporter = make_reporter(opts)
    if as_json:  # the JSON object is the result; warnings still go to stderr
        reporter.out = drop
    ro, wo = read_write(opts)
    memory = parse_size(opts["memory"]) if opts.get("memory") is not None else None
    with open_session(opts, reporter) as session:
        info = blend_files(a_path, b_path, mask_path, output_path, session, levels=levels, analysis=analysis,
                           synthesis=synthesis, border=border, allow_mixed_lattice=allow_mixed_lattice, read=ro,
                           write=wo, reporter=reporter, memory=memory)
    if as_json:
        click.echo(json.dumps(info, ensure_ascii=False))


__all__ = ['fill', 'blend']
