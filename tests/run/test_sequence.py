"""Frame sequences: every pattern form, output mapping, missing frames, colliding outputs, pairing."""

from __future__ import annotations

import os

import numpy as np
import pytest

from helpers.cli import invoke
from helpers.images import write_sequence
from pyramid_cli.core.errors import InputError, UsageError
from pyramid_cli.run import sequence


def touch(folder, *names):
    for n in names:
        (folder / n).write_bytes(b"")


def frames(pattern, spec=None):
    return [f for f, _ in sequence.frames_of(str(pattern), spec)]


def names(pattern, spec=None):
    return [os.path.basename(p) for _, p in sequence.frames_of(str(pattern), spec)]


@pytest.mark.parametrize("pattern, expected", [
    ("plate.1001-1003#.exr", ["plate.1001.exr", "plate.1002.exr", "plate.1003.exr"]),   # lone # is 4 digits
    ("plate.1-3####.exr", ["plate.0001.exr", "plate.0002.exr", "plate.0003.exr"]),      # #### is 4 digits too
    ("plate.1-3##.exr", ["plate.01.exr", "plate.02.exr", "plate.03.exr"]),
    ("plate.1-3@@@.exr", ["plate.001.exr", "plate.002.exr", "plate.003.exr"]),
    ("plate.1-3@.exr", ["plate.1.exr", "plate.2.exr", "plate.3.exr"]),
    ("plate.98-101%03d.exr", ["plate.098.exr", "plate.099.exr", "plate.100.exr", "plate.101.exr"]),
    ("plate.9-11$F2.exr", ["plate.09.exr", "plate.10.exr", "plate.11.exr"]),
    ("plate.1-9x4#.exr", ["plate.0001.exr", "plate.0005.exr", "plate.0009.exr"]),         # steps
    ("plate.-2-1#.exr", ["plate.-002.exr", "plate.-001.exr", "plate.0000.exr", "plate.0001.exr"]),  # negative
    ("plate.-3--1@@.exr", ["plate.-3.exr", "plate.-2.exr", "plate.-1.exr"]),
    ("plate.1-3,7#.exr", ["plate.0001.exr", "plate.0002.exr", "plate.0003.exr", "plate.0007.exr"]),
    ("tex.1001-1002<UDIM>.exr", ["tex.1001.exr", "tex.1002.exr"]),
])
def test_pattern_forms_with_ranges(pattern, expected):
    assert names(pattern) == expected


@pytest.mark.parametrize("pattern", ["plate.####.exr", "plate.%04d.exr", "plate.#.exr", "plate.$F4.exr",
                                     "plate.@@@@.exr"])
def test_frames_found_on_disk_in_every_spelling(tmp_path, pattern):
    touch(tmp_path, "plate.1001.exr", "plate.1002.exr", "plate.1003.exr", "other.1001.exr", "plate.01.exr")
    assert frames(tmp_path / pattern) == [1001, 1002, 1003]


def test_negative_frames_on_disk(tmp_path):
    touch(tmp_path, "neg.-002.exr", "neg.-001.exr", "neg.0000.exr", "neg.0001.exr")
    assert frames(tmp_path / "neg.####.exr") == [-2, -1, 0, 1]


def test_a_gap_on_disk_is_a_missing_frame(tmp_path):
    touch(tmp_path, "plate.1001.exr", "plate.1002.exr", "plate.1004.exr")
    assert frames(tmp_path / "plate.####.exr") == [1001, 1002, 1003, 1004]
    jobs = sequence.plan_jobs([str(tmp_path / "plate.####.exr")], str(tmp_path / "o.####.exr"))
    with pytest.raises(InputError, match=r"plate\.1003\.exr: frame 1003 is missing"):
        sequence.drop_missing(jobs, keep_going=False)
    warned = []
    kept = sequence.drop_missing(jobs, keep_going=True, warn=warned.append)
    assert [j.frame for j in kept] == [1001, 1002, 1004] and "1003" in warned[0]


