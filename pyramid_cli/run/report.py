"""What a run says: results on standard output, warnings and -v lines on standard error.

The command line and the Python API's file helpers hand every runner a :class:`Reporter`;
the lines they share (a written output, a first run's kernel compiles) are spelled here once.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Callable
from dataclasses import dataclass, field

#: What a warning about NaN/Inf kept in an input (an image or a mask) advises.
NAN_HINT = "--nan zero or --nan fail to change that"


def nonfinite_kept(path: str, count: int) -> str:
    """The warning for ``count`` NaN/Inf values of ``path`` kept (``--nan keep``), whole or streamed."""
    return f"{path}: {count} NaN/Inf value(s) kept; they spread through the filter ({NAN_HINT})"


@dataclass
class Reporter:
    """What a run says: results on standard output, warnings and -v lines on standard error.

    ``progress(total)`` (optional) returns a context manager with ``update(n)``, shown
    instead of per-file lines for batches (the CLI passes a progress bar at a terminal).
    """

    quiet: bool = False
    verbose: bool = False
    interactive: bool = False  # standard error is a terminal: one-time notices (kernel compiles) are shown
    out: Callable[[str], None] = field(default=lambda msg: print(msg))
    err: Callable[[str], None] = field(default=lambda msg: print(msg, file=sys.stderr))
    progress: Callable | None = None

    def result(self, msg: str) -> None:
        if not self.quiet:
            self.out(msg)

    def warn(self, msg: str) -> None:
        if not self.quiet:
            self.err(f"pyramid: warning: {msg}")

    def detail(self, msg: str) -> None:
        if self.verbose:
            self.err(f"pyramid: {msg}")

    def say(self, msg: str) -> None:
        """A line for the person running the command (not a warning), on standard error, never under -q."""
        if not self.quiet:
            self.err(f"pyramid: {msg}")

    def error(self, msg: str) -> None:
        self.err(f"pyramid: error: {msg}")

    def notice(self, msg: str) -> None:
        """A one-time notice, at a terminal only and never under -q."""
        if self.interactive and not self.quiet:
            self.err(f"pyramid: {msg}")


@dataclass
class PythonReporter(Reporter):
    """What a run says, for a Python caller (:func:`pyramid_cli.api.process_files`): warnings through
    :mod:`warnings` at the caller's line (a :class:`~pyramid_cli.core.errors.MixedLatticeWarning` for those
    in ``lattice``, the job's own, else a :class:`~pyramid_cli.core.errors.PyramidWarning`), what ``-v``
    and :meth:`say` print logged at INFO on the ``pyramid_cli`` logger, results printed unless ``quiet``."""

    lattice: tuple[str, ...] = ()

    def warn(self, msg: str) -> None:
        from pyramid_cli.core import errors

        errors.warn(msg, errors.MixedLatticeWarning if msg in self.lattice else errors.PyramidWarning)

    def detail(self, msg: str) -> None:
        logging.getLogger("pyramid_cli").info(msg)

    def say(self, msg: str) -> None:
        logging.getLogger("pyramid_cli").info(msg)


def announce_compiles(session, work, images, reporter: Reporter) -> None:
    """On a machine's first run the CPU executor compiles its kernels: say so, and for how long.

    Parameters
    ----------
    session : Session
        The session about to run ``work``.
    work : Work
        The job.
    images : list of numpy.ndarray
        Its inputs.
    reporter : Reporter
        Where the notice goes (at a terminal, not under -q).
    """
    if not (reporter.interactive and not reporter.quiet):
        return
    n = session.uncached(work, images)
    if n:
        reporter.notice(f"compiling {n} CPU kernel(s) for this machine, once (about {max(1, round(0.8 * n))} s; "
                        "later runs load them from the cache in a fraction of a second)")


def wrote_line(path: str, width: int, height: int, levels: int | None, executor: str) -> str:
    """A batch's line for one output: ``wrote PATH (W×H[, N MIP levels], EXECUTOR)``."""
    return f"wrote {path} ({width}×{height}{f', {levels} MIP levels' if levels else ''}, {executor})"


__all__ = ["NAN_HINT", "Reporter", "PythonReporter", "announce_compiles", "wrote_line", "nonfinite_kept"]
