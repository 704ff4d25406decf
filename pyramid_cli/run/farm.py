"""Render-farm job templates: an Open Job Description (2023-09) template for a ``pyramid`` command over frames.

Open Job Description is the open job format that AWS Deadline Cloud runs
(``openjd check`` validates a template, ``openjd run`` runs it on this machine; both
from the ``openjd-cli`` package). The template has one step whose task parameter
``Frame`` is a ``CHUNK[INT]`` over the job parameter ``Frames`` (the
``TASK_CHUNKING`` extension) with ``rangeConstraint: NONCONTIGUOUS``: the frames,
whatever their shape (stepped, listed), are cut into chunks of at most ``ChunkSize``
frames in ascending order, sizes as even as OpenJD makes them (10 frames at 4 a
task: 4, 3, 3); ``CONTIGUOUS`` would cut a stepped range into one-frame tasks. A task
receives its chunk as an OpenJD range (``1001-1007:2``, ``3,7``), which ``--frames``
reads with the same meaning (:mod:`pyramid_cli.run.sequence`). One task is one process
with one warm executor over its chunk; outputs are atomic, so a retried task leaves
no half-written file, and ``--skip-existing`` makes it redo only what is missing.

``Frames`` is written ascending and without overlaps (``--frames 1010-1001`` becomes
``1001-1010``), as ``openjd run`` requires of a range; a range whose OpenJD spelling
is longer than a job parameter may be (1024 characters) is refused when written.

The template is written as JSON, which is also YAML: ``openjd`` reads either.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence

from pyramid_cli.core.errors import UsageError

SPECIFICATION = "jobtemplate-2023-09"
COMMANDS = ("apply", "blur", "mipmap")
MAX_PARAMETER = 1024  # characters of a job parameter's value (openjd-model's ParameterStringValue)
_OWN = {
    "--frames": "farm-template sets --frames itself (each task's chunk): remove it from the command",
    "--shard": "--shard cannot be in a farm template's command: the farm's tasks are the split, and each runs "
               "its chunk on one worker; remove it",
    "--cluster": "--cluster cannot be in a farm template's command: the farm's tasks are the split, and each runs "
                 "its chunk on one worker; remove it",
    "--chunk": "--chunk in the command is a Dask cluster's; give farm-template's own --chunk N (frames per task) "
               "before --",
}


def openjd_range(frames: str) -> str:
    """A frame range (``1001-1240x2``, ``1010-1001``, ``1,5-9``) as an OpenJD range: ascending, no overlap.

    Raises
    ------
    UsageError
        Not a frame range (one line), or too long for a job parameter.
    """
    from pyramid_cli.run.sequence import frame_set, range_text

    chosen = frame_set(frames)
    text = range_text(chosen)
    if len(text) > MAX_PARAMETER:
        raise UsageError(f"--frames {frames[:40]!r}…: its {len(chosen)} frames take {len(text)} characters "
                         f"as an Open Job Description range, more than a job parameter holds ({MAX_PARAMETER}); "
                         "split the job")
    return text


def job_template(command: Sequence[str], frames: str, *, chunk: int = 10, name: str | None = None,
                 executable: str = "pyramid", target_seconds: int | None = None) -> dict:
    """The Open Job Description template (a dict) running ``pyramid COMMAND… --frames CHUNK`` per task.

    Parameters
    ----------
    command : sequence of str
        A batch command and its arguments, without the program name: ``["blur", "--levels",
        "4", "plate.####.exr", "-o", "soft.####.exr"]``. Its inputs should be sequence patterns.
    frames : str
        The job's frames (the ``Frames`` job parameter's default, written by :func:`openjd_range`),
        e.g. ``1001-1240`` or ``1001-1240x2``.
    chunk : int
        Frames per task (the ``ChunkSize`` job parameter's default).
    name : str, optional
        The job's name (default: ``pyramid`` and the command).
    executable : str
        The ``pyramid`` program as the farm's workers find it.
    target_seconds : int, optional
        ``targetRuntimeSeconds``: lets a scheduler that supports it adapt the chunk size.

    Returns
    -------
    dict
        The template; ``json.dumps`` it to a file.

    Raises
    ------
    UsageError
        Not one of the batch commands, an option that cannot be in the command (``--frames``,
        ``--shard``, ``--cluster``, ``--chunk``), ``{{`` in an argument, or a bad frame range.
    """
    args = list(command)
    if not args or args[0] not in COMMANDS:
        raise UsageError(f"farm-template runs one of {', '.join(COMMANDS)}: give it after --, e.g. "
                         "pyramid farm-template --frames 1001-1240 -- blur 'plate.####.exr' -o 'soft.####.exr'")
    for a in args:
        if a.split("=")[0] in _OWN:
            raise UsageError(_OWN[a.split("=")[0]])
    for a in [*args, name or ""]:
        if "{{" in a or "}}" in a:
            raise UsageError(f"{a!r}: {{{{ }}}} in the command would be read by Open Job Description as its own "
                             "expression")
    if chunk < 1:
        raise UsageError("--chunk must be at least 1")
    chunks: dict = {"defaultTaskCount": "{{Param.ChunkSize}}", "rangeConstraint": "NONCONTIGUOUS"}
    if target_seconds:
        chunks["targetRuntimeSeconds"] = int(target_seconds)
    return {
        "specificationVersion": SPECIFICATION,
        "extensions": ["TASK_CHUNKING"],
        "name": (name or " ".join(["pyramid", *args]))[:128],
        "description": "Generated by pyramid farm-template: each task runs the command over a chunk of at most "
                       "ChunkSize frames (--frames with the chunk's range, e.g. 1001-1007:2).",
        "parameterDefinitions": [
            {"name": "Frames", "type": "STRING", "default": openjd_range(frames), "maxLength": MAX_PARAMETER,
             "description": "Frames to process, an Open Job Description range written ascending: 1001-1240, "
                            "1-100:2 (every other frame), 1,5-9."},
            {"name": "ChunkSize", "type": "INT", "default": int(chunk), "minValue": 1,
             "description": "Frames per task (at most): one process and one warm executor each."},
        ],
        "steps": [{
            "name": args[0],
            "parameterSpace": {"taskParameterDefinitions": [
                {"name": "Frame", "type": "CHUNK[INT]", "range": "{{Param.Frames}}", "chunks": chunks},
            ]},
            "script": {"actions": {"onRun": {
                "command": executable,
                "args": [*args, "--frames", "{{Task.Param.Frame}}"],
            }}},
        }],
    }


def check_plan(paths: Sequence[str], output: str | None, frames: str) -> None:
    """Plan the command's jobs over all the job's frames, as its tasks will: refuse now what a task would refuse.

    Every input must be a sequence holding every frame of ``frames`` (a pattern's own range
    may not leave frames out: those would never be made, and a chunk of only such frames
    fails), and the output template must fill (its fields, its token) and give each frame
    its own file. The inputs need not exist here.

    Parameters
    ----------
    paths : sequence of str
        The command's inputs (and, without ``output``, its output sequence last).
    output : str or None
        The command's ``-o`` template.
    frames : str
        The job's frames.

    Raises
    ------
    UsageError
        What the first task would have failed with, in one line.
    """
    from pyramid_cli.run.batch import plan_jobs
    from pyramid_cli.run.sequence import frame_set, parse, range_text

    for p in [*paths, *([output] if output is not None else [])]:
        if not _absolute(p):
            raise UsageError(f"{p}: a farm task runs in a session folder of its own; give absolute paths "
                             "(as the workers see the shared storage)")
    plan_jobs(list(paths), output, frames=frames)
    wanted = frame_set(frames)
    for p in (paths if output is not None else paths[:1]):
        seq = parse(p)
        if seq is not None and seq.frames is not None:
            outside = sorted(set(wanted) - set(seq.frames))
            if outside:
                raise UsageError(f"--frames {frames!r}: frames {range_text(outside)[:60]} are outside {p}'s own range "
                                 "and would never be made (give the pattern without a range)")


def _absolute(path: str) -> bool:
    """Absolute on Linux, macOS or Windows workers (``/``, ``\\\\server``, ``C:\\``), or ``{dir}`` of an input."""
    return path.startswith(("/", "\\", "{dir}")) or bool(re.match(r"[A-Za-z]:[\\/]", path))


def dumps(template: dict) -> str:
    """The template as text (JSON, which is also YAML)."""
    return json.dumps(template, indent=2, ensure_ascii=False) + "\n"


def write(path: str, text: str) -> None:
    """Write a template atomically (its folder created), as every output of the tool is written."""
    from pyramid_cli.imageio.atomic import atomic_path, ensure_output_dir

    ensure_output_dir(path)
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write(text)


__all__ = ["write", "job_template", "check_plan", "openjd_range", "dumps", "SPECIFICATION", "COMMANDS"]
