"""Frame sequences in pipeline conventions (``plate.####.exr``, ``plate.%04d.exr``, ``plate.1001-1240#.exr``)
and the one frame-range language of ``--frames``, patterns and farm templates.

**Frame ranges** (``--frames``, the range in a pattern, a farm template's ``Frames``)::

    RANGE := PART [, PART]...        spaces around parts and around '-' are ignored
    PART  := A | A-B | A-BxN | A-B:N

``A-B`` is every frame from A to B; ``A-BxN`` and ``A-B:N`` (fileseq's and Open Job
Description's spellings) are every N-th frame counted from A: ``1001-1007:2`` is 1001
1003 1005 1007. Frames may be negative (``-5--1``). A descending part (``1010-1001``,
``1010-1001x3`` = 1010 1007 1004 1001) selects the same frames as counting up; a
negative step is accepted on a descending part only (OpenJD's ``10-1:-3``). Whatever
the spelling, the frames run in ascending order, each once. fileseq's ``y`` (every
frame but every N-th) and its stagger meaning of ``:`` are not this language; subframes
neither. At most :data:`MAX_FRAMES` frames. A bad range is one line (exit 2).

**Patterns.** A path is a frame sequence when its file name (not its folder) holds one
frame token: ``#`` (a lone ``#`` is four digits, as fileseq and RV write it; a run of
two or more is one digit each, as Nuke and Houdini write it), ``@`` (one digit each;
``@`` followed by a digit, as in ``icon@2x.png``, is text), ``%0Nd`` / ``%d``, ``$FN`` /
``$F``, ``<UDIM>``, ``%(UDIM)d``. Digits alone are not a token: ``plate.1001.exr`` and
``v2.1001_1.exr`` are plain files. A range may stand right before the token after a
separator (``plate.1001-1240#.exr``). Frames are printf-padded (``-003`` for -3 at
four digits); a file is a frame only with exactly the pattern's padding.

Which frames: the pattern's own range, narrowed by ``--frames`` when both are given;
else ``--frames``; else the frames found on disk, from the first to the last (a gap is
a missing frame). UDIM tiles are never contiguous, so a UDIM pattern without a range
takes the tiles found on disk. A frame whose file is missing is an
:class:`~pyramid_cli.core.errors.InputError` naming it (exit 3), or skipped with a warning
under ``--keep-going``.

**Outputs.** An output template takes the fields ``{frame}`` (``{frame:05d}`` for a
width), ``{stem}``, ``{name}``, ``{ext}`` (with its dot) and ``{dir}`` of the input, and
at most one frame token in its file name (its own padding), in any combination:
``out/{stem}_blur_{frame:05d}{ext}``, ``out/{stem}.####{ext}``. A template without a
token is a path once its fields are filled, never parsed again.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from pyramid_cli.core.errors import InputError, UsageError
from pyramid_cli.run.joblist import Job, expand

MAX_FRAMES = 1_000_000
"""The most frames one range or one sequence may hold (a typo such as ``1-10000000`` is refused, not expanded)."""

RANGE_EXAMPLES = "examples: 1001-1240, 1001-1240x2, 1001-1240:2, 1,5-9"

_PART = re.compile(r"\s*(-?\d+)(?:\s*-\s*(-?\d+)(?:\s*([x:y])\s*(-?\d+))?)?\s*")
# A frame token: UDIM first (its spellings contain '%' and 'd'), then printf, Houdini, hashes, at-signs.
_TOKEN = re.compile(r"<UDIM>|%\(UDIM\)d|%0\d+d|%d|\$F\d*|#+|(?<!@)@+(?![\d@])")
_RANGE_CHARS = set("0123456789-,:xy")
_FIELD = re.compile(r"\{\{|\}\}|\{[^{}]*\}")
_FIELDS = "{frame} {stem} {name} {ext} {dir}"


# --------------------------------------------------------------------------- frame ranges

def _parts(spec: str, what: str) -> list[range]:
    """The parts of a range as Python ranges (ascending or descending, in the order written)."""
    bad = f"{what} {spec!r}: not a frame range ({RANGE_EXAMPLES})"
    if not isinstance(spec, str) or not spec.strip():
        raise UsageError(bad)
    parts, total = [], 0
    for text in spec.split(","):
        m = _PART.fullmatch(text)
        if not m:
            raise UsageError(bad)
        a, b, kind, n = m.groups()
        a = int(a)
        b = a if b is None else int(b)
        step = 1 if n is None else int(n)
        if kind == "y":
            raise UsageError(f"{what} {spec!r}: fileseq's y (every frame but every N-th) is not supported; "
                             "list the frames instead")
        if step == 0:
            raise UsageError(f"{what} {spec!r}: a step must not be 0")
        if step < 0 and a <= b:
            raise UsageError(f"{what} {spec!r}: a negative step needs a descending range (10-1:-3)")
        step = abs(step)
        part = range(a, b + 1, step) if a <= b else range(a, b - 1, -step)
        total += len(part)
        if total > MAX_FRAMES:
            raise UsageError(f"{what} {spec!r}: more than {MAX_FRAMES} frames in one run")
        parts.append(part)
    return parts


def frame_set(spec: str, what: str = "--frames") -> list[int]:
    """The frames of a range (see the module notes), ascending, each once.

    >>> frame_set("1010-1001x3")
    [1001, 1004, 1007, 1010]
    >>> frame_set("1-10:4,20")
    [1, 5, 9, 20]

    Parameters
    ----------
    spec : str
        The range: ``1001-1240``, ``1001-1240x2``, ``1001-1240:2``, ``1,5-9``, ``-5--1``.
    what : str
        How messages name it (``--frames``, or a pattern).

    Raises
    ------
    UsageError
        Not a range (one line), or more than :data:`MAX_FRAMES` frames.
    """
    return sorted({f for part in _parts(spec, what) for f in part})


def range_text(frames: Iterable[int]) -> str:
    """A short spelling of frames, ascending and without overlaps, in this language and Open Job Description's.

    Runs of three or more frames with one step become ``A-B`` or ``A-B:N``; other frames are listed.

    >>> range_text([1, 5, 6, 7, 8, 9, 11, 13, 15, 20])
    '1,5-9,11-15:2,20'
    """
    values = sorted(set(frames))
    out: list[str] = []
    i = 0
    while i < len(values):
        j = i
        if i + 2 < len(values):
            step = values[i + 1] - values[i]
            while j + 1 < len(values) and values[j + 1] - values[j] == step:
                j += 1
        if j - i >= 2:
            out.append(f"{values[i]}-{values[j]}" + (f":{step}" if step != 1 else ""))
            i = j + 1
        else:
            out.append(str(values[i]))
            i += 1
    return ",".join(out)


# --------------------------------------------------------------------------- patterns

@dataclass(frozen=True)
class Pattern:
    """A frame sequence pattern: ``head`` + the frame (``width`` digits, printf-padded) + ``tail``.

    ``frames`` is the pattern's own range (``plate.1001-1240#.exr``), or None.
    """

    head: str
    token: str
    tail: str
    width: int
    frames: tuple[int, ...] | None = None

    @property
    def udim(self) -> bool:
        return self.token in ("<UDIM>", "%(UDIM)d")

    def frame(self, f: int) -> str:
        """The path of frame ``f``."""
        return f"{self.head}{_pad(f, self.width)}{self.tail}"


def _pad(f: int, width: int) -> str:
    return f"{f:0{width}d}" if width else str(f)


def _width(token: str) -> int:
    if token == "#":
        return 4
    if token[0] in "#@":
        return len(token)
    if token.startswith("%0"):
        return int(token[2:-1])
    if token.startswith("$F"):
        return int(token[2:] or 0)
    return 0  # %d, <UDIM>, %(UDIM)d


def _find_token(path: str, masked: str | None = None) -> re.Match | None:
    """The frame token in the file name of ``path`` (searched in ``masked``, ``path`` with fields blanked)."""
    text = path if masked is None else masked
    start = max(text.rfind("/"), text.rfind(os.sep)) + 1
    found = list(_TOKEN.finditer(text, start))
    if len(found) > 1:
        raise UsageError(f"{path}: {len(found)} frame tokens in one name "
                         f"({', '.join(m.group() for m in found)}): give one")
    return found[0] if found else None


def _range_before(path: str, head: str) -> tuple[str, tuple[int, ...] | None]:
    """Split a range off the end of ``head`` (``plate.1001-1240`` → ``plate.``, its frames).

    A range starts at the name's beginning or after a character that is not a letter or a
    digit (``plate.``, ``plate_``, ``plate-``), and ends right at the token.
    """
    name_start = max(head.rfind("/"), head.rfind(os.sep)) + 1
    i = len(head)
    while i > name_start and head[i - 1] in _RANGE_CHARS:
        i -= 1
    first_error = None
    for s in range(i, len(head)):
        text = head[s:]
        if not any(c.isdigit() for c in text) or not (text[0] == "-" or text[0].isdigit()):
            continue
        if s > name_start and head[s - 1].isalnum():
            continue
        try:
            return head[:s], tuple(frame_set(text, what=f"{path}: range"))
        except UsageError as e:
            if first_error is None and re.match(r"-?\d+\s*-", text):
                first_error = e
    if first_error is not None:
        raise first_error
    return head, None


def parse(pattern: str) -> Pattern | None:
    """The :class:`Pattern` of ``pattern``, or None when its file name holds no frame token.

    ``render_v002.exr``, ``plate.1001.exr`` and ``v2.1001_1.exr`` are plain files.

    Raises
    ------
    UsageError
        Two tokens in one name, or a malformed range before the token (one line).
    """
    m = _find_token(pattern)
    if m is None:
        return None
    head, frames = _range_before(pattern, pattern[:m.start()])
    return Pattern(head, m.group(), pattern[m.end():], _width(m.group()), frames)


def is_sequence(path: str) -> bool:
    """Does ``path`` name a frame sequence: a frame token in its file name (see the module notes)? Never raises.

    A name with two tokens counts as one, so that :func:`parse` refuses it.
    """
    try:
        return _find_token(path) is not None
    except UsageError:
        return True


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
        In ascending frame order.

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
    if seq.frames is not None:
        listed = list(seq.frames)
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
        if seq.udim:
            listed = found
        elif found[-1] - found[0] >= MAX_FRAMES:
            raise InputError(f"{pattern}: frames {found[0]} to {found[-1]} on disk span more than {MAX_FRAMES} "
                             "frames; give --frames")
        else:
            listed = list(range(found[0], found[-1] + 1))
    return [(f, seq.frame(f)) for f in listed]


def _on_disk(seq: Pattern) -> list[int]:
    """Frames whose file exists with exactly the pattern's padding (``plate.01.exr`` is not frame 1 of ``####``)."""
    folder, prefix = os.path.split(seq.head)
    if os.sep in seq.tail or "/" in seq.tail:
        return []
    name = re.compile(re.escape(prefix) + r"(-?\d+)" + re.escape(seq.tail))
    try:
        entries = os.listdir(folder or ".")
    except OSError:
        return []
    found = set()
    for entry in entries:
        m = name.fullmatch(entry)
        if m and _pad(int(m.group(1)), seq.width) == m.group(1):
            found.add(int(m.group(1)))
    return sorted(found)


