"""Fixtures of the run layer's stream tests: a CPU session per module, and small pictures made to stream."""

from __future__ import annotations

import pytest

from pyramid_cli.exec.session import Session
from pyramid_cli.run import stream


@pytest.fixture(scope="module")
def session():
    """The compiled CPU executor's session, one per test module (a module may define its own)."""
    pytest.importorskip("numba")
    with Session("cpu") as s:
        yield s


@pytest.fixture
def small_pictures_stream(monkeypatch):
    """Pictures of any size stream by default, in bands of 8 rows of 80 columns."""
    monkeypatch.setattr(stream, "STREAM_PIXELS", 1)
    monkeypatch.setattr(stream, "BAND_PIXELS", 8 * 80)
    return monkeypatch
