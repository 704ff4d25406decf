"""``pyramid mipmap``: a tiled MIP-mapped texture, as maketx writes it."""

from __future__ import annotations

import click

from pyramid_cli.cli.params import batch_options, border_option, io_options, memory_option
from pyramid_cli.cli.running import run_paths
from pyramid_cli.core import catalogue
from pyramid_cli.core.errors import UsageError


@click.command()
@click.argument("paths", metavar="INPUT OUTPUT | INPUT... -o TEMPLATE", nargs=-1, required=True)
@click.option("--analysis", default=catalogue.MIP_ANALYSIS_DEFAULT, show_default=True,
              help=f"{', '.join(catalogue.ANALYSIS_FILTERS)} or a ⊗↓ expression.")
@click.option("--tile", type=click.IntRange(8, 4096), default=64, show_default=True,
              help="Tile size (TIFF/.tx tiles must be a multiple of 16).")
@click.option("--wrap", metavar="MODE[,MODE]",
              help="maketx's wrap modes, black|clamp|periodic|mirror (s,t): how lookups read past the edges "
                   "(the file's wrapmodes). Levels build periodically or mirrored under periodic and mirror, "
                   "inside the domain (mirrored) under clamp and black. Sets --border (black=zero, periodic=wrap).")
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
                   "so every level covers the whole texture domain and keeps the mean (under every --wrap). "
                   "up: ⌈n/2⌉, the analysis pyramid's levels (an odd size is padded by the "
                   "border, so coarse levels cover a little more than the image and lookups drift toward the "
                   "top left).")
@click.option("--resize", is_flag=True, help="maketx's --resize: level 0 resampled up to the next power of two "
              "on each axis first (as a bilinear lookup of the source reads it), then the levels from it.")
@click.option("--nchannels", type=click.IntRange(1, 64), metavar="N", help="maketx's --nchannels: keep the first N "
              "channels, or append channels of zeros up to N.")
@click.option("--monochrome-detect", "monochrome_detect", is_flag=True, help="maketx's flag: an RGB image (no "
              "alpha) whose three channels are equal at every pixel becomes a one-channel (Y) texture.")
@click.option("--colorconvert", nargs=2, metavar="IN OUT", help="maketx's --colorconvert: the source is in colour "
              "space IN, the texture in OUT (names of the colour config, --colorconfig or $OCIO); filtering stays "
              "in linear light. Recorded in the SHA-1's appended text and Exif:ImageHistory, as maketx does.")
@border_option
@io_options
@batch_options
@memory_option
@click.pass_context
def mipmap(ctx: click.Context, paths, analysis, tile, wrap, swrap, twrap, constant_detect, fill_holes, rounding,
           resize, nchannels, monochrome_detect, colorconvert, border, **opts) -> None:
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
    covers the whole texture domain and keeps level 0's mean under every wrap mode (clamp
    and black build inside the domain; see `pyramid plan --mipmap`); --round up keeps the
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
      pyramid mipmap --colorconvert sRGB ACEScg albedo.png albedo.tx.exr   # maketx's spelling, through OCIO
    """
    from pyramid_cli.jobs.texture import TextureLevels
    from pyramid_cli.workflows.mip import border_for_wrap, parse_wrap

    modes = parse_wrap(wrap, swrap, twrap)
    if modes is not None:
        wanted = border_for_wrap(*modes)
        explicit = ctx.get_parameter_source("border") is click.core.ParameterSource.COMMANDLINE
        if explicit and border != wanted:
            raise UsageError(f"--border {border} contradicts --wrap {','.join(modes)} (which reads as --border "
                             f"{wanted}); give one of them")
        border = wanted
    if colorconvert:
        if opts["colorspace"] != "auto" or opts["tocolorspace"] is not None:
            raise UsageError("--colorconvert IN OUT names both spaces: give it or --colorspace/--tocolorspace")
        opts["colorspace"], opts["tocolorspace"] = colorconvert
    work = TextureLevels(levels=None, analysis=analysis, border=border, constant_detect=constant_detect,
                         rounding=rounding, resize=resize, nchannels=nchannels, monochrome_detect=monochrome_detect,
                         fill=fill_holes, colorconvert=tuple(colorconvert) if colorconvert else None)
    run_paths(paths, work, opts, mip_tile=tile)  # refuses a TIFF tile that is not a multiple of 16


__all__ = ['mipmap']
