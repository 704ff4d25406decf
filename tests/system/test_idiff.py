"""``pyramid diff`` against the real ``idiff`` binary: a battery of pairs.

Every case runs ``idiff -v`` and ``pyramid diff --json`` with the same
(idiff-spelled) options and holds the exit code and the statistics (mean, RMS,
PSNR, max error and where, pixels over warn / fail, per level under ``-a``)
equal to idiff's. The deliberate differences are listed in ``DELIBERATE`` and
each is asserted for what it is (its own test below names it).
"""

from __future__ import annotations

import json
import math
import re
import shutil
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from click.testing import CliRunner

from helpers.images import write
from pyramid_cli.cli.diff import diff


def _idiff() -> str | None:
    beside = Path(sys.executable).parent / "idiff"
    if beside.exists():
        return str(beside)
    return shutil.which("idiff")


IDIFF = _idiff()
pytestmark = [pytest.mark.cli, pytest.mark.slow,
              pytest.mark.skipif(IDIFF is None, reason="OpenImageIO's idiff binary is not installed")]


# ---------------------------------------------------------------------------
# Writers


def write_parts(path: Path, parts: list[np.ndarray]) -> Path:
    specs = [oiio.ImageSpec(p.shape[1], p.shape[0], p.shape[2], "float") for p in parts]
    for i, s in enumerate(specs):
        s.attribute("name", f"part{i}")
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), specs), out.geterror()
    for i, p in enumerate(parts):
        if i:
            assert out.open(str(path), specs[i], "AppendSubimage"), out.geterror()
        assert out.write_image(np.ascontiguousarray(p.astype(np.float32))), out.geterror()
    out.close()
    return path


def write_mip(path: Path, levels: list[np.ndarray]) -> Path:
    """A tiled MIP-mapped EXR with exactly these levels."""
    h, w, c = levels[0].shape
    spec = oiio.ImageSpec(w, h, c, "float")
    spec.tile_width = spec.tile_height = 16
    spec.attribute("openexr:levelmode", 1)  # MIPMAP_LEVELS
    spec.attribute("openexr:roundingmode", 0)  # ROUND_DOWN
    spec.attribute("textureformat", "Plain Texture")
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec, "Create"), out.geterror()
    for i, lv in enumerate(levels):
        if i:
            s = oiio.ImageSpec(lv.shape[1], lv.shape[0], c, "float")
            s.tile_width = s.tile_height = 16
            assert out.open(str(path), s, "AppendMIPLevel"), out.geterror()
        assert out.write_image(np.ascontiguousarray(lv.astype(np.float32))), out.geterror()
    out.close()
    return path


