"""OpenImageIO idiff's conventions that ``pyramid diff`` keeps, and this tool's default thresholds.

Kept apart from :mod:`pyramid_cli.diff.compare` so the CLI can build its options without importing numpy.
"""

from __future__ import annotations

import math

# Linear-light absolute errors: float32 vs the float64 reference stays far under WARN,
# half vs float stays under FAIL (README, "Golden-image diffs").
DEFAULT_FAIL = 1e-3
DEFAULT_WARN = 1e-5

# idiff's process return codes.
EXIT_CODES: dict[str, int] = {"match": 0, "warning": 1, "failure": 2, "size": 3, "file": 4}


def format_value(v: float | None) -> str:
    """A statistic as every report of ``pyramid diff`` prints it (text, JSON messages, HTML, JUnit).

    Parameters
    ----------
    v : float or None
        The value; None where there is none (a level that was not compared).

    Returns
    -------
    str
        Six significant digits (``%.6g``, as idiff prints), ``"inf"`` for ±infinity, ``"-"`` for None.
    """
    if v is None:
        return "-"
    return "inf" if math.isinf(v) else f"{v:.6g}"
