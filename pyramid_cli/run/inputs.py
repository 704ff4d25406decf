"""Reading one input image as the read settings say, and warning of the NaN/Inf it keeps."""

from __future__ import annotations

from pyramid_cli import imageio as io
from pyramid_cli.run.report import Reporter, nonfinite_kept
from pyramid_cli.run.settings import ReadOptions


def read_input(path: str, read: ReadOptions, reporter: Reporter, keep_half: bool = False,
               hash_source: bool = False) -> io.Image:
    """``path`` decoded by ``read`` (:func:`pyramid_cli.imageio.read_image`); NaN/Inf kept in float pixels are
    counted and warned about (:func:`~pyramid_cli.run.report.nonfinite_kept`).

    ``keep_half`` keeps half pixels as half; ``hash_source`` hashes the stored pixels as they are read
    (a MIP map's ``oiio:SHA-1``).
    """
    image = io.read_image(path, colorspace=read.colorspace, alpha=read.alpha, nan=read.nan, keep_half=keep_half,
                          hash_source=hash_source, colorconfig=read.colorconfig)
    if image.nonfinite:  # counted as read (decoded integer codes are finite, and are not scanned)
        reporter.warn(nonfinite_kept(path, image.nonfinite))
    return image


__all__ = ["read_input"]
