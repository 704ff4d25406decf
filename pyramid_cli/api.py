"""The Python API: ``import pyramid_cli as pyr``.

Functions on numpy arrays (``apply``, ``reduce``, ``expand``, ``blur``, ``pyramid``, ``laplacian``,
``collapse``, ``mipmap``, and the methods built on them: ``fill``, ``blend``), image files (``read_image``,
``write_image``, ``process_files``), and :class:`~pyramid_cli.exec.session.Session`, which owns one
executor for many calls. They describe jobs as :mod:`pyramid_cli.jobs.work` values and run them through
the same session and pipeline as the ``pyramid`` command. Every function checks its arguments before it
returns (:func:`pyramid` too, which returns an iterator).

Arrays: 2-D is one channel, 3-D is H×W×C with any C (results keep the layout). Values are read
as scikit-image's ``img_as_float`` reads them: floats as they are, integer arrays as normalised
codes (unsigned: code / max, signed: code / max clipped at −1), booleans as 0/1. Pixels are
linear light: filtering sRGB codes directly is the caller's choice (``read_image`` decodes files).

Result dtype (:mod:`pyramid_cli.imageio.dtypes`): the input's, or ``dtype=``. float16/32 results are
computed in float32 (every executor's width); float64 results in float64 by the CPU executor's float64
kernels (``"auto"``, ``"cpu"``; about 1.6× the float32 time: ``dtype=np.float32`` is the fast path) or
the float64 oracle (``"reference"``), and in float32 then widened on ``"gl"``. Integer inputs come back
as codes of their type, ``round(value · max)`` clipped (NaN as 0); booleans as float32. Every level of a pyramid has one
dtype and none is the caller's memory (level 0 is a copy), except in band-by-band runs (``out=``,
``memory=``, a memmap input: computed in float32, level 0 the caller's array itself).

Borders: ``"clamp"``, ``"mirror"``, ``"wrap"``, ``"zero"``, or another library's exact name for one
(:data:`pyramid_cli.core.border.BORDER_ALIASES`, listed in each function's docstring). ``"reflect"``
is refused: numpy's and scikit-image's (d c b | a b c d) is no mode here, scipy's and OpenCV's is
``"mirror"`` (numpy's ``"symmetric"``).

Without ``session=``, a module-level session per backend is made on first use and closed at exit.

Errors (:mod:`pyramid_cli.core.errors`, each with the message the command line prints): ``UsageError``
(a bad argument) and ``DataError`` (bad pixel data) are ``ValueError`` s; ``InputError`` and
``OutputError`` (a file that cannot be read or written) ``OSError`` s; ``BackendError`` (no GL context).
Warnings: what the command line prints as ``pyramid: warning: …`` comes through :mod:`warnings` at the
caller's line as a ``PyramidWarning`` (``MixedLatticeWarning``, ``MaskWarning``, ``BackendWarning``);
what ``-v`` says is logged at INFO on the ``pyramid_cli`` logger.

References
----------
Kraus & Strengert, "Pyramid Filters Based on Bilinear Interpolation", GRAPP 2007:
§3 convolution, §4 analysis (⊗↓), §5 synthesis (⊗↑), §2 and Figure 3 the blur.
"""

from __future__ import annotations

import atexit
import logging
import os
from collections.abc import Iterator, Sequence
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from pyramid_cli import imageio as io
from pyramid_cli.core import catalogue, errors, options
from pyramid_cli.core.border import aliases_text, canonical
from pyramid_cli.core.errors import BackendWarning, MaskWarning, MixedLatticeWarning, PyramidWarning
from pyramid_cli.core.expr import Expr, Op
from pyramid_cli.core.geometry import reduced
from pyramid_cli.core.parse import one_step, parse
from pyramid_cli.exec.session import Session
from pyramid_cli.imageio import dtypes
from pyramid_cli.jobs.texture import TextureLevels
from pyramid_cli.jobs.work import (
    Blend,
    Blur,
    Collapse,
    Fill,
    Filter,
    Laplacian,
    Levels,
    SigmaBlur,
    Work,
    blur_work,
    same_setting,
)
from pyramid_cli.run import arrays
from pyramid_cli.run.arrays import ArrayInput
from pyramid_cli.run.joblist import Report
from pyramid_cli.run.report import PythonReporter
from pyramid_cli.run.tiles import tiles  # pyr.tiles: a viewer's tile set, streamed (its body lives in run/)

#: The logger of what ``-v`` says (the executor chosen and why, a sigma blur's blend): INFO records.
log = logging.getLogger("pyramid_cli")

_sessions: dict[str, Session] = {}


def _session(session: Session | None, backend: str) -> Session:
    if session is not None:
        return session
    options.check("backend", backend, options.BACKENDS)
    if backend not in _sessions:
        _sessions[backend] = Session(backend, warn=partial(errors.warn, category=BackendWarning), note=log.info)
    return _sessions[backend]


