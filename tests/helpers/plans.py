"""Plans and images for the executor tests: an expression planned and checked, and seeded random pictures."""

from __future__ import annotations

import numpy as np

from pyramid_cli.core.parse import parse
from pyramid_cli.plan import check, plan


def planned(text: str, size: tuple[int, int], strategy: str = "cost", border: str = "clamp"):
    """The expression of ``text`` and its checked plan for ``size``."""
    expr = parse(text)
    p = plan(expr, size, strategy, border)
    check(p)
    return expr, p


def random_image(size: tuple[int, int], channels: int | None, seed: int, dtype=np.float32) -> np.ndarray:
    """Standard-normal pixels (negative values included: no executor may clamp), H×W or H×W×C."""
    rng = np.random.default_rng(seed)
    return rng.standard_normal(size if channels is None else size + (channels,)).astype(dtype)
