"""Many images through one command: one process, one GL context, one set of compiled programs.

Decode of image k+1 and encode of image k−1 run in worker threads while the
executor works on image k (OpenImageIO releases the GIL in its codecs).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor

from pyramid_cli.core.errors import PyramidError, UsageError
from pyramid_cli.run import sequence
from pyramid_cli.run.joblist import GLOB_CHARS, Job, Report, expand, is_fresh

# Job, Report, expand and is_fresh live in pyramid_cli.run.joblist; batch.Job etc. name them too.
__all__ = ["Job", "Report", "expand", "is_fresh", "output_for", "plan_jobs", "run"]


def output_for(template: str, path: str) -> str:
    """Fill an output template for a plain input: {stem} {name} {ext} {dir} of its path.

    ``{ext}`` includes the dot (``.exr``); ``{name}`` is ``{stem}{ext}``; ``{dir}`` is the input's
    folder (``.`` when it has none). A frame token or ``{frame}`` needs a frame sequence's input
    (:func:`pyramid_cli.run.sequence.output_path`, which fills every template).
    """
    return sequence.output_path(template, path, None)


def plan_jobs(paths: list[str], output: str | None, frames: str | None = None) -> list[Job]:
    """``IN OUT`` (two paths, no -o) or ``IN... -o TEMPLATE``; frame sequences go to :mod:`.sequence`.

    ``OUT`` of a plain ``IN`` is a path as it is (braces included); it may not hold a frame token.
    """
    if frames is not None or any(sequence.is_sequence(p) for p in (paths if output else paths[:1])):
        return sequence.plan_jobs(paths, output, frames)
    if output is None:
        if len(paths) != 2 or GLOB_CHARS & set(paths[0]):
            raise UsageError("give INPUT OUTPUT, or several inputs with -o/--output TEMPLATE "
                             "(e.g. -o 'out/{stem}_blur.exr')")
        if sequence.is_sequence(paths[1]):
            raise UsageError(f"{paths[1]}: a frame token in the output, and {paths[0]} is not a frame sequence "
                             "(for one frame of a sequence give its token too, e.g. plate.1001#.exr)")
        return [Job(paths[0], paths[1])]
    inputs = expand(paths)
    if not inputs:
        raise UsageError("no input images")
    jobs = [Job(p, output_for(output, p)) for p in inputs]
    if len(jobs) > 1 and len({os.path.abspath(j.output) for j in jobs}) < len(jobs):
        raise UsageError(f"output template {output!r} gives several inputs the same output: add {{stem}}")
    return jobs


def select_jobs(paths: list[str], template: str | None, *, frames: str | None = None, shard=None,
                keep_going: bool = False, reporter=None) -> tuple[list[Job], bool]:
    """The jobs of ``IN OUT`` or ``IN... -o TEMPLATE`` this process runs, and whether the command has several
    (before its shard is cut: a batch reports per job): planned (:func:`plan_jobs`), cut to
    ``shard`` (``K/N``, ``auto`` or a :class:`~pyramid_cli.run.shard.Shard`; the temporaries a killed run of
    it left are removed), missing frames of a sequence dropped or refused
    (:func:`~pyramid_cli.run.sequence.drop_missing`)."""
    job_list = plan_jobs(list(paths), template, frames=frames)
    many = len(job_list) > 1
    if shard is not None:
        from pyramid_cli.run import shard as shards

        shard = shards.parse(shard) if isinstance(shard, str) else shard
        job_list = shards.select(job_list, shard)
        if reporter is not None:
            reporter.detail(f"shard {shard} ({shard.source}): {len(job_list)} job(s)")
        shards.remove_stale_temps([j.output for j in job_list])
    if frames is not None or any(getattr(j, "frame", None) is not None for j in job_list):
        job_list = sequence.drop_missing(job_list, keep_going, reporter.warn if reporter is not None else print)
    return job_list, many


def _prepare_quietly(prepare: Callable[[Job], None], job: Job) -> None:
    try:
        prepare(job)
    except PyramidError:  # an optimisation only: the read and the work report real errors
        pass


def run(jobs: list[Job], read: Callable, work: Callable, write: Callable, *, keep_going: bool = False,
        skip_existing: bool = False, workers: int = 1, progress: Callable[[Job], None] | None = None,
        prepare: Callable[[Job], None] | None = None, written: Callable[[Job, object], None] | None = None) -> Report:
    """Run ``write(job, work(read(job)))`` for each job, overlapping I/O with work when ``workers`` > 1.

    ``written(job, value)`` receives what ``write`` returned, in this thread and in job order
    (writes run in worker threads and may end in another order). ``prepare(job)`` runs once,
    for the first job, while its read is under way (a cold start's set-up overlapped with the
    first decode); its PyramidErrors are ignored, as the read and the work report them. Stops
    at the first failure unless ``keep_going``; failures are collected in the report.
    """
    report = Report()
    todo = []
    for j in jobs:
        if skip_existing and is_fresh(j):
            report.skipped.append(j)
            if progress:  # a bar over every job reaches its end
                progress(j)
        else:
            todo.append(j)
    pool = ThreadPoolExecutor(max_workers=max(1, workers)) if workers > 1 else None

    def reads() -> Iterator[tuple[Job, Future | None]]:
        if pool is None:
            for j in todo:
                yield j, None
            return
        ahead: list[tuple[Job, Future]] = []
        for j in todo:
            ahead.append((j, pool.submit(read, j)))
            if len(ahead) > workers:
                yield ahead.pop(0)
        for j, f in ahead:
            yield j, f

    pending_writes: list[tuple[Job, Future]] = []

    def settle(block: bool) -> None:
        while pending_writes and (block or pending_writes[0][1].done()):
            j, f = pending_writes.pop(0)
            try:
                value = f.result()
            except PyramidError as e:
                report.failed.append((j, e))
            else:
                report.done.append(j)
                if written is not None:
                    written(j, value)

    try:
        for job, fut in reads():
            if report.failed and not keep_going:
                break
            try:
                if prepare is not None:
                    _prepare_quietly(prepare, job)
                    prepare = None
                image = fut.result() if fut is not None else read(job)
                result = work(image)
                if pool is None:
                    value = write(job, result)
                    report.done.append(job)
                    if written is not None:
                        written(job, value)
                else:
                    pending_writes.append((job, pool.submit(write, job, result)))
                    settle(block=False)
            except PyramidError as e:
                report.failed.append((job, e))
            if progress:
                progress(job)
        settle(block=True)
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
    return report