@atexit.register
def _close_sessions() -> None:
    for s in _sessions.values():
        s.close()
    _sessions.clear()


def as_pixels(array: ArrayLike, name: str = "array") -> np.ndarray:
    """``array`` as pixels the executors take: 2-D or 3-D, float (integers normalised to float32, see the
    module notes; floats as they are).

    Raises
    ------
    ValueError
        Not 2-D or 3-D, empty, or not a real number type (a :class:`~pyramid_cli.core.errors.UsageError`).
    """
    return dtypes.as_pixels(array, name)


def _run(work: Work, inp: ArrayInput, session: Session | None, backend: str,
         more: Sequence[np.ndarray] = ()) -> list[np.ndarray]:
    """``work`` on ``inp`` (and ``more`` inputs' pixels), at its width and as its dtype."""
    return arrays.run(_session(session, backend), work, [inp.pixels, *more], inp)


def _check_levels(levels: int, least: int = 1) -> None:
    if not least <= levels <= options.MAX_LEVELS:
        raise errors.UsageError(f"levels must be {least} to {options.MAX_LEVELS}, not {levels}")


def _warn_work(work: Work, size: tuple[int, int] | None = None) -> None:
    """The work's warnings (:meth:`~pyramid_cli.jobs.work.Work.warnings`) as MixedLatticeWarnings at the
    caller's line, and its notes (:meth:`~pyramid_cli.jobs.work.Work.notes`) logged."""
    for message in work.warnings(size):
        errors.warn(message, MixedLatticeWarning)
    for message in work.notes(size):
        log.info(message)


_warn_mask = partial(errors.warn, category=MaskWarning)  # methods.mask_weights' warnings, at the caller's line


class Bands(list):
    """Laplacian bands (a list of arrays) that remember the ``synthesis`` and ``border`` they were made with,
    so that :func:`collapse` uses them and refuses others; a plain list works too, unchecked."""

    def __init__(self, bands: Sequence[np.ndarray], *, analysis: str, synthesis: str, border: str):
        super().__init__(bands)
        self.analysis, self.synthesis, self.border = analysis, synthesis, border


# ------------------------------------------------------------------ arrays
def apply(expr: str | Expr, array: ArrayLike, *, border: str = "clamp", dtype: DTypeLike | None = None,
          backend: str = "auto", session: Session | None = None, out: np.ndarray | None = None,
          memory: int | str | None = None) -> np.ndarray:
    """Apply a filter-chain expression to an image.

    Parameters
    ----------
    expr : str or Expr
        The paper's notation or its ASCII spelling, e.g. ``"h_quadratic ⊗↓ g"`` or
        ``"quadratic *v g"`` (§3 ⊗, §4 ⊗↓, §5 ⊗↑); chains are right-associative.
    array : array_like
        H×W or H×W×C pixels.
    border : str
        How every written operator reads past its input's edges (docs/design.md §1): ``"clamp"``
        (numpy's and scikit-image's ``"edge"``, scipy's ``"nearest"``, OpenCV's ``"replicate"``),
        ``"mirror"`` (d c b a | a b c d: numpy's and scikit-image's ``"symmetric"``, scipy's
        ``"grid-mirror"``), ``"wrap"`` (``"periodic"``, ``"grid-wrap"``) or ``"zero"``
        (``"constant"``, ``"grid-constant"``, ``"black"``). ``"reflect"`` is refused: numpy's
        (d c b | a b c d) is no mode here, and scipy's and OpenCV's is ``"mirror"``.
    dtype : dtype, optional
        The result's type; default the input's (floats keep their width, integer codes come back as
        their type, rounded and clipped; see the module notes for the width each is computed at).
    backend : {"auto", "gl", "cpu", "reference"}
        Where it runs (ignored when ``session`` is given).
    session : Session, optional
        Reuse one executor across calls.
    out : numpy.ndarray, optional
        Write the result here (float16/32/64 of the result's shape), e.g. a ``numpy.memmap`` on disk.
        With ``out``, a ``numpy.memmap`` input or ``memory``, the image runs band by band in bounded memory
        (the pixels of the whole run, in float32), so images larger than RAM work.
    memory : int or str, optional
        Working-set budget of a banded run in bytes, or ``"512M"``, ``"2G"`` (default: what the container's
        memory limit, the rlimits and the available memory leave: :func:`pyramid_cli.run.budget.default_budget`).

    Returns
    -------
    numpy.ndarray
        ``dtype`` (or ``out``); ⊗ keeps the size, ⊗↓ gives ⌈n/2⌉, ⊗↑ gives 2n per axis.

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> pyr.apply("box4 *v g", np.ones((5, 3))).shape
    (3, 2)
    >>> pyr.apply("doosabin *^ g", np.ones((2, 2, 3)), border="symmetric").shape
    (4, 4, 3)
    """
    work = Filter(expr=parse(expr) if isinstance(expr, str) else expr, border=border)
    if arrays.wanted(array, out, memory):
        return arrays.banded(_session(session, backend), work, array, None if out is None else [out], memory, dtype)[0]
    (result,) = _run(work, ArrayInput(array, dtype), session, backend)
    return result


