"""The Python API: ``import pyramid_cli as pyr``.

Functions on numpy arrays (``apply``, ``blur``, ``pyramid``, ``laplacian``,
``collapse``, ``mipmap``, and the methods built on them: ``fill``, ``blend``), image files
(``read_image``, ``write_image``,
``process_files``), and :class:`~pyramid_cli.exec.session.Session`, which owns one
executor for many calls. They describe jobs as :mod:`pyramid_cli.jobs.work` values and
run them through the same session and pipeline as the ``pyramid`` command.

Arrays: 2-D is one channel, 3-D is H×W×C with any C. float16/32/64 are taken as
they are; integer arrays as normalised codes (unsigned: code / max, signed:
code / max clipped at −1, as scikit-image's ``img_as_float``), booleans as 0/1.
Results are float32 (H×W×C, or H×W for 2-D input). Pixels are linear light:
filtering sRGB codes directly is the caller's choice (``read_image`` decodes files).

Without ``session=``, a module-level session per backend is made on first use
and closed at exit.

Errors: a bad argument raises :class:`~pyramid_cli.core.errors.UsageError` and bad pixel data (nothing to
fill from, an image too large) :class:`~pyramid_cli.core.errors.DataError`, both
``ValueError`` s; a file that cannot be read raises :class:`~pyramid_cli.core.errors.InputError`, one
that cannot be written :class:`~pyramid_cli.core.errors.OutputError`, a missing GL context
:class:`~pyramid_cli.core.errors.BackendError` (these three are :class:`~pyramid_cli.core.errors.PyramidError`
s, not ``ValueError``). Every message is the one the command line prints. What the command line
warns about is a ``UserWarning`` here: a filter pair on two lattices
(:class:`~pyramid_cli.core.errors.MixedLatticeWarning`: ``blur``, ``fill``, ``blend``), mask values outside
[0, 1] (clipped).

References
----------
Kraus & Strengert, "Pyramid Filters Based on Bilinear Interpolation", GRAPP 2007:
§3 convolution, §4 analysis (⊗↓), §5 synthesis (⊗↑), §2 and Figure 3 the blur.
"""

from __future__ import annotations

import atexit
import os
import warnings
from collections.abc import Iterator, Sequence

import numpy as np

from pyramid_cli import imageio as io
from pyramid_cli.core import catalogue, options
from pyramid_cli.core.errors import MixedLatticeWarning
from pyramid_cli.core.expr import Expr
from pyramid_cli.core.geometry import reduced
from pyramid_cli.exec.session import Session
from pyramid_cli.jobs.work import Blur, Collapse, Filter, Laplacian, Levels, SigmaBlur, Work, blur_work, same_setting

_sessions: dict[str, Session] = {}


def _session(session: Session | None, backend: str) -> Session:
    if session is not None:
        return session
    options.check("backend", backend, options.BACKENDS)
    if backend not in _sessions:
        _sessions[backend] = Session(backend)
    return _sessions[backend]


@atexit.register
def _close_sessions() -> None:
    for s in _sessions.values():
        s.close()
    _sessions.clear()


def as_pixels(array, name: str = "array") -> np.ndarray:
    """``array`` as pixels the executors take: 2-D or 3-D, float (integers normalised, see the module notes).

    Raises
    ------
    ValueError
        Not 2-D or 3-D, empty, or not a real number type.
    """
    a = np.asarray(array)
    if a.ndim not in (2, 3):
        raise ValueError(f"{name}: expected a 2-D (H, W) or 3-D (H, W, C) array, got shape {a.shape}")
    if 0 in a.shape:
        raise ValueError(f"{name}: an image needs at least one row, column and channel, got shape {a.shape}")
    if a.dtype.kind == "f":
        return a
    if a.dtype.kind == "b":
        return a.astype(np.float32)
    if a.dtype.kind == "u":
        return (a / np.float64(np.iinfo(a.dtype).max)).astype(np.float32)
    if a.dtype.kind == "i":
        return np.maximum(a / np.float64(np.iinfo(a.dtype).max), -1.0).astype(np.float32)
    raise ValueError(f"{name}: pixels must be real numbers, not {a.dtype}")


