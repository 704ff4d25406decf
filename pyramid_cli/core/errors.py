"""Error types and the one table of exit codes.

Every failure the tool reports on purpose is a :class:`PyramidError` whose
``exit_code`` comes from :data:`EXIT_CODES`; the CLI prints its one-line message
and exits with that code. Anything else is a bug and exits with 1 and a
traceback.

For Python callers: :class:`UsageError` (a bad argument) and :class:`DataError` (bad pixel data)
are also ``ValueError`` s; :class:`InputError` (a file that cannot be read) and :class:`OutputError`
(a file that cannot be written) are also ``OSError`` s (with no ``errno``: the message says why);
:class:`BackendError` (no GL context) is only a :class:`PyramidError`.

Warnings: every warning the package gives a Python caller is a :class:`PyramidWarning` (a
``UserWarning``), so ``warnings.filterwarnings("ignore", category=PyramidWarning)`` silences them
all; :class:`MixedLatticeWarning` (a filter pair on two lattices), :class:`MaskWarning` (mask or
weight values clipped, NaN/Inf kept) and :class:`BackendWarning` (an executor that could not be
used, and what ran instead) tell them apart.
"""

from __future__ import annotations

EXIT_CODES: dict[str, tuple[int, str]] = {
    "ok": (0, "success"),
    "internal": (1, "internal error (a bug: please report it with the traceback)"),
    "usage": (2, "bad command line: unknown option, bad expression, bad size, an option the output "
                 "format would ignore, work over the cost limits"),
    "input": (3, "an input image cannot be read: missing, unreadable, truncated, "
                 "unsupported format, zero size, not a regular file, several parts"),
    "output": (4, "an output cannot be written (disk full, quota, size limit, read-only folder), "
                  "or would overwrite an input without --force"),
    "data": (5, "bad pixel data: NaN/Inf under --nan fail, image too large"),
    "backend": (6, "the requested backend is unavailable (no EGL/OpenGL context; a Dask cluster lost)"),
    "interrupted": (130, "interrupted (Ctrl-C); 143 for SIGTERM, 129 for SIGHUP: no output half-written"),
}


def exit_code(name: str) -> int:
    return EXIT_CODES[name][0]


class PyramidError(Exception):
    """An expected failure with a one-line message and a documented exit code."""

    kind = "internal"

    def __init__(self, message: str):
        super().__init__(message)
        self.message = message

    @property
    def exit_code(self) -> int:
        return exit_code(self.kind)


class UsageError(PyramidError, ValueError):
    """A bad argument: an unknown name, a bad expression or size (a ValueError for Python callers)."""

    kind = "usage"


class ExpressionError(UsageError):
    """A filter expression that does not parse or does not make sense.

    ``column`` is 0-based into ``text``; ``length`` is how many characters the
    caret line underlines.
    """

    def __init__(self, message: str, text: str, column: int, length: int = 1):
        self.problem = message
        self.text = text
        self.column = max(0, min(column, len(text)))
        self.length = max(1, length)
        super().__init__(message)

    def caret(self) -> str:
        return " " * self.column + "^" * self.length

    def __str__(self) -> str:
        return f"{self.problem}\n  {self.text}\n  {self.caret()}"


class InputError(PyramidError, OSError):
    """An input file cannot be read (missing, truncated, unsupported), or inputs that do not fit together
    (an ``OSError`` for Python callers)."""

    kind = "input"


class OutputError(PyramidError, OSError):
    """An output cannot be written (disk full, read-only folder), or would overwrite an input (an ``OSError``
    for Python callers)."""

    kind = "output"


class DataError(PyramidError, ValueError):
    """Bad pixel data: NaN/Inf where none may be, an image too large, a fill with no known pixel
    (a ValueError for Python callers)."""

    kind = "data"


class BackendError(PyramidError):
    """The backend asked for is unavailable (no EGL/OpenGL context)."""

    kind = "backend"


class PyramidWarning(UserWarning):
    """What the command line prints as ``pyramid: warning: …``, for a Python caller: the base of every
    warning the package gives."""


class MixedLatticeWarning(PyramidWarning):
    """An analysis and a synthesis filter on different lattices: the result shifts
    (:func:`pyramid_cli.workflows.pyramids.lattice_mismatch`)."""


class MaskWarning(PyramidWarning):
    """Mask or weight values outside [0, 1] (clipped), or NaN/Inf in them (kept: they spread)."""


class BackendWarning(PyramidWarning):
    """An executor that could not be used (no EGL context, an image GL cannot hold, no numba) and what
    ran instead."""


def warn(message: str, category: type[Warning] = PyramidWarning) -> None:
    """``warnings.warn(message, category)`` attributed to the first caller outside this package (the user's
    line), so that filters by module and line, and ``pytest.warns``, see where the user called from."""
    import os
    import sys
    import warnings
    from types import FrameType

    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__))) + os.sep
    frame: FrameType | None = sys._getframe(1)
    level = 2
    while frame is not None and frame.f_code.co_filename.startswith(package):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level)
