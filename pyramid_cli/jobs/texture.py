"""The MIP chain a renderer reads (``pyramid mipmap``, ``pyr.mipmap``): a :class:`~pyramid_cli.jobs.work.Levels`
job with maketx's level sizes and the settings maketx takes."""

from __future__ import annotations

import shlex
from dataclasses import dataclass

from pyramid_cli.core import catalogue
from pyramid_cli.core.errors import UsageError
from pyramid_cli.core.geometry import mip_sizes
from pyramid_cli.jobs.work import Levels
from pyramid_cli.plan.resample import ceil2
from pyramid_cli.workflows.pyramids import mip_axis_weights, mip_plan

ROUNDING = ("down", "up")  # level sizes max(1, ⌊n/2⌋) (maketx's, the default) or ⌈n/2⌉ (⊗↓'s)


@dataclass(frozen=True, kw_only=True)
class TextureLevels(Levels):
    """A MIP chain down to 1×1 (:class:`pyramid_cli.jobs.work.Levels`) as a renderer reads it.

    ``rounding`` "down" (the default): maketx's and OpenEXR's level sizes ``max(1, ⌊n/2⌋)``;
    levels that halve exactly use the paper's ``analysis`` filter, the others are resampled with
    the same filter's continuous kernel so that every level covers the whole texture domain
    (:mod:`pyramid_cli.plan.resample`, :func:`pyramid_cli.workflows.pyramids.mip_plan`); ``border`` is how lookups
    read past the edges (the file's ``wrapmodes``), and under ``clamp`` and ``zero`` the levels are built inside
    the domain by the mirror fold, so each keeps level 0's mean (:func:`pyramid_cli.workflows.pyramids.level_border`).
    "up": the analysis pyramid's sizes ``⌈n/2⌉`` (odd sizes padded by the border), :class:`Levels` as it is.
    ``constant_detect``: an image whose pixels are all the same becomes one tile of that colour
    before the levels are made (:func:`shrink_constant`).
    """

    analysis: str = catalogue.MIP_ANALYSIS_DEFAULT
    constant_detect: bool = False
    rounding: str = "down"
    resize: bool = False           # maketx's --resize: level 0 up to powers of two first (rounding "down" only)
    nchannels: int | None = None   # maketx's --nchannels: keep or pad to this many channels (:func:`channel_plan`)
    monochrome_detect: bool = False  # maketx's --monochrome-detect: R = G = B everywhere → one channel
    fill: bool = False        # pull-push texels of alpha < 1 first (pyramid_cli.run.methods_files.fill_texture)
    colorconvert: tuple[str, str] | None = None  # maketx's --colorconvert IN OUT (the read and write do it)

    @property
    def keeps_input(self) -> bool:  # type: ignore[override]
        """Level 0 is the input, except when it is resized."""
        return not self.resize

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.rounding not in ROUNDING:
            raise UsageError(f"unknown rounding {self.rounding!r} (down or up)")
        if self.rounding == "down":
            mip_axis_weights(self.analysis)  # refuses a filter the rule cannot resample (exit 2)
        elif self.resize:
            raise UsageError("--resize makes maketx's power-of-two levels: it needs --round down")
        if self.nchannels is not None and self.nchannels < 1:
            raise UsageError(f"--nchannels {self.nchannels}: at least 1")

    @property
    def filter_name(self) -> str:
        """The filter, rule and whatever else changes the texels, as the SHA-1's appended text and
        ImageHistory name them: ``quadratic``, ``quadratic/up``, ``quadratic/resize/nchannels=1/fill``,
        ``quadratic/colorconvert=sRGB ACEScg`` …
        (the hash is of the source's pixels, so two files that differ below must differ here)."""
        flags = (["up"] if self.rounding == "up" else []) + (["resize"] if self.resize else [])
        flags += [f"nchannels={self.nchannels}"] if self.nchannels is not None else []
        flags += (["monochrome-detect"] if self.monochrome_detect else []) + (["fill"] if self.fill else [])
        if self.colorconvert is not None:  # as a shell would read it back: maketx's ImageHistory is its command line
            flags.append("colorconvert=" + " ".join(shlex.quote(n) for n in self.colorconvert))
        return "/".join([self.analysis, *flags])

    def count(self, size) -> int:
        size = tuple(size[:2])
        if self.resize:
            return len(mip_sizes((ceil2(size[0]), ceil2(size[1]))))  # level 0 is made too
        return len(mip_sizes(size, self.rounding)) - 1

    def make_plan(self, sizes, strategy="cost"):
        if self.rounding == "up":
            return super().make_plan(sizes, strategy)
        if not self.count(sizes[0]):
            return None
        return mip_plan(tuple(sizes[0][:2]), self.analysis, self.border, strategy, self.resize)

    def reference(self, images):
        if self.rounding == "up":
            return super().reference(images)
        from pyramid_cli.reference.mip import mip_reference

        rows = None if self.analysis in catalogue.ANALYSIS_FILTERS else mip_axis_weights(self.analysis)[0]
        levels = mip_reference(images[0], self.analysis, self.border, self.resize, rows)
        return levels if self.resize else levels[1:]


__all__ = ["TextureLevels", "ROUNDING"]
