"""Array-job shards: ``--shard K/N`` runs the K-th of N contiguous chunks of a batch's job list.

K is 1-based (``1/4`` … ``4/4``), as people count array tasks. Chunks are contiguous
(one process keeps one executor warm over neighbouring frames) and balanced: chunk
``k`` (0-based) of ``n`` over ``L`` jobs is ``jobs[k·L//n : (k+1)·L//n]``, so sizes
differ by at most one and every job is in exactly one chunk. A shard beyond the job
count is empty and exits 0.

``--shard auto`` reads the index and the count from the scheduler's environment
(:data:`SCHEDULERS`); ``--shard auto/N`` takes the count from the command line for
schedulers that do not publish it (AWS Batch, Kubernetes Indexed Jobs, PBS, LSF),
as does the ``PYRAMID_SHARD_COUNT`` environment variable.
"""

from __future__ import annotations

import contextlib
import glob
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

from .errors import UsageError

T = TypeVar("T")

COUNT_VARIABLE = "PYRAMID_SHARD_COUNT"

#: What ``--shard auto`` reads, in this order: scheduler, index variable, how the count is found.
SCHEDULERS = (
    ("Slurm array job", "SLURM_ARRAY_TASK_ID",
     "SLURM_ARRAY_TASK_COUNT, or SLURM_ARRAY_TASK_MIN/MAX/STEP; index (ID − MIN) / STEP"),
    ("SGE/UGE array job", "SGE_TASK_ID", "SGE_TASK_FIRST/LAST/STEPSIZE; index (ID − FIRST) / STEPSIZE"),
    ("AWS Batch array job", "AWS_BATCH_JOB_ARRAY_INDEX", "0-based; the count is the array size: auto/N or "
     f"{COUNT_VARIABLE}"),
    ("Kubernetes Indexed Job", "JOB_COMPLETION_INDEX", "0-based; the count is .spec.completions: auto/N or "
     f"{COUNT_VARIABLE}"),
    ("LSF job array", "LSB_JOBINDEX", "1-based (-J 'name[1-N]'); LSB_JOBINDEX_END, or auto/N or "
     f"{COUNT_VARIABLE}"),
    ("PBS Pro array job", "PBS_ARRAY_INDEX", f"1-based (-J 1-N); auto/N or {COUNT_VARIABLE}"),
    ("Torque array job", "PBS_ARRAYID", f"1-based (-t 1-N); auto/N or {COUNT_VARIABLE}"),
)


@dataclass(frozen=True)
class Shard:
    """Chunk ``index`` (0-based) of ``count``, and where it came from."""

    index: int
    count: int
    source: str = "--shard"

    def __str__(self) -> str:
        return f"{self.index + 1}/{self.count}"


def _int(env: Mapping[str, str], name: str) -> int | None:
    value = env.get(name)
    if value is None or value.strip() in ("", "undefined"):
        return None
    try:
        return int(value)
    except ValueError:
        raise UsageError(f"--shard auto: {name}={value!r} is not a whole number") from None


def _count(env: Mapping[str, str], given: int | None, where: str) -> int:
    if given is not None:
        return given
    n = _int(env, COUNT_VARIABLE)
    if n is None:
        raise UsageError(f"--shard auto: {where} gives the task index but not the task count: "
                         f"use --shard auto/N or set {COUNT_VARIABLE}=N")
    return n


def from_environment(env: Mapping[str, str] | None = None, count: int | None = None) -> Shard:
    """The shard of an array task from its scheduler's environment (see :data:`SCHEDULERS`).

    Parameters
    ----------
    env : mapping, optional
        The environment (default ``os.environ``).
    count : int, optional
        The task count where the scheduler does not publish it (``--shard auto/N``).

    Returns
    -------
    Shard

    Raises
    ------
    UsageError
        No scheduler variable is set, the count is unknown, or the index is outside it.
    """
    env = os.environ if env is None else env
    shard = _detect(env, count)
    if shard is None:
        names = ", ".join(var for _, var, _ in SCHEDULERS)
        raise UsageError(f"--shard auto: not in an array task (none of {names} is set); use --shard K/N")
    if not 0 <= shard.index < shard.count:
        raise UsageError(f"--shard auto: {shard.source} gives task {shard.index + 1} of {shard.count}, "
                         "outside the array")
    return shard


