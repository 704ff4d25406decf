"""Issue 12's battery: nothing lost, nothing hung, nothing silently ignored.

Every case runs the real CLI in a subprocess (``python -m pyramid_cli.cli``) and checks the
exit code, a one-line message without a traceback, no temporary file left behind and the
previous output byte-identical. A full disk is simulated without root by a file size limit
(RLIMIT_FSIZE, with SIGXFSZ ignored so writes fail with EFBIG); where the tests run as root
and may mount, a tiny tmpfs gives a real ENOSPC and a read-only mount a real EROFS.
Signals are real signals sent to real processes.
"""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.cli import CLI
from helpers.disks import leftovers, mounted
from helpers.images import write
from pyramid_cli import imageio as pio
from pyramid_cli.core.errors import InputError, OutputError
from pyramid_cli.core.signals import STUCK_S
from pyramid_cli.imageio import write as pio_write
from pyramid_cli.imageio.atomic import atomic_path, atomic_paths

pytestmark = [pytest.mark.cli, pytest.mark.slow]  # real processes, signals and full disks: seconds each

TIMEOUT = 60  # a hang fails the test instead of the whole run


def noise(h, w, c=3, seed=0):
    return np.random.default_rng(seed).random((h, w, c))


@pytest.fixture(scope="module")
def src(tmp_path_factory):
    d = tmp_path_factory.mktemp("src")
    px = noise(96, 128)
    write(d / "in.exr", px, "half")
    write(d / "in.png", (px * 255).astype(np.uint8), "uint8")
    write(d / "in.tif", (px * 255).astype(np.uint8), "uint8")
    write(d / "tiled.exr", px, "half", tile=32)
    return d


def run(args, *, fsize=None, cwd=None, timeout=TIMEOUT):
    """The CLI in a subprocess, optionally under a file size limit; (exit code, stdout, stderr)."""

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    r = subprocess.run(CLI + [str(a) for a in args], capture_output=True, timeout=timeout, cwd=cwd,
                       preexec_fn=limit if fsize is not None else None)
    return r.returncode, r.stdout.decode(errors="replace"), r.stderr.decode(errors="replace")


def one_line_error(err: str, *names: str) -> str:
    assert "Traceback" not in err, err
    lines = [ln for ln in err.strip().splitlines() if "error" in ln]
    assert lines, err
    for name in names:
        assert name in lines[-1], err
    return lines[-1]


def previous(path, text=b"previous output\n") -> bytes:
    path.write_bytes(text)
    return text


# ---------------------------------------------------------------- a full disk
@pytest.mark.parametrize("ext", ["png", "jpg", "exr", "tif"])
def test_full_disk_keeps_the_previous_output(src, tmp_path, ext):
    out = tmp_path / f"out.{ext}"
    old = previous(out)
    inp = src / ("in.png" if ext == "jpg" else f"in.{ext}")
    code, stdout, err = run(["blur", "--backend", "cpu", "--levels", "1", "--force", inp, out], fsize=3000)
    assert code == 4, err
    one_line_error(err, str(out))
    assert "wrote" not in stdout
    assert ".tmp-" not in err  # the user's path, never the temporary's
    assert out.read_bytes() == old and not leftovers(tmp_path)


def test_full_disk_during_mipmap_ends_instead_of_hanging(src, tmp_path):
    out = tmp_path / "tex.exr"
    old = previous(out)
    code, _, err = run(["mipmap", "--backend", "cpu", src / "in.exr", out], fsize=20_000)
    assert code == 4 and out.read_bytes() == old and not leftovers(tmp_path)
    one_line_error(err, str(out))


def test_full_disk_during_a_tiled_rewrite_and_a_multipart_write(src, tmp_path):
    code, _, err = run(["blur", "--backend", "cpu", src / "tiled.exr", tmp_path / "t.exr"], fsize=5000)
    assert code == 4 and not leftovers(tmp_path), err
    code, _, err = run(["levels", "--backend", "cpu", "--multipart", src / "in.exr", tmp_path / "parts.exr"],
                       fsize=5000)
    assert code == 4 and not leftovers(tmp_path), err
    assert not (tmp_path / "t.exr").exists() and not (tmp_path / "parts.exr").exists()


