"""Array-job shards: ``--shard K/N`` runs the K-th of N contiguous chunks of a batch's job list.

K is 1-based (``1/4`` … ``4/4``), as people count array tasks. Chunks are contiguous
(one process keeps one executor warm over neighbouring frames) and balanced: chunk
``k`` (0-based) of ``n`` over ``L`` jobs is ``jobs[k·L//n : (k+1)·L//n]``, so sizes
differ by at most one and every job is in exactly one chunk. A shard beyond the job
count is empty and exits 0.

``--shard auto`` places an array task from its scheduler's environment
(:data:`SCHEDULERS`). An array is one evenly stepped range of indices FIRST,
FIRST + STEP, … (:class:`Array`); a task does chunk (INDEX − FIRST) / STEP of the
array's COUNT. Every fact the scheduler publishes is used; what it does not publish
the user gives: the count with ``--shard auto/N`` or ``PYRAMID_SHARD_COUNT=N``, the
range as submitted with ``--shard auto/FIRST-LAST[:STEP]`` or
``PYRAMID_SHARD_ARRAY=FIRST-LAST[:STEP]``. A fact given twice must agree. Whether a
fact is missing or contradicted does not depend on the task, so then every task of the
array raises :class:`UsageError` (exit 2) before any work; a task whose index is not in
the array refuses too, naming the variables it read.
"""

from __future__ import annotations

import contextlib
import glob
import os
import re
import shutil
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

from pyramid_cli.core.errors import UsageError

T = TypeVar("T")

COUNT_VARIABLE = "PYRAMID_SHARD_COUNT"
ARRAY_VARIABLE = "PYRAMID_SHARD_ARRAY"
_RANGE_HOW = f"--shard auto/FIRST-LAST[:STEP] or {ARRAY_VARIABLE}=FIRST-LAST[:STEP]"

#: What ``--shard auto`` reads, in this order: scheduler, index variable, where the rest comes from.
SCHEDULERS = (
    ("Slurm array job", "SLURM_ARRAY_TASK_ID", "SLURM_ARRAY_TASK_MIN/MAX/STEP/COUNT (an --array list "
     "that is not one stepped range is refused)"),
    ("SGE/UGE array job", "SGE_TASK_ID", "SGE_TASK_FIRST/LAST/STEPSIZE"),
    ("AWS Batch array job", "AWS_BATCH_JOB_ARRAY_INDEX", "from 0; the count is AWS_BATCH_JOB_ARRAY_SIZE"),
    ("Kubernetes Indexed Job", "JOB_COMPLETION_INDEX", f"from 0; the count (.spec.completions): auto/N or "
     f"{COUNT_VARIABLE}"),
    ("LSF job array", "LSB_JOBINDEX", f"LSB_JOBINDEX_END/STEP; the first index is not published: {_RANGE_HOW}"),
    ("PBS Pro array job", "PBS_ARRAY_INDEX", f"the range is not published: {_RANGE_HOW}"),
    ("Torque array job", "PBS_ARRAYID", f"the range is not published: {_RANGE_HOW}"),
)


@dataclass(frozen=True)
class Shard:
    """Chunk ``index`` (0-based) of ``count``, and where it came from."""

    index: int
    count: int
    source: str = "--shard"

    def __str__(self) -> str:
        return f"{self.index + 1}/{self.count}"