def test_udim_tiles_on_disk_are_not_gaps(tmp_path):
    touch(tmp_path, "tex.1001.exr", "tex.1002.exr", "tex.1011.exr")
    assert frames(tmp_path / "tex.<UDIM>.exr") == [1001, 1002, 1011]
    assert frames(tmp_path / "tex.%(UDIM)d.exr") == [1001, 1002, 1011]
    jobs = sequence.plan_jobs([str(tmp_path / "tex.<UDIM>.exr")], str(tmp_path / "out" / "tex_soft.<UDIM>.exr"))
    assert [os.path.basename(j.output) for j in jobs] == ["tex_soft.1001.exr", "tex_soft.1002.exr",
                                                          "tex_soft.1011.exr"]


def test_frames_option_selects_alone_and_within_a_range(tmp_path):
    assert frames(tmp_path / "plate.####.exr", "1001-1240x2")[:3] == [1001, 1003, 1005]
    assert len(frames(tmp_path / "plate.####.exr", "1001-1240x2")) == 120
    assert frames(tmp_path / "plate.1001-1010#.exr", "1005-1020") == [1005, 1006, 1007, 1008, 1009, 1010]
    with pytest.raises(UsageError, match="selects no frame"):
        frames(tmp_path / "plate.1001-1010#.exr", "2000-2010")
    with pytest.raises(UsageError, match="not a frame range"):
        frames(tmp_path / "plate.####.exr", "ten to twenty")


def test_no_frame_on_disk_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="no frame of this sequence exists"):
        frames(tmp_path / "plate.####.exr")


def test_plain_names_with_digits_are_not_sequences():
    assert not sequence.is_sequence("render_v002.exr")
    assert not sequence.is_sequence("foo@2x.png")
    assert not sequence.is_sequence("out/{stem}_blur.exr")
    assert sequence.is_sequence("plate.####.exr") and sequence.is_sequence("tex.<UDIM>.exr")


@pytest.mark.parametrize("path", ["plate.1001.exr", "v2.1001_1.exr", "render.1001_1.exr",
                                  "out/plate.1001_blur_01001.exr", "shot#3/plate.exr", "icon@@2x.png",
                                  "a/b.c/d-1-3.exr"])
def test_only_a_frame_token_makes_a_sequence(path):
    """Digits alone are a name, not a frame (fileseq read plate.1001.exr as frame 1001 and refused v2.1001_1.exr)."""
    assert not sequence.is_sequence(path) and sequence.parse(path) is None


@pytest.mark.parametrize("pattern, frame, expected", [
    ("soft.####_v2.exr", 7, "soft.0007_v2.exr"),          # the token need not end the name
    ("shot#3/plate.##.exr", 7, "shot#3/plate.07.exr"),    # a folder's '#' is text
    ("shot010####.exr", 7, "shot0100007.exr"),            # digits glued to the token are not a range
    ("plate-1-3#.exr", 2, "plate-0002.exr"),              # a range after a separator
    ("x.$F.exr", 1001, "x.1001.exr"),
    ("x.%d.exr", -3, "x.-3.exr"),
])
def test_tokens_anywhere_in_the_file_name(pattern, frame, expected):
    assert sequence.parse(pattern).frame(frame) == expected


def test_two_tokens_in_a_name_are_refused():
    with pytest.raises(UsageError, match=r"2 frame tokens in one name \(####, %04d\)"):
        sequence.parse("plate.####.%04d.exr")


# --------------------------------------------------------------------------- the range language

@pytest.mark.parametrize("spec, expected", [
    ("1001", [1001]),
    ("1-5", [1, 2, 3, 4, 5]),
    ("1-10x3", [1, 4, 7, 10]),
    ("1-10:3", [1, 4, 7, 10]),                # OpenJD's step: the same as x (fileseq's : staggered)
    ("1001-1007:2", [1001, 1003, 1005, 1007]),
    ("5-1", [1, 2, 3, 4, 5]),                  # descending: the same frames, run ascending
    ("10-1x4", [2, 6, 10]),                    # counted from the first frame written
    ("10-1:-4", [2, 6, 10]),                   # OpenJD's descending spelling
    ("-5--3", [-5, -4, -3]),
    ("-2-1", [-2, -1, 0, 1]),
    ("1-3,7,9-10", [1, 2, 3, 7, 9, 10]),
    ("9,1-3,2", [1, 2, 3, 9]),                 # a list in any order, each frame once
    (" 1 - 3 , 5 ", [1, 2, 3, 5]),             # OpenJD allows spaces
])
def test_range_spellings(spec, expected):
    assert sequence.frame_set(spec) == expected