def test_a_batch_counts_failed_writes_as_failed(src, tmp_path):
    ins = tmp_path / "in"
    ins.mkdir()
    for k in range(3):
        write(ins / f"i{k}.png", (noise(64, 64, seed=k) * 255).astype(np.uint8), "uint8")
    code, _, err = run(["blur", "--backend", "cpu", "--levels", "1", "--keep-going", ins / "*.png", "-o",
                        tmp_path / "out" / "{stem}.png"], fsize=2000)
    assert code == 4, err
    assert "0 written" in err and "3 failed" in err and "Traceback" not in err
    assert not os.path.exists(tmp_path / "out") or not os.listdir(tmp_path / "out")


def test_diff_out_on_a_full_disk_is_a_file_error(src, tmp_path):
    out = tmp_path / "d.png"
    old = previous(out)
    code, _, err = run(["diff", "--out", out, src / "in.png", src / "in.exr"], fsize=120)  # PNG: ~240 B
    assert code == 4, err  # idiff's file error
    assert out.read_bytes() == old and not leftovers(tmp_path)


# ---------------------------------------------------------------- a real full disk, a read-only folder
@pytest.mark.parametrize("ext", ["jpg", "png"])
def test_a_real_full_disk(tmp_path, ext):
    big = tmp_path / "big.png"
    write(big, (noise(512, 512, seed=5) * 255).astype(np.uint8), "uint8")
    with mounted(tmp_path / "small", "size=64k") as disk:
        out = disk / f"out.{ext}"
        old = previous(out)
        code, _, err = run(["apply", "--backend", "cpu", "box^nw * g", big, out])
        assert code == 4, err
        one_line_error(err, str(out))
        assert out.read_bytes() == old and not leftovers(disk)


def test_a_real_full_disk_during_mipmap(tmp_path):
    big = tmp_path / "big.exr"
    write(big, noise(512, 512, seed=6), "half")
    with mounted(tmp_path / "small", "size=64k") as disk:
        code, _, err = run(["mipmap", "--backend", "cpu", big, disk / "tex.exr"])
        assert code == 4 and not leftovers(disk), err


@pytest.mark.parametrize("memory", ["60M", "6M"])  # level 0 kept and the levels spilled; read twice
def test_a_real_full_disk_during_a_streamed_mipmap(tmp_path, memory):
    """The disk fills while the coarser levels spill beside the output (it was a traceback, exit 1) or while
    level 0 is written: one line naming the output, exit 4, the previous output and no temporary left."""
    big = tmp_path / "big.exr"
    write(big, noise(1536, 1536, seed=6), "float")
    with mounted(tmp_path / "small", "size=3m") as disk:
        out = disk / "tex.exr"
        old = previous(out)
        code, _, err = run(["mipmap", "--backend", "cpu", "--memory", memory, "--compression", "none", big, out])
        assert code == 4, err
        one_line_error(err, str(out))
        assert out.read_bytes() == old and not leftovers(disk)


def test_a_read_only_folder(src, tmp_path):
    with mounted(tmp_path / "ro", "ro,size=64k") as disk:
        code, _, err = run(["blur", "--backend", "cpu", src / "in.png", disk / "out.png"])
        assert code == 4, err
        one_line_error(err, "out.png")


def test_a_vanished_folder(tmp_path):
    folder = tmp_path / "gone"
    folder.mkdir()
    with pytest.raises(OutputError, match="gone"):
        with atomic_path(str(folder / "x.png")) as tmp:
            os.unlink(tmp)
            os.rmdir(folder)
    assert not folder.exists()


