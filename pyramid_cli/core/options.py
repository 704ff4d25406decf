"""Every option's choices, defined once (no numpy, no click): the CLI's ``click.Choice``
lists, the API's checks and the I/O layer's validation all read them from here."""

from __future__ import annotations

from pyramid_cli.core.border import BORDER_NAMES

BACKENDS = ("auto", "gl", "cpu", "reference")
BACKEND_HELP = {
    "auto": "the exact executor estimated to finish this job first here (GL or the CPU executor)",
    "gl": "OpenGL through headless EGL (a GPU, or Mesa's llvmpipe); never falls back",
    "cpu": "the CPU executor of plans",
    "reference": "the float64 oracle of the paper's formulas (slow, obvious, exact)",
}
BORDERS = tuple(BORDER_NAMES)
PRECISIONS = ("float", "half")
PIXEL_TYPES = ("uint8", "uint16", "half", "float")
ENCODINGS = ("linear", "srgb")                        # how stored values are encoded
STORED_ALPHA = ("straight", "premultiplied", "none")  # how a file stores alpha
COLORSPACES = ("auto", *ENCODINGS)                    # --colorspace: auto reads the file's metadata
ALPHA_MODES = ("auto", *STORED_ALPHA)                 # --alpha: auto follows the file
NAN_POLICIES = ("keep", "zero", "fail")
STRATEGIES = ("cost", "paper", "fused")
MAX_LEVELS = 16  # the most pyramid levels: --levels ranges, the API's checks, the sigma limits
MAX_WEIGHT_SCALE = 1 << 20  # fill --weight-scale: beyond this K is ∞ in float32 (any weight makes a coarse pixel known)
MAX_SWEEPS = 64  # fill --sweeps


def check(name: str, value: str, choices) -> str:
    """``value`` if it is one of ``choices``, else ValueError with the message the CLI prints."""
    if value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(choices)}, not {value!r}")
    return value


__all__ = ["BACKENDS", "BACKEND_HELP", "BORDERS", "PRECISIONS", "PIXEL_TYPES", "ENCODINGS", "STORED_ALPHA",
           "COLORSPACES", "ALPHA_MODES",
           "NAN_POLICIES", "STRATEGIES", "MAX_LEVELS", "MAX_WEIGHT_SCALE", "MAX_SWEEPS", "check"]