# --------------------------------------------------------------------------- output templates

def output_path(template: str, input_path: str, frame: int | None) -> str:
    """Fill an output template for one input: its fields, and its frame token (see the module notes).

    >>> output_path("out/soft.####.exr", "in/plate.1001.exr", 1001)
    'out/soft.1001.exr'
    >>> output_path("out/{stem}_blur_{frame:05d}{ext}", "in/plate.1001.exr", 1001)
    'out/plate.1001_blur_01001.exr'
    >>> output_path("out/{stem}.####{ext}", "in/v2.1001_1.exr", 7)
    'out/v2.1001_1.0007.exr'

    Parameters
    ----------
    template : str
        The template; without a token or fields it is the output path as it is.
    input_path : str
        The input whose ``{stem}``, ``{name}``, ``{ext}`` and ``{dir}`` fill the fields.
    frame : int or None
        The frame number, None for an input that is not a frame of a sequence.

    Raises
    ------
    UsageError
        An unknown field, a range in the template, or a frame (token or ``{frame}``) with no frame.
    """
    name = os.path.basename(input_path)
    stem, ext = os.path.splitext(name)
    fields: dict[str, str | int] = {"stem": stem, "name": name, "ext": ext, "dir": os.path.dirname(input_path) or "."}
    if frame is not None:
        fields["frame"] = frame
    masked = _FIELD.sub(lambda f: "\0" * len(f.group()), template)
    m = _find_token(template, masked)
    if m is not None:
        if frame is None:
            raise UsageError(f"output {template!r} has a frame token ({m.group()}), and {input_path} is not a frame "
                             "of a sequence")
        head, own = _range_before(template, masked[:m.start()])
        if own is not None:
            raise UsageError(f"output {template!r}: a frame range in an output ({masked[len(head):m.start()]}); "
                             f"an output takes the token alone ({m.group()})")
        before, after = template[:m.start()], template[m.end():]
        return (_fill(before, fields, template, input_path) + _pad(frame, _width(m.group()))
                + _fill(after, fields, template, input_path))
    return _fill(template, fields, template, input_path)


