"""imageio.spill: rows kept until their turn, in memory or in a raw temporary file."""

from __future__ import annotations

import numpy as np
import pytest

from helpers.images import noise
from pyramid_cli.core.errors import OutputError
from pyramid_cli.imageio.spill import KeptChunks, KeptRows

SHAPES = [(5, 3, 2), (2, 1, 2)]


@pytest.mark.parametrize("on_disk", [False, True])
def test_rows_come_back_as_written_in_any_order(tmp_path, on_disk):
    kept = KeptRows(SHAPES, str(tmp_path / "spill") if on_disk else None, np.float32)
    a, b = noise(5, 3, 2), noise(2, 1, 2, seed=1)
    kept.write(1, 0, b)
    kept.write(0, 2, a[2:])
    kept.write(0, 0, a[:2])
    assert np.array_equal(kept.rows(0, 1, 4), a[1:4]) and np.array_equal(kept.rows(1, 0, 2), b)
    kept.close()
    assert (tmp_path / "spill").stat().st_size == (5 * 3 + 2) * 2 * 4 if on_disk else True


def test_a_file_that_fails_names_the_output_beside_it(tmp_path):
    with pytest.raises(OutputError, match=r"cannot write out\.tif: .*temporary file of its reduced levels"):
        KeptRows(SHAPES, str(tmp_path / "gone" / "spill"), beside="out.tif", what="reduced levels")
    kept = KeptRows(SHAPES, str(tmp_path / "spill"), beside="out.tif")
    kept.write(0, 0, noise(5, 3, 2))
    with pytest.raises(OutputError, match="ends 16 bytes early"):
        kept.rows(1, 0, 2)
    kept.close()
    with pytest.raises(ValueError, match="closed"):
        kept.rows(0, 0, 1)


def test_chunks_come_back_per_image_in_the_order_they_came(tmp_path):
    """Chunks of two images appended interleaved (a pyramidal TIFF's levels compressed as they complete) come back
    per image, in order, whole; a closed file is a ValueError."""
    kept = KeptChunks(2, str(tmp_path / "chunks"), beside="out.tif")
    want: list[list[bytes]] = [[], []]
    for n in range(7):
        data = bytes([n]) * (n * 1000 + 1)
        kept.append(n % 2, data)
        want[n % 2].append(data)
    assert [list(kept.chunks(i)) for i in (0, 1)] == want
    assert (tmp_path / "chunks").stat().st_size == sum(len(d) for d in want[0] + want[1])
    kept.close()
    with pytest.raises(ValueError, match="closed"):
        kept.append(0, b"x")


def test_a_chunk_file_that_fails_names_the_output_beside_it(tmp_path, monkeypatch):
    with pytest.raises(OutputError, match=r"cannot write out\.tif: .*temporary file of its reduced levels"):
        KeptChunks(1, str(tmp_path / "gone" / "chunks"), beside="out.tif", what="reduced levels")
    kept = KeptChunks(1, str(tmp_path / "chunks"), beside="out.tif")
    kept.append(0, b"abc")
    (tmp_path / "chunks").write_bytes(b"a")  # cut short under it
    with pytest.raises(OutputError, match="ends 2 bytes early"):
        list(kept.chunks(0))
    kept.close()

