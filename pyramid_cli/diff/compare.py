"""Compare two images the way OpenImageIO's ``idiff`` does.

:func:`compare` takes two pixel arrays (as :func:`pyramid_cli.imageio.read_image`
returns them: float, shape ``(H, W, C)``, linear light) and returns a
:class:`DiffResult` with idiff's statistics and verdict. :func:`difference_image`
and :func:`heatmap` make pictures of the difference for a person to look at.

Rules (idiff's, see ``idiff`` in the OpenImageIO documentation)
----------------------------------------------------------------
Error
    Per channel value, ``|a - b|``; its relative error is
    ``|a - b| / mean(|a|, |b|)`` (0 where both are 0), as in OpenImageIO's
    ``ImageBufAlgo::compare``.
Failing and warning pixels
    A pixel *fails* when any of its channels has an error ``> fail`` **and** a
    relative error ``> failrelative`` (the relative test is off at its default
    0, since any error > 0 has a relative error > 0). Likewise for *warn* with
    ``warn``/``warnrelative``. Comparisons are strict: an error equal to the
    threshold does not count. A pixel is *over hardfail* (*over hardwarn*) when
    any channel's absolute error is ``> hardfail`` (``> hardwarn``).
Non-finite values
    NaN against NaN, and an infinity against the same infinity, match (error
    0). NaN or Inf against anything else is an infinite error at that value:
    the pixel counts as over fail, warn, hardfail and hardwarn whatever their
    values (``inf`` included), so the verdict is a failure unless
    ``allowfailures`` covers it, and the largest error becomes ``inf`` at the
    first such value in row-major order.
Verdict (the idiff 3.2 binary's, tested against it)
    With ``N = H * W`` pixels, the first rule that applies decides
    (``DiffResult.rule`` names it)::

        failure  "nonfinite"      n_nonfinite > allowfailures   (this tool only)
        match    "allowfailures"  n_fail <= allowfailures
        failure  "fail"           n_fail > failpercent/100 * N
        failure  "hardfail"       max_error > hardfail
        warning  "warn"           n_warn > warnpercent/100 * N
        warning  "hardwarn"       max_error > hardwarn
        match    "failpercent"    otherwise

    So, like idiff, a comparison with no failing pixel passes whatever the
    warn thresholds say (exit 0): a warning needs failing pixels that
    ``failpercent`` tolerates.

Deliberate differences from the idiff 3.2 binary
    idiff counts no pixel where NaN or Inf meets a number (the comparison is
    false), so such images pass; here every such pixel fails (rule
    ``"nonfinite"``) unless ``allowfailures`` covers them. Opposite
    infinities match in idiff and are an error here. Different sizes or channel
    counts are compared by idiff over the union (missing values read 0); here
    they raise :class:`ShapeMismatchError` (exit 3). Statistics otherwise equal
    idiff's: mean and RMS error over all values, PSNR ``20 log10(peak / RMS)``
    with ``peak = max(1, largest finite |value|)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, TypedDict

import numpy as np

from pyramid_cli.diff.idiff import DEFAULT_FAIL, DEFAULT_WARN, EXIT_CODES

__all__ = [
    "DEFAULT_FAIL",
    "DEFAULT_WARN",
    "EXIT_CODES",
    "DiffResult",
    "ShapeMismatchError",
    "Thresholds",
    "compare",
    "difference_image",
    "heatmap",
]


VERDICTS = ("match", "warning", "failure")


class Thresholds(TypedDict, total=False):
    """:func:`compare`'s thresholds by keyword, as ``pyramid diff`` passes them (each one optional)."""

    fail: float
    warn: float
    failpercent: float
    warnpercent: float
    hardfail: float
    hardwarn: float
    failrelative: float
    warnrelative: float
    allowfailures: int


class ShapeMismatchError(ValueError):
    """The two images differ in size or channel count (idiff's exit code 3)."""


