"""Frame sequences in pipeline conventions: ``plate.####.exr``, ``plate.%04d.exr``, ``plate.1001-1240#.exr``.

Parsing is :mod:`fileseq`'s (``#``, ``@``, ``%04d``, ``$F4``, ``<UDIM>``, ``%(UDIM)d``,
frame ranges with steps and negative frames). One rule is this tool's: a lone ``#``
means four digits (``plate.1001-1240#.exr``, as fileseq and RV write it), a run of
two or more ``#`` means one digit each (``plate.####.exr``, as Nuke and Houdini write
it); ``@`` is always one digit each.

Which frames: the pattern's own range (``plate.1001-1240#.exr``), narrowed by
``--frames`` when both are given; else ``--frames``; else the frames found on disk,
from the first to the last (a gap is a missing frame). UDIM tiles are never
contiguous, so a UDIM pattern without a range takes the tiles found on disk.
A frame whose file is missing is an :class:`~pyramid_cli.errors.InputError` naming it
(exit 3), or skipped with a warning under ``--keep-going``.

Output templates take the same tokens (``out/soft.####.exr``: frame to frame, with the
template's own padding) and the fields ``{frame}`` (``{frame:04d}`` for a width),
``{stem}``, ``{name}``, ``{ext}``, ``{dir}``.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass

import fileseq

from .batch import Job, expand, output_for
from .errors import InputError, UsageError

_UDIM = ("<UDIM>", "%(UDIM)d")


@dataclass
class FrameJob(Job):
    """A job of a frame sequence: its frame number, and whether its input exists."""

    frame: int = 0
    missing: bool = False


def _pad_style(pattern: str):
    seq = fileseq.FileSequence(pattern, allow_subframes=False)
    return fileseq.PAD_STYLE_HASH4 if seq.padding() == "#" else fileseq.PAD_STYLE_HASH1


def parse(pattern: str) -> fileseq.FileSequence | None:
    """The :class:`fileseq.FileSequence` of ``pattern``, or None when it names no sequence.

    A path is a sequence when it holds a padding token (``#``, ``@``, ``%0Nd``, ``$FN``,
    ``<UDIM>``, ``%(UDIM)d``); ``render_v002.exr`` is a plain file.

    Parameters
    ----------
    pattern : str
        A path or sequence pattern, e.g. ``plate.1001-1240#.exr``.

    Returns
    -------
    fileseq.FileSequence or None
    """
    try:
        seq = fileseq.FileSequence(pattern, allow_subframes=False)
    except fileseq.ParseException as e:
        raise UsageError(f"{pattern}: not a frame sequence pattern ({e})") from None
    if not seq.padding():
        return None
    return fileseq.FileSequence(pattern, pad_style=_pad_style(pattern), allow_subframes=False)


def is_sequence(path: str) -> bool:
    """Does ``path`` name a frame sequence (see :func:`parse`)?"""
    try:
        return parse(path) is not None
    except UsageError:
        return False


def _is_udim(seq: fileseq.FileSequence) -> bool:
    return seq.padding() in _UDIM


def frame_set(spec: str) -> list[int]:
    """Frames of a range such as ``1001-1240x2``, ``1-10,20``, ``-5--1`` (fileseq's syntax), in order.

    Raises
    ------
    UsageError
        Not a frame range.
    """
    try:
        frames = list(fileseq.FrameSet(spec))
    except (fileseq.ParseException, ValueError, TypeError) as e:
        raise UsageError(f"--frames {spec!r}: not a frame range such as 1001-1240x2 ({e})") from None
    if not frames:
        raise UsageError(f"--frames {spec!r} selects no frame")
    return [int(f) for f in frames]


def frames_of(pattern: str, frames: str | None = None) -> list[tuple[int, str]]:
    """``(frame, path)`` of every frame of a sequence, missing files included (see the module notes).

    Parameters
    ----------
    pattern : str
        A sequence pattern (``plate.####.exr``, ``plate.1001-1240#.exr``, ``tex.<UDIM>.exr``…).
    frames : str, optional
        A frame range selecting frames (``--frames``): alone, or within the pattern's own range.

    Returns
    -------
    list of (int, str)
        In frame order as the range gives it (ascending when found on disk).

    Raises
    ------
    UsageError
        ``pattern`` is not a sequence, or ``--frames`` is not a range or selects nothing.
    InputError
        No range anywhere and no frame of the sequence on disk.
    """
    seq = parse(pattern)
    if seq is None:
        raise UsageError(f"{pattern}: not a frame sequence (use #, @, %04d, $F4 or <UDIM> for the frame number)")
    chosen = frame_set(frames) if frames is not None else None
    own = seq.frameSet()
    if own is not None:
        listed = [int(f) for f in own]
        if chosen is not None:
            keep = set(chosen)
            listed = [f for f in listed if f in keep]
            if not listed:
                raise UsageError(f"--frames {frames!r} selects no frame of {pattern}")
    elif chosen is not None:
        listed = chosen
    else:
        found = _on_disk(seq)
        if not found:
            raise InputError(f"{pattern}: no frame of this sequence exists")
        listed = found if _is_udim(seq) else list(range(found[0], found[-1] + 1))
    return [(f, seq.frame(f)) for f in listed]


def _on_disk(seq: fileseq.FileSequence) -> list[int]:
    """Frames whose file exists with exactly the pattern's padding (``plate.01.exr`` is not frame 1 of ``####``)."""
    try:
        found = fileseq.findSequenceOnDisk(seq.format("{dirname}{basename}@{extension}"),
                                           pad_style=fileseq.PAD_STYLE_HASH1)
    except fileseq.FileSeqException:
        return []
    fs = found.frameSet()
    candidates = sorted(int(f) for f in fs) if fs is not None else []
    return [f for f in candidates if os.path.exists(seq.frame(f))]


def output_path(template: str, input_path: str, frame: int) -> str:
    """Fill an output template for one frame: ``{frame}`` ``{stem}`` … and then a sequence token.

    >>> output_path("out/soft.####.exr", "in/plate.1001.exr", 1001)
    'out/soft.1001.exr'
    >>> output_path("out/{stem}_x.exr", "in/plate.1001.exr", 1001)
    'out/plate.1001_x.exr'
    """
    name = os.path.basename(input_path)
    stem, ext = os.path.splitext(name)
    try:
        filled = template.format(stem=stem, name=name, ext=ext, dir=os.path.dirname(input_path) or ".", frame=frame)
    except (KeyError, IndexError, ValueError) as e:
        raise UsageError(f"bad output template {template!r}: use {{frame}} {{stem}} {{name}} {{ext}} {{dir}} "
                         f"or a frame token such as #### ({e})") from None
    seq = parse(filled)
    return seq.frame(frame) if seq is not None else filled


def plan_jobs(paths: list[str], output: str | None, frames: str | None = None) -> list[Job]:
    """Jobs of inputs among which some are sequences: ``SEQ OUTSEQ``, or ``INPUTS... -o TEMPLATE``.

    Sequence inputs give :class:`FrameJob` values (missing frames marked, see
    :func:`drop_missing`); globs and plain files give :class:`~pyramid_cli.batch.Job`.

    Raises
    ------
    UsageError
        Bad template, no output, or several jobs with one output (frames would collide).
    """
    if output is None:
        if len(paths) != 2:
            raise UsageError("give SEQUENCE OUTPUT_SEQUENCE, or inputs with -o/--output TEMPLATE "
                             "(e.g. -o 'out/soft.####.exr')")
        paths, output = paths[:1], paths[1]
    jobs: list[Job] = []
    for p in paths:
        if is_sequence(p):
            for f, path in frames_of(p, frames):
                jobs.append(FrameJob(path, output_path(output, path, f), frame=f, missing=not os.path.exists(path)))
        elif frames is not None:
            raise UsageError(f"--frames selects frames of a sequence, and {p} is not one "
                             "(use plate.####.exr, plate.%04d.exr or plate.1001-1240#.exr)")
        else:
            jobs += [Job(q, output_for(output, q)) for q in expand([p])]
    if not jobs:
        raise UsageError("no input images")
    seen: dict[str, Job] = {}
    for j in jobs:
        key = os.path.abspath(j.output)
        if key in seen:
            raise UsageError(f"output template {output!r} gives {_label(seen[key])} and {_label(j)} the same "
                             f"output {j.output}: add a frame token (####) or {{frame}}")
        seen[key] = j
    return jobs


def _label(job: Job) -> str:
    return f"frame {job.frame}" if isinstance(job, FrameJob) else job.input


def drop_missing(jobs: list[Job], keep_going: bool, warn: Callable[[str], None] | None = None) -> list[Job]:
    """``jobs`` without missing frames: an :class:`InputError` naming them, or a warning under ``keep_going``."""
    missing = [j for j in jobs if isinstance(j, FrameJob) and j.missing]
    if not missing:
        return jobs
    names = ", ".join(str(j.frame) for j in missing[:10]) + (f" and {len(missing) - 10} more" if len(missing) > 10
                                                               else "")
    if not keep_going:
        first = missing[0]
        raise InputError(f"{first.input}: frame {first.frame} is missing"
                         + (f" (missing frames: {names})" if len(missing) > 1 else "")
                         + "; --keep-going skips missing frames")
    if warn is not None:
        warn(f"skipping {len(missing)} missing frame(s): {names} (first: {missing[0].input})")
    return [j for j in jobs if not (isinstance(j, FrameJob) and j.missing)]


def pair_frames(a_pattern: str, b_pattern: str, frames: str | None = None) -> list[tuple[int, str, str]]:
    """Pair two sequences frame by frame (``pyramid diff`` of two sequences).

    The frames are A's (its range, ``frames``, or what exists on disk, as
    :func:`frames_of`); each must exist in both.

    Parameters
    ----------
    a_pattern, b_pattern : str
        Sequence patterns, e.g. ``out/soft.####.exr`` and ``golden/soft.%04d.exr``.
    frames : str, optional
        A frame range selecting frames.

    Returns
    -------
    list of (int, str, str)
        ``(frame, a_path, b_path)`` in frame order.

    Raises
    ------
    UsageError
        A pattern is not a sequence.
    InputError
        A frame is missing on either side (the first one is named).
    """
    b = parse(b_pattern)
    if b is None:
        raise UsageError(f"{b_pattern}: not a frame sequence (use #, @, %04d, $F4 or <UDIM> for the frame number)")
    pairs = [(f, a, b.frame(f)) for f, a in frames_of(a_pattern, frames)]
    for f, a, bp in pairs:
        for path in (a, bp):
            if not os.path.exists(path):
                raise InputError(f"{path}: frame {f} is missing")
    return pairs


__all__ = ["FrameJob", "parse", "is_sequence", "frame_set", "frames_of", "output_path", "plan_jobs",
           "drop_missing", "pair_frames"]
