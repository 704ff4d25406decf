"""Golden-image comparisons of files, folders and globs, and safe golden updates.

:func:`compare_files` compares one output with one reference file (every
subimage and MIP level with ``all_levels``) and returns a :class:`PairResult`.
:func:`pair_inputs` pairs two folders (or two globs) by relative path and
finds each output's accepted references: ``name.exr`` and ``name-*.exr`` beside
it (OpenImageIO's testsuite convention); :func:`compare_pairs` compares them
all (an output passes when any one reference matches); :func:`update_goldens`
copies the new outputs over the goldens that fail or are missing, byte for byte
and atomically.

Statuses and their exit codes (the combined exit code is the largest):

=========  ====  ===========================================================
match      0     within the thresholds (or no pixel over ``fail``)
warning    1     failing pixels tolerated by ``failpercent`` but over ``warn``
failure    2     over the fail thresholds
missing    2     an output with no golden (folder / glob mode)
extra      2     a golden with no output (folder / glob mode)
size       3     different sizes, channel counts or MIP level counts
file       4     a file cannot be read (missing single file, corrupt, not an image)
=========  ====  ===========================================================
"""

from __future__ import annotations

import glob
import os
import re
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pyramid_cli.core.errors import PyramidError
from pyramid_cli.diff.compare import DiffResult, ShapeMismatchError, Thresholds, compare
from pyramid_cli.diff.idiff import format_value

__all__ = ["STATUS_CODES", "CompareOptions", "LevelResult", "PairResult", "compare_files", "compare_pairs",
           "is_pattern", "pair_inputs", "update_goldens", "worst_code"]

STATUS_CODES: dict[str, int] = {"match": 0, "warning": 1, "failure": 2, "missing": 2, "extra": 2,
                                "size": 3, "file": 4}


@dataclass(frozen=True)
class CompareOptions:
    """Thresholds and reading rules of a comparison (see :func:`pyramid_cli.diff.compare.compare`).

    ``linear`` compares decoded linear light (:func:`pyramid_cli.imageio.read_image`,
    with ``colorspace``, ``alpha`` and ``colorconfig``) instead of the stored values, converted to
    ``tocolorspace`` when given (:func:`pyramid_cli.imageio.pixels_in`);
    ``all_levels`` compares every subimage and MIP level (idiff's ``-a``);
    ``metric="flip"`` adds NVIDIA's FLIP, failing when the mean FLIP error is
    over ``flip_fail``.
    """

    thresholds: Thresholds = field(default_factory=lambda: Thresholds())
    all_levels: bool = False
    linear: bool = False
    colorspace: str = "auto"
    alpha: str = "auto"
    metric: str = "idiff"
    flip_fail: float = 0.05
    tocolorspace: str | None = None  # decoded pixels converted to this colour space before comparing
    colorconfig: str | None = None   # the OpenColorIO config of the names (None: $OCIO, else the built-in one)


@dataclass
class LevelResult:
    """One subimage / MIP level: its statistics, and the FLIP mean when asked for."""

    subimage: int
    miplevel: int
    result: DiffResult
    flip: float | None = None


@dataclass
class PairResult:
    """The outcome of one output against its reference(s).

    Attributes
    ----------
    name : str
        The pair's name: the relative path in folder / glob mode, else A.
    path_a, path_b : str or None
        The output and the reference that decided (the primary golden path
        when it is missing; ``None`` for the absent side of ``extra``/``missing``).
    status : str
        A key of :data:`STATUS_CODES`.
    rule : str
        What decided: a verdict rule of :func:`pyramid_cli.diff.compare.compare`, or
        ``"size"``, ``"channels"``, ``"miplevels"``, ``"subimages"``, ``"file"``,
        ``"missing"``, ``"extra"``, ``"flip"``.
    message : str
        One line for a person.
    levels : list of LevelResult
        The compared levels (empty when nothing could be compared).
    references : list of str
        Every accepted reference that was tried.
    a_readable : bool
        False when the output itself could not be read (never copied by --update).
    golden : str or None
        Where ``--update`` writes this output (the primary reference path).
    """

    name: str
    path_a: str | None
    path_b: str | None
    status: str
    rule: str
    message: str = ""
    levels: list[LevelResult] = field(default_factory=list)
    references: list[str] = field(default_factory=list)
    a_readable: bool = True
    golden: str | None = None

    @property
    def exit_code(self) -> int:
        """This pair's exit code (:data:`STATUS_CODES`)."""
        return STATUS_CODES[self.status]

    @property
    def worst(self) -> DiffResult | None:
        """The statistics of the worst level (first of the worst), if any was compared."""
        if not self.levels:
            return None
        return max(self.levels, key=lambda lv: STATUS_CODES[lv.result.verdict]).result

    def to_dict(self) -> dict[str, Any]:
        """A JSON-safe summary: status, exit code, rule, paths and each level's statistics."""
        d: dict[str, Any] = {"name": self.name, "path_a": self.path_a, "path_b": self.path_b,
                             "status": self.status, "exit_code": self.exit_code, "rule": self.rule,
                             "message": self.message, "references": list(self.references)}
        d["levels"] = [{"subimage": lv.subimage, "miplevel": lv.miplevel, "flip_mean": lv.flip,
                        **lv.result.to_dict()} for lv in self.levels]
        return d


