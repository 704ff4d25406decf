"""Dask's log lines and warnings kept off the terminal during a run (pyramid_cli.run.cluster.logs)."""

import logging
import warnings

from pyramid_cli.run.cluster import logs
from pyramid_cli.run.report import Reporter


def reporter(verbose: bool):
    lines: list[str] = []
    return Reporter(verbose=verbose, out=lines.append, err=lines.append), lines


def test_captured_output_keeps_dask_records_and_warnings_then_puts_the_handlers_back():
    logger = logging.getLogger("distributed.test_logs")
    before = (logger.handlers[:], logger.propagate)
    with logs.captured_output() as (handler, warned):
        logging.getLogger("distributed").warning("lost a worker\nwith a traceback")
        logging.getLogger("distributed").info("below warning: not kept")
        warnings.warn("a deprecation", DeprecationWarning, stacklevel=1)
    assert [r.getMessage() for r in handler.records] == ["lost a worker\nwith a traceback"]
    assert [str(w.message) for w in warned] == ["a deprecation"]
    assert logging.getLogger("distributed").handlers != [handler]
    assert (logger.handlers, logger.propagate) == before


def test_summarise_says_one_line_under_verbose_only():
    with logs.captured_output() as (handler, warned):
        logging.getLogger("distributed.scheduler").error("first\nsecond")
        warnings.warn("x" * 200, UserWarning, stacklevel=1)
    loud, said = reporter(verbose=True)
    logs.summarise(handler, warned, loud)
    assert said == ["pyramid: cluster: Dask logged 2 message(s) during the run; the first: error from "
                    "distributed.scheduler: first"]
    quiet, said = reporter(verbose=False)
    logs.summarise(handler, warned, quiet)
    assert said == []
    loud, said = reporter(verbose=True)
    logs.summarise(logs.CapturedLogs(), [], loud)
    assert said == []
