"""Error types and the one table of exit codes.

Every failure the tool reports on purpose is a :class:`PyramidError` whose
``exit_code`` comes from :data:`EXIT_CODES`; the CLI prints its one-line message
and exits with that code. Anything else is a bug and exits with 1 and a
traceback.

For Python callers: :class:`UsageError` (a bad argument) and :class:`DataError` (bad pixel data)
are also ``ValueError`` s; :class:`InputError` (a file that cannot be read), :class:`OutputError`
(a file that cannot be written) and :class:`BackendError` (no GL context) are only
:class:`PyramidError` s. :class:`MixedLatticeWarning` is the ``UserWarning`` of a filter pair on
two lattices.
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


class InputError(PyramidError):
    """An input file cannot be read (missing, truncated, unsupported), or inputs that do not fit together."""

    kind = "input"


class OutputError(PyramidError):
    """An output cannot be written (disk full, read-only folder), or would overwrite an input."""

    kind = "output"


class DataError(PyramidError, ValueError):
    """Bad pixel data: NaN/Inf where none may be, an image too large, a fill with no known pixel
    (a ValueError for Python callers)."""

    kind = "data"


class BackendError(PyramidError):
    """The backend asked for is unavailable (no EGL/OpenGL context)."""

    kind = "backend"


class MixedLatticeWarning(UserWarning):
    """An analysis and a synthesis filter on different lattices: the result shifts
    (:func:`pyramid_cli.workflows.pyramids.lattice_mismatch`)."""