def reduce(array: ArrayLike, *, analysis: str = catalogue.DEFAULT_ANALYSIS, border: str = "clamp",
           dtype: DTypeLike | None = None, backend: str = "auto", session: Session | None = None) -> np.ndarray:
    """One analysis step (§4), ⌈n/2⌉ per axis: ``apply(f"{analysis} *v g", array)`` (OpenCV's ``pyrDown``,
    scikit-image's ``pyramid_reduce``, with the paper's filters and lattice instead of a Gaussian).

    ``analysis`` is a ⊗↓ filter (box, box4, quadratic, cubic) or a one-step expression (``"box *v^2 g"``);
    ``border``, ``dtype``, ``backend``, ``session`` as in :func:`apply`: ``border`` one of {borders}. The
    result is ``dtype`` (default the input's).

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> pyr.reduce(np.ones((5, 3), dtype=np.uint8) * 200, analysis="quadratic")
    array([[200, 200],
           [200, 200],
           [200, 200]], dtype=uint8)
    """
    return apply(one_step(analysis, Op.DOWN), array, border=border, dtype=dtype, backend=backend, session=session)


def expand(array: ArrayLike, *, synthesis: str = catalogue.DEFAULT_SYNTHESIS, border: str = "clamp",
           dtype: DTypeLike | None = None, backend: str = "auto", session: Session | None = None) -> np.ndarray:
    """One synthesis step (§5), 2n per axis: ``apply(f"{synthesis} *^ g", array)`` (OpenCV's ``pyrUp``,
    scikit-image's ``pyramid_expand``, with the paper's filters and lattice).

    ``synthesis`` is a ⊗↑ filter (nearest, midpoint, doosabin, cubic, fourpoint) or a one-step expression;
    ``border``, ``dtype``, ``backend``, ``session`` as in :func:`apply`: ``border`` one of {borders}. The
    result is ``dtype`` (default the input's).

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> pyr.expand(np.ones((2, 3), dtype=np.float64)).dtype, pyr.expand(np.ones((2, 3))).shape
    (dtype('float64'), (4, 6))
    """
    return apply(one_step(synthesis, Op.UP), array, border=border, dtype=dtype, backend=backend, session=session)


def blur(array: ArrayLike, levels: int = 4, *, sigma: float | None = None,
         analysis: str = catalogue.DEFAULT_ANALYSIS, synthesis: str = catalogue.DEFAULT_SYNTHESIS,
         quasi: bool = False, border: str = "clamp", dtype: DTypeLike | None = None, backend: str = "auto",
         session: Session | None = None, out: np.ndarray | None = None, memory: int | str | None = None
         ) -> np.ndarray:
    """Pyramidal blur: ``levels`` analysis steps down, then synthesis back to the input size (§2, Figure 3).

    Parameters
    ----------
    array : array_like
        H×W or H×W×C pixels.
    levels : int
        Analysis steps (1 to 16); ignored when ``sigma`` is given.
    sigma : float, optional
        Strength as a Gaussian sigma in input pixels: the blend of two neighbouring
        level counts whose equivalent kernel has that standard deviation.
    analysis, synthesis : str
        A ⊗↓ filter (box, box4, quadratic, cubic, §4) and a ⊗↑ filter (nearest,
        midpoint, doosabin, cubic, fourpoint, §5), or one-step expressions.
        The defaults are the paper's Figure 3b. A pair on two lattices (``pyramid explain`` shows a
        filter's) shifts the result by half a fine pixel per level and warns (MixedLatticeWarning).
    quasi : bool
        Apply the §5.5 quasi-interpolation prefilter at the coarsest level.
    border, dtype, backend, session, out, memory
        As in :func:`apply` (``out`` and memory-mapped inputs run band by band); ``border`` one of {borders}.

    Returns
    -------
    numpy.ndarray
        ``dtype`` (default the input's, or ``out``), the input's shape.

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> impulse = np.zeros((33, 33)); impulse[16, 16] = 1
    >>> soft = pyr.blur(impulse, 3)
    >>> soft.shape, soft.dtype, round(float(soft.sum()), 4)
    ((33, 33), dtype('float64'), 1.0)
    """
    if sigma is None:
        _check_levels(levels)
    work = blur_work(levels, sigma=sigma, analysis=analysis, synthesis=synthesis, quasi=quasi, border=border)
    if arrays.wanted(array, out, memory):
        _warn_work(work)
        return arrays.banded(_session(session, backend), work, array, None if out is None else [out], memory, dtype)[0]
    inp = ArrayInput(array, dtype)
    _warn_work(work)
    (result,) = _run(work, inp, session, backend)
    return result