def worst_code(pairs: Sequence[PairResult]) -> int:
    """The combined exit code: the largest of the pairs' (0 for none)."""
    return max((p.exit_code for p in pairs), default=0)


def read_pixels(path: str, opts: CompareOptions, subimage: int, miplevel: int) -> tuple[np.ndarray, list[str]]:
    """The pixels ``pyramid diff`` compares of one subimage and MIP level, and their channel names: decoded
    linear light under ``opts.linear`` (:func:`pyramid_cli.imageio.read_image`), else the stored values
    (:func:`pyramid_cli.imageio.raw.read_level`, as idiff reads them)."""
    if opts.linear:
        from pyramid_cli import imageio as io

        img = io.read_image(path, colorspace=opts.colorspace, alpha=opts.alpha, nan="keep", subimage=subimage,
                            colorconfig=opts.colorconfig)
        pixels = io.pixels_in(img, opts.tocolorspace) if opts.tocolorspace else img.pixels
        return pixels, list(img.spec.channel_names)
    from pyramid_cli.imageio import raw as io_raw

    lv = io_raw.read_level(path, subimage, miplevel)
    return lv.pixels, lv.channel_names


def _levels(path: str, opts: CompareOptions) -> list[int]:
    from pyramid_cli.imageio import raw as io_raw

    counts = io_raw.count_levels(path)
    if opts.linear:  # decoded reads see the top level of each part
        counts = [1] * len(counts)
    return counts if opts.all_levels else [1]


def _flip_mean(a: np.ndarray, b: np.ndarray, linear: bool) -> float:
    try:
        import flip_evaluator
    except ImportError:
        raise PyramidError("--metric flip needs NVIDIA's FLIP: pip install 'bilinear-pyramid[flip]' "
                           "(or pip install flip-evaluator)") from None
    def rgb(x: np.ndarray) -> np.ndarray:
        x = np.nan_to_num(np.asarray(x, dtype=np.float32), nan=0.0, posinf=0.0, neginf=0.0)
        if x.shape[2] >= 3:
            x = x[..., :3]
        else:
            x = np.repeat(x[..., :1], 3, axis=2)
        return np.ascontiguousarray(np.maximum(x, 0.0))

    ra, rb = rgb(a), rgb(b)
    hdr = bool(ra.max() > 1.0 or rb.max() > 1.0)
    if hdr:
        _, mean, _ = flip_evaluator.evaluate(rb, ra, "HDR", applyMagma=False)
    else:
        # Stored integer values are display-encoded (sRGB); linear light is not.
        _, mean, _ = flip_evaluator.evaluate(np.clip(rb, 0, 1), np.clip(ra, 0, 1), "LDR",
                                             inputsRGB=not linear, applyMagma=False)
    return float(mean)


