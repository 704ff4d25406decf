"""``pyramid tiles``: a pyramid for viewers (Deep Zoom, IIIF, OME-Zarr, pyramidal TIFF), streamed."""

from __future__ import annotations

import json
import sys

import click

from pyramid_cli.cli.params import batch_options_of, border_option, choice, io_options, memory_option
from pyramid_cli.cli.running import cluster_spec, drop, make_reporter, open_session, read_write
from pyramid_cli.core import catalogue
from pyramid_cli.core.errors import UsageError

# the layouts of pyramid_cli.imageio.tilesets.LAYOUTS (not imported here: it loads OpenImageIO)
LAYOUT_NAMES = ("dz", "iiif3", "iiif", "ome-zarr", "tiff", "ome-tiff")
FORMAT_NAMES = ("jpeg", "jpg", "png", "webp", "tif", "tiff")


@click.command()
@click.argument("paths", metavar="INPUT OUTPUT | INPUT... -o TEMPLATE", nargs=-1, required=True)
@click.option("--layout", type=choice(LAYOUT_NAMES), help="dz: Deep Zoom (name.dzi and name_files/); iiif3, iiif: "
              "a static IIIF Image API 3 or 2 level-0 folder with info.json; ome-zarr: OME-NGFF multiscales; tiff: "
              "a tiled pyramidal TIFF; ome-tiff: an OME-TIFF with SubIFDs. Default: from OUTPUT's name (.dzi, .zarr, "
              ".ome.zarr, .tif, .ome.tif).")
@click.option("--analysis", default=catalogue.MIP_ANALYSIS_DEFAULT, show_default=True,
              help=f"The filter each level is reduced with: {', '.join(catalogue.ANALYSIS_FILTERS)} or a ⊗↓ "
                   "expression (one step).")
@click.option("--tile-size", type=click.IntRange(1, 1 << 16), metavar="N",
              help="Tile (or chunk) edge in pixels (default: the layout's; Deep Zoom 254, as vips dzsave).")
@click.option("--overlap", type=click.IntRange(0, 1 << 15), metavar="N",
              help="Pixels each tile shares with its neighbours (Deep Zoom; default 1, as vips dzsave).")
@click.option("--format", "--suffix", "tile_format", type=choice(FORMAT_NAMES),
              help="Tile files of dz, iiif3 and iiif (default: jpeg as vips dzsave, png when the input has alpha; "
                   "jpeg with alpha is refused).")
@click.option("--quality", type=click.IntRange(1, 100), metavar="Q", help="JPEG/WebP quality (default: the "
              "layout's, 75 as vips dzsave).")
@click.option("--id", "iiif_id", metavar="URL",
              help="The IIIF layouts' base address (vips dzsave's --id): info.json's id is URL/NAME, where the "
                   "folder NAME is served; viewers build tile URLs from it (default https://example.com/iiif).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object per tile set (a list for -o batches): "
              "its layout, path, tile size, overlap, format, every level's size, reduction, scale and rule, and the "
              "input, backend, analysis, border, band and seconds.")
@border_option
@io_options
@batch_options_of(jobs=False, cluster=False)
@click.option("--cluster", metavar="ADDRESS", help="Write the tiles (or Zarr chunks) of each picture in parallel on a "
              "Dask cluster, rows of tiles per task, byte for byte what one process writes: a scheduler address "
              "(tcp://HOST:8786, HOST:PORT, tls://, ...), a scheduler file, or local:N for N worker processes here. "
              "The workers read the input and write the tiles on storage they share with this machine. Not for TIFF "
              "(one file written in order) (needs pip install 'bilinear-pyramid[cluster]').")
@click.option("--chunk", type=click.IntRange(1), metavar="N", help="Rows of level-0 tiles per cluster task, rounded up "
              "to a power of two (default: about two tasks per worker).")
@click.option("--cluster-timeout", type=click.FloatRange(0, min_open=True), metavar="SECONDS",
              help="How long --cluster waits to connect (or for its scheduler file), and with no worker connected "
                   "(default 30).")