@dataclass(frozen=True)
class DiffResult:
    """Statistics and verdict of one comparison.

    Attributes
    ----------
    verdict : str
        ``"match"``, ``"warning"`` or ``"failure"``.
    width, height, channels : int
        Size of the compared images.
    max_error : float
        Largest absolute error of any channel value; ``inf`` when a NaN/Inf
        value meets a different value.
    max_x, max_y : int or None
        Column and row (row 0 = top of the file) of ``max_error``; ``None`` when
        ``max_error`` is 0.
    max_channel : int or None
        Channel index of ``max_error``.
    max_channel_name : str or None
        Its name (``channel_names`` given to :func:`compare`, else ``"c<i>"``).
    a_values, b_values : list of float
        All channels of the two images at (``max_x``, ``max_y``); empty when
        ``max_error`` is 0.
    mean_error : float
        Mean absolute error over all ``H * W * C`` values (non-finite values
        contribute 0; mismatches are counted in ``n_nonfinite``).
    rms_error : float
        Root mean square error over the same values.
    psnr : float
        ``20 log10(1 / rms_error)`` in dB (peak 1.0); ``inf`` when
        ``rms_error`` is 0.
    n_pixels : int
        ``H * W``.
    n_warn, n_fail : int
        Pixels with a channel over the warn / fail test (see the module notes).
    n_hardwarn, n_hardfail : int
        Pixels with a channel's absolute error over hardwarn / hardfail, NaN/Inf
        mismatches included.
    n_nonfinite : int
        Pixels where a NaN/Inf value meets a different value.
    rule : str
        The verdict rule that decided (module notes): ``"nonfinite"``,
        ``"allowfailures"``, ``"fail"``, ``"hardfail"``, ``"warn"``,
        ``"hardwarn"`` or ``"failpercent"``.
    thresholds : dict
        The thresholds used, by option name.
    """

    verdict: str
    width: int
    height: int
    channels: int
    max_error: float
    max_x: int | None
    max_y: int | None
    max_channel: int | None
    max_channel_name: str | None
    a_values: list[float]
    b_values: list[float]
    mean_error: float
    rms_error: float
    psnr: float
    n_pixels: int
    n_warn: int
    n_fail: int
    n_hardwarn: int
    n_hardfail: int
    n_nonfinite: int
    thresholds: dict[str, float] = field(default_factory=dict)
    rule: str = "allowfailures"

    @property
    def exit_code(self) -> int:
        """idiff's return code for the verdict: 0 match, 1 warning, 2 failure."""
        return EXIT_CODES[self.verdict]

    def percent(self, count: int) -> float:
        """``count`` as a percentage of the pixels."""
        return 100.0 * count / max(self.n_pixels, 1)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-safe dict: every non-finite float becomes ``None``.

        ``None`` for ``max_error`` means infinite (a NaN/Inf mismatch), for
        ``psnr`` infinite (identical images), for a threshold infinite (off).
        The keys ``max_error_infinite`` and ``psnr_infinite`` say so
        explicitly.
        """
        d = asdict(self)
        d["max_error_infinite"] = math.isinf(self.max_error)
        d["psnr_infinite"] = math.isinf(self.psnr)
        d["percent_warn"] = self.percent(self.n_warn)
        d["percent_fail"] = self.percent(self.n_fail)
        d["exit_code"] = self.exit_code
        return json_safe(d)


def json_safe(value: Any) -> Any:
    """``value`` with non-finite floats as ``None`` (JSON has no infinity), through dicts, lists and tuples."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