def compare_files(path_a: str, path_b: str, opts: CompareOptions, *, name: str | None = None) -> PairResult:
    """Compare output ``path_a`` with reference ``path_b``.

    Parameters
    ----------
    path_a, path_b : str
        Image files.
    opts : CompareOptions
    name : str, optional
        The pair's name in reports (default ``path_a``).

    Returns
    -------
    PairResult
        Never raises for a bad file: an unreadable file is status ``"file"``,
        different sizes, channel counts or MIP level counts ``"size"``,
        different subimage counts under ``all_levels`` ``"failure"`` (idiff's codes).
    """
    name = name or path_a
    pr = PairResult(name=name, path_a=path_a, path_b=path_b, status="match", rule="allowfailures",
                    references=[path_b], golden=path_b)
    try:
        counts_a = _levels(path_a, opts)
    except PyramidError as e:
        pr.status, pr.rule, pr.message, pr.a_readable = "file", "file", e.message, False
        return pr
    try:
        counts_b = _levels(path_b, opts)
    except PyramidError as e:
        pr.status, pr.rule, pr.message = "file", "file", e.message
        return pr
    for sub in range(min(len(counts_a), len(counts_b))):
        if counts_a[sub] != counts_b[sub]:
            pr.status, pr.rule = "size", "miplevels"
            pr.message = f"{path_a} and {path_b}: subimage {sub} has {counts_a[sub]} MIP levels vs {counts_b[sub]}"
            return pr
        for mip in range(counts_a[sub]):
            try:
                pa, names = read_pixels(path_a, opts, sub, mip)
            except PyramidError as e:
                pr.status, pr.rule, pr.message, pr.a_readable = "file", "file", e.message, False
                return pr
            try:
                pb, _ = read_pixels(path_b, opts, sub, mip)
            except PyramidError as e:
                pr.status, pr.rule, pr.message = "file", "file", e.message
                return pr
            try:
                r = compare(pa, pb, channel_names=names, **opts.thresholds)
            except ShapeMismatchError as e:
                pr.status = "size"
                pr.rule = "size" if pa.shape[:2] != pb.shape[:2] else "channels"
                where = f"subimage {sub} MIP level {mip}: " if opts.all_levels else ""
                pr.message = f"{path_a} and {path_b}: {where}{e}"
                return pr
            lv = LevelResult(sub, mip, r)
            if opts.metric == "flip":
                lv.flip = _flip_mean(pa, pb, opts.linear)
            pr.levels.append(lv)
    _decide(pr, opts, len(counts_a), len(counts_b))
    return pr


def _decide(pr: PairResult, opts: CompareOptions, nsub_a: int, nsub_b: int) -> None:
    worst = 0
    for lv in pr.levels:
        code = STATUS_CODES[lv.result.verdict]
        if code > worst:
            worst, pr.status, pr.rule = code, lv.result.verdict, lv.result.rule
    if pr.status == "match" and pr.levels:
        pr.rule = pr.levels[0].result.rule
    if opts.metric == "flip":
        over = [lv for lv in pr.levels if lv.flip is not None and lv.flip > opts.flip_fail]
        if over and worst < 2:
            pr.status, pr.rule = "failure", "flip"
            pr.message = f"mean FLIP {over[0].flip:.4g} > {opts.flip_fail:g}"
    if opts.all_levels and nsub_a != nsub_b and pr.exit_code < 2:
        pr.status, pr.rule = "failure", "subimages"
        pr.message = f"{nsub_a} subimages vs {nsub_b}"
    if not pr.message:
        r = pr.worst
        if r is not None:
            pr.message = (f"max error {format_value(r.max_error)}, {r.n_fail} pixels over fail, "
                          f"{r.n_warn} over warn ({pr.rule})")


# ---------------------------------------------------------------------------
# Pairing folders and globs

_MAGIC = set("*?[")
_FRAMES = re.compile(r"%0?(\d*)d|#|@")


def as_glob(path: str) -> str:
    """``path`` with frame-number patterns as globs: ``%04d`` is four digits, ``%d`` any digits,
    ``#`` four digits and ``@`` one (oiiotool's spelling)."""
    def digits(m: re.Match[str]) -> str:
        tok = m.group(0)
        if tok == "#":
            return "[0-9]" * 4
        if tok == "@":
            return "[0-9]"
        return "[0-9]" * int(m.group(1)) if m.group(1) else "[0-9]*"
    return _FRAMES.sub(digits, path)


def is_pattern(path: str) -> bool:
    """True when ``path`` is a glob pattern (``*``, ``?``, ``[``) or a frame sequence
    (``%04d``, ``#``, ``@``)."""
    return any(ch in _MAGIC for ch in as_glob(path))


