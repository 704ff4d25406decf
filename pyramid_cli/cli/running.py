"""How a command's options become a run: the reporter, the session, the read and write settings, and the
one call into :func:`pyramid_cli.run.pipeline.process` every batch command makes."""

from __future__ import annotations

import sys

import click

from pyramid_cli.cli.group import collector_on


class ProgressBar:
    """click's progress bar as the pipeline's progress (shown at a terminal only)."""

    def __init__(self, total: int):
        self.bar = click.progressbar(length=total, label="pyramid", file=sys.stderr)

    def __enter__(self):
        return self.bar.__enter__()

    def __exit__(self, *exc):
        return self.bar.__exit__(*exc)


def make_reporter(opts: dict):
    """The run's :class:`~pyramid_cli.run.report.Reporter`: -q, -v, click's output, a bar at a terminal."""
    from pyramid_cli.run.report import Reporter

    return Reporter(quiet=opts["quiet"], verbose=opts["verbose"], interactive=sys.stderr.isatty(), out=click.echo,
                    err=lambda msg: click.echo(msg, err=True), progress=ProgressBar if sys.stderr.isatty() else None)


def drop(msg: str) -> None:
    """A Reporter's ``out`` where a command prints its own result (--json)."""


def open_session(opts: dict, reporter):
    """The :class:`~pyramid_cli.exec.session.Session` of --backend, --precision and --threads (-v says which, once
    chosen: ``auto`` chooses when the first job is known, with each backend's estimate)."""
    from pyramid_cli.exec.session import Session

    collector_on()
    return Session(opts["backend"], opts["precision"], threads=opts["threads"], warn=reporter.warn,
                   note=reporter.detail)


def cluster_spec(opts: dict):
    """The :class:`~pyramid_cli.run.cluster.SessionSpec` of --backend, --precision and --threads that each worker of a
    --cluster run opens its session with (this process opens none)."""
    from pyramid_cli.run.cluster import SessionSpec

    collector_on()
    return SessionSpec(opts["backend"], opts["precision"], opts["threads"])


def read_write(opts: dict):
    """The read and write settings (:mod:`pyramid_cli.run.settings`) of the io options."""
    from pyramid_cli import imageio as io
    from pyramid_cli.run.settings import ReadOptions, WriteOptions

    io.check_colorspaces(opts["colorspace"], opts.get("tocolorspace"), colorconfig=opts.get("colorconfig"))
    return (ReadOptions(opts["colorspace"], opts["alpha"], opts["nan_policy"], opts.get("colorconfig")),
            WriteOptions(opts["pixel_type"], opts["dither"], opts["compression"], opts["force"],
                         opts.get("tocolorspace")))


def run_paths(paths, work, opts: dict, mip_tile: int | None = None) -> None:
    """``work`` on every input of ``paths`` through :func:`pyramid_cli.run.pipeline.process` with the batch
    options; exits with the first failure's code when a batch had failures."""
    from pyramid_cli.run.pipeline import process

    reporter = make_reporter(opts)
    ro, wo = read_write(opts)
    batch = {"read": ro, "write": wo, "reporter": reporter, "keep_going": opts["keep_going"],
             "skip_existing": opts["skip_existing"], "jobs": opts["jobs"], "mip_tile": mip_tile,
             "frames": opts["frames"], "shard": opts["shard"], "cluster": opts["cluster"], "chunk": opts["chunk"],
             "cluster_timeout": opts["cluster_timeout"]}
    if opts.get("memory") is not None:
        from pyramid_cli.run.stream import parse_size

        batch["memory"] = parse_size(opts["memory"])
    if opts["cluster"]:  # every worker opens its own session; none is needed here
        report = process(list(paths), opts["template"], work, cluster_spec(opts), **batch)
    else:
        with open_session(opts, reporter) as session:
            report = process(list(paths), opts["template"], work, session, **batch)
    if report.failed:
        sys.exit(report.exit_code)


__all__ = ["ProgressBar", "cluster_spec", "make_reporter", "drop", "open_session", "read_write", "run_paths"]