# ---------------------------------------------------------------- signals
def start_long_batch(src, tmp_path, n=60):
    ins = tmp_path / "in"
    ins.mkdir()
    for k in range(n):
        write(ins / f"i{k:02d}.exr", noise(256, 256, seed=k), "half")
    outs = tmp_path / "out"
    outs.mkdir()
    golden = outs / f"i{n - 1:02d}.exr"
    old = previous(golden)
    p = subprocess.Popen(CLI + ["blur", "--backend", "cpu", "--levels", "3", "--force", "--jobs", "2",
                                str(ins / "*.exr"), "-o", str(outs / "{stem}.exr")],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    return p, outs, golden, old


@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGHUP, 129), (signal.SIGINT, 130)])
def test_a_signal_mid_batch_cleans_up(src, tmp_path, sig, code):
    p, outs, golden, old = start_long_batch(src, tmp_path)
    deadline = time.monotonic() + TIMEOUT
    while time.monotonic() < deadline and len(os.listdir(outs)) < 3:  # wait until writing is under way
        time.sleep(0.05)
    p.send_signal(sig)
    _, err = p.communicate(timeout=STUCK_S + 30)  # a stuck clean-up ends itself, with every thread's stack
    assert p.returncode == code, err.decode()
    assert b"Traceback" not in err and b"has not ended" not in err, err.decode()
    assert not leftovers(outs)
    assert golden.read_bytes() == old  # the last output was never reached
    for f in os.listdir(outs):  # everything renamed into place is complete
        if f != golden.name:
            inp = oiio.ImageInput.open(str(outs / f))
            assert inp is not None and inp.read_image("float").shape == (256, 256, 3)
            inp.close()


@pytest.mark.slow
def test_a_signal_during_one_big_write(tmp_path):
    from helpers.interrupt import interrupt_runs

    big = tmp_path / "big.exr"
    write(big, noise(1024, 1024, seed=7), "float")
    out = tmp_path / "out.exr"

    def complete(f):
        inp = oiio.ImageInput.open(str(f))
        try:
            return inp is not None and inp.read_image("float").shape == (1024, 1024, 3)
        finally:
            if inp is not None:
                inp.close()

    interrupt_runs(CLI + ["blur", "--backend", "cpu", "--levels", "1", "--compression", "zip", big, out], out,
                   (0.4, 0.8, 1.2), complete)


def run_script(tmp_path, body: str):
    """Run ``body`` in a fresh interpreter after ``signals.install()``; KeyboardInterrupt ends it the CLI's way."""
    script = tmp_path / "script.py"
    lines = "\n".join("    " + line for line in body.strip().splitlines())
    script.write_text(f"""
import gc, os, signal, sys, time
from pyramid_cli.core import signals
signals.install()

def busy(s):
    t = time.monotonic() + s
    while time.monotonic() < t:
        pass

try:
{lines}
except KeyboardInterrupt as e:
    print(signals.describe(e))
    sys.exit(signals.exit_code(e))
""")
    return subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=TIMEOUT)


def test_a_signal_inside_a_finaliser_is_delivered_after_it(tmp_path):
    """Python cannot raise out of ``__del__`` (llvmlite frees LLVM objects there while numba compiles): a
    SIGTERM landing in one used to print 'Exception ignored ... Traceback' and the run went on to exit 0.
    It is delivered again once the finaliser returns: exit 143, one line, the clean-up runs."""
    r = run_script(tmp_path, """
class Freed:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGTERM)
        busy(0.2)
Freed()
gc.collect()
busy(5)
print("finished")
""")
    assert (r.returncode, r.stdout.strip(), r.stderr) == (143, "terminated by SIGTERM", "")


def test_a_signal_during_a_deferred_call_is_raised_when_it_ends(tmp_path):
    """signals.deferred() (numba's compiles run under it) holds the signal until the block ends, then raises."""
    r = run_script(tmp_path, """
with signals.deferred():
    with signals.deferred():
        os.kill(os.getpid(), signal.SIGTERM)
        busy(0.2)
    print("inner block ended")
    busy(0.1)
    print("outer block ended")
busy(5)
print("finished")
""")
    assert (r.returncode, r.stderr) == (143, "")
    assert r.stdout.split("\n")[:3] == ["inner block ended", "outer block ended", "terminated by SIGTERM"]


