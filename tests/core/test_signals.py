"""Signals as exit codes and one-line messages (pyramid_cli.core.signals); real signals: tests/system/test_faults.py."""

import signal

import pytest

from pyramid_cli.core import signals


def test_a_keyboard_interrupt_exits_130_and_says_interrupted():
    assert signals.exit_code(KeyboardInterrupt()) == 128 + signal.SIGINT == 130
    assert signals.describe(KeyboardInterrupt()) == "interrupted"
    assert set(signals.HANDLED) == {"SIGINT", "SIGTERM", "SIGHUP"}


def _slow_module(folder) -> None:
    """``folder/slow_module.py``: a module that sends its process SIGTERM, then runs bytecodes for 0.3 s (a handler
    that raised there would stop the import)."""
    import textwrap

    (folder / "slow_module.py").write_text(textwrap.dedent("""
        import os, signal, time
        os.kill(os.getpid(), signal.SIGTERM)
        end = time.monotonic() + 0.3
        while time.monotonic() < end:
            pass
        DONE = True
    """))


def test_a_signal_during_an_import_is_raised_once_the_import_is_done(tmp_path):
    """SIGTERM while a module body runs (an extension's init runs Python code: OpenImageIO's nanobind enums
    abort on an exception there) waits for the import to finish, then stops the run as exit 143 would."""
    import subprocess
    import sys
    import textwrap

    _slow_module(tmp_path)
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


def test_a_signal_that_arrives_as_the_interpreter_shuts_down_lets_it_end(tmp_path):
    """SIGTERM during the last atexit call (C code: the signal waits) is handled in the first Python code after
    it, standard output's flush, once the interpreter is finalising: there no thread can start (Python 3.11 waits
    for it for ever, a hang of the kind CI met once), so nothing there may start one; the run's work is
    done and the process ends."""
    import subprocess
    import sys
    import textwrap
    import time

    script = textwrap.dedent("""
        import atexit, os, sys
        from pyramid_cli.core import signals

        class Out:  # a flush in Python, reached without any other Python code first (no __getattr__)
            closed = False
            def write(self, text):
                return len(text)
            def flush(self):
                for _ in range(3):
                    pass

        sys.stdout = Out()
        signals.install()
        atexit.register(os.system, "sleep 1")  # registered first, called last: the signal comes during it
        os.write(1, b"done\\n")
    """)
    p = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert p.stdout is not None and p.stdout.readline() == b"done\n"
    time.sleep(0.3)
    p.send_signal(signal.SIGTERM)
    try:
        _, err = p.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        p.kill()
        raise AssertionError("the interpreter hung in its shut-down after the signal") from None
    assert p.returncode == 0, err.decode()


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


