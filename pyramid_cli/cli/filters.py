"""The filter commands: ``apply`` an expression, ``blur``, write a pyramid's ``levels`` and ``collapse``
Laplacian bands back."""

from __future__ import annotations

import click

from pyramid_cli.cli.params import (
    EXPR,
    batch_options,
    border_option,
    choice,
    io_options,
    memory_option,
    mixed_lattice_option,
)
from pyramid_cli.cli.running import make_reporter, open_session, read_write, run_paths
from pyramid_cli.core import catalogue
from pyramid_cli.core.options import BORDERS, MAX_LEVELS


@click.command()
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
      pyramid apply --colorconfig studio.ocio '[1] * g' shot_log.exr same.exr   # keeps pixels and label
    """
    from pyramid_cli.jobs.work import Filter

    run_paths(paths, Filter(expr=expression, border=border), opts)


@click.command()
@click.argument("paths", metavar="INPUT OUTPUT | INPUT... -o TEMPLATE", nargs=-1, required=True)
@click.option("--levels", "-m", type=click.IntRange(1, MAX_LEVELS), default=4, show_default=True,
              help="Analysis steps down (and synthesis steps back up).")
@click.option("--analysis", default=catalogue.DEFAULT_ANALYSIS, show_default=True,
              help=f"{', '.join(catalogue.ANALYSIS_FILTERS)}, or a ⊗↓ expression.")
@click.option("--synthesis", default=catalogue.DEFAULT_SYNTHESIS, show_default=True,
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
      pyramid blur -v --levels 3 plate_acescg.exr preview.png     # ACEScg → sRGB Rec.709 PNG, via OCIO
    """
    from pyramid_cli.jobs.work import blur_work

    work = blur_work(levels, sigma=sigma, analysis=analysis, synthesis=synthesis, quasi=quasi, border=border,
                     allow_mixed_lattice=allow_mixed_lattice)  # refuses --quasi with --sigma, a bad sigma
    run_paths(paths, work, opts)


@click.command()
@click.argument("input_path", metavar="INPUT")
@click.argument("pattern", metavar="OUTPUT_PATTERN")
@click.option("--levels", "-m", type=click.IntRange(1, MAX_LEVELS), default=4, show_default=True)
@click.option("--analysis", default=catalogue.DEFAULT_ANALYSIS, show_default=True,
              help=f"{', '.join(catalogue.ANALYSIS_FILTERS)} or a ⊗↓ expression.")
@click.option("--laplacian", is_flag=True, help="Write band-pass levels L_k = G_k − expand(G_k+1) and the coarsest "
              "G_m, which `pyramid collapse` sums back to the input.")
@click.option("--synthesis", default=catalogue.DEFAULT_SYNTHESIS, show_default=True,
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
    reporter = make_reporter(opts)
    ro, wo = read_write(opts)
    memory = None
    if opts.get("memory") is not None:
        from pyramid_cli.run.stream import parse_size

        memory = parse_size(opts["memory"])
    with open_session(opts, reporter) as session:
        write_levels_files(input_path, pattern, work, session, read=ro, write=wo, reporter=reporter,
                           multipart=multipart, sheet=sheet, memory=memory)


@click.command()
@click.argument("inputs", nargs=-1, required=True, metavar="BANDS... | BANDS.exr")
@click.argument("output_path", metavar="OUTPUT")
@click.option("--synthesis", default=None, help="Expansion the bands were made with (default: as recorded, "
              f"else {catalogue.DEFAULT_SYNTHESIS}).")
@click.option("--border", type=choice(BORDERS), default=None,
              help="The border the bands were made with (default: as recorded, else clamp).")
@io_options
@memory_option
def collapse(inputs, output_path, synthesis, border, **opts) -> None:
    """Sum Laplacian bands back to the image: G_k = L_k + expand(G_k+1).

    INPUT is the multi-part EXR of `pyramid levels --laplacian --multipart`, or the
    level files L_0 … L_m-1, G_m in order. Use the --border the bands were made with.
    Level files are read and the output written band by band from a megapixel on the CPU
    executor, or when the whole run would not fit --memory (the same bytes; -v says which);
    a multi-part EXR is read whole.

    \b
    Example:
      pyramid collapse bands.exr rebuilt.exr
      pyramid collapse 'pyr/band_*.exr' rebuilt.exr
      pyramid collapse --memory 512M -v 'pyr/band_*.exr' rebuilt_32k.exr
    """
    from pyramid_cli.run.pipeline import collapse_files
    from pyramid_cli.run.stream import parse_size

    reporter = make_reporter(opts)
    ro, wo = read_write(opts)
    memory = parse_size(opts["memory"]) if opts.get("memory") is not None else None
    with open_session(opts, reporter) as session:
        collapse_files(list(inputs), output_path, session, synthesis=synthesis, border=border, read=ro, write=wo,
                       reporter=reporter, memory=memory)


__all__ = ['apply', 'blur', 'levels', 'collapse']
