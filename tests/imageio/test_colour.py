"""sRGB curves and non-finite counts (pyramid_cli.imageio.colour)."""

import numpy as np

from pyramid_cli.imageio import colour


def test_srgb_curves_are_inverse_and_match_the_standard_at_known_points():
    x = np.linspace(0, 1, 1001)
    np.testing.assert_allclose(colour.srgb_to_linear(colour.linear_to_srgb(x)), x, rtol=0, atol=1e-6)
    np.testing.assert_allclose(colour.srgb_to_linear(np.array([0.0, 0.04045, 1.0])), [0, 0.04045 / 12.92, 1],
                               rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(colour.linear_to_srgb(np.array([0.5])), [0.7353569830524495], rtol=1e-6)


def test_count_nonfinite():
    assert colour.count_nonfinite(np.array([0.0, np.nan, np.inf, -np.inf, 1.0])) == 3


def test_srgb8_tables_kept_in_the_cache_folder_are_the_computed_ones(monkeypatch, tmp_path):
    """The 8-bit sRGB tables read back from the cache folder equal the computed ones; an entry whose bytes
    do not match their digest (flipped, cut short) is computed again and rewritten."""
    from pyramid_cli.core import cache

    monkeypatch.setenv(cache.HOME_ENV, str(tmp_path))
    want = colour._compute_srgb8_tables()
    for damage in (None, "flip", "cut"):
        colour.srgb8_tables.cache_clear()
        if damage:
            (entry,) = (tmp_path / "tables").iterdir()
            data = bytearray(entry.read_bytes())
            if damage == "flip":
                data[-100] ^= 0x01
            entry.write_bytes(bytes(data if damage == "flip" else data[:-1]))
            assert colour._read_tables(entry.name) is None
        got = colour.srgb8_tables()
        assert all(np.array_equal(a, b) and a.dtype == b.dtype for a, b in zip(got, want, strict=True))
        (entry,) = (tmp_path / "tables").iterdir()
        got = colour._read_tables(entry.name)
        assert got is not None and all(np.array_equal(a, b) for a, b in zip(got, want, strict=True))
    colour.srgb8_tables.cache_clear()
