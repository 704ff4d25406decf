"""How a run decodes its inputs and encodes its outputs: the read and write settings of every command.

These are the command line's ``--colorspace --alpha --nan --colorconfig`` and ``--type --dither --compression
--force --tocolorspace`` as values (:mod:`pyramid_cli.core.options` holds what each may be); the runners in
:mod:`pyramid_cli.run` hand them to :func:`pyramid_cli.imageio.read_image` and
:func:`pyramid_cli.imageio.write_image`.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class ReadOptions:
    """How inputs are decoded (see :func:`pyramid_cli.imageio.read_image`)."""

    colorspace: str = "auto"
    alpha: str = "auto"
    nan: str = "keep"
    colorconfig: str | None = None  # an OpenColorIO config file; None: $OCIO, else OpenImageIO's built-in one


@dataclass
class WriteOptions:
    """How outputs are encoded (see :func:`pyramid_cli.imageio.write_image`)."""

    pixel_type: str | None = None
    dither: bool = False
    compression: str | None = None
    force: bool = False
    tocolorspace: str | None = None  # the outputs' colour space; None: the input's, as the format holds it

    def for_inputs(self, inputs) -> dict:
        """The keyword arguments of :func:`pyramid_cli.imageio.write_image` for an output made from ``inputs``."""
        options = {"pixel_type": self.pixel_type, "dither": self.dither, "compression": self.compression,
                   "force": self.force, "inputs": tuple(inputs)}
        if self.tocolorspace is not None:
            options["colorspace"] = self.tocolorspace
        return options


__all__ = ["ReadOptions", "WriteOptions"]
