"""Bad input to every command: a one-line message naming the file, a documented exit code, nothing half-written."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import OpenImageIO as oiio
import pytest
from click.testing import CliRunner

from helpers.images import write
from pyramid_cli.cli import main


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad")
    good = d / "good.exr"
    write(good, np.random.default_rng(0).random((16, 16, 3)))
    full = good.read_bytes()
    (d / "truncated.exr").write_bytes(full[: len(full) // 2])
    png = d / "good.png"
    write(png, (np.random.default_rng(1).random((16, 16, 3)) * 255).astype(np.uint8), "uint8")
    (d / "truncated.png").write_bytes(png.read_bytes()[:200])
    (d / "empty.exr").write_bytes(b"")
    (d / "text.exr").write_text("this is not an image\n")
    nan = np.random.default_rng(2).random((16, 16, 3))
    nan[3, 5, 1] = np.nan
    write(d / "nan.exr", nan)
    return d


# each command with the arguments around its input (IN) and output (OUT)
COMMANDS = {
    "apply": ["apply", "--backend", "cpu", "box *v g", "IN", "OUT.exr"],
    "blur": ["blur", "--levels", "2", "IN", "OUT.exr"],
    "levels": ["levels", "--levels", "2", "IN", "OUT_{level}.exr"],
    "mipmap": ["mipmap", "IN", "OUT.exr"],
    "collapse": ["collapse", "IN", "OUT.exr"],
}


def run(cmd, src, tmp_path, *extra):
    args = [a.replace("IN", str(src)).replace("OUT", str(tmp_path / "out")) for a in COMMANDS[cmd]]
    return CliRunner().invoke(main, args[:1] + list(extra) + args[1:])


@pytest.mark.parametrize("cmd", COMMANDS)
@pytest.mark.parametrize("name, why", [
    ("missing.exr", "no such file"), ("truncated.exr", "cannot read"), ("truncated.png", "cannot read"),
    ("empty.exr", "the file is empty"), ("text.exr", "cannot read"),
])
def test_unreadable_inputs_exit_3_with_one_line(files, tmp_path, cmd, name, why):
    r = run(cmd, files / name, tmp_path)
    assert r.exit_code == 3, r.output
    line = r.output.strip().splitlines()[-1]
    assert line.startswith("pyramid: error: ") and name in line and why in line
    assert "Traceback" not in r.output
    assert not any(p.name.startswith("out") for p in tmp_path.iterdir())


@pytest.mark.parametrize("args, code", [(["blur", "--levels", "2", "IN", "OUT.png"], 3),
                                        (["diff", "IN", "IN"], 4)], ids=["blur", "diff"])
def test_a_png_cut_short_is_one_line_on_the_real_standard_error(tmp_path, args, code):
    """libpng prints its own line to descriptor 2 when it reads a PNG that ends early; the file is refused
    before it is decoded, so the run's standard error (a fresh process's, not click's capture) is one line."""
    from helpers.cli import CLI

    png = tmp_path / "cut.png"
    write(png, (np.random.default_rng(3).random((256, 256, 3)) * 255).astype(np.uint8), "uint8")
    png.write_bytes(png.read_bytes()[:-2000])
    argv = [a.replace("IN", str(png)).replace("OUT", str(tmp_path / "out")) for a in args]
    r = subprocess.run(CLI + argv, capture_output=True, text=True, timeout=120)
    assert r.returncode == code, r.stderr
    assert r.stderr.splitlines() == [r.stderr.strip()] and "cut.png" in r.stderr and "IEND" in r.stderr, r.stderr
    assert not (tmp_path / "out.png").exists()


@pytest.mark.parametrize("cmd", ["apply", "blur", "levels", "mipmap"])
def test_nan_fail_exits_5_and_names_the_pixel(files, tmp_path, cmd):
    r = run(cmd, files / "nan.exr", tmp_path, "--nan", "fail")
    assert r.exit_code == 5, r.output
    assert "nan.exr" in r.output and "x=5, y=3" in r.output


@pytest.mark.parametrize("cmd", ["apply", "blur"])
def test_nan_keep_warns_and_zero_cleans(files, tmp_path, cmd):
    r = run(cmd, files / "nan.exr", tmp_path)
    assert r.exit_code == 0 and "1 NaN/Inf value(s) kept" in r.output
    r = run(cmd, files / "nan.exr", tmp_path, "--nan", "zero", "--force")
    assert r.exit_code == 0
    out = oiio.ImageInput.open(str(tmp_path / "out.exr")).read_image("float")
    assert np.isfinite(out).all()


@pytest.mark.parametrize("name", ["missing.exr", "truncated.exr", "empty.exr", "text.exr"])
def test_diff_unreadable_is_idiffs_exit_4(files, name):
    r = CliRunner().invoke(main, ["diff", str(files / name), str(files / "good.exr")])
    assert r.exit_code == 4 and name in r.output


def test_unknown_output_extension_exits_4(files, tmp_path):
    r = CliRunner().invoke(main, ["blur", str(files / "good.exr"), str(tmp_path / "o.nope")])
    assert r.exit_code == 4 and "o.nope" in r.output


@pytest.mark.slow
def test_a_killed_write_leaves_the_previous_output_intact(tmp_path):
    """SIGKILL a real process at many moments of a large write: the output is always the old
    file or the complete new one, never a truncated mix."""
    src = tmp_path / "big.exr"
    write(src, np.random.default_rng(3).random((1024, 1536, 3)))
    dst = tmp_path / "golden.exr"
    write(dst, np.zeros((8, 8, 3)))
    old = dst.read_bytes()
    cmd = [sys.executable, "-m", "pyramid_cli.cli", "blur", "--backend", "cpu", "--levels", "1", "--force",
           str(src), str(dst)]
    outcomes = set()
    for delay in (0.3, 0.6, 0.9, 1.2, 1.5, 1.8, 2.5):
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(delay)
        p.send_signal(signal.SIGKILL)
        p.wait()
        data = dst.read_bytes()
        if data == old:
            outcomes.add("old")
            continue
        inp = oiio.ImageInput.open(str(dst))  # a complete new file reads whole
        assert inp is not None and inp.read_image("float").shape == (1024, 1536, 3)
        inp.close()
        outcomes.add("new")
        dst.write_bytes(old)
    assert "old" in outcomes
    leftovers = [f for f in os.listdir(tmp_path) if f.startswith(".golden.exr.tmp")]
    assert all(f.endswith(".exr") for f in leftovers)  # hidden temp files at worst, never the golden
