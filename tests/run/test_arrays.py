"""Arrays through a session for the Python API (pyramid_cli.run.arrays): whole and band by band, same dtype rules."""

from __future__ import annotations

import numpy as np
import pytest

from pyramid_cli.core.errors import UsageError
from pyramid_cli.exec.session import Session
from pyramid_cli.jobs.work import Blur, Fill, Levels
from pyramid_cli.run import arrays


@pytest.fixture(scope="module")
def session():
    with Session("cpu") as s:
        yield s


def test_banded_runs_give_the_whole_runs_dtype_and_values(session):
    a = np.random.default_rng(0).integers(0, 256, (40, 30, 3)).astype(np.uint8)
    whole = arrays.run(session, Blur(levels=2), [arrays.ArrayInput(a).pixels], arrays.ArrayInput(a))[0]
    (banded,) = arrays.banded(session, Blur(levels=2), a, None, "64K")
    assert whole.dtype == banded.dtype == np.uint8
    np.testing.assert_array_equal(banded, whole)
    out = np.empty((40, 30, 3), np.float32)
    assert arrays.banded(session, Blur(levels=2), a, [out], None)[0] is out
    with pytest.raises(UsageError, match="expected a float array"):
        arrays.banded(session, Blur(levels=2), a, [np.empty((40, 30, 3), np.uint8)], None)


def test_a_kept_input_is_a_copy_and_fill_keeps_float64_pixels(session):
    a = np.random.default_rng(1).random((9, 7))
    inp = arrays.ArrayInput(a)
    levels = arrays.run(session, Levels(levels=2), [inp.pixels], inp)
    assert inp.wide and [lv.dtype for lv in levels] == [np.float64] * 3 and not np.shares_memory(levels[0], a)
    weight = np.ones((9, 7, 1), np.float32)
    colour = arrays.fill_colour(a[:, :, None].astype(np.float32), inp, "mask")
    assert colour.dtype == np.float64
    (filled,) = session.run(Fill(levels=2), [colour, weight], inp.compute)
    np.testing.assert_array_equal(filled[:, :, 0], a)


def test_zarr_outputs_are_told_without_loading_zarr(tmp_path):
    from pathlib import Path

    zarr = pytest.importorskip("zarr")
    group = zarr.open_group(zarr.storage.MemoryStore(), mode="w", zarr_format=3)
    assert [arrays.zarr_out(o) for o in (group, "a.ome.zarr", Path("b.ZARR/"), tmp_path / "c.zarr")] == [True] * 4
    assert [arrays.zarr_out(o) for o in (None, "a.tif", [np.zeros((2, 2))], (), zarr.storage.MemoryStore())] == \
        [False] * 5
