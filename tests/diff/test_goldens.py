"""``pyramid diff`` on folders and globs, ``--update``, FLIP, idiff spellings (pyramid_cli.diff.goldens).

The reports: tests/diff/test_junit.py, tests/diff/test_html.py; the ``tree`` fixture: tests/diff/conftest.py."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from click.testing import CliRunner

from helpers.cli import invoke
from helpers.golden_tree import img
from helpers.images import write
from helpers.paths import SAMPLES
from pyramid_cli.cli.diff import diff, idiff_argv
from pyramid_cli.diff import goldens


def run(*args) -> object:
    return invoke(*args, command=diff)


def digest(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_folders_one_verdict_with_a_line_each(tree):
    out, gold = tree
    res = run(out, gold)
    assert res.exit_code == 2, res.output
    lines = res.stdout.splitlines()
    assert any(ln.startswith("FAIL") and "fail.exr" in ln for ln in lines)
    assert any(ln.startswith("MISSING") and "new.exr" in ln for ln in lines)
    assert any(ln.startswith("EXTRA") and "gone.exr" in ln for ln in lines)
    assert any(ln.startswith("PASS") and "pass.exr" in ln for ln in lines)
    assert any(ln.startswith("PASS") and "sub/alt.exr" in ln for ln in lines)
    assert lines[-1] == ("5 pairs: 2 passed, 0 warned, 1 failed, 0 differ in size, 0 unreadable, "
                         "1 missing, 1 extra")


def test_folders_json(tree):
    out, gold = tree
    res = run("--json", out, gold)
    obj = json.loads(res.stdout)
    assert obj["exit_code"] == res.exit_code == 2
    assert obj["decided_by"] == {"name": "fail.exr", "status": "failure", "rule": "fail"}
    assert obj["summary"] == {"match": 2, "warning": 0, "failure": 1, "size": 0, "file": 0, "missing": 1,
                              "extra": 1}
    by = {p["name"]: p for p in obj["pairs"]}
    assert by["fail.exr"]["rule"] == "fail" and by["fail.exr"]["levels"][0]["n_fail"] == 64
    assert by["sub/alt.exr"]["path_b"].endswith("alt-gpu.exr")
    assert len(by["sub/alt.exr"]["references"]) == 2
    assert by["new.exr"]["status"] == "missing" and by["gone.exr"]["status"] == "extra"


def test_all_pass_exit_0(tmp_path):
    for k in range(3):
        write(tmp_path / "o" / f"{k}.exr", img(k))
        write(tmp_path / "g" / f"{k}.exr", img(k))
    assert run(tmp_path / "o", tmp_path / "g").exit_code == 0


def test_worst_code_wins(tmp_path):
    write(tmp_path / "o" / "a.exr", img(1))
    write(tmp_path / "g" / "a.exr", img(1)[:4])          # size: 3
    write(tmp_path / "o" / "b.exr", img(2) + 1)
    write(tmp_path / "g" / "b.exr", img(2))              # failure: 2
    assert run(tmp_path / "o", tmp_path / "g").exit_code == 3
    (tmp_path / "g" / "c.exr").write_bytes(b"\x76\x2f\x31\x01broken")
    write(tmp_path / "o" / "c.exr", img(3))              # file error: 4
    assert run(tmp_path / "o", tmp_path / "g").exit_code == 4


def test_globs_pair_by_relative_path(tree):
    out, gold = tree
    res = run("--json", f"{out}/**/*.exr", f"{gold}/**/*.exr")
    obj = json.loads(res.stdout)
    assert {p["name"] for p in obj["pairs"]} == {"pass.exr", "fail.exr", "new.exr", "gone.exr",
                                                   os.path.join("sub", "alt.exr")}
    assert res.exit_code == 2
    res = run(f"{out}/p*.exr", f"{gold}/p*.exr")
    assert res.exit_code == 0, res.output


def test_frame_sequences(tmp_path):
    for f in (1, 2, 3):
        write(tmp_path / "o" / f"shot.{f:04d}.exr", img(f))
        write(tmp_path / "g" / f"shot.{f:04d}.exr", img(f) + (0.5 if f == 2 else 0))
    assert goldens.as_glob("o/shot.%04d.exr") == "o/shot.[0-9][0-9][0-9][0-9].exr"
    assert goldens.as_glob("o/shot.#.exr") == goldens.as_glob("o/shot.%04d.exr")
    for pattern in ("shot.%04d.exr", "shot.#.exr"):
        res = run("--json", tmp_path / "o" / pattern, tmp_path / "g" / pattern)
        obj = json.loads(res.stdout)
        assert res.exit_code == 2 and obj["summary"]["failure"] == 1 and obj["summary"]["match"] == 2
        assert [p["name"] for p in obj["pairs"] if p["status"] == "failure"] == ["shot.0002.exr"]


def test_folder_against_file_is_a_usage_error(tree):
    out, gold = tree
    res = run(out, gold / "pass.exr")
    assert res.exit_code == 2 and "folder" in res.stderr
    assert run(f"{out}/*.nothing", gold).exit_code == 4


# ---------------------------------------------------------------------------
# --update


def test_update_changes_exactly_failing_and_missing(tree):
    out, gold = tree
    before_gold, before_out = digest(gold), digest(out)
    res = run("--update", out, gold)
    assert res.exit_code == 2  # the comparison before the update
    assert f"copied {out / 'fail.exr'} -> {gold / 'fail.exr'}" in res.stdout
    assert f"copied {out / 'new.exr'} -> {gold / 'new.exr'}" in res.stdout
    after = digest(gold)
    changed = {k for k in after if before_gold.get(k) != after[k]}
    assert changed == {"fail.exr", "new.exr"}
    assert set(before_gold) - set(after) == set()          # nothing deleted (gone.exr stays)
    assert after["fail.exr"] == before_out["fail.exr"]     # byte for byte
    assert after["new.exr"] == before_out["new.exr"]
    assert digest(out) == before_out
    assert not [p for p in gold.rglob("*") if ".tmp" in p.name]
    # now only the extra golden keeps the run failing
    res = run("--json", out, gold)
    assert json.loads(res.stdout)["summary"]["extra"] == 1 and res.exit_code == 2


def test_update_dry_run_lists_and_writes_nothing(tree):
    out, gold = tree
    before = digest(gold)
    res = run("--update", "--dry-run", out, gold)
    assert res.exit_code == 2
    assert "would copy" in res.stdout and "fail.exr" in res.stdout and "new.exr" in res.stdout
    assert "alt.exr ->" not in res.stdout and "pass.exr ->" not in res.stdout
    assert digest(gold) == before
    res = run("--update", "--dry-run", "--json", out, gold)
    obj = json.loads(res.stdout)
    assert obj["dry_run"] is True and len(obj["updated"]) == 2


def test_a_golden_folder_not_made_yet_is_every_golden_missing_and_update_makes_it(tree, tmp_path):
    out, _ = tree
    new = tmp_path / "tests" / "golden"  # the first `make golden-update` of a project (README's Makefile)
    res = run(out, new)
    assert res.exit_code == 2 and "missing" in res.stdout and not new.exists()
    res = run("--update", out, new)
    assert res.exit_code == 2 and digest(new) == digest(out)
    assert run(out, new).exit_code == 0


def test_an_html_report_inside_the_outputs_is_never_compared_or_copied(tree):
    out, gold = tree
    assert run(out, gold, "--html", out / "diff-report").exit_code == 2
    assert (out / "diff-report" / "img").is_dir()
    before = digest(gold)
    res = run("--update", out, gold)
    assert "diff-report" not in res.stdout
    assert {k for k in digest(gold) if k not in before} == {"new.exr"}


def test_update_single_file(tmp_path):
    a = write(tmp_path / "a.exr", img(1) + 1)
    b = write(tmp_path / "b.exr", img(1))
    assert run("--update", a, b).exit_code == 2
    assert b.read_bytes() == a.read_bytes()
    assert run(a, b).exit_code == 0


def test_interrupted_update_leaves_no_half_golden(tree, monkeypatch):
    out, gold = tree
    before = digest(gold)
    real = shutil.copyfile

    def half_then_interrupt(src, dst, *a, **k):
        with open(src, "rb") as f, open(dst, "wb") as g:
            g.write(f.read()[:100])
        raise KeyboardInterrupt

    monkeypatch.setattr(shutil, "copyfile", half_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        goldens.update_goldens(goldens.compare_pairs(goldens.pair_inputs(str(out), str(gold)),
                                                     goldens.CompareOptions()))
    monkeypatch.setattr(shutil, "copyfile", real)
    assert digest(gold) == before
    assert not [p for p in gold.rglob("*") if ".tmp" in p.name]


def test_update_never_copies_unreadable_output(tmp_path):
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "a.exr").write_bytes(b"broken")
    g = write(tmp_path / "g" / "a.exr", img(1))
    before = g.read_bytes()
    assert run("--update", tmp_path / "o", tmp_path / "g").exit_code == 4
    assert g.read_bytes() == before


# ---------------------------------------------------------------------------
# idiff's spellings


def test_idiff_argv_rewrites_only_option_positions():
    assert idiff_argv(["-fail", "0.004", "-failpercent", "1", "a.png", "b.png"]) == \
        ["--fail", "0.004", "--failpercent", "1", "a.png", "b.png"]
    assert idiff_argv(["-o", "-abs", "-abs", "a", "b"]) == ["-o", "-abs", "--abs", "a", "b"]
    assert idiff_argv(["-a", "-od", "-scale", "10", "--", "-fail", "b"]) == \
        ["-a", "--od", "--scale", "10", "--", "-fail", "b"]
    for opt in ("-fail", "-failpercent", "-hardfail", "-failrelative", "-warn", "-warnpercent", "-hardwarn",
                "-warnrelative", "-allowfailures", "-od", "-abs", "-scale"):
        assert idiff_argv([opt])[0] == "-" + opt


def test_od_writes_only_when_different(tmp_path):
    a = write(tmp_path / "a.exr", img(1))
    b = write(tmp_path / "b.exr", img(1))
    d = tmp_path / "d.exr"
    assert run("-o", d, "-od", a, b).exit_code == 0 and not d.exists()
    c = write(tmp_path / "c.exr", img(1) + 0.5)
    assert run("-o", d, "-od", a, c).exit_code == 2 and d.exists()


def test_warn_only_exits_0_like_idiff(tmp_path):
    a = write(tmp_path / "a.exr", img(1))
    b = write(tmp_path / "b.exr", img(1) + 1e-4)
    res = run("--json", "-warn", "1e-6", a, b)
    obj = json.loads(res.stdout)
    assert res.exit_code == 0 and obj["n_warn"] == 64 and obj["rule"] == "allowfailures"


# ---------------------------------------------------------------------------
# Threshold advice of the README, on the tool's own outputs


@pytest.mark.gl
@pytest.mark.slow
def test_gl_against_cpu_blur_of_zoneplate_passes_at_one_code(tmp_path, gl_executor):
    from pyramid_cli.cli import main

    outs = {}
    for backend in ("gl", "cpu"):
        outs[backend] = tmp_path / f"{backend}.png"
        res = CliRunner().invoke(main, ["blur", "--levels", "4", "--backend", backend, "-q",
                                        str(SAMPLES / "zoneplate.png"), str(outs[backend])])
        assert res.exit_code == 0, res.output
    res = run("--json", "-fail", "0.004", outs["gl"], outs["cpu"])
    obj = json.loads(res.stdout)
    assert res.exit_code == 0, obj
    assert obj["max_error"] <= 1 / 255 + 1e-7     # at most one 8-bit code apart
    assert run("-fail", "0.003", outs["gl"], outs["cpu"]).exit_code in (0, 2)


def test_half_advice_default_below_4_relative_above(tmp_path):
    v = np.random.default_rng(4).random((16, 16, 3)).astype(np.float32)
    low = v * 3.99
    high = 4 + v * 60
    for name, px in (("low", low), ("high", high)):
        write(tmp_path / f"{name}_f.exr", px)
        write(tmp_path / f"{name}_h.exr", px, "half")
    assert run(tmp_path / "low_h.exr", tmp_path / "low_f.exr").exit_code == 0
    assert run(tmp_path / "high_h.exr", tmp_path / "high_f.exr").exit_code == 2
    assert run("--failrelative", "1e-3", tmp_path / "high_h.exr", tmp_path / "high_f.exr").exit_code == 0


def test_sixteen_bit_advice(tmp_path):
    v = np.random.default_rng(3).integers(2, 60000, (6, 6, 3)).astype(np.uint16)
    a = write(tmp_path / "a.png", v, "uint16")
    assert run("-fail", "2e-5", a, write(tmp_path / "one.png", v + 1, "uint16")).exit_code == 0
    assert run("-fail", "2e-5", a, write(tmp_path / "two.png", v + 2, "uint16")).exit_code == 2


def test_eight_bit_advice_one_code_passes_two_fail(tmp_path):
    v = np.random.default_rng(3).integers(2, 250, (6, 6, 3)).astype(np.uint8)
    a = write(tmp_path / "a.png", v, "uint8")
    one = write(tmp_path / "one.png", v + 1, "uint8")
    two = write(tmp_path / "two.png", v + 2, "uint8")
    assert run("-fail", "0.004", a, one).exit_code == 0
    assert run("-fail", "0.004", a, two).exit_code == 2


# ---------------------------------------------------------------------------
# FLIP


def test_flip_metric(tmp_path):
    pytest.importorskip("flip_evaluator")
    a = write(tmp_path / "a.exr", img(1, 32, 32, 3))
    b = write(tmp_path / "b.exr", img(1, 32, 32, 3))
    res = run("--json", "--metric", "flip", a, b)
    obj = json.loads(res.stdout)
    assert res.exit_code == 0 and obj["levels"][0]["flip_mean"] == 0.0
    c = write(tmp_path / "c.exr", img(9, 32, 32, 3))
    res = run("--json", "--metric", "flip", "--fail", "10", a, c)
    obj = json.loads(res.stdout)
    assert res.exit_code == 2 and obj["rule"] == "flip" and obj["levels"][0]["flip_mean"] > 0.05
    assert run("--metric", "flip", "--fail", "10", "--flip-fail", "1", a, c).exit_code == 0


def test_flip_missing_names_the_install_command(tmp_path, monkeypatch):
    import builtins

    real = builtins.__import__

    def no_flip(name, *a, **k):
        if name == "flip_evaluator":
            raise ImportError(name)
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_flip)
    a = write(tmp_path / "a.exr", img(1))
    res = run("--metric", "flip", a, a)
    assert res.exit_code == 2
    assert "pip install 'bilinear-pyramid[flip]'" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_two_frame_sequences_pair_by_frame_number(tmp_path):
    """render.####.exr against golden/plate.%04d.exr: names differ, frames pair (fileseq's conventions)."""

    from pyramid_cli.cli import main

    def put(path, value):
        spec = oiio.ImageSpec(4, 4, 1, "float")
        out = oiio.ImageOutput.create(str(path))
        out.open(str(path), spec)
        out.write_image(np.full((4, 4, 1), value, np.float32))
        out.close()

    (tmp_path / "golden").mkdir()
    for f in (1001, 1002, 1003):
        put(tmp_path / f"render.{f}.exr", 0.5)
    for f in (1001, 1002, 1004):
        put(tmp_path / "golden" / f"plate.{f:04d}.exr", 0.5 if f != 1002 else 0.9)
    r = CliRunner().invoke(main, ["diff", str(tmp_path / "render.####.exr"),
                                  str(tmp_path / "golden" / "plate.%04d.exr")])
    lines = r.output + r.stderr
    assert r.exit_code == 2
    assert "PASS     render.1001.exr" in lines and "FAIL     render.1002.exr" in lines
    assert "MISSING  render.1003.exr" in lines and "EXTRA    plate.1004.exr" in lines
