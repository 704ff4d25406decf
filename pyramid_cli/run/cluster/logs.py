"""Dask's own log lines and warnings kept off the terminal for a run, and said under -v in one line."""

from __future__ import annotations

import contextlib
import logging
import warnings
from collections.abc import Iterator

#: Logger families whose records are captured for a run (Dask's, and the libraries it logs through).
DASK_LOGGERS = ("distributed", "dask", "tornado", "asyncio", "bokeh")


class CapturedLogs(logging.Handler):
    """Keeps the records of Dask's loggers (warnings and worse) instead of printing them."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


@contextlib.contextmanager
def captured_output() -> Iterator[tuple[CapturedLogs, list]]:
    """Dask's log records and Python warnings kept, not printed, for the block: ``(handler, warnings)``.

    Import ``distributed`` first: its import installs its own handlers, which this replaces
    for the block and puts back after.
    """
    handler = CapturedLogs()
    family = {n for n in logging.root.manager.loggerDict if n.split(".")[0] in DASK_LOGGERS} | set(DASK_LOGGERS)
    saved = []
    for name in sorted(family):
        logger = logging.getLogger(name)
        if logger.handlers or name in DASK_LOGGERS:
            saved.append((logger, logger.handlers[:], logger.propagate))
            logger.handlers[:] = [handler]
            logger.propagate = False
    try:
        with warnings.catch_warnings(record=True) as warned:
            warnings.simplefilter("always")
            yield handler, warned
    finally:
        for logger, handlers, propagate in saved:
            logger.handlers[:] = handlers
            logger.propagate = propagate


def summarise(handler: CapturedLogs, warned: list, reporter) -> None:
    """Under -v, one line for what Dask logged or warned during the run (its own lines never reach the terminal)."""
    def first_line(text: str) -> str:
        line = next((t.strip() for t in text.splitlines() if t.strip()), "")
        return line[:160] + ("…" if len(line) > 160 else "")

    texts = [f"{r.levelname.lower()} from {r.name}: {first_line(r.getMessage())}" for r in handler.records]
    texts += [f"{w.category.__name__}: {first_line(str(w.message))}" for w in warned]
    if texts:
        reporter.detail(f"cluster: Dask logged {len(texts)} message(s) during the run; the first: {texts[0]}")


__all__ = ["DASK_LOGGERS", "CapturedLogs", "captured_output", "summarise"]