def pyramid(array: ArrayLike, *, analysis: str = catalogue.DEFAULT_ANALYSIS, levels: int | None = None,
            border: str = "clamp", dtype: DTypeLike | None = None, backend: str = "auto",
            session: Session | None = None, out: Sequence[np.ndarray] | Any = None,
            memory: int | str | None = None) -> Iterator[Any]:
    """The analysis pyramid (§4), level 0 (a copy of the input) first, as scikit-image's ``pyramid_gaussian``.

    The levels are computed (and the arguments checked) when it is called; it returns an iterator over them.

    Parameters
    ----------
    array : array_like
        H×W or H×W×C pixels.
    analysis : str
        A ⊗↓ filter or one-step expression.
    levels : int, optional
        Reductions after level 0 (0 to 16); None goes down to 1×1 (scikit-image's convention).
    border, dtype, backend, session, memory
        As in :func:`apply`: ``border`` one of {borders}.
    out : sequence of numpy.ndarray, optional
        One array per level after level 0 to write into (memmaps, say); with it, ``memory`` or a
        memory-mapped input the pyramid runs band by band, as in :func:`apply`, and level 0 is ``array``
        itself (not a copy: a memmap stays on disk). Or a ``zarr.Group`` or ``.zarr`` path: every level is written
        there as OME-Zarr (:mod:`~pyramid_cli.imageio.tilesets.omezarr`) and comes back as a zarr array (c, y, x).

    Returns
    -------
    Iterator of numpy.ndarray
        Level k has ⌈n/2ᵏ⌉ rows and columns; every level is of ``dtype`` (default the input's).

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> a = np.random.default_rng(0).random((5, 3))
    >>> levels = list(pyr.pyramid(a))
    >>> levels[0] is a, bool((levels[0] == a).all()), [lv.shape for lv in levels]
    (False, True, [(5, 3), (3, 2), (2, 1), (1, 1)])
    """
    if levels is not None:
        _check_levels(levels, 0)
    work = Levels(levels=levels, analysis=analysis, border=border)
    if arrays.zarr_out(out):
        return iter(arrays.to_zarr(out, list(pyramid(array, analysis=analysis, levels=levels, border=border,
                    dtype=dtype, backend=backend, session=session, memory=memory)), analysis))
    if arrays.wanted(array, out, memory):
        outs = arrays.banded(_session(session, backend), work, array, out, memory, dtype)
        return iter([arrays.as_array(array), *outs])
    return iter(_run(work, ArrayInput(array, dtype), session, backend))


def laplacian(array: ArrayLike, levels: int = 4, *, analysis: str = catalogue.DEFAULT_ANALYSIS,
              synthesis: str = catalogue.DEFAULT_SYNTHESIS, border: str = "clamp", dtype: DTypeLike | None = None,
              backend: str = "auto", session: Session | None = None, out: Sequence[np.ndarray] | None = None,
              memory: int | str | None = None) -> Bands:
    """Laplacian bands L_k = G_k − expand(G_k+1) for k < ``levels``, then the coarsest G_m (Burt & Adelson).

    Returns a :class:`Bands` list that records ``synthesis`` and ``border``: :func:`collapse` sums it
    back to the input with them, exactly up to float rounding. ``out`` (one array per band), ``memory``
    or a memory-mapped input run it band by band, as in :func:`apply`. ``border`` is one of {borders}.

    Bands are signed: a float input's keep its dtype, an integer input's are float32 (``dtype=`` asks for
    another).

    Unlike scikit-image's ``pyramid_laplacian``, whose layer k is G_k minus G_k *smoothed at the same
    size* (a Gaussian of sigma 2/3 by default) and whose last layer is such a band too (so the layers do not
    sum back to the image), each band here is G_k minus the *expansion of the next level* (§5 synthesis),
    and the last element is the coarse image G_m itself: the same shapes, another meaning, and
    :func:`collapse` inverts it. ``levels`` defaults to 4, not to 1×1.

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> a = np.random.default_rng(1).random((17, 13, 3)).astype(np.float32)
    >>> bands = pyr.laplacian(a, 3)
    >>> [b.shape[:2] for b in bands]
    [(17, 13), (9, 7), (5, 4), (3, 2)]
    >>> bool(np.abs(pyr.collapse(bands) - a).max() < 1e-5)
    True
    """
    _check_levels(levels)
    work = Laplacian(levels=levels, analysis=analysis, synthesis=synthesis, border=border)
    if arrays.wanted(array, out, memory):
        bands = arrays.banded(_session(session, backend), work, array, out, memory, dtype)
    else:
        a = np.asarray(array)
        signed = dtype if dtype is not None or a.dtype.kind == "f" else np.float32
        bands = _run(work, ArrayInput(a, signed), session, backend)
    return Bands(bands, analysis=analysis, synthesis=synthesis, border=work.border)


