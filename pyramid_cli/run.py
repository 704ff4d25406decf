"""Choose an executor for an expression and run it (GL, or the numpy reference)."""

from __future__ import annotations

import numpy as np

from .border import Border
from .expr import Expr


def execute(expr: Expr, pixels: np.ndarray, backend: str = "auto", border: str = "clamp") -> tuple[np.ndarray, str]:
    """Run ``expr`` on ``pixels`` (H, W, C) float32; returns (result float32, backend used)."""
    from . import reference

    out = reference.run(expr, pixels, Border.parse(border))
    return out.astype(np.float32), "cpu reference"