def test_the_range_language_is_filesequence_where_the_two_agree():
    """fileseq is the oracle of the spellings both languages share (x steps, lists, negative frames,
    descending parts); only ``:`` (a step here, fileseq's stagger) and ``y`` (refused here) differ."""
    fileseq = pytest.importorskip("fileseq")
    rng = np.random.default_rng(22)
    for _ in range(400):
        parts = []
        for _ in range(rng.integers(1, 4)):
            a, b = (int(v) for v in rng.integers(-30, 60, size=2))
            step = int(rng.integers(1, 6))
            parts.append(str(a) if rng.random() < 0.2 else f"{a}-{b}" + (f"x{step}" if rng.random() < 0.5 else ""))
        spec = ",".join(parts)
        assert sequence.frame_set(spec) == sorted({int(f) for f in fileseq.FrameSet(spec)}), spec


@pytest.mark.parametrize("pattern", ["sh/plate.####.exr", "sh/plate.#.exr", "sh/plate.@@.exr", "sh/plate.%05d.exr",
                                     "sh/plate.$F3.exr", "sh/tex.<UDIM>.exr", "sh/tex.%(UDIM)d.exr",
                                     "sh/plate.1-9x2#.exr", "sh/plate.-3-3@@@.exr"])
def test_frame_paths_are_filesequence_s(pattern):
    fileseq = pytest.importorskip("fileseq")
    pad = fileseq.PAD_STYLE_HASH4 if "#." in pattern and "##" not in pattern else fileseq.PAD_STYLE_HASH1
    theirs = fileseq.FileSequence(pattern, pad_style=pad, allow_subframes=False)
    ours = sequence.parse(pattern)
    for f in (1001, 1002, 1011, 1099) if ours.udim else (-12, -1, 0, 7, 1001, 12345):  # UDIMs are 1001 and up
        assert ours.frame(f) == theirs.frame(f), (pattern, f)
    if theirs.frameSet() is not None:
        assert list(ours.frames) == sorted(int(f) for f in theirs.frameSet())


@pytest.mark.parametrize("spec, message", [
    ("abc", "not a frame range (examples: 1001-1240, 1001-1240x2, 1001-1240:2, 1,5-9)"),
    ("1.5", "not a frame range"),
    ("1,,2", "not a frame range"),
    ("1-10y3", "fileseq's y (every frame but every N-th) is not supported"),
    ("1-10:0", "a step must not be 0"),
    ("1-10:-1", "a negative step needs a descending range"),
    ("1-20000000", "more than 1000000 frames in one run"),
])
def test_bad_ranges_are_one_line_exit_2(tmp_path, spec, message):
    write_sequence(tmp_path / "in", 1, 2)
    r = invoke("blur", "--backend", "cpu", tmp_path / "in" / "plate.####.exr", "-o", tmp_path / "o.####.exr",
               "--frames", spec)
    assert r.exit_code == 2
    assert r.output.startswith(f"pyramid: error: --frames {spec!r}: ") and message in r.output
    assert r.output.count("\n") == 1 and not (tmp_path / "o.0001.exr").exists()


def test_a_pattern_range_speaks_the_same_language():
    assert names("plate.1-7:3#.exr") == ["plate.0001.exr", "plate.0004.exr", "plate.0007.exr"]
    assert frames("plate.5-3#.exr") == [3, 4, 5]
    with pytest.raises(UsageError, match=r"plate\.1-9y2#\.exr: range '1-9y2': fileseq's y"):
        frames("plate.1-9y2#.exr")


