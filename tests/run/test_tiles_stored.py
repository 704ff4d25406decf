"""``pyramid tiles``' level 0 from the input's stored rows (:func:`pyramid_cli.run.tiles.stored_rows`): taken only
where encoding the decoded rows gives them back, and then the same bytes as encoding them."""

from __future__ import annotations

import os

import numpy as np
import pytest

from helpers.images import write
from helpers.tilesets import tree
from pyramid_cli.run import tiles as run_tiles
from pyramid_cli.run.tiles import StoredRows, tiles


@pytest.fixture
def taken(monkeypatch):
    """The stored_rows decisions of the runs so far (True: level 0 from the stored rows)."""
    seen: list[bool] = []
    real = run_tiles.stored_rows

    def spy(*args):
        kept = real(*args)
        seen.append(kept is not None)
        return kept

    monkeypatch.setattr(run_tiles, "stored_rows", spy)
    return seen


@pytest.mark.parametrize("pixel_type, channels, out, kw", [
    ("uint8", 3, "t.dzi", {"tile_size": 16, "memory": "400K"}),   # several bands: the kept rows split and joined
    ("uint8", 1, "t.tif", {"tile_size": 16, "compression": "deflate"}),
    ("uint16", 3, "t.tif", {"tile_size": 16}),
    ("uint8", 3, "t.ome.zarr", {"tile_size": 16, "memory": "400K"}),
])
def test_stored_level0_writes_the_same_bytes(tmp_path, session, taken, monkeypatch, pixel_type, channels, out, kw):
    """Level 0 from the stored rows, and level 1 from them read through the decoding table by the CPU executor
    (no float copy of the input, run.stream.executor_codes): the same bytes as every level encoded from decoded
    floats."""
    top = 255 if pixel_type == "uint8" else 65535
    codes = np.random.default_rng(3).integers(0, top + 1, (71, 93, channels)).astype(pixel_type)
    codes[0, :, 0] = np.arange(93)  # every small code: the linear segment of sRGB
    src = write(tmp_path / "in.png", codes, pixel_type)
    tables = []
    real = run_tiles.executor_codes
    monkeypatch.setattr(run_tiles, "executor_codes", lambda *a: tables.append(real(*a)) or tables[-1])
    tiles(src, tmp_path / "a" / out, session=session, **kw)
    assert taken == [True] and len(tables) == 1 and tables[0] is not None
    monkeypatch.setattr(run_tiles, "stored_rows", lambda *a: None)  # every level encoded from its decoded rows
    tiles(src, tmp_path / "b" / out, session=session, **kw)
    a, b = ({k.split(os.sep, 1)[1]: v for k, v in tree(tmp_path / run).items()} for run in ("a", "b"))
    assert a.keys() == b.keys() and len(a) > (2 if out.endswith(".dzi") else 0)
    assert [k for k in a if a[k] != b[k]] == []


@pytest.mark.parametrize("channels, kw", [
    (4, {"format": "png"}),                     # alpha: a code under alpha 0 does not come back
    (3, {"dither": True}),                      # dither moves codes
    (3, {"tocolorspace": "srgb"}),              # a space asked: not taken (even the input's own)
    (3, {"pixel_type": "uint16", "format": "png"}),  # another type
])
def test_stored_level0_only_where_it_comes_back(tmp_path, session, taken, channels, kw):
    codes = np.random.default_rng(4).integers(0, 256, (20, 30, channels)).astype(np.uint8)
    src = write(tmp_path / "in.png", codes, "uint8", alpha=3 if channels == 4 else None)
    out = tmp_path / "t.dzi"
    tiles(src, out, session=session, tile_size=16, **kw)
    assert taken == [False]


def test_kept_rows_are_taken_in_any_split():
    kept = StoredRows()
    rows = np.arange(40).reshape(20, 2)
    for a, b in ((0, 7), (7, 8), (8, 20)):
        kept.keep(rows[a:b])
    got = [kept.take(n) for n in (3, 6, 11)]
    assert np.array_equal(np.concatenate(got), rows)
    assert [len(g) for g in got] == [3, 6, 11]