def _listing(arg: str) -> tuple[str, dict[str, str]]:
    """Base folder and {relative path: path} of the images a folder or glob names."""
    from pyramid_cli.imageio.raw import image_extensions

    exts = image_extensions()
    found: dict[str, str] = {}
    if is_pattern(arg) and not os.path.exists(arg):
        arg = as_glob(arg)
        parts = arg.split(os.sep)
        fixed = []
        for part in parts:
            if is_pattern(part):
                break
            fixed.append(part)
        base = os.sep.join(fixed) or "."
        for p in sorted(glob.glob(arg, recursive=True)):
            if os.path.isfile(p):
                found[os.path.relpath(p, base)] = p
        return base, found
    for root, dirs, files in os.walk(arg):
        if root != arg and REPORT_MARKER in files:  # an HTML report written into out/ is not an output
            dirs[:] = []
            continue
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for f in sorted(files):
            if f.startswith(".") or os.path.splitext(f)[1][1:].lower() not in exts:
                continue
            p = os.path.join(root, f)
            found[os.path.relpath(p, arg)] = p
    return arg, found


#: The file that marks a folder as a ``--html`` report (written by :mod:`pyramid_cli.diff.html`), so that a
#: report kept beside the outputs (``--html out/diff-report``) is never compared or copied as a golden.
REPORT_MARKER = ".pyramid-diff-report"


@dataclass
class Pairing:
    """What :func:`pair_inputs` found: each output with its accepted references, and extra goldens."""

    pairs: list[tuple[str, str, list[str], str]]  # (name, output, references, primary golden path)
    extras: list[tuple[str, str]]                 # (name, golden path)
    many: bool                                    # folder / glob mode (a summary, not one report)


def _alternatives(rel: str) -> tuple[str, str]:
    stem, ext = os.path.splitext(rel)
    return stem + "-", ext


def pair_inputs(a: str, b: str) -> Pairing:
    """Pair outputs ``a`` with references ``b``.

    Parameters
    ----------
    a, b : str
        Two files; a file and a folder (``b/basename(a)``, as idiff does); two
        folders (every image file below them, paired by relative path); or two
        glob patterns (``**`` recursive; paired by the path below each
        pattern's fixed leading folders), or two frame sequences
        (``out/f.%04d.exr``, ``out/f.#.exr``: see :func:`as_glob`).

    Returns
    -------
    Pairing
        In folder / glob mode each output's references are ``rel`` and every
        ``stem-*.ext`` beside it that is not itself an output's primary golden.

    Raises
    ------
    PyramidError
        A folder paired with a file or a pattern with a non-pattern, or a pattern
        that matches nothing.
    """
    if _frame_sequences(a, b):
        return _pair_frames(a, b)
    a_dir, b_dir = os.path.isdir(a), os.path.isdir(b)
    a_pat, b_pat = is_pattern(a) and not os.path.exists(a), is_pattern(b) and not os.path.exists(b)
    if not a_dir and not a_pat:
        ref = os.path.join(b, os.path.basename(a)) if b_dir else b
        return Pairing(pairs=[(a, a, [ref], ref)], extras=[], many=False)
    if a_dir and not os.path.lexists(b):  # a golden folder not made yet: every golden is missing (--update makes it)
        b_dir = True
    if (a_dir and not b_dir and not b_pat) or (a_pat and not b_pat and not b_dir):
        from pyramid_cli.core.errors import UsageError

        raise UsageError(f"{a} is a {'folder' if a_dir else 'pattern'}: B must be a folder or a pattern too, "
                         f"not {b}")
    _, outs = _listing(a)
    b_base, golds = _listing(b)
    if a_pat and not outs:
        from pyramid_cli.core.errors import InputError

        raise InputError(f"no file matches {a}")
    used: set[str] = set()
    pairs = []
    for rel, path in outs.items():
        refs = [golds[rel]] if rel in golds else []
        prefix, ext = _alternatives(rel)
        for grel, gpath in golds.items():
            if grel.startswith(prefix) and grel.endswith(ext) and grel != rel and grel not in outs:
                refs.append(gpath)
        used.update(r for r in refs)
        pairs.append((rel, path, refs, os.path.join(b_base, rel)))
    extras = [(grel, gpath) for grel, gpath in golds.items() if gpath not in used]
    return Pairing(pairs=pairs, extras=extras, many=True)