def test_signals_module_direct():
    from pyramid_cli.core import signals

    e = signals.Interrupted(signal.SIGTERM)
    assert isinstance(e, KeyboardInterrupt) and signals.exit_code(e) == 143
    assert signals.exit_code(KeyboardInterrupt()) == 130
    assert signals.describe(e) == "terminated by SIGTERM"


# ---------------------------------------------------------------- all-or-nothing groups
def test_atomic_paths_renames_all_or_none(tmp_path):
    paths = [str(tmp_path / f"f{k}.txt") for k in range(3)]
    for p in paths:
        with open(p, "w") as f:
            f.write("old")
    with pytest.raises(RuntimeError):
        with atomic_paths(paths) as tmps:
            for t in tmps[:2]:
                with open(t, "w") as f:
                    f.write("new")
            raise RuntimeError("the third file failed")
    assert [open(p).read() for p in paths] == ["old"] * 3 and not leftovers(tmp_path)
    with atomic_paths(paths) as tmps:
        for t in tmps:
            with open(t, "w") as f:
                f.write("new")
    assert [open(p).read() for p in paths] == ["new"] * 3 and not leftovers(tmp_path)


def test_write_images_is_all_or_nothing(src, tmp_path, monkeypatch):
    image = pio.read_image(src / "in.exr")
    paths = [tmp_path / f"l{k}.exr" for k in range(3)]
    for p in paths:
        previous(p)
    real = pio_write.write_file

    def fail_third(tmp, user, fmt, parts, mode="single"):
        if user.endswith("l2.exr"):
            raise OutputError(f"cannot write {user}: disk full")
        real(tmp, user, fmt, parts, mode)

    monkeypatch.setattr(pio_write, "write_file", fail_third)  # where write_images looks it up
    with pytest.raises(OutputError, match="l2.exr"):
        pio.write_images(paths, [image] * 3)
    assert all(p.read_bytes() == b"previous output\n" for p in paths) and not leftovers(tmp_path)
    monkeypatch.setattr(pio_write, "write_file", real)
    pio.write_images(paths, [image] * 3)
    assert all(pio.read_image(p).pixels.shape == (96, 128, 3) for p in paths)


def test_levels_failing_on_one_level_changes_nothing(src, tmp_path):
    outs = [tmp_path / f"l_{k}.exr" for k in range(2)]
    for p in outs:
        previous(p)
    (tmp_path / "l_2.exr").mkdir()  # the last level cannot be written
    code, _, err = run(["levels", "--backend", "cpu", "--levels", "2", src / "in.exr", tmp_path / "l_{level}.exr"])
    assert code == 4, err
    one_line_error(err, "l_2.exr")
    assert all(p.read_bytes() == b"previous output\n" for p in outs) and not leftovers(tmp_path)


# ---------------------------------------------------------------- inputs
@pytest.mark.parametrize("cmd", [["blur", "--backend", "cpu"], ["blur"], ["apply", "box"], ["mipmap"],
                                 ["levels"], ["collapse"]])
def test_a_fifo_input_is_refused_at_once(tmp_path, cmd):
    fifo = tmp_path / "pipe.exr"
    os.mkfifo(fifo)
    out = tmp_path / ("o_{level}.exr" if cmd[0] == "levels" else "o.exr")
    code, _, err = run(cmd + [fifo, out], timeout=30)
    assert code == 3, err
    assert "FIFO" in one_line_error(err, "pipe.exr")


def test_devices_and_folders_are_refused(tmp_path):
    code, _, err = run(["blur", "--backend", "cpu", "/dev/zero", tmp_path / "o.exr"], timeout=30)
    assert code == 3 and "device" in err
    code, _, err = run(["blur", "--backend", "cpu", tmp_path, tmp_path / "o.exr"], timeout=30)
    assert code == 3 and "directory" in err