def test_a_clean_up_that_never_ends_is_stopped_with_every_threads_stack(tmp_path):
    """A clean-up stuck after SIGTERM (a thread that never returns) does not hang the run: after STUCK_S the
    process says so, prints what each thread was doing, and exits 143; a clean-up that ends is not touched."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent("""
        import os, signal, sys, threading, time
        from pyramid_cli.core import signals
        signals.STUCK_S = 0.5
        signals.install()
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(10)
        except signals.Interrupted:
            if sys.argv[1] == "stuck":
                threading.Event().wait()   # a clean-up waiting for what never comes
            print("cleaned up", flush=True)
            sys.exit(7)                    # the timer is a daemon: it keeps no process alive
    """)
    stuck = subprocess.run([sys.executable, "-c", script, "stuck"], capture_output=True, text=True, timeout=60)
    assert stuck.returncode == 143, stuck.stderr
    assert "the clean-up after SIGTERM has not ended in 0.5 s" in stuck.stderr, stuck.stderr
    assert "most recent call first" in stuck.stderr and "in <module>" in stuck.stderr, stuck.stderr
    done = subprocess.run([sys.executable, "-c", script, "done"], capture_output=True, text=True, timeout=60)
    assert (done.returncode, done.stdout) == (7, "cleaned up\n"), done.stderr


def test_a_forked_child_sends_a_signal_again_too(tmp_path):
    """The helper thread that sends a signal again is started anew in a forked child (fork copies only the
    thread that forked): a child whose signal comes inside an import is still stopped once the import is done."""
    import subprocess
    import sys
    import textwrap

    _slow_module(tmp_path)
    script = textwrap.dedent("""
        import os, sys, time
        from pyramid_cli.core import signals
        signals.install()
        pid = os.fork()
        if pid == 0:
            try:
                import slow_module  # noqa: F401
                time.sleep(10)
                os._exit(1)
            except signals.Interrupted:
                os._exit(0)
        print(os.waitpid(pid, 0)[1] >> 8)
    """)
    r = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert (r.returncode, r.stdout.strip()) == (0, "0"), r.stderr


@pytest.mark.parametrize("status", [0, 3])
def test_a_finished_run_ends_after_its_threads_and_atexit_handlers_without_the_teardown(status):
    """``end`` after a run: the threads that are not daemons are joined and the atexit handlers run (in that
    order, as Python's exit does), buffered output reaches a pipe, the status is the run's; the interpreter's
    teardown (here a finaliser of a module global, which a plain exit runs) is skipped."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent("""
        import atexit, sys, threading, time
        from pyramid_cli.cli import group

        class Global:
            def __del__(self):
                sys.stderr.write("teardown\\n")

        kept = Global()
        atexit.register(lambda: print("atexit", flush=False))

        def late():
            time.sleep(0.5)
            print("thread", flush=False)

        STATUS = int(sys.argv[2])

        @group.main.command("finish")
        def finish():
            threading.Thread(target=late).start()
            print("x" * 100000, flush=False)  # more than a pipe's buffer: flushed on the way out
            sys.exit(STATUS)

        sys.argv = ["pyramid", "finish"]
        group.run()
    """)
    ended = subprocess.run([sys.executable, "-c", script, "finish", str(status)], capture_output=True, text=True,
                           timeout=60)
    assert ended.returncode == status, ended.stderr
    assert ended.stdout.splitlines() == ["x" * 100000, "thread", "atexit"]
    assert "teardown" not in ended.stderr
    plain = subprocess.run([sys.executable, "-c", script.replace("group.run()", "group.main()"), "finish",
                            str(status)], capture_output=True, text=True, timeout=60)
    assert plain.returncode == status and "teardown" in plain.stderr  # the finaliser runs at a plain exit


def test_a_signal_never_leaves_a_lock_taken_that_other_threads_wait_for():
    """A signal that lands between a ``threading.Semaphore``'s lock being taken (in C) and the block that gives it
    back (``Condition.__enter__`` returns through Python) is sent again once the main thread is out of the
    standard library's locking code. Raised there, it left the lock taken for ever: a thread pool's workers then
    waited for their idle semaphore, and a batch stopped by SIGINT hung in its clean-up (CI, 2026-11-28). Here
    100 interruptions of a loop that releases and takes a semaphore leave none taken (raised there at once, about
    one in five did)."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent("""
        import os, random, signal, threading, time
        from pyramid_cli.core import signals
        signals.STUCK_S = 3600  # every round is a first signal's clean-up: no watchdog ending the script
        random.seed(1)
        sem, taken = threading.Semaphore(0), 0
        for _ in range(100):
            signals.install()
            timer = threading.Timer(random.random() * 0.003, os.kill, (os.getpid(), signal.SIGINT))
            try:
                timer.start()  # the signal may come before start() returns (it waits for the thread to run)
                while True:
                    sem.release()
                    sem.acquire(timeout=0)
                    sum(range(30))  # some work of the loop's own, where the signal can be raised
            except signals.Interrupted:
                timer.join()
            if sem._cond._lock.locked():
                taken, sem = taken + 1, threading.Semaphore(0)
        print(taken, flush=True)
        os._exit(0)
    """)
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert (r.returncode, r.stdout.strip()) == (0, "0"), r.stdout + r.stderr


@pytest.mark.parametrize("wait", ["event", "join", "future"])
def test_a_signal_still_ends_a_long_wait_at_once(wait):
    """The waits of the standard library's locking code handle an exception themselves (``Condition.wait``, a
    thread's join): a signal is raised there at once, not sent again until the wait ends (here after 60 s)."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent("""
        import os, signal, sys, threading, time
        from concurrent.futures import ThreadPoolExecutor
        from pyramid_cli.core import signals
        signals.install()
        threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGTERM)).start()
        start = time.monotonic()
        try:
            if sys.argv[1] == "event":
                threading.Event().wait(60)
            elif sys.argv[1] == "join":
                t = threading.Thread(target=time.sleep, args=(60,), daemon=True)
                t.start()
                t.join()
            else:
                ThreadPoolExecutor(1).submit(time.sleep, 60).result()
            print("waited", flush=True)
        except signals.Interrupted:
            print("interrupted" if time.monotonic() - start < 30 else "late", flush=True)
        os._exit(0)
    """)
    r = subprocess.run([sys.executable, "-c", script, wait], capture_output=True, text=True, timeout=120)
    assert (r.returncode, r.stdout.strip()) == (0, "interrupted"), r.stdout + r.stderr


def test_a_signal_waits_at_most_a_moment_for_the_locking_code_to_end():
    """A main thread that stays in the locking modules' code (here logging's handler, blocked writing to a pipe
    that nobody reads) is not waited for beyond LOCK_PATIENCE_S: the signal is then raised where it is."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent("""
        import logging, os, signal, threading, time
        from pyramid_cli.core import signals
        signals.install()
        r, w = os.pipe()
        os.set_blocking(w, True)
        log = logging.getLogger("blocked")
        log.addHandler(logging.StreamHandler(os.fdopen(w, "w", buffering=1)))
        threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGTERM)).start()
        start = time.monotonic()
        try:
            log.warning("x" * (1 << 20))  # more than a pipe holds: the write blocks
            print("written", flush=True)
        except signals.Interrupted:
            print("interrupted" if time.monotonic() - start < 30 else "late", flush=True)
        os._exit(0)
    """)
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert (r.returncode, r.stdout.strip()) == (0, "interrupted"), r.stdout + r.stderr