def _frame_sequences(a: str, b: str) -> bool:
    from pyramid_cli.run import sequence

    return not (os.path.exists(a) or os.path.exists(b)) and sequence.is_sequence(a) and sequence.is_sequence(b)


def _pair_frames(a: str, b: str) -> Pairing:
    """Two frame sequences (``out/soft.####.exr`` against ``golden/plate.%04d.exr``), paired by frame number
    (:mod:`pyramid_cli.run.sequence`, fileseq's conventions): a frame with no golden is missing, a golden frame
    with no output is extra."""
    from pyramid_cli.run import sequence

    outs, golds = dict(sequence.frames_of(a)), dict(sequence.frames_of(b))
    sa, sb = sequence.parse(a), sequence.parse(b)
    assert sa is not None and sb is not None, "called for two frame sequences (_frame_sequences)"
    pairs, extras = [], []
    for f in sorted(set(outs) | set(golds)):
        out, gold = outs.get(f) or sa.frame(f), golds.get(f) or sb.frame(f)
        if not os.path.exists(out):
            if os.path.exists(gold):
                extras.append((os.path.basename(gold), gold))
            continue
        pairs.append((os.path.basename(out), out, [gold] if os.path.exists(gold) else [], gold))
    return Pairing(pairs=pairs, extras=extras, many=True)


def compare_pairs(pairing: Pairing, opts: CompareOptions,
                  progress: Callable[[PairResult], None] | None = None) -> list[PairResult]:
    """Compare every pair of ``pairing``; an output passes when any one reference matches.

    Returns
    -------
    list of PairResult
        One per output (the best reference's result), then one ``"extra"`` per
        golden with no output, in order.
    """
    results: list[PairResult] = []
    for name, out, refs, golden in pairing.pairs:
        if not refs:
            pr = PairResult(name=name, path_a=out, path_b=golden, status="missing", rule="missing",
                            message=f"no golden for {out} (expected {golden})", golden=golden)
        else:
            tried = [compare_files(out, ref, opts, name=name) for ref in refs]
            pr = min(tried, key=lambda t: t.exit_code)
            pr.references = list(refs)
            pr.golden = golden
            pr.a_readable = all(t.a_readable for t in tried)
        results.append(pr)
        if progress:
            progress(pr)
    for name, gpath in pairing.extras:
        pr = PairResult(name=name, path_a=None, path_b=gpath, status="extra", rule="extra",
                        message=f"golden {gpath} has no output", a_readable=False)
        results.append(pr)
        if progress:
            progress(pr)
    return results


# ---------------------------------------------------------------------------
# Updating goldens

UPDATED_STATUSES = ("failure", "size", "missing", "file")


def goldens_to_update(results: Sequence[PairResult]) -> list[PairResult]:
    """The pairs ``--update`` rewrites: failing, size-mismatched, missing or unreadable goldens whose
    output was read (warnings, matches and extra goldens are left alone)."""
    return [r for r in results
            if r.status in UPDATED_STATUSES and r.a_readable and r.path_a and r.golden]


def copy_atomic(src: str, dst: str) -> None:
    """Copy ``src`` over ``dst`` byte for byte; an interrupted copy leaves ``dst`` as it was.

    Raises
    ------
    OutputError
        The copy cannot be written.
    """
    from pyramid_cli.imageio.atomic import atomic_path

    folder = os.path.dirname(os.path.abspath(dst))
    os.makedirs(folder, exist_ok=True)
    with atomic_path(dst) as tmp:
        shutil.copyfile(src, tmp)


def update_goldens(results: Sequence[PairResult], *, dry_run: bool = False) -> list[tuple[str, str]]:
    """Copy each failing or missing pair's output over its golden.

    Parameters
    ----------
    results : sequence of PairResult
    dry_run : bool
        List what would be copied and write nothing.

    Returns
    -------
    list of (str, str)
        ``(output, golden)`` for each copy made (or to make).
    """
    done = []
    for r in goldens_to_update(results):
        assert r.path_a is not None and r.golden is not None
        if not dry_run:
            copy_atomic(r.path_a, r.golden)
        done.append((r.path_a, r.golden))
    return done
