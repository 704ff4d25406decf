"""Tests for ``pyramid diff`` (pyramid_cli.diff.compare and pyramid_cli.cli.diff).

Fixture images are written with OpenImageIO directly as float EXR (so the
values read back are exactly the float32 values written), and every expected
number is worked out here from the arrays the test wrote, never taken from the
code under test. The command is run through click's CliRunner on a throwaway
group, so it must work without being registered on ``pyramid``'s own group.
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import click
import numpy as np
import OpenImageIO as oiio
import pytest
from click.testing import CliRunner

from helpers.images import write
from pyramid_cli.cli.diff import diff
from pyramid_cli.diff import compare as D

# ---------------------------------------------------------------------------
# Helpers


def write_exr(path: Path, pixels, names=None) -> Path:
    return write(path, np.asarray(pixels, dtype=np.float32), names=names)


def write_png8(path: Path, pixels) -> Path:
    return write(path, np.asarray(pixels, dtype=np.uint8), "uint8")


def read_oiio(path: Path, fmt: str = "float") -> tuple[np.ndarray, oiio.ImageSpec]:
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, oiio.geterror()
    spec = inp.spec()
    data = inp.read_image(fmt)
    inp.close()
    return np.asarray(data).reshape(spec.height, spec.width, spec.nchannels), spec


def group() -> click.Group:
    g = click.Group()
    g.add_command(diff)
    return g


def run(*args: str):
    return CliRunner().invoke(group(), ["diff", *map(str, args)])


def pair(tmp_path: Path, a, b, names=None) -> tuple[Path, Path]:
    return (write_exr(tmp_path / "a.exr", a, names), write_exr(tmp_path / "b.exr", b, names))


def base(h=10, w=10, c=3, value=0.5) -> np.ndarray:
    return np.full((h, w, c), value, dtype=np.float32)


# ---------------------------------------------------------------------------
# Exit codes 0..4 through the command


def test_exit_0_identical(tmp_path):
    a, b = pair(tmp_path, base(), base())
    res = run(a, b)
    assert res.exit_code == 0, res.output
    assert "MATCH" in res.stdout


def test_exit_0_float32_rounding_is_below_default_warn(tmp_path):
    # float32 against float64: a relative error of one float32 ulp (~6e-8).
    rng = np.random.default_rng(1)
    ref = rng.random((8, 8, 3))
    a = ref.astype(np.float32)
    b = np.nextafter(a, np.float32(2))
    assert float(np.abs(a.astype(np.float64) - b).max()) < 1e-5
    pa, pb = pair(tmp_path, a, b)
    assert run(pa, pb).exit_code == 0


def test_exit_0_half_rounding_within_default_fail(tmp_path):
    # A half output against a float one: rounding error under 2^-11 |v|: over --warn, under --fail.
    # Like the idiff binary, no pixel over fail passes (exit 0) whatever --warn says.
    rng = np.random.default_rng(2)
    a = (rng.random((8, 8, 3)) * 3.9).astype(np.float32)
    b = a.astype(np.float16).astype(np.float32)
    err = np.abs(a.astype(np.float64) - b)
    assert 1e-5 < err.max() < 1e-3  # the premise of the default thresholds
    pa, pb = pair(tmp_path, a, b)
    res = run(pa, pb)
    assert res.exit_code == 0, res.output
    assert "MATCH (rule: allowfailures)" in res.stdout
    assert run("--failpercent", "100", "--fail", "1e-5", pa, pb).exit_code == 1  # a warning needs fails


def test_exit_2_failure(tmp_path):
    b = base()
    b[3, 4, 1] += 0.01
    pa, pb = pair(tmp_path, base(), b)
    res = run(pa, pb)
    assert res.exit_code == 2, res.output
    assert "FAILURE" in res.stdout


def test_exit_3_size_differs(tmp_path):
    pa = write_exr(tmp_path / "a.exr", base(4, 5))
    pb = write_exr(tmp_path / "b.exr", base(5, 4))
    res = run(pa, pb)
    assert res.exit_code == 3
    assert "size" in res.stderr


def test_exit_3_channel_count_differs(tmp_path):
    pa = write_exr(tmp_path / "a.exr", base(4, 4, 3))
    pb = write_exr(tmp_path / "b.exr", base(4, 4, 4))
    res = run(pa, pb)
    assert res.exit_code == 3
    assert "channel" in res.stderr


@pytest.mark.parametrize("which", ["a", "b"])
def test_exit_4_missing_file_named(tmp_path, which):
    good = write_exr(tmp_path / "good.exr", base())
    missing = tmp_path / "missing.exr"
    args = (missing, good) if which == "a" else (good, missing)
    res = run(*args)
    assert res.exit_code == 4
    assert str(missing) in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    assert res.stdout == ""


def test_exit_4_truncated_file(tmp_path):
    rng = np.random.default_rng(3)
    png = write_png8(tmp_path / "full.png", rng.integers(0, 256, (64, 64, 3)))
    data = png.read_bytes()
    cut = tmp_path / "cut.png"
    cut.write_bytes(data[: len(data) // 2])
    good = write_png8(tmp_path / "good.png", np.zeros((64, 64, 3)))
    res = run(good, cut)
    assert res.exit_code == 4, res.output
    assert str(cut) in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_exit_4_not_an_image(tmp_path):
    txt = tmp_path / "notes.exr"
    txt.write_text("this is not an image\n")
    good = write_exr(tmp_path / "good.exr", base())
    res = run(txt, good)
    assert res.exit_code == 4
    assert str(txt) in res.stderr


def test_exit_4_even_when_registered_on_pyramid_group(tmp_path):
    # pyramid's group maps InputError to its own exit 3; diff must not.
    from pyramid_cli.cli import main

    added = "diff" not in main.commands
    if added:
        main.add_command(diff)
    try:
        good = write_exr(tmp_path / "good.exr", base())
        res = CliRunner().invoke(main, ["diff", str(good), str(tmp_path / "nope.exr")])
        assert res.exit_code == 4
        b = base()
        b[0, 0, 0] = 0.75
        pa, pb = pair(tmp_path, base(), b)
        assert CliRunner().invoke(main, ["diff", str(pa), str(pb)]).exit_code == 2
    finally:
        if added:
            del main.commands["diff"]


def test_help_shows_example_and_exit_codes():
    res = run("--help")
    assert res.exit_code == 0
    text = res.stdout
    assert "Examples:" in text and "pyramid diff" in text
    for line in ("0  match", "1  warning", "2  failure", "3  the images differ", "4  file error"):
        assert line in text


# ---------------------------------------------------------------------------
# Threshold edges (idiff compares with '>': an error equal to a threshold passes)


def edge_pair():
    a = base(4, 4, 3, 0.5)
    b = a.copy()
    b[1, 2, 0] = 0.75  # error exactly 0.25, exactly representable
    return a, b


@pytest.mark.parametrize(("fail", "warn", "code"), [
    ("0.25", "0.25", 0),      # error == fail == warn: nothing over
    ("0.25", "0.125", 0),     # over warn only: idiff passes it
    ("0.125", "0.125", 2),    # over fail
    ("0.2499", "0.25", 2),
])
def test_threshold_edges_cli(tmp_path, fail, warn, code):
    pa, pb = pair(tmp_path, *edge_pair())
    res = run("--fail", fail, "--warn", warn, pa, pb)
    assert res.exit_code == code, res.output


def test_threshold_edges_api():
    a, b = edge_pair()
    err = float(np.float64(b[1, 2, 0]) - np.float64(a[1, 2, 0]))
    assert D.compare(a, b, fail=err, warn=err).verdict == "match"
    r = D.compare(a, b, fail=err, warn=err / 2)
    assert (r.verdict, r.n_fail, r.n_warn, r.exit_code, r.rule) == ("match", 0, 1, 0, "allowfailures")
    r = D.compare(a, b, fail=err / 2, warn=err / 2)
    assert (r.verdict, r.n_fail, r.exit_code) == ("failure", 1, 2)


def five_of_hundred():
    """10x10 image, 5 pixels off by 0.25 (one channel each)."""
    a = base(10, 10, 3, 0.5)
    b = a.copy()
    spots = [(0, 0, 0), (1, 3, 1), (4, 4, 2), (7, 2, 0), (9, 9, 1)]
    for y, x, c in spots:
        b[y, x, c] = 0.75
    return a, b, len(spots), a.shape[0] * a.shape[1]


def test_failpercent_edge(tmp_path):
    a, b, nbad, npx = five_of_hundred()
    pct = 100.0 * nbad / npx  # 5 %
    pa, pb = pair(tmp_path, a, b)
    common = ("--fail", "0.1", "--warn", "0.1")
    # exactly failpercent % fail: not a failure; still a warning (warnpercent 0)
    assert run(*common, "--failpercent", pct, pa, pb).exit_code == 1
    assert run(*common, "--failpercent", pct, "--warnpercent", pct, pa, pb).exit_code == 0
    assert run(*common, "--failpercent", pct - 0.01, "--warnpercent", pct, pa, pb).exit_code == 2
    assert run(*common, "--failpercent", pct, "--warnpercent", pct - 0.01, pa, pb).exit_code == 1


def test_allowfailures_edge(tmp_path):
    a, b, nbad, _ = five_of_hundred()
    pa, pb = pair(tmp_path, a, b)
    assert run("--allowfailures", nbad, pa, pb).exit_code == 0
    assert run("--allowfailures", nbad - 1, pa, pb).exit_code == 2
    r = D.compare(a, b, allowfailures=nbad)
    assert (r.verdict, r.n_fail) == ("match", nbad)


def test_hardfail(tmp_path):
    a = base(10, 10, 1, 0.25)
    b = a.copy()
    b[6, 3, 0] = 0.75  # one pixel off by 0.5: 1 % of the pixels
    pa, pb = pair(tmp_path, a, b)
    lenient = ("--fail", "0.1", "--failpercent", "5")
    assert run(*lenient, pa, pb).exit_code == 1                          # within failpercent: warning
    assert run(*lenient, "--hardfail", "0.5", pa, pb).exit_code == 1     # error == hardfail: not over
    assert run(*lenient, "--hardfail", "0.4", pa, pb).exit_code == 2     # over hardfail: failure
    # idiff: --allowfailures N lets N pixels differ "by any amount", hardfail included
    assert run(*lenient, "--hardfail", "0.4", "--allowfailures", "1", pa, pb).exit_code == 0
    r = D.compare(a, b, fail=0.1, failpercent=5, hardfail=0.4)
    assert (r.verdict, r.n_hardfail, r.n_fail) == ("failure", 1, 1)


def test_hardwarn():
    a = base(10, 10, 1, 0.25)
    b = a.copy()
    b[0, 0, 0] = 0.5
    # idiff: hardwarn only counts once some pixel fails and failpercent tolerates it
    r = D.compare(a, b, fail=0.1, failpercent=5, warn=0.1, warnpercent=5, hardwarn=0.2)
    assert (r.verdict, r.n_hardwarn, r.rule) == ("warning", 1, "hardwarn")
    assert D.compare(a, b, fail=0.1, failpercent=5, warn=0.1, warnpercent=5).verdict == "match"
    assert D.compare(a, b, fail=1.0, warn=0.1, hardwarn=0.2).verdict == "match"


# ---------------------------------------------------------------------------
# Relative mode: |a-b| / mean(|a|, |b|), combined with the absolute test by AND


def relative_pair():
    a = np.full((2, 2, 1), 64.0, dtype=np.float32)
    b = a.copy()
    b[0, 1, 0] = 64.0625   # abs 0.0625, rel 0.0625 / 64.03125 ~ 9.76e-4
    a[1, 0, 0] = 0.0
    b[1, 0, 0] = 0.0025    # abs 0.0025, rel 2 (mean 0.00125)
    return a, b


def test_relative_mode(tmp_path):
    a, b = relative_pair()
    rel_big = 0.0625 / ((64.0 + 64.0625) / 2)
    rel_small = 0.0025 / ((0.0 + 0.0025) / 2)
    assert 9e-4 < rel_big < 1e-3 and rel_small == pytest.approx(2.0)
    pa, pb = pair(tmp_path, a, b)
    # absolute only: both pixels fail
    r = D.compare(a, b, fail=1e-3)
    assert (r.verdict, r.n_fail) == ("failure", 2)
    # relative 1e-3: the 64 pixel is within, the small one (rel 2) still fails
    r = D.compare(a, b, fail=1e-3, failrelative=1e-3)
    assert (r.verdict, r.n_fail) == ("failure", 1)
    # relative 2 (== rel of the small pixel): nothing fails; warnings remain
    r = D.compare(a, b, fail=1e-3, failrelative=2.0)
    assert (r.verdict, r.n_fail, r.n_warn) == ("match", 0, 2)
    assert run("--failrelative", "2", pa, pb).exit_code == 0
    assert run("--failrelative", "2", "--warnrelative", "2", pa, pb).exit_code == 0
    assert run("--failrelative", "1.9", pa, pb).exit_code == 2
    # the relative edge on the big pixel, from this test's own arithmetic
    r = D.compare(a[:1], b[:1], fail=1e-3, failrelative=rel_big)
    assert r.n_fail == 0
    r = D.compare(a[:1], b[:1], fail=1e-3, failrelative=np.nextafter(rel_big, 0))
    assert r.n_fail == 1


def test_relative_false_is_off():
    a, b = relative_pair()
    assert D.compare(a, b, failrelative=False).n_fail == D.compare(a, b).n_fail == 2


# ---------------------------------------------------------------------------
# NaN and Inf


def test_nan_in_one_image_fails_whatever_the_thresholds(tmp_path):
    a = base(3, 4, 3)
    b = a.copy()
    b[2, 1, 2] = np.nan
    pa, pb = pair(tmp_path, a, b)
    res = run("--json", "--fail", "1e9", "--warn", "1e9", "--failpercent", "50", pa, pb)
    assert res.exit_code == 2, res.output
    d = json.loads(res.stdout)
    assert d["verdict"] == "failure"
    assert d["n_nonfinite"] == 1 and d["n_fail"] == 1
    assert (d["max_x"], d["max_y"], d["max_channel_name"]) == (1, 2, "B")
    assert d["max_error"] is None and d["max_error_infinite"] is True
    assert d["n_hardfail"] == 1  # an infinite error is over even an infinite hardfail
    # ... unless --allowfailures lets that pixel differ "by any amount" (idiff)
    assert run("--allowfailures", "1", pa, pb).exit_code == 0


def test_nan_in_both_at_same_place_matches(tmp_path):
    a = base(3, 4, 3)
    a[1, 1, 0] = np.nan
    a[0, 2, 1] = np.inf
    pa, pb = pair(tmp_path, a, a.copy())
    res = run("--json", pa, pb)
    assert res.exit_code == 0, res.output
    d = json.loads(res.stdout)
    assert (d["verdict"], d["n_nonfinite"], d["max_error"]) == ("match", 0, 0.0)


def test_nan_in_both_plus_a_real_difference():
    a = base(3, 4, 1)
    a[0, 0, 0] = np.nan
    b = a.copy()
    b[2, 3, 0] = 0.625  # error 0.125
    r = D.compare(a, b, fail=0.1)
    assert (r.verdict, r.n_fail, r.max_error, r.max_x, r.max_y) == ("failure", 1, 0.125, 3, 2)
    assert r.mean_error == pytest.approx(0.125 / 12)


def test_opposite_infinities_differ():
    a = base(2, 2, 1)
    b = a.copy()
    a[0, 0, 0] = np.inf
    b[0, 0, 0] = -np.inf
    r = D.compare(a, b)
    assert (r.verdict, r.n_nonfinite, math.isinf(r.max_error)) == ("failure", 1, True)


# ---------------------------------------------------------------------------
# Statistics and JSON


def test_json_fields_match_own_arithmetic(tmp_path):
    a = base(6, 7, 3, 0.5)
    b = a.copy()
    b[4, 5, 2] = 0.5 + 0.03125    # the largest error, at x=5, y=4, channel B
    b[1, 0, 0] = 0.5 - 0.0078125
    pa, pb = pair(tmp_path, a, b, names=["R", "G", "B"])
    res = run("--json", pa, pb)
    d = json.loads(res.stdout)
    err = np.abs(a.astype(np.float64) - b.astype(np.float64))
    rms = math.sqrt(float(np.mean(err ** 2)))
    assert d["verdict"] == "failure" and d["exit_code"] == res.exit_code == 2
    assert (d["max_x"], d["max_y"], d["max_channel"], d["max_channel_name"]) == (5, 4, 2, "B")
    assert d["max_error"] == pytest.approx(0.03125)
    assert d["a_values"] == [0.5, 0.5, 0.5] and d["b_values"] == [0.5, 0.5, 0.53125]
    assert d["mean_error"] == pytest.approx(float(err.mean()))
    assert d["rms_error"] == pytest.approx(rms)
    assert d["psnr"] == pytest.approx(20 * math.log10(1.0 / rms))
    assert (d["n_pixels"], d["n_fail"], d["n_warn"]) == (42, 2, 2)
    assert d["percent_fail"] == pytest.approx(100 * 2 / 42)
    assert d["thresholds"]["fail"] == 1e-3 and d["thresholds"]["warn"] == 1e-5
    assert d["thresholds"]["hardfail"] is None


def test_json_identical_images_parses_without_infinity(tmp_path):
    pa, pb = pair(tmp_path, base(), base())
    res = run("--json", pa, pb)
    assert res.exit_code == 0
    assert "Infinity" not in res.stdout and "NaN" not in res.stdout
    d = json.loads(res.stdout)
    assert d["verdict"] == "match" and d["exit_code"] == 0
    assert d["psnr"] is None and d["psnr_infinite"] is True
    assert d["max_x"] is None and d["max_error"] == 0.0


def test_json_on_file_error_and_size_error(tmp_path):
    pa = write_exr(tmp_path / "a.exr", base(4, 4))
    res = run("--json", pa, tmp_path / "gone.exr")
    assert res.exit_code == 4
    d = json.loads(res.stdout)
    assert d["exit_code"] == 4 and d["verdict"] is None and "gone.exr" in d["error"]
    pb = write_exr(tmp_path / "b.exr", base(4, 5))
    d = json.loads(run("--json", pa, pb).stdout)
    assert d["exit_code"] == 3


def test_human_report_lines(tmp_path):
    a = base(4, 4, 3)
    b = a.copy()
    b[2, 3, 1] = 0.625
    pa, pb = pair(tmp_path, a, b, names=["R", "G", "B"])
    out = run(pa, pb).stdout
    for label in ("max error", "mean error", "RMS error", "PSNR", "over warn", "over fail", "verdict"):
        assert f"  {label}" in out
    assert "0.125 @ (x=3, y=2, G)" in out
    assert "1 pixels (6.25%) over 0.001" in out   # 1 of 16 pixels


def test_quiet(tmp_path):
    pa, pb = pair(tmp_path, base(), base())
    res = run("-q", pa, pb)
    assert (res.exit_code, res.stdout, res.stderr) == (0, "", "")
    b = base()
    b[0, 0, 0] = 1.0
    pa, pb = pair(tmp_path, base(), b)
    res = run("-q", pa, pb)
    assert res.exit_code == 2 and res.stdout == "" and "FAIL" in res.stderr


def test_api_max_location_orientation_and_default_names():
    a = np.zeros((3, 5), dtype=np.float32)   # 2-D input is one channel
    b = a.copy()
    b[2, 4] = 0.5
    r = D.compare(a, b)
    assert (r.max_x, r.max_y, r.max_channel, r.max_channel_name) == (4, 2, 0, "c0")
    assert (r.width, r.height, r.channels, r.n_pixels) == (5, 3, 1, 15)


def test_api_shape_mismatch():
    with pytest.raises(D.ShapeMismatchError):
        D.compare(np.zeros((2, 2, 3)), np.zeros((2, 2, 4)))
    with pytest.raises(D.ShapeMismatchError):
        D.difference_image(np.zeros((2, 3, 1)), np.zeros((3, 2, 1)), 1.0)


# ---------------------------------------------------------------------------
# Pictures: difference_image, heatmap, --out


def test_difference_image_values():
    a = base(2, 3, 2, 0.5)
    b = a.copy()
    b[1, 2, 1] = 0.25
    b[0, 0, 0] = np.nan
    d = D.difference_image(a, b, 8.0)
    assert d.shape == (2, 3, 2) and d.dtype == np.float32
    assert d[1, 2, 1] == 0.25 * 8.0
    assert np.isinf(d[0, 0, 0])
    mask = np.ones_like(d, dtype=bool)
    mask[1, 2, 1] = mask[0, 0, 0] = False
    assert np.all(d[mask] == 0)


def test_heatmap_colours():
    a = base(2, 3, 3, 0.5)
    b = a.copy()
    b[0, 1, 2] = 0.5 + 1e-4        # a small error: coloured, not black
    b[1, 2, 0] = np.nan            # mismatch: white
    h = D.heatmap(a, b)
    assert h.shape == (2, 3, 3) and h.dtype == np.float32
    assert np.all(h[0, 0] == 0.0)                 # identical: black
    assert np.all(h[1, 2] == 1.0)
    assert h[0, 1].max() > 0.0 and not np.all(h[0, 1] == 1.0)
    # log scale: 1e-4 sits half-way between 1e-8 and 1
    import matplotlib
    want = np.asarray(matplotlib.colormaps["viridis"](0.5))[:3]
    np.testing.assert_allclose(h[0, 1], want, atol=1e-3)


def test_out_difference_exr_exact(tmp_path):
    a = base(5, 6, 3, 0.5)
    b = a.copy()
    b[3, 1, 0] = 0.5 + 0.0625
    pa, pb = pair(tmp_path, a, b)
    out = tmp_path / "d.exr"
    res = run("--out", out, "--scale", "4", pa, pb)
    assert res.exit_code == 2
    px, spec = read_oiio(out)
    assert (spec.width, spec.height, spec.nchannels) == (6, 5, 3)
    want = (a.astype(np.float64) - b) * 4  # idiff's -o: signed A-B
    np.testing.assert_array_equal(px, want.astype(np.float32))
    assert run("-o", out, "-abs", "-scale", "4", pa, pb).exit_code == 2  # idiff's spelling, |A-B|
    np.testing.assert_array_equal(read_oiio(out)[0], np.abs(want).astype(np.float32))


def test_out_png_and_heatmap_png(tmp_path):
    a = base(7, 9, 3, 0.25)
    b = a.copy()
    b[2, 5, 1] = 0.0  # A-B > 0: a PNG clamps negative differences to 0
    pa, pb = pair(tmp_path, a, b)
    out = tmp_path / "d.png"
    assert run("--out", out, pa, pb).exit_code == 2
    px, spec = read_oiio(out)
    assert (spec.width, spec.height, spec.nchannels) == (9, 7, 3)
    assert px[2, 5, 1] > 0 and px[0, 0].max() == 0
    hm = tmp_path / "h.png"
    assert run("--out", hm, "--heatmap", pa, pb).exit_code == 2
    px, spec = read_oiio(hm, "uint8")
    assert (spec.width, spec.height, spec.nchannels, str(spec.format)) == (9, 7, 3, "uint8")
    assert px[0, 0].max() == 0 and px[2, 5].max() > 0
    assert not list(tmp_path.glob("*.tmp*"))  # atomic write leaves nothing behind


def test_heatmap_needs_out(tmp_path):
    pa, pb = pair(tmp_path, base(), base())
    res = run("--heatmap", pa, pb)
    assert res.exit_code == 2 and "--out" in res.output


def test_out_refuses_to_overwrite_an_input(tmp_path):
    b = base()
    b[0, 0, 0] = 0.0
    pa, pb = pair(tmp_path, base(), b)
    before = pb.read_bytes()
    res = run("--out", pb, pa, pb)
    assert res.exit_code == 4
    assert pb.read_bytes() == before


def test_inputs_read_alike_into_linear_light(tmp_path):
    # An 8-bit sRGB PNG against the float EXR of its decoded values matches.
    v = np.array([[[0, 64, 128], [200, 255, 10]]], dtype=np.uint8)
    png = write_png8(tmp_path / "s.png", v)
    s = v / 255.0
    lin = np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)
    exr = write_exr(tmp_path / "l.exr", lin)
    assert run("--linear", png, exr).exit_code == 0
    # read as linear (no decoding) they differ; so do the stored code values (the default)
    assert run("--linear", "--colorspace", "linear", png, exr).exit_code == 2
    assert run(png, exr).exit_code == 2


# ---------------------------------------------------------------------------
# Against the idiff binary itself, where idiff follows its own documentation


def _idiff() -> str | None:
    """idiff from PATH, else the one the OpenImageIO wheel put next to this Python."""
    found = shutil.which("idiff")
    if found:
        return found
    beside = Path(sys.executable).parent / "idiff"
    return str(beside) if beside.exists() else None


IDIFF = _idiff()


@pytest.mark.slow
@pytest.mark.cli
@pytest.mark.skipif(IDIFF is None, reason="OpenImageIO's idiff is not installed")
def test_exit_codes_agree_with_idiff(tmp_path):
    """Random images and thresholds: same exit code as the idiff binary, every case, in both spellings."""
    rng = np.random.default_rng(7)
    compared = 0
    for _ in range(30):  # the hand-picked battery is tests/test_diff_idiff.py
        a = (rng.random((6, 6, 3)) * rng.choice([1.0, 10.0])).astype(np.float32)
        b = a.copy()
        for _ in range(int(rng.integers(0, 10))):
            y, x, c = rng.integers(0, 6, size=2).tolist() + [int(rng.integers(0, 3))]
            b[y, x, c] += np.float32(rng.choice([1e-5, 1e-4, 1e-3, 1e-2, 0.1, 0.5]) * rng.choice([-1, 1]))
        pa, pb = pair(tmp_path, a, b)
        fail = float(rng.choice([1e-4, 1e-3, 1e-2]))
        opts = {"fail": fail, "warn": float(rng.choice([1e-6, 1e-5, fail])),
                "failpercent": float(rng.choice([0, 2, 5])), "warnpercent": float(rng.choice([0, 2, 5])),
                "failrelative": float(rng.choice([0, 0, 1e-3])), "allowfailures": int(rng.choice([0, 1, 3]))}
        hardfail = float(rng.choice([np.inf, 0.3]))
        if math.isfinite(hardfail):
            opts["hardfail"] = hardfail
        # Which pixels fail / warn / exceed hardfail, worked out here.
        err = np.abs(a.astype(np.float64) - b)
        rel = err / np.maximum((np.abs(a) + np.abs(b)) / 2.0, 1e-30)
        n_fail = int(((err > opts["fail"]) & (rel > opts["failrelative"])).any(axis=2).sum())
        n_warn = int((err > opts["warn"]).any(axis=2).sum())
        n_hard = int((err > hardfail).any(axis=2).sum())
        args = []
        for k, v in opts.items():
            args += [f"-{k}", str(v)]
        got_idiff = subprocess.run([IDIFF, "-q", *args, str(pa), str(pb)], capture_output=True).returncode
        cli_args = []
        for k, v in opts.items():
            cli_args += [f"--{k}", str(v)]
        assert run(*cli_args, pa, pb).exit_code == got_idiff, (opts, n_fail, n_warn, n_hard)
        assert run(*args, pa, pb).exit_code == got_idiff, (opts, n_fail, n_warn, n_hard)  # idiff's spelling
        compared += 1
    assert compared == 30
