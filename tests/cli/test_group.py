"""The ``pyramid`` group (pyramid_cli.cli.group): its help and version, one line per error with its exit code,
and the console script's entry point."""

import os
import subprocess
import sys

import pytest

from helpers.cli import CLI, invoke
from pyramid_cli.cli.group import EXIT_CODE_HELP
from pyramid_cli.core.errors import EXIT_CODES

pytestmark = pytest.mark.cli


@pytest.mark.parametrize("command", [[], ["explain"], ["plan"], ["apply"]])
def test_every_command_has_help_with_an_example(command):
    r = invoke(*command, "--help")
    assert r.exit_code == 0
    assert "Example" in r.output


def test_console_script_and_help_do_not_import_heavy_modules():
    code = ("import sys; from pyramid_cli.cli import main\n"
            "try:\n    main(['--help'], standalone_mode=False)\nexcept SystemExit:\n    pass\n"
            "heavy = [m for m in ('numpy', 'OpenImageIO', 'moderngl', 'matplotlib') if m in sys.modules]\n"
            "print('HEAVY=' + ','.join(heavy))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={**os.environ})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "HEAVY="


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="counts threads in /proc")
@pytest.mark.parametrize("chosen", [None, "2"])
def test_the_console_script_starts_no_blas_threads_unless_asked(chosen):
    """numpy's OpenBLAS threads (one per core, spinning after import) are not started for a run, which makes no
    BLAS call; a user's OPENBLAS_NUM_THREADS is kept."""
    code = ("import atexit, os, sys\nfrom pyramid_cli.cli import group\nsys.argv = ['pyramid', '--version']\n"
            "def count():\n    import numpy  # noqa: F401\n"
            "    print(os.environ['OPENBLAS_NUM_THREADS'], len(os.listdir('/proc/self/task')))\n"
            "atexit.register(count)\ngroup.run()")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if chosen:
        env["OPENBLAS_NUM_THREADS"] = chosen
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    value, threads = out.stdout.split()[-2:]
    assert value == (chosen or "1")
    if not chosen:
        assert int(threads) == 2, threads  # the main thread and core.signals' helper


def test_malloc_is_set_to_reuse_freed_blocks_unless_the_user_chose(monkeypatch):
    """On Linux the console script fixes glibc's mapping threshold (32 MiB) and the free memory kept at the heap's
    top (64 MiB) with mallopt; not where MALLOC_MMAP_THRESHOLD_ or MALLOC_TRIM_THRESHOLD_ is set, nor elsewhere
    than Linux, nor without glibc's mallopt."""
    import ctypes

    from pyramid_cli.cli import group

    calls: list[tuple[int, int]] = []

    class Libc:
        def mallopt(self, param, value):
            calls.append((param, value))
            return 1

    monkeypatch.setattr(ctypes, "CDLL", lambda name: Libc())
    for k in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_"):
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    group.reuse_freed_blocks()
    assert calls == [(-3, 32 << 20), (-1, 64 << 20)]
    for k in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_"):
        calls.clear()
        monkeypatch.setenv(k, "1000000")
        group.reuse_freed_blocks()
        assert calls == []
        monkeypatch.delenv(k)
    monkeypatch.setattr(sys, "platform", "darwin")
    group.reuse_freed_blocks()
    assert calls == []
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.setattr(ctypes, "CDLL", lambda name: object())  # a libc without mallopt (musl's is a stub)
    group.reuse_freed_blocks()
    assert calls == []


@pytest.mark.parametrize("args", [
    ["explain", "box4 *v g"], ["plan", "box4 *v g", "--size", "64x64"],
    ["farm-template", "--frames", "1-9", "--", "blur", "/sh/a.####.exr", "-o", "/sh/b.####.exr"],
    ["blur", "--backend", "cpu", "{a}", "{o}/blur.exr"], ["tiles", "--backend", "cpu", "{a}", "{o}/t.dzi"],
    ["diff", "{a}", "{a}"]], ids=lambda a: a[0])
def test_the_console_script_collects_cycles_again_once_a_command_works(tmp_path, args):
    """run() turns the cyclic garbage collector off while a command imports what it runs with; whatever the
    command (a session, a cluster spec, none), it is back on by its end, what the imports made frozen out of its
    walks. Called from Python, main leaves the collector as it was."""
    import gc

    import numpy as np

    from helpers.images import write
    from pyramid_cli.cli.group import collector_on

    a = write(tmp_path / "a.exr", np.random.default_rng(1).random((20, 30, 3)).astype(np.float32))
    argv = [v.replace("{a}", str(a)).replace("{o}", str(tmp_path)) for v in args]
    code = ("import atexit, gc, sys\nfrom pyramid_cli.cli import group\n"
            f"sys.argv = ['pyramid', *{argv!r}]\n"
            "atexit.register(lambda: print('GC', gc.isenabled(), gc.get_freeze_count() > 0))\ngroup.run()")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[-1] == "GC True True", out.stdout
    assert gc.isenabled()
    collector_on()  # not turned off here: nothing to do
    assert gc.isenabled() and gc.get_freeze_count() == 0


@pytest.mark.parametrize("args", [["explain", "box4 *v g"], ["plan", "box4 *v g", "--size", "64x64"],
                                  ["farm-template", "--frames", "1-9", "--", "blur", "/sh/a.####.exr",
                                   "-o", "/sh/b.####.exr"]],
                         ids=lambda a: a[0])
def test_printing_commands_exit_0_quietly_when_stdout_is_closed(args):
    proc = subprocess.Popen(CLI + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    proc.stdout.close()  # closed before the command prints
    try:
        code = proc.wait(timeout=60)
    finally:
        proc.kill()
    assert (code, proc.stderr.read()) == (0, "")


def test_version_names_the_program():
    r = invoke("--version")
    assert r.exit_code == 0 and r.output.startswith("pyramid, version ")


def test_help_lists_every_exit_code():
    r = invoke("--help")
    assert r.exit_code == 0
    assert EXIT_CODE_HELP.startswith("\b\nExit codes:\n")
    for code, text in EXIT_CODES.values():
        assert f"  {code}  {text.split()[0]}" in r.output


def test_a_pyramid_error_is_one_line_and_its_kind_exit_code():
    r = invoke("plan", "gauss7", "--size", "8x8", "--backend", "cpu")  # a UsageError raised inside the command
    assert r.exit_code == EXIT_CODES["usage"][0] == 2
    assert r.output == "pyramid: error: --backend says whose memory --memory estimates: give --memory too\n"