def collapse(bands: Sequence[ArrayLike], *, synthesis: str | None = None, border: str | None = None,
             dtype: DTypeLike | None = None, backend: str = "auto", session: Session | None = None) -> np.ndarray:
    """Sum Laplacian bands back to the image: G_k = L_k + expand(G_k+1) (inverse of :func:`laplacian`).

    The image comes back only with the ``synthesis`` and ``border`` the bands were made with. The
    :class:`Bands` that :func:`laplacian` returns record them: they are used by default, and others are
    refused (ValueError), as ``pyramid collapse`` refuses what contradicts a file's record. A plain list
    of arrays cannot say: its defaults are the paper's Doo-Sabin and ``"clamp"``, and a wrong one gives
    a wrong image without an error. Band sizes and channel counts are checked either way. ``border``
    as in :func:`apply` (one of {borders}); the result is ``dtype``, default the bands' (all
    the bands' dtypes combined, as ``numpy.result_type``).

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> a = np.random.default_rng(2).random((9, 8))
    >>> bands = pyr.laplacian(a, 2, synthesis="nearest", border="mirror")
    >>> bool(np.abs(pyr.collapse(bands) - a).max() < 1e-12)
    True
    >>> pyr.collapse(bands, synthesis="doosabin")
    Traceback (most recent call last):
    ...
    pyramid_cli.core.errors.UsageError: the bands were made with synthesis 'nearest'; collapsing with 'doosabin' ...
    """
    recorded = {k: getattr(bands, k, None) for k in ("synthesis", "border")}
    synthesis = _as_recorded("synthesis", synthesis, recorded["synthesis"], catalogue.DEFAULT_SYNTHESIS)
    border = _as_recorded("border", None if border is None else canonical(border), recorded["border"], "clamp")
    given = [np.asarray(b) for b in bands]
    if len(given) < 2:
        raise errors.UsageError(f"collapse needs at least two bands, got {len(given)}")
    joint = ArrayInput(given[0], dtype if dtype is not None else np.result_type(*[b.dtype for b in given]), "band 0")
    pixels = [dtypes.as_pixels(b, f"band {k}", joint.wide) for k, b in enumerate(given)]
    for k in range(1, len(pixels)):
        want = tuple(reduced(n) for n in pixels[k - 1].shape[:2])
        if pixels[k].shape[:2] != want or pixels[k].shape[2:] != pixels[0].shape[2:]:
            raise errors.UsageError(f"band {k} has shape {pixels[k].shape}; after {pixels[k - 1].shape} it must "
                                    f"be {want + pixels[0].shape[2:]}")
    (out,) = _run(Collapse(bands=len(pixels), synthesis=synthesis, border=border), joint, session, backend,
                  pixels[1:])
    return out


def _as_recorded(what: str, asked: str | None, recorded: str | None, default: str) -> str:
    """``asked`` where it agrees with what :class:`Bands` record, the record where not asked."""
    if asked is None:
        return recorded or default
    if recorded is not None and not same_setting(what, asked, recorded):
        raise errors.UsageError(f"the bands were made with {what} {recorded!r}; collapsing with {asked!r} would "
                                "not give the image back")
    return asked


def mipmap(array: ArrayLike, *, analysis: str = catalogue.MIP_ANALYSIS_DEFAULT, border: str = "clamp",
           rounding: str = "down", dtype: DTypeLike | None = None, backend: str = "auto",
           session: Session | None = None, out: Sequence[np.ndarray] | None = None,
           memory: int | str | None = None) -> list[np.ndarray]:
    """MIP levels down to 1×1, level 0 (a copy of the input) first, as ``pyramid mipmap`` writes them.

    Every level is of ``dtype`` (default the input's). ``border`` as in :func:`apply` (one of {borders}).
    ``out`` (one array per level after level 0), ``memory`` or a memory-mapped
    input run it band by band, as in :func:`apply` (level 0 is then ``array`` itself).

    ``rounding`` "down" (maketx's and OpenEXR's sizes ``max(1, ⌊n/2⌋)``): a level that halves
    exactly is the paper's ⊗↓ (§4) of the one above; any other is resampled with the same
    filter's kernel stretched to the ratio, covering the whole texture domain
    (:mod:`pyramid_cli.plan.resample`). "up": the analysis pyramid's ``⌈n/2⌉`` (:func:`pyramid`).

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> [lv.shape for lv in pyr.mipmap(np.ones((5, 8, 4)))]
    [(5, 8, 4), (2, 4, 4), (1, 2, 4), (1, 1, 4)]
    >>> [lv.shape for lv in pyr.mipmap(np.ones((5, 8, 4)), rounding="up")]
    [(5, 8, 4), (3, 4, 4), (2, 2, 4), (1, 1, 4)]
    """
    work = TextureLevels(levels=None, analysis=analysis, border=border, rounding=rounding)
    if arrays.wanted(array, out, memory):
        return [arrays.as_array(array), *arrays.banded(_session(session, backend), work, array, out, memory, dtype)]
    return _run(work, ArrayInput(array, dtype), session, backend)