@pytest.mark.parametrize("template, expected", [
    ("out/soft.####.exr", "out/soft.0007.exr"),
    ("out/soft.#.exr", "out/soft.0007.exr"),
    ("out/soft.%06d.exr", "out/soft.000007.exr"),
    ("out/soft.@.exr", "out/soft.7.exr"),
    ("out/soft_{frame}.exr", "out/soft_7.exr"),
    ("out/soft_{frame:05d}.exr", "out/soft_00007.exr"),
    ("out/{stem}_soft{ext}", "out/plate.0007_soft.exr"),
    ("out/{stem}_blur_{frame:05d}{ext}", "out/plate.0007_blur_00007.exr"),   # fields combined, no token
    ("out/{stem}.####{ext}", "out/plate.0007.0007.exr"),                    # fields and a token
    ("{dir}/soft/{name}", "in/soft/plate.0007.exr"),
    ("out/v2.1001_1.exr", "out/v2.1001_1.exr"),                              # a path as it is
    ("out/{{stem}}_#.exr", "out/{stem}_0007.exr"),
])
def test_output_mapping(template, expected):
    assert sequence.output_path(template, "in/plate.0007.exr", 7) == expected


def test_negative_frames_map_to_negative_outputs():
    assert sequence.output_path("o.####.exr", "plate.-003.exr", -3) == "o.-003.exr"


def test_a_plain_output_is_never_renumbered():
    """fileseq read soft.7.exr as frame 7 of a sequence and wrote frame 1001 to soft.1001.exr."""
    assert sequence.output_path("out/soft.7.exr", "in/plate.1001.exr", 1001) == "out/soft.7.exr"


@pytest.mark.parametrize("template, frame, message", [
    ("out/{nope}.exr", 7, "unknown field 'nope'"),
    ("out/soft.1-3#.exr", 7, r"a frame range in an output \(1-3\)"),
    ("out/soft.####.exr", None, r"has a frame token \(####\), and in/a\.exr is not a frame of a sequence"),
    ("out/soft_{frame}.exr", None, r"has \{frame\}, and in/a\.exr is not a frame of a sequence"),
])
def test_bad_output_templates(template, frame, message):
    with pytest.raises(UsageError, match=message):
        sequence.output_path(template, "in/a.exr", frame)


def test_template_whose_frames_collide_is_a_usage_error(tmp_path):
    with pytest.raises(UsageError, match=r"gives frame 1 and frame 2 the same output .*out\.exr"):
        sequence.plan_jobs([str(tmp_path / "plate.1-3#.exr")], str(tmp_path / "out.exr"))


def test_frames_option_on_a_plain_file_is_a_usage_error(tmp_path):
    with pytest.raises(UsageError, match="not one"):
        sequence.plan_jobs([str(tmp_path / "a.exr")], str(tmp_path / "{stem}.png"), frames="1-3")


def test_pair_frames(tmp_path):
    touch(tmp_path, "a.0001.exr", "a.0002.exr", "b.01.exr", "b.02.exr")
    pairs = sequence.pair_frames(str(tmp_path / "a.####.exr"), str(tmp_path / "b.%02d.exr"))
    assert [(f, os.path.basename(a), os.path.basename(b)) for f, a, b in pairs] == [
        (1, "a.0001.exr", "b.01.exr"), (2, "a.0002.exr", "b.02.exr")]
    (tmp_path / "b.02.exr").unlink()
    with pytest.raises(InputError, match=r"b\.02\.exr: frame 2 is missing"):
        sequence.pair_frames(str(tmp_path / "a.####.exr"), str(tmp_path / "b.%02d.exr"))


# --------------------------------------------------------------------------- the command line

