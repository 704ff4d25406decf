"""How a run decodes its inputs and encodes its outputs: the read and write settings of every command.

These are the command line's ``--colorspace --alpha --nan`` and ``--type --dither --compression
--force`` as values (:mod:`pyramid_cli.core.options` holds what each may be); the runners in
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


@dataclass
class WriteOptions:
    """How outputs are encoded (see :func:`pyramid_cli.imageio.write_image`)."""

    pixel_type: str | None = None
    dither: bool = False
    compression: str | None = None
    force: bool = False

    def for_inputs(self, inputs) -> dict:
        """The keyword arguments of :func:`pyramid_cli.imageio.write_image` for an output made from ``inputs``."""
        return {"pixel_type": self.pixel_type, "dither": self.dither, "compression": self.compression,
                "force": self.force, "inputs": tuple(inputs)}


__all__ = ["ReadOptions", "WriteOptions"]