def test_a_multipart_input_to_a_single_image_command_names_its_parts(src, tmp_path):
    bands = tmp_path / "bands.exr"
    assert run(["levels", "--backend", "cpu", "--laplacian", "--multipart", "--levels", "2", src / "in.exr",
                bands])[0] == 0
    code, _, err = run(["blur", "--backend", "cpu", bands, tmp_path / "o.exr"])
    assert code == 3
    assert "3 parts (level0, level1, level2)" in one_line_error(err, "bands.exr")
    assert run(["collapse", "--backend", "cpu", bands, tmp_path / "back.exr"])[0] == 0  # all parts, by design


def test_collapse_of_parts_with_different_channels_exits_3(tmp_path):
    path = str(tmp_path / "mixed.exr")
    a = oiio.ImageSpec(64, 64, 3, "half")
    b = oiio.ImageSpec(32, 32, 4, "half")
    a.attribute("name", "level0")
    b.attribute("name", "level1")
    b.full_width, b.full_height = 64, 64
    out = oiio.ImageOutput.create(path)
    assert out.open(path, (a, b))
    out.write_image(np.zeros((64, 64, 3), np.float32))
    out.open(path, b, "AppendSubimage")
    out.write_image(np.zeros((32, 32, 4), np.float32))
    out.close()
    code, _, err = run(["collapse", "--backend", "cpu", path, tmp_path / "o.exr"])
    assert code == 3 and "channels" in one_line_error(err, "mixed.exr")


def test_a_tiled_input_is_written_tiled(src, tmp_path):
    out = tmp_path / "o.exr"
    assert run(["blur", "--backend", "cpu", src / "tiled.exr", out])[0] == 0
    inp = oiio.ImageInput.open(str(out))
    assert (inp.spec().tile_width, inp.spec().tile_height) == (32, 32)
    inp.close()
    assert run(["blur", "--backend", "cpu", src / "in.exr", out])[0] == 0
    inp = oiio.ImageInput.open(str(out))
    assert inp.spec().tile_width == 0  # scanline in, scanline out
    inp.close()


def test_non_utf8_file_names_work(src, tmp_path):
    if sys.platform != "linux":
        pytest.skip("byte file names")
    out = os.path.join(os.fsencode(tmp_path), b"o\xff.exr")
    code, _, err = run(["blur", "--backend", "cpu", src / "in.exr", os.fsdecode(out)])
    assert code == 0, err
    assert os.path.isfile(out) and not leftovers(tmp_path)
    back = os.path.join(os.fsencode(tmp_path), b"p\xfe.png")
    code, _, err = run(["blur", "--backend", "cpu", os.fsdecode(out), os.fsdecode(back)])
    assert code == 0 and os.path.isfile(back), err


def test_missing_output_folders_are_created_for_one_input_and_many(src, tmp_path):
    assert run(["blur", "--backend", "cpu", src / "in.png", tmp_path / "a" / "b" / "o.png"])[0] == 0
    assert (tmp_path / "a" / "b" / "o.png").is_file()
    assert run(["blur", "--backend", "cpu", src / "in.png", "-o", tmp_path / "c" / "{stem}{ext}"])[0] == 0
    assert (tmp_path / "c" / "in.png").is_file()  # {ext} includes the dot


# ---------------------------------------------------------------- expressions and costs
@pytest.mark.parametrize("digits", [400, 4300, 5000])
def test_huge_numbers_in_a_mask_exit_2_with_a_caret(digits):
    code, _, err = run(["explain", f"[1 {'9' * digits} 1]"])
    assert code == 2 and "Traceback" not in err
    assert "at most 12 digits" in err and "   ^^^" in err


def test_costly_kernels_are_refused_at_once():
    """Refused by the cost check (its message names the limit), not computed; the timeout only turns a hang
    into a failure."""
    for text in ("(box)^16 *v g", "(cubic)^6 *^ g", "(box4)^8 *v g"):
        code, _, err = run(["explain", text], timeout=30)
        assert code == 2 and "limit" in one_line_error(err), err