@dataclass(frozen=True)
class Array:
    """The indices ``first``, ``first + step``, … of an array's ``count`` tasks."""

    first: int
    step: int
    count: int

    @property
    def last(self) -> int:
        return self.first + (self.count - 1) * self.step

    def __str__(self) -> str:
        return f"{self.first}-{self.last}" + (f":{self.step}" if self.step != 1 else "")

    @classmethod
    def parse(cls, text: str, where: str) -> Array:
        """``FIRST-LAST[:STEP]`` as the scheduler was given it (a ``%LIMIT`` suffix is allowed and ignored).

        Raises
        ------
        UsageError
            Not that form, or LAST before FIRST, or STEP below 1; ``where`` names the setting.
        """
        m = _RANGE.fullmatch(text.strip())
        if not m:
            raise UsageError(f"{where}: expected the array's range FIRST-LAST[:STEP], e.g. 1-10 or 0-99:4")
        first, last, step = int(m.group(1)), int(m.group(2)), int(m.group(3) or 1)
        if step < 1 or last < first:
            raise UsageError(f"{where}: expected FIRST ≤ LAST and STEP ≥ 1")
        return cls(first, step, (last - first) // step + 1)


_RANGE = re.compile(r"(\d+)\s*-\s*(\d+)(?:\s*:\s*(\d+))?(?:\s*%\s*\d+)?")

_FACTS = {"first": "first index", "step": "step", "count": "task count"}


@dataclass
class _Task:
    """What one array task knows of its array: each fact with where it came from."""

    scheduler: str
    index_variable: str
    index: int
    read: list[str]
    facts: dict[str, tuple[int, str]] = field(default_factory=dict)
    #: A published last index (and its source): the count once the first index and step are known.
    last: tuple[int, str] | None = None
    #: How to give what this scheduler does not publish (an example for the message).
    example: str = ""

    def refuse(self, problem: str) -> UsageError:
        return UsageError(f"--shard auto: {problem} (read {', '.join(self.read)})")

    def put(self, fact: str, value: int, source: str) -> None:
        if fact == "step" and value < 1 or fact == "count" and value < 1 or fact == "first" and value < 0:
            raise self.refuse(f"{source} is not a possible {_FACTS[fact]}")
        if fact not in self.facts:
            self.facts[fact] = value, source
        elif self.facts[fact][0] != value:
            old, where = self.facts[fact]
            raise self.refuse(f"the {_FACTS[fact]} is {old} by {where} but {value} by {source}")

    def put_array(self, array: Array, source: str) -> None:
        self.put("first", array.first, source)
        self.put("step", array.step, source)
        self.put("count", array.count, source)


def _read(env: Mapping[str, str], name: str, read: list[str]) -> int | None:
    value = env.get(name)
    if value is None or value.strip() in ("", "undefined"):
        return None
    read.append(f"{name}={value}")
    try:
        return int(value)
    except ValueError:
        raise UsageError(f"--shard auto: {name}={value!r} is not a whole number") from None


def _slurm(env: Mapping[str, str], task: _Task) -> None:
    lo, hi, step, n = (_read(env, f"SLURM_ARRAY_TASK_{k}", task.read) for k in ("MIN", "MAX", "STEP", "COUNT"))
    if (lo is not None and hi is not None and step is not None and n is not None and step > 0
            and ((hi - lo) % step or (hi - lo) // step + 1 != n)):
        # Slurm's STEP is the number after the first ':' of --array, COUNT the number of indices, so a list
        # (1,3,7 or 1-5,10) shows here, in every task alike. Its chunks cannot be known: refuse them all.
        raise task.refuse("the Slurm array is not one evenly stepped range (an --array list such as 1,3,7 or "
                          "1-5,10): submit --array=FIRST-LAST[:STEP] (a %LIMIT is fine), or run each job "
                          "with its own --shard K/N")
    for fact, value, name in (("first", lo, "MIN"), ("step", step, "STEP"), ("count", n, "COUNT")):
        if value is not None:
            task.put(fact, value, f"SLURM_ARRAY_TASK_{name}")
    if hi is not None:
        task.last = hi, "SLURM_ARRAY_TASK_MAX"
    task.example = "auto/1-20:2 for --array=1-20:2"


def _sge(env: Mapping[str, str], task: _Task) -> None:
    first, last, step = (_read(env, f"SGE_TASK_{k}", task.read) for k in ("FIRST", "LAST", "STEPSIZE"))
    if first is not None:
        task.put("first", first, "SGE_TASK_FIRST")
    if step is not None:
        task.put("step", step, "SGE_TASK_STEPSIZE")
    if last is not None:
        task.last = last, "SGE_TASK_LAST"
    task.example = "auto/1-20:2 for qsub -t 1-20:2"


def _from_zero(name: str, count: str | None) -> Callable[[Mapping[str, str], _Task], None]:
    def read(env: Mapping[str, str], task: _Task) -> None:
        task.put("first", 0, f"{name} (from 0)")
        task.put("step", 1, f"{name} (from 0)")
        if count:
            n = _read(env, count, task.read)
            if n is not None:
                task.put("count", n, count)
        task.example = "auto/10 for 10 tasks"
    return read


def _lsf(env: Mapping[str, str], task: _Task) -> None:
    end, step = _read(env, "LSB_JOBINDEX_END", task.read), _read(env, "LSB_JOBINDEX_STEP", task.read)
    if step is not None:
        task.put("step", step, "LSB_JOBINDEX_STEP")
    if end is not None:
        task.last = end, "LSB_JOBINDEX_END"
    if env.get("LSB_JOBNAME"):
        task.read.append(f"LSB_JOBNAME={env['LSB_JOBNAME']}")
    task.example = f"auto/5-{end or 9} for bsub -J 'x[5-{end or 9}]'"


def _lsf_name_check(env: Mapping[str, str], task: _Task, array: Array) -> None:
    """Refuse where LSB_JOBNAME shows an index list unlike ``array``.

    LSF documents LSB_JOBNAME only as the job's name; OpenLava's sbatchd sets it to the
    submitted ``name[LIST]`` and takes LSB_JOBINDEX_END/STEP from the sub-range of LIST
    holding the task, so a list of ranges (``x[1-5,10-14]``) looks like a plain range in
    each task. Where the name shows such a list, or another range, every task refuses;
    a name without a list, or with only the task's own index, says nothing.
    """
    name = env.get("LSB_JOBNAME", "")
    m = re.search(r"\[([\d\s,:\-]+)\](?:%\d+)?\s*$", name)
    if not m:
        return
    parts = [p for p in m.group(1).split(",") if p.strip()]
    if len(parts) == 1 and parts[0].strip() == str(task.index):
        return
    if len(parts) > 1:
        raise task.refuse("the LSF array is a list of ranges, not one stepped range: submit -J 'name[FIRST-LAST"
                          "[:STEP]]', or run each job with its own --shard K/N")
    try:
        named = Array.parse(parts[0] if "-" in parts[0] else f"{parts[0]}-{parts[0]}", "LSB_JOBNAME")
    except UsageError:
        return
    if named != array:
        raise task.refuse(f"the array is {array} by the facts above but {named} by LSB_JOBNAME")


_READERS = {"SLURM_ARRAY_TASK_ID": _slurm, "SGE_TASK_ID": _sge,
            "AWS_BATCH_JOB_ARRAY_INDEX": _from_zero("AWS Batch", "AWS_BATCH_JOB_ARRAY_SIZE"),
            "JOB_COMPLETION_INDEX": _from_zero("Kubernetes", None), "LSB_JOBINDEX": _lsf}
_PBS_EXAMPLES = {"PBS_ARRAY_INDEX": "auto/0-3 for qsub -J 0-3", "PBS_ARRAYID": "auto/0-3 for qsub -t 0-3"}


def from_environment(env: Mapping[str, str] | None = None, count: int | None = None,
                     array: Array | None = None) -> Shard:
    """The shard of an array task from its scheduler's environment (see :data:`SCHEDULERS`).

    Parameters
    ----------
    env : mapping, optional
        The environment (default ``os.environ``).
    count : int, optional
        The task count (``--shard auto/N``).
    array : Array, optional
        The array's range as submitted (``--shard auto/FIRST-LAST[:STEP]``).

    Returns
    -------
    Shard
        Its ``source`` says where the index, first index, step and count came from.

    Raises
    ------
    UsageError
        Not in an array task; the first index, step or count is neither published nor
        given; two of them disagree; or the task's index is not in the array.
    """
    env = os.environ if env is None else env
    task = _detect(env)
    if task is None:
        names = ", ".join(var for _, var, _ in SCHEDULERS)
        raise UsageError(f"--shard auto: not in an array task (none of {names} is set); use --shard K/N")
    if count is not None:
        task.put("count", count, f"--shard auto/{count}")
    if array is not None:
        task.put_array(array, f"--shard auto/{array}")
    if env.get(ARRAY_VARIABLE, "").strip():
        task.read.append(f"{ARRAY_VARIABLE}={env[ARRAY_VARIABLE]}")
        task.put_array(Array.parse(env[ARRAY_VARIABLE], f"{ARRAY_VARIABLE}={env[ARRAY_VARIABLE]!r}"),
                       ARRAY_VARIABLE)
    n = _read(env, COUNT_VARIABLE, task.read)
    if n is not None:
        task.put("count", n, COUNT_VARIABLE)
    facts = task.facts
    if task.last is not None and "first" in facts and "step" in facts:
        last, where = task.last
        first, step = facts["first"][0], facts["step"][0]
        if last < first:
            raise task.refuse(f"{where} is before the first index {first} ({facts['first'][1]})")
        task.put("count", (last - first) // step + 1, f"{where} from the first index {first}")
    # A published last index gives the count once the rest is known: name only what the user must give.
    missing = [_FACTS[f] for f in _FACTS if f not in facts and not (f == "count" and task.last)]
    if missing:
        if "task count" in missing and len(missing) == 1:
            how = f"use --shard auto/N or set {COUNT_VARIABLE}=N, or give the range: {_RANGE_HOW}"
        else:
            how = f"give the array's range as submitted: {_RANGE_HOW} (e.g. {task.example})"
            if "count" in facts:
                how = f"a count alone cannot place the task; {how}"
        raise task.refuse(f"the {task.scheduler} does not publish its {' or '.join(missing)}: {how}")
    arr = Array(facts["first"][0], facts["step"][0], facts["count"][0])
    if task.index_variable == "LSB_JOBINDEX":
        _lsf_name_check(env, task, arr)
    position, off = divmod(task.index - arr.first, arr.step)
    if off or not 0 <= position < arr.count:
        where = "outside the array" if not arr.first <= task.index <= arr.last else "not an index of the array"
        raise task.refuse(f"{task.index_variable}={task.index} is {where} {arr}: check the range given")
    sources = "; ".join(f"{_FACTS[f]} from {facts[f][1]}" for f in _FACTS)
    return Shard(position, arr.count, f"{task.index_variable}={task.index} of {arr}: {sources}")


def _detect(env: Mapping[str, str]) -> _Task | None:
    for scheduler, variable, _ in SCHEDULERS:
        read: list[str] = []
        index = _read(env, variable, read)
        if index is None or variable == "LSB_JOBINDEX" and index == 0:  # LSF sets 0 outside arrays
            continue
        task = _Task(scheduler, variable, index, read)
        if variable in _READERS:
            _READERS[variable](env, task)
        else:
            task.example = _PBS_EXAMPLES[variable]
        return task
    return None


_SPEC = re.compile(r"\s*(?:(\d+)\s*/\s*(\d+)|auto(?:\s*/\s*(?:(\d+)|(\d[\d\s:%-]*)))?)\s*")


def parse(spec: str, env: Mapping[str, str] | None = None) -> Shard:
    """``K/N`` (1-based K), ``auto``, ``auto/N`` or ``auto/FIRST-LAST[:STEP]`` as a :class:`Shard`.

    Raises
    ------
    UsageError
        Not one of those forms, K outside 1..N, N < 1, or (``auto``) see :func:`from_environment`.
    """
    m = _SPEC.fullmatch(spec or "")
    if not m:
        raise UsageError(f"--shard {spec!r}: expected K/N (e.g. 3/10, K from 1), auto, auto/N or "
                         "auto/FIRST-LAST[:STEP] (the array's range as submitted)")
    k, n, count, span = m.groups()
    if (n or count) is not None and int(n or count) < 1:
        raise UsageError(f"--shard {spec!r}: the count must be at least 1")
    if k is None:
        array = Array.parse(span, f"--shard {spec!r}") if span else None
        return from_environment(env, int(count) if count else None, array)
    if not 1 <= int(k) <= int(n):
        raise UsageError(f"--shard {spec!r}: K must be between 1 and {n}")
    return Shard(int(k) - 1, int(n))


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
    """Remove the temporaries a killed writer left beside ``outputs`` (``.NAME.tmp-*``: a file's, or a tile set's
    staging folder, :class:`~pyramid_cli.imageio.tilesets.staging.Staging`); returns how many.

    Only for outputs this process owns (its shard's, or a cluster task's chunk): no
    other writer can be writing them.
    """
    removed = 0
    for out in outputs:
        folder, base = os.path.split(os.path.abspath(out.rstrip(os.sep) or out))
        for tmp in glob.glob(os.path.join(glob.escape(folder), f".{glob.escape(base)}.tmp-*")):
            if os.path.isdir(tmp) and not os.path.islink(tmp):
                shutil.rmtree(tmp, ignore_errors=True)
                removed += 1
                continue
            with contextlib.suppress(OSError):
                os.unlink(tmp)
                removed += 1
    return removed


__all__ = ["Shard", "Array", "SCHEDULERS", "COUNT_VARIABLE", "ARRAY_VARIABLE", "parse", "from_environment",
           "bounds", "select", "remove_stale_temps"]