def _fill(text: str, fields: dict, template: str, input_path: str) -> str:
    try:
        return text.format(**fields)
    except KeyError as e:
        if e.args and e.args[0] == "frame":
            raise UsageError(f"output {template!r} has {{frame}}, and {input_path} is not a frame of a "
                             "sequence") from None
        raise UsageError(f"bad output template {template!r}: unknown field {e} (use {_FIELDS} or a frame token "
                         "such as ####)") from None
    except (IndexError, ValueError) as e:
        raise UsageError(f"bad output template {template!r}: {e} (use {_FIELDS}, or {{{{ }}}} for a brace)") from None


# --------------------------------------------------------------------------- jobs

@dataclass
class FrameJob(Job):
    """A job of a frame sequence: its frame number, and whether its input exists."""

    frame: int = 0
    missing: bool = False


def plan_jobs(paths: list[str], output: str | None, frames: str | None = None) -> list[Job]:
    """Jobs of inputs among which some are sequences: ``SEQ OUTSEQ``, or ``INPUTS... -o TEMPLATE``.

    Sequence inputs give :class:`FrameJob` values (missing frames marked, see
    :func:`drop_missing`); globs and plain files give :class:`~pyramid_cli.run.joblist.Job`.

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
            jobs += [Job(q, output_path(output, q, None)) for q in expand([p])]
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


__all__ = ["FrameJob", "Pattern", "MAX_FRAMES", "parse", "is_sequence", "frame_set", "range_text",
           "frames_of", "output_path", "plan_jobs", "drop_missing", "pair_frames"]