@pytest.mark.parametrize("sigma", ["1000", "1e6", "inf"])
def test_sigma_beyond_the_image_is_refused_at_once(src, tmp_path, sigma):
    code, _, err = run(["blur", "--backend", "cpu", "--sigma", sigma, src / "in.exr", tmp_path / "o.exr"],
                       timeout=30)
    assert code == 2 and "sigma" in one_line_error(err)


def test_an_enormous_result_is_refused_before_work(src, tmp_path):
    code, _, err = run(["apply", "--backend", "cpu", "(doosabin)^8 *^ g", src / "in.exr", tmp_path / "o.exr"],
                       timeout=30)
    assert code == 5 and "limit" in one_line_error(err, "in.exr")


# ---------------------------------------------------------------- options honoured or refused
@pytest.mark.parametrize("args, out, says", [
    (["--compression", "bogus"], "o.exr", "OpenEXR takes none, rle"),
    (["--compression", "zip"], "o.png", "zlib level"),
    (["--type", "uint8"], "o.exr", "half or float"),
    (["--type", "half"], "o.png", "uint8 or uint16"),
    (["--type", "float"], "o.jpg", "uint8"),
])
def test_options_a_format_would_ignore_exit_2(src, tmp_path, args, out, says):
    code, _, err = run(["blur", "--backend", "cpu", *args, src / "in.png", tmp_path / out])
    assert code == 2
    assert says in one_line_error(err, out)
    assert not (tmp_path / out).exists() and not leftovers(tmp_path)


def test_options_that_apply_are_honoured(src, tmp_path):
    assert run(["blur", "--backend", "cpu", "--compression", "dwaa:45", src / "in.exr", tmp_path / "o.exr"])[0] == 0
    inp = oiio.ImageInput.open(str(tmp_path / "o.exr"))
    assert inp.spec().get_string_attribute("compression").startswith("dwaa")
    inp.close()
    assert run(["blur", "--backend", "cpu", "--compression", "60", src / "in.png", tmp_path / "o.jpg"])[0] == 0


def test_explain_plot_refuses_a_format_it_cannot_write(tmp_path):
    code, _, err = run(["explain", "--plot", tmp_path / "x.exr", "box4 *v g"])
    assert code == 2 and ".png" in one_line_error(err, "x.exr")
    assert not (tmp_path / "x.exr").exists()
    code, _, err = run(["explain", "--plot", tmp_path / "x.svg", "box4 *v g"])
    assert code == 0 and (tmp_path / "x.svg").read_bytes().lstrip().startswith(b"<?xml")


def test_check_pyramid_refuses_mismatched_levels(tmp_path):
    def band(h, c, name):
        info = pio.ImageInfo(path=str(tmp_path / name), format="openexr", pixel_type="half",
                             channel_names=list("RGBA")[:c], alpha_channel=-1, colorspace="linear", alpha_mode="none")
        return pio.Image(np.zeros((h, h, c), np.float32), info)

    pio.check_pyramid([band(64, 3, "a"), band(32, 3, "b"), band(16, 3, "c")])
    with pytest.raises(InputError, match="channels"):
        pio.check_pyramid([band(64, 3, "a"), band(32, 4, "b")])
    with pytest.raises(InputError, match="level 1 is 20x20"):
        pio.check_pyramid([band(64, 3, "a"), band(20, 3, "b")])


def test_collapse_of_files_that_are_not_one_pyramid_exits_3(tmp_path):
    for name, (h, c) in {"b0.exr": (64, 3), "b1.exr": (32, 4), "c1.exr": (20, 3)}.items():
        write(tmp_path / name, np.zeros((h, h, c)), "half")
    for second in ("b1.exr", "c1.exr"):
        code, _, err = run(["collapse", "--backend", "cpu", tmp_path / "b0.exr", tmp_path / second,
                            tmp_path / "o.exr"])
        assert code == 3 and not (tmp_path / "o.exr").exists()
        one_line_error(err, second)