def _expr(expr: str | Expr) -> Expr:
    if isinstance(expr, str):
        from pyramid_cli.core.parse import parse

        return parse(expr)
    return expr


def _run(work: Work, arrays: list, session: Session | None, backend: str) -> list[np.ndarray]:
    return _session(session, backend).run(work, arrays)


def _check_levels(levels: int) -> None:
    if not 1 <= levels <= options.MAX_LEVELS:
        raise ValueError(f"levels must be 1 to {options.MAX_LEVELS}, not {levels}")


def _warn_work(work: Work, size=None) -> None:
    """The work's warnings (:meth:`~pyramid_cli.jobs.work.Work.warnings`) as MixedLatticeWarnings at the
    caller's line."""
    for message in work.warnings(size):
        warnings.warn(message, MixedLatticeWarning, stacklevel=3)


def _warn_mask(message: str) -> None:  # called by methods.mask_weights, under fill_inputs or mask_channels
    warnings.warn(message, UserWarning, stacklevel=5)


class Bands(list):
    """Laplacian bands (a list of arrays) that remember the ``synthesis`` and ``border`` they were made with,
    so that :func:`collapse` uses them and refuses others; a plain list works too, unchecked."""

    def __init__(self, bands, *, analysis: str, synthesis: str, border: str):
        super().__init__(bands)
        self.analysis, self.synthesis, self.border = analysis, synthesis, border


def _banded(work: Work, array, out: Sequence[np.ndarray] | None, memory, session: Session | None,
            backend: str) -> list[np.ndarray]:
    """One image through ``work`` band by band (:mod:`pyramid_cli.exec.tiles`): a memory-mapped input is read
    a band at a time and the results written into ``out`` (one array per output of the plan, after level 0
    for a job that keeps its input; a memmap keeps it on disk), within ``memory`` bytes of working set
    (default: :func:`pyramid_cli.run.budget.default_budget`), the pixels of the whole run."""
    from pyramid_cli.exec import tiles
    from pyramid_cli.run import stream

    a = array if isinstance(array, np.ndarray) else np.asarray(array)
    if a.ndim not in (2, 3) or 0 in a.shape:
        as_pixels(a)  # raises the usual message
    s = _session(session, backend)
    if s.executor is None:
        raise ValueError("out= and memory= need a plan executor (backend 'gl' or 'cpu'): the reference "
                         "backend holds whole pictures")
    work.check((a.shape[:2],))
    plan = s.plan(work, [a.shape[:2]])
    shapes = [plan.images[k].size + a.shape[2:] for k in plan.outputs]
    outs = [np.empty(shape, dtype=np.float32) for shape in shapes] if out is None else list(out)
    if len(outs) != len(shapes):
        raise ValueError(f"out: expected {len(shapes)} arrays (shapes {shapes}), got {len(outs)}")
    for k, (o, shape) in enumerate(zip(outs, shapes, strict=True)):
        if tuple(o.shape) != shape or o.dtype not in (np.float16, np.float32, np.float64):
            name = "out" if len(outs) == 1 else f"out[{k}]"
            raise ValueError(f"{name}: expected a float array of shape {shape}, got {o.dtype} {tuple(o.shape)}")
    budget = stream.parse_size(memory) if isinstance(memory, str) else memory or stream.default_memory()
    channels = a.shape[2] if a.ndim == 3 else 1
    executor = s.executor
    choice = stream.choose(plan, channels, budget, in_bytes=max(4, a.dtype.itemsize), force=True,
                           **stream.costs(executor))
    tiles.run_arrays(executor, plan, [a], band=choice.band, out=outs, convert=as_pixels)
    s.ran = s.name
    return outs


def _bands_wanted(array, out, memory) -> bool:
    """Whether a call runs band by band: ``out=``, ``memory=`` or a memory-mapped input."""
    return out is not None or memory is not None or isinstance(array, np.memmap)