def fill(array: ArrayLike, *, mask: ArrayLike | None = None, holes: str | None = None, levels: int | None = None,
         analysis: str = catalogue.FILL_ANALYSIS, synthesis: str = catalogue.FILL_SYNTHESIS,
         weight_scale: int | tuple[int, int] = catalogue.FILL_SCALE,
         sweeps: int | tuple[int, int] = catalogue.FILL_SWEEPS,
         keep_alpha: bool = False, border: str = "clamp", dtype: DTypeLike | None = None, backend: str = "auto",
         session: Session | None = None) -> np.ndarray:
    """Fill holes by pull-push (Kraus, "The Pull-Push Algorithm Revisited", GRAPP 2009).

    Known pixels are pulled down the analysis pyramid as premultiplied colours with their
    weights (a coarse weight is ``weight_scale``× the filtered weight, clamped to 1), then each level is
    composited over the expanded coarser one by its weight (§4 ⊗↓ and §5 ⊗↑ filters of
    Kraus & Strengert 2007) and, at levels 1 and coarser, smoothed by ``sweeps`` membrane sweeps
    (:mod:`pyramid_cli.workflows.methods`). Pixels of weight 1 come out unchanged; holes get a smooth
    interpolation of what surrounds them.

    Parameters
    ----------
    array : array_like
        H×W or H×W×C pixels, linear light; with an alpha channel premultiplied (as
        :func:`read_image` gives them).
    mask : array_like, optional
        Weights in [0, 1] (H×W, or H×W×C one per channel): 1 known, 0 a hole, between partly
        known. Implies ``holes="mask"``. NaN/Inf are kept (they spread) and values outside [0, 1]
        clipped, each with a MaskWarning.
    holes : {"alpha", "mask", "nan"}, optional
        Where the weights come from: the alpha channel (the last of 2 or 4 channels; the
        default without ``mask``), ``mask``, or every pixel with a NaN/Inf is a hole.
    levels : int, optional
        Pull steps; default down to 1×1 (so every hole is filled, however large).
    analysis, synthesis : str
        The pull's ⊗↓ filter (default the biquadratic B-spline, §4.3) and the push's ⊗↑ filter
        (default Doo-Sabin, §5.3), or one-step expressions. A pair on two lattices fills from beside
        the holes (2–3× the error) and warns (MixedLatticeWarning).
    weight_scale, sweeps : int or (int, int)
        The weight scale K (1 … 2²⁰) and the membrane smoothing sweeps (0 … 64), one for every
        level or a pair (level 1, the coarser levels). The defaults ((16, 2) and (1, 4)) beat
        ``oiiotool --fillholes`` on the project's test images; Gortler's classic pull-push, the
        former default, is ``analysis="box4", weight_scale=4, sweeps=0``.
    keep_alpha : bool
        With ``holes="alpha"``: return the input's alpha beside the filled colours, which are
        then straight (not multiplied by alpha), instead of an opaque image.
    border, dtype, backend, session
        As in :func:`apply`: ``border`` one of {borders}.

    Returns
    -------
    numpy.ndarray
        ``dtype`` (default the input's), the input's shape; the alpha channel (``holes="alpha"``) is 1 everywhere,
        as ``oiiotool --fillholes`` writes it (or the input's, with ``keep_alpha``).

    Raises
    ------
    ValueError
        No alpha channel for ``holes="alpha"``, a mask of another size or channel count
        (:class:`~pyramid_cli.core.errors.UsageError`); no known pixel at all, NaN/Inf in a known
        pixel (:class:`~pyramid_cli.core.errors.DataError`).

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> ramp = np.tile(np.linspace(0, 1, 9), (5, 1))
    >>> known = np.ones_like(ramp); known[1:4, 2:7] = 0
    >>> filled = pyr.fill(ramp, mask=known)
    >>> bool(np.all(filled[known == 1] == ramp[known == 1]).item())
    True
    >>> [round(float(v), 2) for v in filled[2]]
    [0.0, 0.12, 0.2, 0.32, 0.48, 0.64, 0.8, 0.88, 1.0]
    """
    from pyramid_cli.workflows.methods import fill_inputs

    holes = holes or ("mask" if mask is not None else "alpha")
    if keep_alpha and holes != "alpha":
        raise errors.UsageError(f"keep_alpha keeps the alpha the holes come from; with holes={holes!r} every "
                                "channel is filled")
    inp = ArrayInput(array, dtype)
    pixels = inp.pixels
    colour, weight, premultiplied = fill_inputs(pixels, holes, None if mask is None else as_pixels(mask, "mask"),
                                                warn=_warn_mask)
    work = Fill(levels=levels, analysis=analysis, synthesis=synthesis, premultiplied=premultiplied, border=border,
                weight_scale=weight_scale, sweeps=sweeps)
    _warn_work(work, pixels.shape[:2])
    (out,) = _session(session, backend).run(work, [arrays.fill_colour(colour, inp, holes), weight], inp.compute)
    return arrays.fill_result(out, inp, holes, keep_alpha)


