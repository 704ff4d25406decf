"""Signals as exit codes and one-line messages (pyramid_cli.core.signals); real signals: tests/system/test_faults.py."""

import signal

from pyramid_cli.core import signals


def test_a_keyboard_interrupt_exits_130_and_says_interrupted():
    assert signals.exit_code(KeyboardInterrupt()) == 128 + signal.SIGINT == 130
    assert signals.describe(KeyboardInterrupt()) == "interrupted"
    assert set(signals.HANDLED) == {"SIGINT", "SIGTERM", "SIGHUP"}


def test_a_signal_during_an_import_is_raised_once_the_import_is_done(tmp_path):
    """SIGTERM while a module body runs (an extension's init runs Python code: OpenImageIO's nanobind enums
    abort on an exception there) waits for the import to finish, then stops the run as exit 143 would."""
    import subprocess
    import sys
    import textwrap

    (tmp_path / "slow_module.py").write_text(textwrap.dedent("""
        import os, signal, time
        os.kill(os.getpid(), signal.SIGTERM)
        end = time.monotonic() + 0.3
        while time.monotonic() < end:   # bytecodes run here: a handler that raised would stop the import
            pass
        DONE = True
    """))
    script = textwrap.dedent("""
        import sys, time
        from pyramid_cli.core import signals
        signals.install()
        try:
            import slow_module  # noqa: F401 - a failed import is not in sys.modules
            time.sleep(10)
            print("not interrupted")
        except signals.Interrupted as e:
            print("interrupted", e.signum, "after import" if "slow_module" in sys.modules else "in import")
    """)
    r = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == f"interrupted {int(signal.SIGTERM)} after import", r.stdout


def test_an_interrupted_command_ends_without_the_interpreters_teardown(tmp_path):
    """The console script, once a signal's clean-up is done, exits 143 at once: no atexit handler (nor C++
    destructor, which could abort on a busy thread) runs; a run that ends normally tears down as usual."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent("""
        import atexit, os, signal, sys, time
        atexit.register(lambda: print("teardown", flush=True))
        from pyramid_cli.cli import group

        @group.main.command("stop")
        def stop():
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(10)

        @group.main.command("finish")
        def finish():
            print("done", flush=True)

        sys.argv = ["pyramid", sys.argv[1]]
        group.run()
    """)
    stopped = subprocess.run([sys.executable, "-c", script, "stop"], capture_output=True, text=True, timeout=60)
    assert (stopped.returncode, stopped.stdout, stopped.stderr) == (143, "", "pyramid: terminated by SIGTERM\n")
    finished = subprocess.run([sys.executable, "-c", script, "finish"], capture_output=True, text=True, timeout=60)
    assert (finished.returncode, finished.stdout) == (0, "done\nteardown\n"), finished.stderr