# ------------------------------------------------------------------ arrays
def apply(expr: str | Expr, array, *, border: str = "clamp", backend: str = "auto",
          session: Session | None = None, out: np.ndarray | None = None, memory: int | str | None = None
          ) -> np.ndarray:
    """Apply a filter-chain expression to an image.

    Parameters
    ----------
    expr : str or Expr
        The paper's notation or its ASCII spelling, e.g. ``"h_quadratic ⊗↓ g"`` or
        ``"quadratic *v g"`` (§3 ⊗, §4 ⊗↓, §5 ⊗↑); chains are right-associative.
    array : array_like
        H×W or H×W×C pixels.
    border : {"clamp", "mirror", "wrap", "zero"}
        How every written operator reads past its input's edges (docs/design.md §1).
    backend : {"auto", "gl", "cpu", "reference"}
        Where it runs (ignored when ``session`` is given).
    session : Session, optional
        Reuse one executor across calls.
    out : numpy.ndarray, optional
        Write the result here (float16/32/64 of the result's shape), e.g. a ``numpy.memmap`` on disk.
        With ``out``, a ``numpy.memmap`` input or ``memory``, the image runs band by band in bounded memory
        (the pixels of the whole run), so images larger than RAM work.
    memory : int or str, optional
        Working-set budget of a banded run in bytes, or ``"512M"``, ``"2G"`` (default: what the container's
        memory limit, the rlimits and the available memory leave: :func:`pyramid_cli.run.budget.default_budget`).

    Returns
    -------
    numpy.ndarray
        float32 (or ``out``); ⊗ keeps the size, ⊗↓ gives ⌈n/2⌉, ⊗↑ gives 2n per axis.

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> pyr.apply("box4 *v g", np.ones((5, 3))).shape
    (3, 2)
    >>> pyr.apply("doosabin *^ g", np.ones((2, 2, 3)), border="mirror").shape
    (4, 4, 3)
    """
    work = Filter(expr=_expr(expr), border=border)
    if _bands_wanted(array, out, memory):
        return _banded(work, array, None if out is None else [out], memory, session, backend)[0]
    (result,) = _run(work, [as_pixels(array)], session, backend)
    return result