def mip_chain(px: np.ndarray) -> list[np.ndarray]:
    levels = [px.astype(np.float32)]
    while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
        p = levels[-1]
        h, w = max(p.shape[0] // 2, 1), max(p.shape[1] // 2, 1)
        levels.append(p[: h * 2 : 2][:, : w * 2 : 2][:h, :w].copy())
    return levels


def rnd(seed: int, h: int = 16, w: int = 16, c: int = 3, scale: float = 1.0) -> np.ndarray:
    return (np.random.default_rng(seed).random((h, w, c)) * scale).astype(np.float32)


def poke(px: np.ndarray, *spots: tuple[int, int, int, float]) -> np.ndarray:
    out = px.copy()
    for y, x, c, dv in spots:
        out[y, x, c] += np.float32(dv)
    return out


def noise(px: np.ndarray, seed: int, amp: float, frac: float = 1.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = (rng.random(px.shape) * 2 - 1) * amp
    d[rng.random(px.shape[:2]) >= frac] = 0
    return (px + d).astype(np.float32)


# ---------------------------------------------------------------------------
# Cases


@dataclass
class Case:
    name: str
    make: Callable[[Path], tuple[str, str]]   # writes A and B into the folder, returns their paths
    args: tuple[str, ...] = ()
    ours: int | None = None     # our exit code where it deliberately differs from idiff's
    why: str = ""
    stats: bool = True          # compare statistics (not where NaN/Inf or shapes make them differ)


def files(a_px, b_px, fmt_a="float", fmt_b=None, ext_a="exr", ext_b=None, names=None):
    def make(d: Path) -> tuple[str, str]:
        pa = write(d / f"a.{ext_a}", a_px, fmt_a, names=names)
        pb = write(d / f"b.{ext_b or ext_a}", b_px, fmt_b or fmt_a, names=names)
        return str(pa), str(pb)
    return make


BASE = rnd(1)
U8 = (np.random.default_rng(5).integers(0, 256, (12, 10, 3))).astype(np.uint8)
U8_ONE = U8.copy()
U8_ONE[3, 4, 1] = U8[3, 4, 1] ^ 1                    # one code apart
U8_NOISE = np.clip(U8.astype(int) + np.random.default_rng(6).integers(-2, 3, U8.shape), 0, 255).astype(np.uint8)
RGBA8 = np.random.default_rng(8).integers(0, 256, (8, 8, 4)).astype(np.uint8)
RGBA8_B = RGBA8.copy()
RGBA8_B[2, 2, 3] = RGBA8[2, 2, 3] ^ 8                # alpha off by 8 codes
HALFVALS = (np.random.default_rng(9).random((10, 10, 3)) * 3.9).astype(np.float32)
FIVE = np.full((10, 10, 3), 0.5, np.float32)
FIVE_B = poke(FIVE, (0, 0, 0, 0.25), (1, 3, 1, 0.25), (4, 4, 2, 0.25), (7, 2, 0, 0.25), (9, 9, 1, 0.25))
REL_A = np.full((4, 4, 1), 64.0, np.float32)
REL_A[1, 0, 0] = 0.0
REL_B = REL_A.copy()
REL_B[0, 1, 0] = 64.0625
REL_B[1, 0, 0] = 0.0025


def nan_in(px, y, x, c, v=np.nan):
    out = px.copy()
    out[y, x, c] = v
    return out


def mip_pair(change_level: int | None, drop_last: bool = False, *, dv: float = 0.25, swap: bool = False):
    def make(d: Path) -> tuple[str, str]:
        la = mip_chain(rnd(11, 32, 32))
        lb = [lv.copy() for lv in la]
        if change_level is not None:
            lb[change_level][0, 0, 0] += np.float32(dv)
        pa = write_mip(d / "a.exr", la)
        pb = write(d / "b.exr", lb[0]) if drop_last else write_mip(d / "b.exr", lb)  # drop_last: not MIP-mapped
        return (str(pb), str(pa)) if swap else (str(pa), str(pb))
    return make


def parts_pair(change_part: int | None, n_b: int = 2):
    def make(d: Path) -> tuple[str, str]:
        pa = [rnd(20, 8, 8), rnd(21, 8, 8, 4)]
        pb = [p.copy() for p in pa][:n_b]
        if change_part is not None:
            pb[change_part][1, 1, 1] += np.float32(0.125)
        return str(write_parts(d / "a.exr", pa)), str(write_parts(d / "b.exr", pb))
    return make


def special(kind: str):
    def make(d: Path) -> tuple[str, str]:
        pa = write(d / "a.exr", BASE)
        if kind == "missing_b":
            return str(pa), str(d / "nope.exr")
        if kind == "missing_a":
            return str(d / "nope.exr"), str(pa)
        if kind == "corrupt":
            good = write(d / "g.exr", BASE).read_bytes()
            (d / "b.exr").write_bytes(good[: len(good) // 2])
            return str(pa), str(d / "b.exr")
        if kind == "text":
            (d / "b.png").write_text("not an image\n")
            return str(pa), str(d / "b.png")
        if kind == "dir":
            (d / "ref").mkdir()
            write(d / "ref" / "a.exr", poke(BASE, (2, 2, 2, 0.01)))
            return str(pa), str(d / "ref")
        raise AssertionError(kind)
    return make


T = ("-fail", "0.004", "-warn", "0.001")
CASES: list[Case] = [
    Case("identical", files(BASE, BASE)),
    Case("identical_defaults_both_pass", files(BASE, BASE), ()),
    Case("tiny_below_idiff_default", files(BASE, poke(BASE, (3, 3, 0, 4e-7)))),
    Case("tiny_over_idiff_default", files(BASE, poke(BASE, (3, 3, 0, 1e-4))), ours=0,
         why="defaults: this tool's --fail 1e-3 is looser than idiff's 1e-6", stats=False),
    Case("tiny_explicit_thresholds", files(BASE, poke(BASE, (3, 3, 0, 1e-4))), ("-fail", "1e-6", "-warn", "1e-6")),
    Case("one_pixel_large", files(BASE, poke(BASE, (5, 7, 2, 0.5))), ("-fail", "0.1")),
    Case("one_pixel_under_fail", files(BASE, poke(BASE, (5, 7, 2, 0.05))), ("-fail", "0.1", "-warn", "0.01")),
    Case("many_pixels_noise_fail", files(BASE, noise(BASE, 2, 0.01)), T),
    Case("many_pixels_noise_pass", files(BASE, noise(BASE, 3, 0.003)), T),
    Case("sparse_noise", files(BASE, noise(BASE, 4, 0.05, frac=0.1)), T),
    Case("failpercent_tolerates_warns", files(FIVE, FIVE_B), ("-fail", "0.1", "-warn", "0.1", "-failpercent", "5")),
    Case("failpercent_and_warnpercent", files(FIVE, FIVE_B),
         ("-fail", "0.1", "-warn", "0.1", "-failpercent", "5", "-warnpercent", "5")),
    Case("failpercent_just_under", files(FIVE, FIVE_B), ("-fail", "0.1", "-failpercent", "4.99")),
    Case("warnpercent_just_under", files(FIVE, FIVE_B),
         ("-fail", "0.1", "-warn", "0.1", "-failpercent", "5", "-warnpercent", "4.99")),
    Case("hardfail_over", files(FIVE, FIVE_B), ("-fail", "0.1", "-failpercent", "10", "-hardfail", "0.2")),
    Case("hardfail_equal", files(FIVE, FIVE_B), ("-fail", "0.1", "-failpercent", "10", "-hardfail", "0.25",
                                                 "-warnpercent", "10")),
    Case("hardwarn_over", files(FIVE, FIVE_B), ("-fail", "0.1", "-failpercent", "10", "-warnpercent", "10",
                                                 "-hardwarn", "0.2")),
    Case("hardwarn_without_fails", files(FIVE, FIVE_B), ("-fail", "1", "-hardwarn", "0.2")),
    Case("allowfailures_covers", files(FIVE, FIVE_B), ("-fail", "0.1", "-allowfailures", "5")),
    Case("allowfailures_short", files(FIVE, FIVE_B), ("-fail", "0.1", "-allowfailures", "4")),
    Case("allowfailures_beats_hardfail", files(FIVE, FIVE_B), ("-fail", "0.1", "-allowfailures", "5",
                                                               "-hardfail", "0.2")),
    Case("failrelative_absolute_only", files(REL_A, REL_B), ("-fail", "0.001")),
    Case("failrelative_hides_big_value", files(REL_A, REL_B), ("-fail", "0.001", "-failrelative", "0.001")),
    Case("failrelative_hides_all", files(REL_A, REL_B), ("-fail", "0.001", "-failrelative", "2.5")),
    Case("warnrelative", files(REL_A, REL_B), ("-fail", "0.001", "-failpercent", "50", "-warn", "0.001",
                                               "-warnrelative", "0.001")),
    Case("hdr_values_psnr_peak", files(rnd(30, scale=8.0), noise(rnd(30, scale=8.0), 31, 0.01)), T),
    Case("nan_in_b", files(BASE, nan_in(BASE, 2, 3, 1)), T, ours=2, stats=False,
         why="NaN against a number fails here; idiff counts no failing pixel"),
    Case("nan_in_a", files(nan_in(BASE, 2, 3, 1), BASE), T, ours=2, stats=False, why="as nan_in_b"),
    Case("nan_in_both_same_place", files(nan_in(BASE, 2, 3, 1), nan_in(BASE, 2, 3, 1)), T, stats=False),
    Case("pos_inf_in_b", files(BASE, nan_in(BASE, 0, 0, 0, np.inf)), T, ours=2, stats=False,
         why="Inf against a number fails here"),
    Case("neg_inf_in_a", files(nan_in(BASE, 4, 1, 2, -np.inf), BASE), T, ours=2, stats=False,
         why="-Inf against a number fails here"),
    Case("opposite_infinities", files(nan_in(BASE, 4, 1, 2, np.inf), nan_in(BASE, 4, 1, 2, -np.inf)), T,
         ours=2, stats=False, why="+Inf against -Inf fails here; idiff matches them"),
    Case("same_inf_both", files(nan_in(BASE, 4, 1, 2, np.inf), nan_in(BASE, 4, 1, 2, np.inf)), T, stats=False),
    Case("size_differs", files(BASE, BASE[:8, :8]), T, ours=3, stats=False,
         why="different sizes exit 3 here; idiff compares the union with zeros"),
    Case("size_differs_zero_border", files(np.pad(BASE[:8, :8] * 0, ((0, 8), (0, 8), (0, 0))), BASE[:8, :8] * 0),
         T, ours=3, stats=False, why="idiff passes a zero image against a smaller zero image"),
    Case("channels_differ", files(BASE, np.concatenate([BASE, BASE[..., :1]], axis=2)), T, ours=3, stats=False,
         why="different channel counts exit 3 here"),
    Case("uint8_one_code_passes_0.004", files(U8, U8_ONE, "uint8", ext_a="png"), ("-fail", "0.004")),
    Case("uint8_one_code_fails_0.003", files(U8, U8_ONE, "uint8", ext_a="png"), ("-fail", "0.003")),
    Case("uint8_noise_two_codes", files(U8, U8_NOISE, "uint8", ext_a="png"), ("-fail", "0.004", "-warn", "0.004")),
    Case("uint8_vs_uint16_same_codes", files(U8, U8.astype(np.uint16) * 257, "uint8", "uint16", "png"), T),
    Case("uint16_small_difference", files(U8.astype(np.uint16) * 257, U8.astype(np.uint16) * 257 + 3, "uint16",
                                          ext_a="png"), ("-fail", "1e-5", "-warn", "1e-5")),
    Case("uint8_tiff", files(U8, U8_ONE, "uint8", ext_a="tif"), ("-fail", "0.001")),
    Case("rgba8_straight_alpha_as_stored", files(RGBA8, RGBA8_B, "uint8", ext_a="png"), ("-fail", "0.01")),
    Case("half_vs_float", files(HALFVALS, HALFVALS.astype(np.float16).astype(np.float32), "float", "half"),
         ("-fail", "0.001", "-warn", "1e-5")),
    Case("half_vs_float_relative", files(HALFVALS * 8, (HALFVALS * 8).astype(np.float16).astype(np.float32),
                                         "float", "half"), ("-fail", "0.001", "-failrelative", "0.001")),
    Case("float_tiff", files(BASE, poke(BASE, (1, 1, 1, 0.002)), "float", ext_a="tif"), T),
    Case("single_channel", files(BASE[..., :1], poke(BASE[..., :1], (6, 6, 0, 0.5))), ("-fail", "0.1")),
    Case("mip_identical_a", mip_pair(None), ("-a", *T)),
    Case("mip_level2_differs_a", mip_pair(2), ("-a", *T)),
    Case("mip_level2_differs_no_a", mip_pair(2), T),
    Case("mip_count_differs_a", mip_pair(None, drop_last=True), ("-a", *T), stats=False),
    Case("mip_count_differs_a_plain_first", mip_pair(None, drop_last=True, swap=True), ("-a", *T), stats=False,
         ours=3, why="-a: different MIP level counts exit 3 either way; idiff only when A has more levels"),
    Case("mip_count_differs_no_a", mip_pair(None, drop_last=True), T),
    Case("parts_identical_a", parts_pair(None), ("-a", *T)),
    Case("parts_second_differs_a", parts_pair(1), ("-a", *T)),
    Case("parts_second_differs_no_a", parts_pair(1), T),
    Case("parts_count_differs_a", parts_pair(None, n_b=1), ("-a", *T), stats=False),
    Case("missing_b", special("missing_b"), T, stats=False),
    Case("missing_a", special("missing_a"), T, stats=False),
    Case("corrupt_b", special("corrupt"), T, stats=False),
    Case("not_an_image", special("text"), T, stats=False),
    Case("b_is_a_folder", special("dir"), T),
    Case("quiet", files(BASE, poke(BASE, (1, 1, 1, 0.5))), ("-q", *T), stats=False),
]

DELIBERATE = {c.name: c.why for c in CASES if c.ours is not None}


# ---------------------------------------------------------------------------
# Reading idiff's report

_NUM = r"([-+]?(?:inf|nan|[0-9.]+(?:e[-+]?[0-9]+)?))"


def _num(s: str) -> float:
    return float(s)


def parse_idiff(text: str) -> list[dict]:
    """Each statistics block of ``idiff -v`` output, in order."""
    blocks: list[dict] = []
    cur: dict | None = None
    for line in text.splitlines():
        if m := re.match(r"\s*Mean error = " + _NUM, line):
            cur = {"mean": _num(m[1]), "over": []}
            blocks.append(cur)
        elif cur is None:
            continue
        elif m := re.match(r"\s*RMS error = " + _NUM, line):
            cur["rms"] = _num(m[1])
        elif m := re.match(r"\s*Peak SNR = " + _NUM, line):
            cur["psnr"] = _num(m[1])
        elif m := re.match(r"\s*Max error\s+= " + _NUM + r"(?: @ \((\d+), (\d+), ([^)]+)\))?", line):
            cur["max"] = _num(m[1])
            cur["at"] = (int(m[2]), int(m[3]), m[4]) if m[2] else None
        elif m := re.match(r"\s*(\d+) pixels \(", line):
            cur["over"].append(int(m[1]))
    return blocks


def close(ours: float | None, theirs: float) -> bool:
    if ours is None:  # JSON null: infinite
        return math.isinf(theirs)
    if math.isinf(theirs):
        return math.isinf(ours)
    return math.isclose(ours, theirs, rel_tol=2e-5, abs_tol=1e-12)


def run_both(tmp_path: Path, case: Case) -> tuple[subprocess.CompletedProcess, dict, int]:
    pa, pb = case.make(tmp_path)
    theirs = subprocess.run([IDIFF, "-v", *case.args, pa, pb] if "-q" not in case.args else
                            [IDIFF, *case.args, pa, pb], capture_output=True, text=True, cwd=tmp_path)
    res = CliRunner().invoke(diff, ["--json", *case.args, pa, pb])
    obj = json.loads(res.stdout.splitlines()[-1]) if res.stdout.strip() else {}
    return theirs, obj, res.exit_code


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_battery_against_idiff(tmp_path, case):
    theirs, ours, code = run_both(tmp_path, case)
    want = theirs.returncode if case.ours is None else case.ours
    assert code == want, (case.name, theirs.returncode, code, theirs.stdout, ours)
    if case.ours is not None:
        assert theirs.returncode != case.ours  # a deliberate difference must be one
    if not case.stats:
        return
    blocks = parse_idiff(theirs.stdout)
    levels = ours.get("levels") or [ours]
    assert len(blocks) == len(levels), (theirs.stdout, ours)
    for blk, lv in zip(blocks, levels, strict=True):
        assert close(lv["mean_error"], blk["mean"]), (blk, lv)
        assert close(lv["rms_error"], blk["rms"]), (blk, lv)
        assert close(lv["psnr"], blk["psnr"]), (blk, lv)
        assert close(lv["max_error"], blk["max"]), (blk, lv)
        n_warn, n_fail = blk["over"]
        assert (lv["n_warn"], lv["n_fail"]) == (n_warn, n_fail), (blk, lv)
        if blk["at"] is not None:
            x, y, cname = blk["at"]
            err = lv["max_error"]
            # the location agrees unless another value ties the largest error
            if lv["max_x"] != x or lv["max_y"] != y:
                assert err is not None and lv["n_fail"] + lv["n_warn"] > 1, (blk, lv)
            else:
                assert lv["max_channel_name"] == cname


def test_battery_is_large_enough():
    assert len(CASES) >= 40
    assert len(DELIBERATE) >= 8


# ---------------------------------------------------------------------------
# Each deliberate difference, by name


def _case(name: str) -> Case:
    return next(c for c in CASES if c.name == name)


@pytest.mark.parametrize("name", ["nan_in_b", "nan_in_a", "pos_inf_in_b", "neg_inf_in_a", "opposite_infinities"])
def test_deliberate_nonfinite_against_a_number_fails(tmp_path, name):
    theirs, ours, code = run_both(tmp_path, _case(name))
    assert theirs.returncode == 0 and code == 2
    assert ours["rule"] == "nonfinite" and ours["n_nonfinite"] == 1


@pytest.mark.parametrize("name", ["size_differs", "size_differs_zero_border", "channels_differ"])
def test_deliberate_shape_mismatch_exits_3(tmp_path, name):
    theirs, ours, code = run_both(tmp_path, _case(name))
    assert theirs.returncode in (0, 2) and code == 3
    assert ours["rule"] in ("size", "channels") and ours["error"]


def test_deliberate_mip_level_counts_differ_either_way(tmp_path):
    theirs, ours, code = run_both(tmp_path, _case("mip_count_differs_a_plain_first"))
    assert theirs.returncode == 0 and code == 3 and ours["rule"] == "miplevels"
    (tmp_path / "r").mkdir()
    theirs, ours, code = run_both(tmp_path / "r", _case("mip_count_differs_a"))
    assert theirs.returncode == code == 3


def test_deliberate_defaults_are_looser_than_idiffs(tmp_path):
    theirs, ours, code = run_both(tmp_path, _case("tiny_over_idiff_default"))
    assert theirs.returncode == 2 and code == 0
    assert ours["thresholds"]["fail"] == 1e-3 and ours["thresholds"]["warn"] == 1e-5


def test_deliberate_usage_errors_exit_2(tmp_path):
    a = str(write(tmp_path / "a.exr", BASE))
    assert subprocess.run([IDIFF, "-bogus", a, a], capture_output=True).returncode == 1
    res = CliRunner().invoke(diff, ["-bogus", a, a])
    assert res.exit_code == 2


def test_deliberate_perceptual_is_refused(tmp_path):
    a = str(write(tmp_path / "a.exr", BASE))
    res = CliRunner().invoke(diff, ["-p", a, a])
    assert res.exit_code == 2 and "--metric flip" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


# ---------------------------------------------------------------------------
# -o: the difference image equals idiff's


def _pixels(path: Path) -> np.ndarray:
    inp = oiio.ImageInput.open(str(path))
    px = inp.read_image("float")
    inp.close()
    return np.asarray(px)


@pytest.mark.parametrize("opts", [(), ("-abs",), ("-scale", "10"), ("-abs", "-scale", "0.5")],
                         ids=["signed", "abs", "scale", "abs_scale"])
def test_out_image_equals_idiffs(tmp_path, opts):
    a = write(tmp_path / "a.exr", BASE)
    b = write(tmp_path / "b.exr", noise(BASE, 12, 0.05))
    subprocess.run([IDIFF, "-q", "-o", str(tmp_path / "theirs.exr"), *opts, str(a), str(b)], capture_output=True)
    res = CliRunner().invoke(diff, ["-q", "-o", str(tmp_path / "ours.exr"), *opts, str(a), str(b)])
    assert res.exit_code == 2
    np.testing.assert_array_equal(_pixels(tmp_path / "ours.exr"), _pixels(tmp_path / "theirs.exr"))


def test_out_diff_only_like_idiff(tmp_path):
    a = write(tmp_path / "a.exr", BASE)
    subprocess.run([IDIFF, "-q", "-od", "-o", str(tmp_path / "theirs.exr"), str(a), str(a)], capture_output=True)
    CliRunner().invoke(diff, ["-q", "-od", "-o", str(tmp_path / "ours.exr"), str(a), str(a)])
    assert not (tmp_path / "theirs.exr").exists() and not (tmp_path / "ours.exr").exists()