def _detect(env: Mapping[str, str], count: int | None) -> Shard | None:
    task = _int(env, "SLURM_ARRAY_TASK_ID")
    if task is not None:
        lo, hi = _int(env, "SLURM_ARRAY_TASK_MIN"), _int(env, "SLURM_ARRAY_TASK_MAX")
        step = _int(env, "SLURM_ARRAY_TASK_STEP") or 1
        n = count or _int(env, "SLURM_ARRAY_TASK_COUNT")
        if lo is None:
            raise UsageError("--shard auto: SLURM_ARRAY_TASK_ID is set without SLURM_ARRAY_TASK_MIN")
        if n is None and hi is not None:
            n = (hi - lo) // step + 1
        if n is None:
            raise UsageError("--shard auto: Slurm gives no SLURM_ARRAY_TASK_COUNT or SLURM_ARRAY_TASK_MAX")
        if (task - lo) % step:
            raise UsageError(f"--shard auto: SLURM_ARRAY_TASK_ID={task} is not MIN + k·STEP "
                             "(an irregular --array list): use --shard K/N")
        return Shard((task - lo) // step, n, "SLURM_ARRAY_TASK_ID")
    task = _int(env, "SGE_TASK_ID")
    if task is not None:
        first, last = _int(env, "SGE_TASK_FIRST"), _int(env, "SGE_TASK_LAST")
        step = _int(env, "SGE_TASK_STEPSIZE") or 1
        if first is None or last is None:
            raise UsageError("--shard auto: SGE_TASK_ID is set without SGE_TASK_FIRST/SGE_TASK_LAST")
        return Shard((task - first) // step, count or (last - first) // step + 1, "SGE_TASK_ID")
    task = _int(env, "AWS_BATCH_JOB_ARRAY_INDEX")
    if task is not None:
        return Shard(task, _count(env, count, "AWS_BATCH_JOB_ARRAY_INDEX"), "AWS_BATCH_JOB_ARRAY_INDEX")
    task = _int(env, "JOB_COMPLETION_INDEX")
    if task is not None:
        return Shard(task, _count(env, count, "JOB_COMPLETION_INDEX"), "JOB_COMPLETION_INDEX")
    task = _int(env, "LSB_JOBINDEX")
    if task is not None and task > 0:  # LSF sets 0 outside arrays
        end, step = _int(env, "LSB_JOBINDEX_END"), _int(env, "LSB_JOBINDEX_STEP") or 1
        n = count or _int(env, COUNT_VARIABLE) or (None if end is None else (end - 1) // step + 1)
        if n is None:
            n = _count(env, None, "LSB_JOBINDEX")
        return Shard((task - 1) // step, n, "LSB_JOBINDEX")
    for name in ("PBS_ARRAY_INDEX", "PBS_ARRAYID"):
        task = _int(env, name)
        if task is not None:
            return Shard(task - 1, _count(env, count, name), name)
    return None


_SPEC = re.compile(r"\s*(?:(\d+)|(auto))\s*(?:/\s*(\d+))?\s*")


def parse(spec: str, env: Mapping[str, str] | None = None) -> Shard:
    """``K/N`` (1-based K), ``auto`` or ``auto/N`` as a :class:`Shard`.

    Raises
    ------
    UsageError
        Not one of those forms, K outside 1..N, N < 1, or (``auto``) see :func:`from_environment`.
    """
    m = _SPEC.fullmatch(spec or "")
    if not m or (m.group(1) and not m.group(3)):
        raise UsageError(f"--shard {spec!r}: expected K/N (e.g. 3/10, K from 1), auto or auto/N")
    n = int(m.group(3)) if m.group(3) else None
    if n is not None and n < 1:
        raise UsageError(f"--shard {spec!r}: the count must be at least 1")
    if m.group(2):
        return from_environment(env, n)
    k = int(m.group(1))
    if not 1 <= k <= n:
        raise UsageError(f"--shard {spec!r}: K must be between 1 and {n}")
    return Shard(k - 1, n)


def bounds(shard: Shard, total: int) -> tuple[int, int]:
    """``[start, stop)`` of the shard's chunk of ``total`` jobs."""
    return shard.index * total // shard.count, (shard.index + 1) * total // shard.count


def select(jobs: Sequence[T], shard: Shard | str | None) -> list[T]:
    """The shard's contiguous chunk of ``jobs`` (all of them when ``shard`` is None).

    Parameters
    ----------
    jobs : sequence
        The whole batch's job list, in the same order in every task.
    shard : Shard or str or None
        A :class:`Shard`, or a ``--shard`` spec for :func:`parse`.

    Returns
    -------
    list
    """
    if shard is None:
        return list(jobs)
    if isinstance(shard, str):
        shard = parse(shard)
    start, stop = bounds(shard, len(jobs))
    return list(jobs[start:stop])


def remove_stale_temps(outputs: Sequence[str]) -> int:
    """Remove temporary files a killed writer left beside ``outputs`` (``.NAME.tmp-*``); returns how many.

    Only for outputs this process owns (its shard's, or a cluster task's chunk): no
    other writer can be writing them.
    """
    removed = 0
    for out in outputs:
        folder, base = os.path.split(os.path.abspath(out))
        for tmp in glob.glob(os.path.join(glob.escape(folder), f".{glob.escape(base)}.tmp-*")):
            with contextlib.suppress(OSError):
                os.unlink(tmp)
                removed += 1
    return removed


__all__ = ["Shard", "SCHEDULERS", "COUNT_VARIABLE", "parse", "from_environment", "bounds", "select",
           "remove_stale_temps"]