def blur(array, levels: int = 4, *, sigma: float | None = None, analysis: str = catalogue.DEFAULT_ANALYSIS,
         synthesis: str = catalogue.DEFAULT_SYNTHESIS, quasi: bool = False, border: str = "clamp",
         backend: str = "auto", session: Session | None = None, out: np.ndarray | None = None,
         memory: int | str | None = None) -> np.ndarray:
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
    border, backend, session, out, memory
        As in :func:`apply` (``out`` and memory-mapped inputs run band by band).

    Returns
    -------
    numpy.ndarray
        float32 (or ``out``), the input's shape.

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> impulse = np.zeros((33, 33)); impulse[16, 16] = 1
    >>> soft = pyr.blur(impulse, 3)
    >>> soft.shape, round(float(soft.sum()), 4)
    ((33, 33), 1.0)
    """
    if sigma is None:
        _check_levels(levels)
    work = blur_work(levels, sigma=sigma, analysis=analysis, synthesis=synthesis, quasi=quasi, border=border)
    _warn_work(work)
    if _bands_wanted(array, out, memory):
        return _banded(work, array, None if out is None else [out], memory, session, backend)[0]
    (result,) = _run(work, [as_pixels(array)], session, backend)
    return result


def pyramid(array, *, analysis: str = catalogue.DEFAULT_ANALYSIS, levels: int | None = None, border: str = "clamp",
            backend: str = "auto", session: Session | None = None, out: Sequence[np.ndarray] | None = None,
            memory: int | str | None = None) -> Iterator[np.ndarray]:
    """The analysis pyramid (§4), level 0 (the input itself) first.

    Parameters
    ----------
    array : array_like
        H×W or H×W×C pixels.
    analysis : str
        A ⊗↓ filter or one-step expression.
    levels : int, optional
        Reductions after level 0; None goes down to 1×1 (scikit-image's convention).
    border, backend, session, memory
        As in :func:`apply`.
    out : sequence of numpy.ndarray, optional
        One array per level after level 0 to write into (memmaps, say); with it, ``memory`` or a
        memory-mapped input the pyramid runs band by band, as in :func:`apply`.

    Yields
    ------
    numpy.ndarray
        Level k has ⌈n/2ᵏ⌉ rows and columns; level 0 is ``array`` unchanged.

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> a = np.random.default_rng(0).random((5, 3))
    >>> levels = list(pyr.pyramid(a))
    >>> levels[0] is a, [lv.shape for lv in levels]
    (True, [(5, 3), (3, 2), (2, 1), (1, 1)])
    """
    work = Levels(levels=levels, analysis=analysis, border=border)
    if _bands_wanted(array, out, memory):
        outs = _banded(work, array, out, memory, session, backend)
        yield array
        yield from outs
        return
    pixels = as_pixels(array)
    outs = _run(work, [pixels], session, backend)
    yield array if pixels is array else pixels
    yield from outs[1:]


def laplacian(array, levels: int = 4, *, analysis: str = catalogue.DEFAULT_ANALYSIS,
              synthesis: str = catalogue.DEFAULT_SYNTHESIS, border: str = "clamp", backend: str = "auto",
              session: Session | None = None, out: Sequence[np.ndarray] | None = None,
              memory: int | str | None = None) -> list[np.ndarray]:
    """Laplacian bands L_k = G_k − expand(G_k+1) for k < ``levels``, then the coarsest G_m.

    Returns a :class:`Bands` list that records ``synthesis`` and ``border``: :func:`collapse` sums it
    back to the input with them, exactly up to float rounding. ``out`` (one array per band), ``memory``
    or a memory-mapped input run it band by band, as in :func:`apply`.

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> a = np.random.default_rng(1).random((17, 13, 3))
    >>> bands = pyr.laplacian(a, 3)
    >>> [b.shape[:2] for b in bands]
    [(17, 13), (9, 7), (5, 4), (3, 2)]
    >>> bool(np.abs(pyr.collapse(bands) - a).max() < 1e-5)
    True
    """
    _check_levels(levels)
    work = Laplacian(levels=levels, analysis=analysis, synthesis=synthesis, border=border)
    if _bands_wanted(array, out, memory):
        bands = _banded(work, array, out, memory, session, backend)
    else:
        bands = _run(work, [as_pixels(array)], session, backend)
    return Bands(bands, analysis=analysis, synthesis=synthesis, border=work.border)


def collapse(bands: Sequence, *, synthesis: str | None = None, border: str | None = None, backend: str = "auto",
             session: Session | None = None) -> np.ndarray:
    """Sum Laplacian bands back to the image: G_k = L_k + expand(G_k+1) (inverse of :func:`laplacian`).

    The image comes back only with the ``synthesis`` and ``border`` the bands were made with. The
    :class:`Bands` that :func:`laplacian` returns record them: they are used by default, and others are
    refused (ValueError), as ``pyramid collapse`` refuses what contradicts a file's record. A plain list
    of arrays cannot say: its defaults are the paper's Doo-Sabin and ``"clamp"``, and a wrong one gives
    a wrong image without an error. Band sizes and channel counts are checked either way.

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> a = np.random.default_rng(2).random((9, 8))
    >>> bands = pyr.laplacian(a, 2, synthesis="nearest", border="mirror")
    >>> bool(np.abs(pyr.collapse(bands) - a).max() < 1e-5)
    True
    >>> pyr.collapse(bands, synthesis="doosabin")
    Traceback (most recent call last):
    ...
    pyramid_cli.core.errors.UsageError: the bands were made with synthesis 'nearest'; collapsing with 'doosabin' ...
    """
    recorded = {k: getattr(bands, k, None) for k in ("synthesis", "border")}
    synthesis = _as_recorded("synthesis", synthesis, recorded["synthesis"], catalogue.DEFAULT_SYNTHESIS)
    border = _as_recorded("border", border, recorded["border"], "clamp")
    bands = [as_pixels(b, f"band {k}") for k, b in enumerate(bands)]
    if len(bands) < 2:
        raise ValueError(f"collapse needs at least two bands, got {len(bands)}")
    for k in range(1, len(bands)):
        want = tuple(reduced(n) for n in bands[k - 1].shape[:2])
        if bands[k].shape[:2] != want or bands[k].shape[2:] != bands[0].shape[2:]:
            raise ValueError(f"band {k} has shape {bands[k].shape}; after {bands[k - 1].shape} it must be "
                             f"{want + bands[0].shape[2:]}")
    (out,) = _run(Collapse(bands=len(bands), synthesis=synthesis, border=border), bands, session, backend)
    return out


def _as_recorded(what: str, asked: str | None, recorded: str | None, default: str) -> str:
    """``asked`` where it agrees with what :class:`Bands` record, the record where not asked."""
    if asked is None:
        return recorded or default
    if recorded is not None and not same_setting(what, asked, recorded):
        from pyramid_cli.core.errors import UsageError

        raise UsageError(f"the bands were made with {what} {recorded!r}; collapsing with {asked!r} would not "
                         "give the image back")
    return asked


def mipmap(array, *, analysis: str = catalogue.MIP_ANALYSIS_DEFAULT, border: str = "clamp", rounding: str = "down",
           backend: str = "auto", session: Session | None = None, out: Sequence[np.ndarray] | None = None,
           memory: int | str | None = None) -> list[np.ndarray]:
    """MIP levels down to 1×1, level 0 first, as ``pyramid mipmap`` writes them.

    ``out`` (one array per level after level 0), ``memory`` or a memory-mapped input run it band by
    band, as in :func:`apply`.

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
    from pyramid_cli.jobs.texture import TextureLevels

    work = TextureLevels(levels=None, analysis=analysis, border=border, rounding=rounding)
    if _bands_wanted(array, out, memory):
        return [array, *_banded(work, array, out, memory, session, backend)]
    pixels = as_pixels(array)
    return [array if pixels is array else pixels, *_run(work, [pixels], session, backend)[1:]]


def fill(array, *, mask=None, holes: str | None = None, levels: int | None = None,
         analysis: str = catalogue.FILL_ANALYSIS, synthesis: str = catalogue.FILL_SYNTHESIS,
         weight_scale: int | tuple[int, int] = catalogue.FILL_SCALE,
         sweeps: int | tuple[int, int] = catalogue.FILL_SWEEPS,
         keep_alpha: bool = False, border: str = "clamp", backend: str = "auto",
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
        clipped, each with a UserWarning.
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
    border, backend, session
        As in :func:`apply`.

    Returns
    -------
    numpy.ndarray
        float32, the input's shape; the alpha channel (``holes="alpha"``) is 1 everywhere,
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
    from pyramid_cli.jobs.work import Fill
    from pyramid_cli.workflows.methods import fill_inputs, fill_output

    holes = holes or ("mask" if mask is not None else "alpha")
    if keep_alpha and holes != "alpha":
        raise ValueError(f"keep_alpha keeps the alpha the holes come from; with holes={holes!r} every channel "
                         "is filled")
    pixels = as_pixels(array)
    colour, weight, premultiplied = fill_inputs(pixels, holes, None if mask is None else as_pixels(mask, "mask"),
                                                warn=_warn_mask)
    work = Fill(levels=levels, analysis=analysis, synthesis=synthesis, premultiplied=premultiplied, border=border,
                weight_scale=weight_scale, sweeps=sweeps)
    _warn_work(work, pixels.shape[:2])
    (out,) = _run(work, [colour, weight], session, backend)
    return fill_output(out, pixels, holes, keep_alpha=keep_alpha)


def blend(a, b, mask, *, levels: int | None = None, analysis: str = catalogue.DEFAULT_ANALYSIS,
          synthesis: str = catalogue.DEFAULT_SYNTHESIS, border: str = "clamp", backend: str = "auto",
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
        outside [0, 1] clipped, each with a UserWarning.
    levels : int, optional
        Laplacian levels; default as many as the size allows while the coarsest level keeps 16
        pixels on its shorter side (:func:`pyramid_cli.workflows.methods.blend_levels`; 4 at 256×256, 7 at
        3840×2160): deeper bands would mix the two images' mean colours across the whole frame.
    analysis, synthesis : str
        ⊗↓ and ⊗↑ filters (§4, §5); the defaults are the paper's Figure 3b. A pair on two
        lattices moves the seam (7.5 px at 4 levels) and warns (MixedLatticeWarning).
    border, backend, session
        As in :func:`apply`.

    Returns
    -------
    numpy.ndarray
        float32, the shape of ``a``.

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> a, b = np.zeros((16, 16)), np.ones((16, 16))
    >>> left = np.zeros((16, 16)); left[:, :8] = 1
    >>> pyr.blend(a, b, left, levels=2)[8, ::3].round(3)
    array([0.   , 0.094, 0.328, 0.672, 0.906, 1.   ], dtype=float32)
    """
    from pyramid_cli.jobs.work import Blend
    from pyramid_cli.workflows.methods import mask_channels

    pa, pb = as_pixels(a, "a"), as_pixels(b, "b")
    if pa.shape != pb.shape:
        raise ValueError(f"a has shape {pa.shape} and b {pb.shape}: they must have one shape")
    m = mask_channels(as_pixels(mask, "mask"), pa, warn=_warn_mask)
    if levels is not None and levels < 0:
        raise ValueError(f"levels must be 0 or more, not {levels}")
    work = Blend(levels=levels, analysis=analysis, synthesis=synthesis, border=border)
    _warn_work(work, pa.shape[:2])
    (out,) = _run(work, [pa, pb, m], session, backend)
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
                  shard=None, cluster=None, chunk: int | None = None, cluster_timeout: float | None = None,
                  **io_options) -> int:
    """Run a job on files through the CLI's pipeline: ``inputs[0]`` → ``output``, or every input → ``template``.

    ``work`` is a :mod:`pyramid_cli.jobs.work` value (``Filter``, ``Blur``, …); ``io_options``
    are :class:`~pyramid_cli.run.settings.ReadOptions` and ``WriteOptions`` fields. Inputs may
    be frame sequences (``plate.####.exr``; ``frames="1001-1240x2"`` selects); ``shard``
    (``"K/N"`` or ``"auto"``) keeps one chunk of the jobs; ``cluster`` (a Dask address,
    ``"local:N"`` or a ``distributed.Client``) runs them on a Dask cluster in tasks of
    ``chunk`` jobs, waiting up to ``cluster_timeout`` seconds (default 30) to connect and with
    no worker connected. Returns the batch's exit code (0 when every file was written); a
    single file's failure raises.
    """
    from pyramid_cli.run.pipeline import process
    from pyramid_cli.run.report import Reporter
    from pyramid_cli.run.settings import ReadOptions, WriteOptions

    read_keys = {"colorspace", "alpha", "nan", "colorconfig"}
    ro = ReadOptions(**{k: v for k, v in io_options.items() if k in read_keys})
    wo = WriteOptions(**{k: v for k, v in io_options.items() if k not in read_keys})
    paths = [*inputs, output] if template is None else list(inputs)
    if cluster is not None and session is None:
        from pyramid_cli.run.cluster import SessionSpec

        runner = SessionSpec(backend)
    else:
        runner = _session(session, backend)
    if quiet:  # the pipeline says them only where it prints
        _warn_work(work)
    report = process(paths, template, work, runner, read=ro, write=wo, reporter=Reporter(quiet=quiet),
                     keep_going=keep_going, skip_existing=skip_existing, jobs=jobs, frames=frames, shard=shard,
                     cluster=cluster, chunk=chunk, cluster_timeout=cluster_timeout)
    return report.exit_code


__all__ = ["fill", "blend", "apply", "blur", "pyramid", "laplacian", "collapse", "mipmap", "read_image", "write_image",
           "process_files", "as_pixels", "Session", "Work", "Filter", "Blur", "SigmaBlur", "Levels", "Laplacian",
           "Collapse", "Bands"]
