"""The fast tier's representatives: parametrisations whose first few values run fast and the rest ``slow``."""

from __future__ import annotations

from collections.abc import Iterable

import pytest


def _slow(v, unpack: bool):
    return pytest.param(*v, marks=pytest.mark.slow) if unpack else pytest.param(v, marks=pytest.mark.slow)


def slow_beyond(values: Iterable, fast: int = 1, *, unpack: bool = False) -> list:
    """``values`` as pytest parameters, the first ``fast`` of them in the fast tier and every other one ``slow``
    (``pytest -m 'not slow'`` keeps a representative; the whole suite runs them all). ``unpack``: each value is
    a tuple of several argument names' values."""
    return [v if i < fast else _slow(v, unpack) for i, v in enumerate(values)]


def slow_unless(values: Iterable, fast: Iterable, *, unpack: bool = False) -> list:
    """``values`` as pytest parameters, those in ``fast`` in the fast tier and every other one ``slow``."""
    keep = list(fast)
    return [v if v in keep else _slow(v, unpack) for v in values]