def blend(a: ArrayLike, b: ArrayLike, mask: ArrayLike, *, levels: int | None = None,
          analysis: str = catalogue.DEFAULT_ANALYSIS, synthesis: str = catalogue.DEFAULT_SYNTHESIS,
          border: str = "clamp", dtype: DTypeLike | None = None, backend: str = "auto",
          session: Session | None = None) -> np.ndarray:
    """Join ``a`` and ``b`` along ``mask`` without a seam (Burt & Adelson, "A Multiresolution Spline With
    Application to Image Mosaics", ACM ToG 1983).

    Each Laplacian band of A and B (:func:`laplacian`) is blended with the same level of the
    mask's analysis pyramid (:func:`pyramid`), ``GM·LA + (1 − GM)·LB``, and the bands are
    collapsed (:func:`collapse`): fine detail joins over a narrow seam, coarse shading over a
    wide one.

    Parameters
    ----------
    a, b : array_like
        H×W or H×W×C pixels of one shape.
    mask : array_like
        H×W (or H×W×1) weights in [0, 1], or H×W×C one per channel: 1 takes A, 0 takes B.
        Another channel count raises ValueError; NaN/Inf are kept (they spread) and values
        outside [0, 1] clipped, each with a MaskWarning.
    levels : int, optional
        Laplacian levels; default as many as the size allows while the coarsest level keeps 16
        pixels on its shorter side (:func:`pyramid_cli.workflows.methods.blend_levels`; 4 at 256×256, 7 at
        3840×2160): deeper bands would mix the two images' mean colours across the whole frame.
    analysis, synthesis : str
        ⊗↓ and ⊗↑ filters (§4, §5); the defaults are the paper's Figure 3b. A pair on two
        lattices moves the seam (7.5 px at 4 levels) and warns (MixedLatticeWarning).
    border, dtype, backend, session
        As in :func:`apply`: ``border`` one of {borders}.

    Returns
    -------
    numpy.ndarray
        ``dtype`` (default ``a``'s), the shape of ``a``.

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> a, b = np.zeros((16, 16)), np.ones((16, 16))
    >>> left = np.zeros((16, 16)); left[:, :8] = 1
    >>> pyr.blend(a, b, left, levels=2)[8, ::3].round(3)
    array([0.   , 0.094, 0.328, 0.672, 0.906, 1.   ])
    """
    from pyramid_cli.workflows.methods import mask_channels

    ia, ib = ArrayInput(a, dtype, "a"), ArrayInput(b, dtype, "b")
    if ia.pixels.shape != ib.pixels.shape:
        raise errors.UsageError(f"a has shape {ia.pixels.shape} and b {ib.pixels.shape}: they must have one shape")
    m = mask_channels(as_pixels(mask, "mask"), ia.pixels, warn=_warn_mask)
    if levels is not None and levels < 0:
        raise errors.UsageError(f"levels must be 0 or more, not {levels}")
    work = Blend(levels=levels, analysis=analysis, synthesis=synthesis, border=border)
    _warn_work(work, ia.pixels.shape[:2])
    (out,) = _run(work, ia, session, backend, [ib.at(ia.wide), m])
    return out


# ------------------------------------------------------------------ files
def read_image(path: str | os.PathLike[str], *, colorspace: str = "auto", alpha: str = "auto",
               nan: str = "keep", colorconfig: str | None = None) -> io.Image:
    """Read an image file into linear-light float32 pixels (alpha premultiplied) and its metadata.

    ``colorspace``, ``alpha``, ``nan`` and ``colorconfig`` are the CLI's ``--colorspace``, ``--alpha``,
    ``--nan`` and ``--colorconfig``; see :func:`pyramid_cli.imageio.read_image`. The result's ``pixels``
    is H×W×C, in the linear space ``spec.linear_space`` names.
    """
    return io.read_image(path, colorspace=colorspace, alpha=alpha, nan=nan, colorconfig=colorconfig)


def write_image(path: str | os.PathLike[str], image, *, like: io.Image | None = None,
                pixel_type: str | None = None, colorspace: str | None = None, alpha: str | None = None,
                dither: bool = False, compression: str | None = None, force: bool = False,
                channel_names: list[str] | None = None, tocolorspace: str | None = None,
                colorconfig: str | None = None) -> None:
    """Write an :class:`~pyramid_cli.imageio.Image` (like its source) or an array of linear pixels, atomically.

    An array is stored like ``like`` (an image from :func:`read_image`: its type,
    channels, colour and alpha rules and metadata) or, without it, as float where the
    format allows with channels named by count (Y, YA, RGB, RGBA, or ``channel_names``).
    ``pixel_type`` etc. are the CLI's options; ``tocolorspace`` (or its older name ``colorspace``) is
    the space stored, ``colorconfig`` the OpenColorIO config of an array's names.
    """
    if tocolorspace is not None and colorspace is not None and tocolorspace != colorspace:
        raise ValueError(f"tocolorspace={tocolorspace!r} and colorspace={colorspace!r}: give one")
    colorspace = tocolorspace if tocolorspace is not None else colorspace
    if not isinstance(image, io.Image):
        pixels = as_pixels(image)
        pixels = pixels if pixels.ndim == 3 else pixels[:, :, None]
        info = like.spec if like is not None else io.info_for_array(path, pixels.shape[2], channel_names)
        if colorconfig is not None and like is None:
            info.colorconfig = colorconfig
        if len(info.channel_names) != pixels.shape[2]:
            raise ValueError(f"{pixels.shape[2]} channel(s) cannot be stored like {len(info.channel_names)}")
        image = io.Image(np.ascontiguousarray(pixels, dtype=np.float32), info)
    io.write_image(path, image, pixel_type=pixel_type, colorspace=colorspace, alpha=alpha, dither=dither,
                   compression=compression, force=force)