@memory_option
def tiles(paths, layout, analysis, tile_size, overlap, tile_format, quality, iiif_id, as_json, border, cluster, chunk,
          cluster_timeout, **opts) -> None:
    """Write a tiled pyramid for viewers: Deep Zoom, IIIF, OME-Zarr or pyramidal TIFF.

    Level 0 is the input; every level below is ⌈n/2⌉ of the one above, reduced with the
    --analysis filter in linear light on premultiplied alpha, exact at every border and odd
    size (Kraus & Strengert §4): no 2×2 mean of stored 8-bit codes, so coarse levels neither
    alias nor darken. The tiles keep the input's type and colour space where their format can.
    The levels are made band by band and each tile written when its rows are complete: memory
    stays flat whatever the picture's size (-v says the band and the budget). The tile set is
    built beside OUTPUT and moved into place at the end, descriptor last: an interrupted or
    failed run leaves the previous OUTPUT as it was.

    \b
    Example:
      pyramid tiles scan.tif scan.dzi                      # Deep Zoom as vips dzsave lays it out
      pyramid tiles --layout iiif3 --id https://img.example.org/iiif scan.tif iiif/scan   # static IIIF 3
      pyramid tiles --tile-size 512 slide.tif slide.ome.zarr
      pyramid tiles --analysis quadratic --format png map.png map.dzi
      pyramid tiles --memory 1G -v --json huge_32k.tif huge.dzi
      pyramid tiles 'scans/*.tif' -o 'dz/{stem}.dzi' --shard auto
      pyramid tiles --cluster tcp://scheduler:8786 slide.tif slide.dzi     # the tiles written on Dask workers
    """
    from pyramid_cli.imageio.tilesets import TileOptions
    from pyramid_cli.run.stream import parse_size
    from pyramid_cli.run.tiles import TileSettings

    reporter = make_reporter(opts)
    if as_json:  # the JSON is the result; warnings and -v still go to stderr
        reporter.out = drop
    ro, wo = read_write(opts)
    write: dict = {"pixel_type": wo.pixel_type, "dither": wo.dither}
    if wo.tocolorspace is not None:
        write["colorspace"] = wo.tocolorspace
    settings = TileSettings(layout, analysis, border, TileOptions(tile_size, overlap, tile_format, quality,
                                                                  wo.compression, write, iiif_id))
    memory = parse_size(opts["memory"]) if opts.get("memory") is not None else None
    if cluster is None and (chunk is not None or cluster_timeout is not None):
        raise UsageError("--chunk and --cluster-timeout are for --cluster runs")
    if cluster is not None:
        from pyramid_cli.run.tiles import tile_files

        if memory is not None:
            raise UsageError("--memory is not for --cluster runs: each worker streams its rows of tiles in bands "
                             "of its own")
        report, described = tile_files(
            list(paths), opts["template"], settings, cluster_spec(opts),
            read=ro, reporter=reporter, force=wo.force, keep_going=opts["keep_going"],
            skip_existing=opts["skip_existing"], frames=opts["frames"], shard=opts["shard"], cluster=cluster,
            chunk=chunk, cluster_timeout=cluster_timeout)
    else:
        report, described = _local(paths, settings, opts, reporter, ro, memory, wo.force)
    if as_json:
        batch = opts["template"] is not None
        click.echo(json.dumps(described if batch else described[0], ensure_ascii=False) if described else "[]")
    if report.failed:
        sys.exit(report.exit_code)


def _local(paths, settings, opts: dict, reporter, ro, memory, force: bool):
    """The tile sets written in this process."""
    from pyramid_cli.run.tiles import tile_files

    with open_session(opts, reporter) as session:
        report, described = tile_files(list(paths), opts["template"], settings, session, read=ro, reporter=reporter,
                                       memory=memory, force=force, keep_going=opts["keep_going"],
                                       skip_existing=opts["skip_existing"], frames=opts["frames"],
                                       shard=opts["shard"])
    return report, described


__all__ = ["tiles", "LAYOUT_NAMES"]