def _as_hwc(x: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(x)
    if arr.ndim == 2:
        arr = arr[..., None]
    if arr.ndim != 3:
        raise ValueError(f"image {name} must have shape (H, W) or (H, W, C), got {arr.shape}")
    return arr.astype(np.float64, copy=False)


def _check_shapes(a: np.ndarray, b: np.ndarray) -> None:
    if a.shape[:2] != b.shape[:2]:
        raise ShapeMismatchError(
            f"images differ in size: {a.shape[1]}x{a.shape[0]} vs {b.shape[1]}x{b.shape[0]}")
    if a.shape[2] != b.shape[2]:
        raise ShapeMismatchError(f"images differ in channel count: {a.shape[2]} vs {b.shape[2]}")


def _errors(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Absolute error, relative error and the non-finite-mismatch mask, per value."""
    both_finite = np.isfinite(a) & np.isfinite(b)
    with np.errstate(invalid="ignore"):
        same_nonfinite = ~both_finite & ((np.isnan(a) & np.isnan(b)) | (a == b))
    mismatch = ~both_finite & ~same_nonfinite
    aa = np.where(both_finite, a, 0.0)
    bb = np.where(both_finite, b, 0.0)
    err = np.abs(aa - bb)
    mean_abs = 0.5 * (np.abs(aa) + np.abs(bb))
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(mean_abs > 0.0, err / np.where(mean_abs > 0.0, mean_abs, 1.0), 0.0)
    err[mismatch] = np.inf
    rel[mismatch] = np.inf
    return err, rel, mismatch


def compare(a: np.ndarray, b: np.ndarray, *, fail: float = DEFAULT_FAIL, warn: float = DEFAULT_WARN,
            failpercent: float = 0.0, warnpercent: float = 0.0, hardfail: float = math.inf,
            hardwarn: float = math.inf, failrelative: float = 0.0, warnrelative: float = 0.0,
            allowfailures: int = 0, channel_names: Sequence[str] | None = None) -> DiffResult:
    """Compare two images value by value with idiff's rules.

    Parameters
    ----------
    a, b : numpy.ndarray
        Pixels, shape ``(H, W, C)`` or ``(H, W)``, any float or integer type
        (compared in float64).
    fail, warn : float
        Absolute error thresholds (strict ``>``).
    failpercent, warnpercent : float
        Percentage (0-100) of pixels allowed over fail / warn.
    hardfail, hardwarn : float
        Any pixel with an absolute error over this fails / warns.
    failrelative, warnrelative : float
        Relative thresholds, ``|a-b| / mean(|a|, |b|)``; a pixel fails only
        when both its absolute and its relative error are over their
        thresholds. 0 (the default) turns the relative test off. ``False`` is
        accepted as 0.
    allowfailures : int
        Up to this many pixels may differ by any amount.
    channel_names : sequence of str, optional
        Names for the report (e.g. ``Image.spec.channel_names``).

    Returns
    -------
    DiffResult

    Raises
    ------
    ShapeMismatchError
        Different sizes or channel counts.
    ValueError
        An array that is not 2-D or 3-D, or a negative threshold or count.
    """
    a = _as_hwc(a, "A")
    b = _as_hwc(b, "B")
    _check_shapes(a, b)
    for name, value in (("fail", fail), ("warn", warn), ("failpercent", failpercent),
                        ("warnpercent", warnpercent), ("hardfail", hardfail), ("hardwarn", hardwarn),
                        ("failrelative", failrelative), ("warnrelative", warnrelative),
                        ("allowfailures", allowfailures)):
        if math.isnan(float(value)) or float(value) < 0:
            raise ValueError(f"{name} must be a number >= 0, got {value}")
    height, width, nch = a.shape
    n_pixels = height * width

    err, rel, mismatch = _errors(a, b)
    mismatch_px = mismatch.any(axis=2)
    fail_px = ((err > fail) & (rel > float(failrelative))).any(axis=2) | mismatch_px
    warn_px = ((err > warn) & (rel > float(warnrelative))).any(axis=2) | mismatch_px
    n_fail = int(np.count_nonzero(fail_px))
    n_warn = int(np.count_nonzero(warn_px))
    # A NaN/Inf mismatch is over every threshold, an infinite hardfail included.
    n_hardfail = int(np.count_nonzero((err > hardfail).any(axis=2) | mismatch_px))
    n_hardwarn = int(np.count_nonzero((err > hardwarn).any(axis=2) | mismatch_px))
    n_nonfinite = int(np.count_nonzero(mismatch_px))

    npels = max(n_pixels, 1)
    allow = int(allowfailures)
    finite_err = np.where(mismatch, 0.0, err)
    finite_max = float(finite_err.max()) if finite_err.size else 0.0
    verdict, rule = _verdict(n_nonfinite=n_nonfinite, n_fail=n_fail, n_warn=n_warn, max_error=finite_max,
                             npels=npels, allow=allow, failpercent=failpercent, warnpercent=warnpercent,
                             hardfail=hardfail, hardwarn=hardwarn)

    nvals = max(err.size, 1)
    mean_error = float(finite_err.sum() / nvals)
    rms_error = float(math.sqrt(float(np.square(finite_err).sum()) / nvals))
    with np.errstate(invalid="ignore"):
        finite_abs = np.abs(np.concatenate([a[np.isfinite(a)], b[np.isfinite(b)]]))
    peak = max(1.0, float(finite_abs.max()) if finite_abs.size else 0.0)
    psnr = math.inf if rms_error == 0.0 else 20.0 * math.log10(peak / rms_error)

    names = list(channel_names) if channel_names is not None else []
    if n_nonfinite:
        flat = int(np.flatnonzero(mismatch)[0])
    else:
        flat = int(np.argmax(err)) if err.size else 0
    max_error = float(err.reshape(-1)[flat]) if err.size else 0.0
    if max_error > 0.0:
        y, x, c = (int(v) for v in np.unravel_index(flat, err.shape))
        cname = names[c] if c < len(names) else f"c{c}"
        a_values = [float(v) for v in a[y, x]]
        b_values = [float(v) for v in b[y, x]]
        loc: tuple[int | None, int | None, int | None, str | None] = (x, y, c, cname)
    else:
        loc = (None, None, None, None)
        a_values, b_values = [], []

    thresholds = {"fail": float(fail), "warn": float(warn), "failpercent": float(failpercent),
                  "warnpercent": float(warnpercent), "hardfail": float(hardfail), "hardwarn": float(hardwarn),
                  "failrelative": float(failrelative), "warnrelative": float(warnrelative),
                  "allowfailures": allow}
    return DiffResult(
        verdict=verdict, width=width, height=height, channels=nch,
        max_error=max_error, max_x=loc[0], max_y=loc[1], max_channel=loc[2], max_channel_name=loc[3],
        a_values=a_values, b_values=b_values,
        mean_error=mean_error, rms_error=rms_error, psnr=psnr, n_pixels=n_pixels,
        n_warn=n_warn, n_fail=n_fail, n_hardwarn=n_hardwarn, n_hardfail=n_hardfail,
        n_nonfinite=n_nonfinite, thresholds=thresholds, rule=rule,
    )


def _verdict(*, n_nonfinite: int, n_fail: int, n_warn: int, max_error: float, npels: int, allow: int,
             failpercent: float, warnpercent: float, hardfail: float, hardwarn: float) -> tuple[str, str]:
    """The verdict and the rule that decided it (module notes, "Verdict")."""
    if n_nonfinite > allow:
        return "failure", "nonfinite"
    if n_fail <= allow:
        return "match", "allowfailures"
    if n_fail > failpercent / 100.0 * npels:
        return "failure", "fail"
    if max_error > hardfail:
        return "failure", "hardfail"
    if n_warn > warnpercent / 100.0 * npels:
        return "warning", "warn"
    if max_error > hardwarn:
        return "warning", "hardwarn"
    return "match", "failpercent"


def difference_image(a: np.ndarray, b: np.ndarray, scale: float = 1.0, *, absolute: bool = True) -> np.ndarray:
    """``|a - b| * scale`` (or the signed ``(a - b) * scale``) per channel.

    Parameters
    ----------
    a, b : numpy.ndarray
        Same shape, ``(H, W, C)`` or ``(H, W)``.
    scale : float
        Multiplier that makes small differences visible (idiff's ``-scale``).
    absolute : bool
        ``False``: the signed difference computed in float32, exactly what
        idiff's ``-o`` writes (NaN and Inf propagate as IEEE arithmetic says).
        ``True``: idiff's ``-abs``, with the non-finite rules below.

    Returns
    -------
    numpy.ndarray
        float32 ``(H, W, C)``. NaN against NaN (or the same infinity) is 0;
        a NaN/Inf against a different value is ``+inf``.

    Raises
    ------
    ShapeMismatchError
        Different sizes or channel counts.
    """
    a = _as_hwc(a, "A")
    b = _as_hwc(b, "B")
    _check_shapes(a, b)
    if not absolute:
        with np.errstate(invalid="ignore", over="ignore"):
            signed = a.astype(np.float32) - b.astype(np.float32)
            return (signed * np.float32(scale) if scale != 1.0 else signed).astype(np.float32)
    err, _, _ = _errors(a, b)
    with np.errstate(invalid="ignore", over="ignore"):
        out = err * float(scale)
    out[np.isnan(out)] = 0.0  # inf * 0 with --scale 0
    return out.astype(np.float32)


def heatmap(a: np.ndarray, b: np.ndarray, *, lo: float = 1e-8, hi: float = 1.0,
            cmap: str = "viridis") -> np.ndarray:
    """False-colour picture of each pixel's largest channel error, log scaled.

    The error ``e`` (max over channels of ``|a - b|``) is placed on a log scale
    from ``lo`` to ``hi`` (fixed, so pictures of different runs compare) and
    coloured with a matplotlib colour map; exact zero is black and a NaN/Inf
    mismatch is white, so both stand out from every colour of the map.

    Parameters
    ----------
    a, b : numpy.ndarray
        Same shape, ``(H, W, C)`` or ``(H, W)``.
    lo, hi : float
        Errors at or below ``lo`` get the map's first colour, at or above
        ``hi`` its last. The defaults span float32 rounding (1e-8) to a whole
        unit of linear light.
    cmap : str
        A matplotlib colour map name.

    Returns
    -------
    numpy.ndarray
        float32 ``(H, W, 3)`` display (sRGB-encoded) colours in [0, 1].

    Raises
    ------
    ShapeMismatchError
        Different sizes or channel counts.
    ValueError
        ``lo`` or ``hi`` not positive, or ``lo >= hi``.
    UsageError
        matplotlib is not installed (the ``plot`` extra).
    """
    if not (0.0 < lo < hi) or not math.isfinite(hi):
        raise ValueError(f"heatmap range must satisfy 0 < lo < hi < inf, got lo={lo}, hi={hi}")
    try:
        import matplotlib
    except ImportError:
        from pyramid_cli.core.errors import UsageError

        raise UsageError("--heatmap needs matplotlib for its colour map: pip install 'bilinear-pyramid[plot]'") \
            from None
    a = _as_hwc(a, "A")
    b = _as_hwc(b, "B")
    _check_shapes(a, b)
    err, _, _ = _errors(a, b)
    e = err.max(axis=2) if err.shape[2] else np.zeros(err.shape[:2])
    with np.errstate(divide="ignore"):
        t = (np.log10(np.maximum(e, lo)) - math.log10(lo)) / (math.log10(hi) - math.log10(lo))
    t = np.clip(np.nan_to_num(t, nan=1.0, posinf=1.0), 0.0, 1.0)
    rgb = np.asarray(matplotlib.colormaps[cmap](t))[..., :3]
    rgb[e == 0.0] = 0.0
    rgb[np.isinf(e)] = 1.0
    return rgb.astype(np.float32)