def process_files(work: Work, inputs: Sequence[str], output: str | None = None, *, template: str | None = None,
                  backend: str = "auto", session: Session | None = None, keep_going: bool = False,
                  skip_existing: bool = False, jobs: int = 2, quiet: bool = True, frames: str | None = None,
                  shard: Any = None, cluster: Any = None, chunk: int | None = None,
                  cluster_timeout: float | None = None, memory: int | str | None = None, **io_options: Any) -> Report:
    """Run a job on files through the CLI's pipeline: ``inputs[0]`` → ``output``, or every input → ``template``.

    ``work`` is a :mod:`pyramid_cli.jobs.work` value (``Filter``, ``Blur``, …); ``io_options``
    are :class:`~pyramid_cli.run.settings.ReadOptions` and ``WriteOptions`` fields. Inputs may
    be frame sequences (``plate.####.exr``; ``frames="1001-1240x2"`` selects); ``shard``
    (``"K/N"`` or ``"auto"``) keeps one chunk of the jobs; ``cluster`` (a Dask address,
    ``"local:N"`` or a ``distributed.Client``) runs them on a Dask cluster in tasks of
    ``chunk`` jobs, waiting up to ``cluster_timeout`` seconds (default 30) to connect and with
    no worker connected. ``memory`` (bytes, or ``"512M"``) is ``--memory``, this machine's budget (default: what
    the container's and process's limits leave; docs/performance.md). A single file's failure raises.

    Returns a :class:`~pyramid_cli.run.joblist.Report`: ``done``, ``skipped`` (up to date, with
    ``skip_existing``) and ``failed`` (each job with its :class:`~pyramid_cli.core.errors.PyramidError`,
    with ``keep_going``), and the ``exit_code`` the command line exits with (0 when nothing failed).
    Warnings come through :mod:`warnings` (a filter pair on two lattices as a MixedLatticeWarning, once),
    the lines ``-v`` prints are logged; the "wrote …" lines are printed unless ``quiet``.
    """
    from pyramid_cli.run.budget import parse_size
    from pyramid_cli.run.pipeline import process
    from pyramid_cli.run.settings import ReadOptions, WriteOptions

    read_keys = {"colorspace", "alpha", "nan", "colorconfig"}
    ro = ReadOptions(**{k: v for k, v in io_options.items() if k in read_keys})
    wo = WriteOptions(**{k: v for k, v in io_options.items() if k not in read_keys})
    if template is None and output is None:
        raise errors.UsageError("process_files needs an output path or a template")
    paths = [*inputs, output] if template is None and output is not None else list(inputs)
    runner: Any  # a session, or for a cluster without one what each worker's is made of
    if cluster is not None and session is None:
        from pyramid_cli.run.cluster import SessionSpec

        runner = SessionSpec(backend)
    else:
        runner = _session(session, backend)
    reporter = PythonReporter(quiet=quiet, lattice=tuple(work.warnings()))
    return process(paths, template, work, runner, read=ro, write=wo, reporter=reporter, keep_going=keep_going,
                   skip_existing=skip_existing, jobs=jobs, frames=frames, shard=shard, cluster=cluster, chunk=chunk,
                   cluster_timeout=cluster_timeout, memory=parse_size(memory) if isinstance(memory, str) else memory)


# The border aliases in the docstrings come from core.border's one table.
for _f in (reduce, expand, blur, pyramid, laplacian, collapse, mipmap, fill, blend):
    _f.__doc__ = (_f.__doc__ or "").replace("{borders}", aliases_text())

__all__ = ["fill", "blend", "apply", "reduce", "expand", "blur", "pyramid", "laplacian", "collapse", "mipmap", "tiles",
           "read_image", "write_image", "process_files", "as_pixels", "Session", "Work", "Filter", "Blur", "SigmaBlur",
           "Levels", "Laplacian", "Collapse", "Fill", "Blend", "TextureLevels", "Bands", "Report", "PyramidWarning",
           "MixedLatticeWarning", "MaskWarning", "BackendWarning"]
