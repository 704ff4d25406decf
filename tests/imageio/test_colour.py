"""sRGB curves and non-finite counts (pyramid_cli.imageio.colour)."""

import numpy as np
import pytest

from pyramid_cli.imageio import colour


def test_srgb_curves_are_inverse_and_match_the_standard_at_known_points():
    x = np.linspace(0, 1, 1001)
    np.testing.assert_allclose(colour.srgb_to_linear(colour.linear_to_srgb(x)), x, rtol=0, atol=1e-6)
    np.testing.assert_allclose(colour.srgb_to_linear(np.array([0.0, 0.04045, 1.0])), [0, 0.04045 / 12.92, 1],
                               rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(colour.linear_to_srgb(np.array([0.5])), [0.7353569830524495], rtol=1e-6)


def test_count_nonfinite():
    assert colour.count_nonfinite(np.array([0.0, np.nan, np.inf, -np.inf, 1.0])) == 3


@pytest.mark.parametrize("dtype", [np.float16, np.float32, np.float64])
def test_count_nonfinite_in_blocks_counts_across_their_edges(dtype, monkeypatch):
    """The scan goes a block at a time (NONFINITE_BLOCK values): values at each block's first and last place, a
    last block shorter than the others, views that are not contiguous, empty arrays and lists all count."""
    monkeypatch.setattr(colour, "NONFINITE_BLOCK", 7)
    a = np.random.default_rng(3).standard_normal((5, 6, 3)).astype(dtype)  # 90 values: 12 blocks and 6 over
    flat = a.reshape(-1)
    flat[[0, 6, 7, 13, 14, 89]] = [np.nan, np.inf, -np.inf, np.nan, np.inf, np.nan]
    assert colour.count_nonfinite(a) == 6
    assert colour.count_nonfinite(a[:, ::2]) == a[:, ::2].size - np.count_nonzero(np.isfinite(a[:, ::2]))
    assert colour.count_nonfinite(a[:0]) == 0
    assert colour.count_nonfinite([1.0, float("nan")]) == 1


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


def _srgb8_by_formula(x: np.ndarray) -> np.ndarray:
    """The float64 route srgb8 replaces (linear_to_srgb, ×255, round half up, clamp; NaN → 0)."""
    with np.errstate(over="ignore", invalid="ignore"):
        v = np.nan_to_num(colour.linear_to_srgb(x.astype(np.float64)), nan=0.0, posinf=1.0, neginf=0.0) * 255.0
    return np.clip(np.floor(v + 0.5), 0, 255).astype(np.uint8)


def bucket_loop(out, x, bits, codes, thresholds, i0, i1):
    """What a compiled loop given to use_srgb8_loop computes (the CPU executor's ``encode8``), in numpy."""
    b = bits[i0:i1] >> 16
    with np.errstate(invalid="ignore"):
        c = codes[b] + (x[i0:i1] >= thresholds[b])
    c[np.isnan(x[i0:i1])] = 0
    out[i0:i1] = c


@pytest.fixture(params=["numpy", "loop"])
def srgb8_route(request, monkeypatch):
    """srgb8 by numpy's lookups, then on a loop over :func:`srgb8_buckets` (restored after the test)."""
    monkeypatch.setattr(colour, "_LOOP", [bucket_loop] if request.param == "loop" else [])
    monkeypatch.setattr(colour, "LOOP_MIN", 0)  # every size on the loop
    return request.param


def test_srgb8_is_the_formula_on_every_kind_of_float32(srgb8_route):
    """srgb8's bucket lookup against the float64 formula, by numpy and on a loop over the 16-bit buckets: around
    every code boundary (±2 ulps, both signs), a sweep of all 2^32 bit patterns (every 4099th: every exponent,
    both signs, the NaNs), and the values that take numpy's slow path (+inf, and NaNs that share +inf's bucket)
    beside ordinary ones in one band, at a band's edges."""
    thresholds, _ = colour.srgb8_tables()
    t = thresholds.view(np.uint32).astype(np.int64)
    edges = np.concatenate([t + d for d in (-2, -1, 0, 1, 2)]).astype(np.uint32).view(np.float32)
    sweep = np.arange(0, 1 << 32, 4099, dtype=np.uint64).astype(np.uint32).view(np.float32)
    special = np.array([0x7F800000, 0x7F800001, 0x7F800FFF, 0x7F801000, 0x7FC00000, 0xFF800000, 0xFFC00000,
                        0x80000000, 0x00000001, 0x7F7FFFFF], np.uint32).view(np.float32)
    band = np.full(colour.SRGB8_BAND + 5, 0.25, np.float32)
    band[[0, 7, colour.SRGB8_BAND - 1, colour.SRGB8_BAND + 4]] = special[[0, 1, 2, 4]]
    for x in (edges, -edges, sweep, special, band, band.reshape(-1, 1, 1)[:-2], np.zeros(0, np.float32)):
        np.testing.assert_array_equal(colour.srgb8(x), _srgb8_by_formula(x))


def test_8bit_decoding_two_codes_at_a_time_is_one_at_a_time():
    """decode_integer's pair gathers (contiguous 8-bit codes, no alpha) give the one-code table's float32 values,
    an odd count's last code and a band's edge included."""
    every = np.stack(np.meshgrid(np.arange(256), np.arange(256)), -1).reshape(-1).astype(np.uint8)  # all pairs
    for srgb in (True, False):
        table = colour._integer_levels("uint8", srgb).astype(np.float32)
        for data in (every.reshape(-1, 2, 1), every[:-1].reshape(-1, 1, 1),
                     every[:2 * colour.PAIR_BAND + 3].reshape(1, -1, 1), np.zeros((0, 4, 3), np.uint8)):
            got = colour.decode_integer(data, srgb, np.ones(data.shape[2], bool), -1, False)
            assert got.dtype == np.float32
            np.testing.assert_array_equal(got, table[data])