@pytest.mark.cli
@pytest.mark.parametrize("command", [["blur", "--levels", "2"], ["apply", "box *v g"], ["mipmap"]])
def test_every_batch_command_takes_sequences(tmp_path, command):
    write_sequence(tmp_path / "in", 1, 4)
    r = invoke(*command, "--backend", "cpu", tmp_path / "in" / "plate.####.exr", "--frames", "2-4",
               "-o", tmp_path / "out" / "soft.%04d.exr")
    assert r.exit_code == 0, r.output
    assert sorted(os.listdir(tmp_path / "out")) == ["soft.0002.exr", "soft.0003.exr", "soft.0004.exr"]


@pytest.mark.cli
def test_sequence_in_sequence_out_without_o(tmp_path):
    write_sequence(tmp_path / "in", 1001, 1003)
    r = invoke("blur", "--backend", "cpu", "--levels", "2", tmp_path / "in" / "plate.1001-1003#.exr",
               tmp_path / "out" / "soft.####.exr")
    assert r.exit_code == 0, r.output
    assert sorted(os.listdir(tmp_path / "out")) == ["soft.1001.exr", "soft.1002.exr", "soft.1003.exr"]


@pytest.mark.cli
def test_missing_frame_exits_3_naming_it_or_is_skipped_with_keep_going(tmp_path):
    write_sequence(tmp_path / "in", 1, 5)
    (tmp_path / "in" / "plate.0003.exr").unlink()
    args = ["blur", "--backend", "cpu", "--levels", "2", tmp_path / "in" / "plate.1-5#.exr",
            "-o", tmp_path / "out" / "soft.####.exr"]
    r = invoke(*args)
    assert r.exit_code == 3 and "plate.0003.exr: frame 3 is missing" in r.output
    assert not (tmp_path / "out").exists()
    r = invoke(*args, "--keep-going")
    assert r.exit_code == 0, r.output
    assert "skipping 1 missing frame(s): 3" in r.output
    assert sorted(os.listdir(tmp_path / "out")) == ["soft.0001.exr", "soft.0002.exr", "soft.0004.exr",
                                                    "soft.0005.exr"]


@pytest.mark.cli
@pytest.mark.parametrize("command", [["blur", "--levels", "2"], ["apply", "box *v g"], ["mipmap"]])
def test_single_outputs_are_named_freely(tmp_path, command):
    """A frame file in, a name with digits out: IN OUT, -o, and one frame of a sequence (issue 22)."""
    write_sequence(tmp_path / "in", 1001, 1001)
    plate = tmp_path / "in" / "plate.1001.exr"
    assert invoke(*command, "--backend", "cpu", plate, tmp_path / "v2.1001_1.exr").exit_code == 0
    assert invoke(*command, "--backend", "cpu", plate, "-o", tmp_path / "render.1001_1.exr").exit_code == 0
    r = invoke(*command, "--backend", "cpu", tmp_path / "in" / "plate.####.exr", "--frames", "1001",
               "-o", tmp_path / "out" / "v2.1001_1.exr")
    assert r.exit_code == 0, r.output
    assert sorted(os.listdir(tmp_path)) == ["in", "out", "render.1001_1.exr", "v2.1001_1.exr"]
    assert os.listdir(tmp_path / "out") == ["v2.1001_1.exr"]


@pytest.mark.cli
def test_combined_fields_and_stepped_frames_on_the_command_line(tmp_path):
    write_sequence(tmp_path / "in", 1001, 1007)
    r = invoke("blur", "--backend", "cpu", "--levels", "2", tmp_path / "in" / "plate.####.exr",
               "-o", tmp_path / "out" / "{stem}_blur_{frame:05d}{ext}", "--frames", "1007-1001:3")
    assert r.exit_code == 0, r.output
    assert sorted(os.listdir(tmp_path / "out")) == ["plate.1001_blur_01001.exr", "plate.1004_blur_01004.exr",
                                                    "plate.1007_blur_01007.exr"]


@pytest.mark.cli
def test_colliding_outputs_exit_2(tmp_path):
    write_sequence(tmp_path / "in", 1, 3)
    r = invoke("blur", "--backend", "cpu", tmp_path / "in" / "plate.####.exr", "-o", tmp_path / "out.exr")
    assert r.exit_code == 2 and "the same output" in r.output and "{frame}" in r.output
