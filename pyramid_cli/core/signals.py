"""SIGTERM and SIGHUP handled like Ctrl-C, so that interrupted writes clean up.

A render farm or CI job that times out sends SIGTERM; a closed terminal sends SIGHUP. By
default Python dies at once on both, leaving ``.NAME.tmp-XXXX.EXT`` files beside the outputs.
After :func:`install` each raises :class:`Interrupted` (a KeyboardInterrupt) in the main
thread, so the same ``finally``/``except BaseException`` clean-up as Ctrl-C runs (the
temporary is removed, the previous output is untouched) and the process exits with
``128 + signal number``: 130 for SIGINT, 143 for SIGTERM, 129 for SIGHUP
(:func:`exit_code`). A second signal while cleaning up ends the process the default way.

Python cannot raise out of a finaliser: an :class:`Interrupted` raised while a ``__del__``, a
weak-reference callback or a ctypes callback runs (llvmlite frees its LLVM objects in
``__del__``) would be printed as "Exception ignored" and lost, and the run would go on. The
``sys.unraisablehook`` that ``install`` sets catches exactly those, prints nothing, and sends the
signal again a moment later, once the finaliser has returned. The signal is sent again by a helper thread
started by ``install``, never by a thread started there and then: a finaliser can run while the interpreter
shuts down, where Python 3.11 waits for ever for a new thread to start (a hang: see tests/core/test_signals.py).
A signal that arrives while the interpreter shuts down is ignored: the run is over.

Nor should it raise inside an import: a C extension that runs Python code while it initialises (OpenImageIO's
nanobind enums, numba) aborts the process on an exception it did not expect (SIGABRT and a "Critical
nanobind error" traceback, not exit 143). A signal that arrives while a module is being imported is sent
again a moment later, until it finds the import done.

Nor should it raise between the two steps with which Python code takes a lock and starts the block that gives it
back: ``threading.Condition.__enter__`` and ``Semaphore.acquire`` take theirs in C and return through Python, where
the handler can run. An exception there leaves the lock taken for ever. A batch stopped by SIGINT at that point
hung: the thread pool's workers waited for its idle semaphore, and the clean-up waited for them (60 s, until the
clean-up's watchdog ended it; tests/core/test_signals.py). A signal that arrives in the code of the standard
library's locking modules (:data:`LOCKING_MODULES`) is sent again a moment later, as for an import, except where
that code waits and handles an exception itself (:data:`WAITS`: a ``Condition.wait``, a thread's join), so that a
signal still ends a long wait at once; and not for more than :data:`LOCK_PATIENCE_S` (a thread still there is
blocked in a call made there, such as a log record written to a pipe that nobody reads).

Nor should it raise into a library that keeps state across a call: an exception thrown into
numba's compiler in mid-compile leaves it inconsistent, and its clean-up then fails with a
traceback of its own. Code that calls such a library runs it under :func:`deferred`, which holds
a signal until the call returns and raises it then.

A clean-up is bounded: one that has not ended :data:`STUCK_S` seconds after the signal is stuck (a thread that
never returns, a lock never released). The process then prints one line and every thread's stack (so that the
cause can be found) and ends with the signal's exit code, as a farm's kill after its grace period would end it,
instead of hanging until someone looks. A second signal still ends it at once.

``install`` also ignores SIGXFSZ, so that a file size limit (``ulimit -f``) makes writes
fail with EFBIG, reported as exit 4, instead of killing the process mid-write.

A reader that closes standard output (``pyramid blur … | head -1``, a log viewer quitting) sends
SIGPIPE, which Python ignores: the next write fails with EPIPE (BrokenPipeError), and a batch would
stop part-way with exit 1. The work is the files, not the lines, so after :func:`guard_streams` a
closed standard output or error drops what is written to it (its descriptor is pointed at
/dev/null) and the run goes on: every frame is written, the exit code is what it would have been,
and Python's flush at exit has nothing to complain about.
"""

from __future__ import annotations

import atexit
import contextlib
import faulthandler
import linecache
import os
import queue
import signal
import sys
import threading
import time
from collections.abc import Iterator

HANDLED = ("SIGINT", "SIGTERM", "SIGHUP")


class Interrupted(KeyboardInterrupt):
    """Raised in the main thread when SIGINT, SIGTERM or SIGHUP arrives."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum

    @property
    def exit_code(self) -> int:
        return 128 + self.signum

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name


_received: list[int] = []
_held: list[int] = []  # signals held by deferred(), to raise when it ends
_depth = 0  # how many deferred() blocks the main thread is inside


def _handler(signum, frame):  # noqa: ARG001 - the signal module's signature
    if sys.is_finalizing():
        return  # the interpreter is shutting down: the run is over, and nothing raised now could be handled
    if _received:
        # A second signal while the first is being handled: give up cleaning, die the default way.
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
        return
    _received.append(signum)
    if _depth:
        _held.append(signum)
        _watch(signum)
        return
    if _importing(frame):
        _redeliver(signum)
        return
    if _taking_a_lock(frame) and _patient():
        _redeliver(signum, LOCK_REDELIVER_S)
        return
    _lock_since.clear()
    _watch(signum)
    raise Interrupted(signum)


def interrupted() -> bool:
    """Whether SIGINT, SIGTERM or SIGHUP has arrived (the run is being cleaned up, or was)."""
    return bool(_received)


STUCK_S = 60.0  # seconds a clean-up may take after a signal (a farm's grace period is 30 s: it would be killed)

# What the handler, and the hook of a signal raised in a finaliser, ask of the helper thread. Neither may start a
# thread: both can run while the interpreter shuts down, where Python 3.11's Thread.start() waits for ever for a
# thread that can no longer run. A SimpleQueue's put never waits and is reentrant (made for finalisers).
_requests: queue.SimpleQueue = queue.SimpleQueue()
_AGAIN, _WATCH = "again", "watch"
_helper: threading.Thread | None = None


def _watch(signum: int) -> None:
    """End the process :data:`STUCK_S` seconds from now, with every thread's stack on stderr, unless it ended
    first (the helper thread is a daemon: a clean-up that finishes never hears of it)."""
    _requests.put((_WATCH, signum, 0.0))


def _serve() -> None:
    """The helper thread: sends a signal again (:func:`_redeliver`), and ends a stuck clean-up (:func:`_watch`)."""
    deadline, watched = None, 0
    while True:
        try:
            wait = None if deadline is None else max(0.0, deadline - time.monotonic())
            kind, signum, delay = _requests.get(timeout=wait)
        except queue.Empty:
            _stuck(watched)
            return
        if kind == _AGAIN:
            time.sleep(delay)
            os.kill(os.getpid(), signum)
        elif deadline is None:
            deadline, watched = time.monotonic() + STUCK_S, signum


def _stuck(signum: int) -> None:
    """Say that the clean-up after ``signum`` is stuck, print every thread's stack, and exit 128 + ``signum``.
    Straight to descriptor 2: the stuck thread may hold a stream's lock, and a flush here would wait for it."""
    line = (f"pyramid: the clean-up after {signal.Signals(signum).name} has not ended in {STUCK_S:g} s: stopping "
            "it now; what each thread was doing:\n")
    with contextlib.suppress(OSError):
        os.write(2, line.encode())
    with contextlib.suppress(Exception):
        faulthandler.dump_traceback(file=2, all_threads=True)
    os._exit(128 + signum)


_IMPORT_MACHINERY = ("<frozen importlib._bootstrap>", "<frozen importlib._bootstrap_external>")


def _importing(frame) -> bool:
    """Whether the main thread was stopped inside an import (a module's body, or an extension's init)."""
    while frame is not None:
        if frame.f_code.co_filename in _IMPORT_MACHINERY:
            return True
        frame = frame.f_back
    return False


#: Modules of the standard library whose Python code takes a lock and enters the block that releases it in two
#: steps (threading's Condition and Semaphore, the futures and their thread pool, queue, logging's handlers).
LOCKING_MODULES = frozenset({"threading", "queue", "concurrent.futures._base", "concurrent.futures.thread", "logging"})
#: Where code of those modules waits and handles an exception raised there: a function's code, and what the line
#: it waits on calls. ``Condition.wait`` restores its lock in a ``finally``; a thread's join releases what it took
#: (bpo-45274; Python 3.13 joins in C).
#:
#: :meta hide-value:
WAITS = tuple((fn.__code__, call) for fn, call in (
    (threading.Condition.wait, "acquire("),
    (getattr(threading.Thread, "_wait_for_tstate_lock", None), "acquire("),
    (threading.Thread.join, "_handle.join("),
) if fn is not None)


LOCK_PATIENCE_S = 1.0  # how long a signal waits for the main thread to leave the locking code before it is raised
_lock_since: list[float] = []  # when the signal being sent again first found the main thread there


def _patient() -> bool:
    """Whether a signal that found the main thread in the locking code may still wait for it to leave
    (:data:`LOCK_PATIENCE_S`). Taking a lock is microseconds; a thread still there a second later is blocked in a
    call made there (a write of logging's to a pipe nobody reads), which the signal must end."""
    now = time.monotonic()
    if not _lock_since:
        _lock_since.append(now)
    return now - _lock_since[0] < LOCK_PATIENCE_S


def _taking_a_lock(frame) -> bool:
    """Whether the main thread was stopped in the code of :data:`LOCKING_MODULES`, outside the waits of
    :data:`WAITS` (where an exception might leave a lock taken that other threads then wait for)."""
    if frame is None or frame.f_globals.get("__name__") not in LOCKING_MODULES:
        return False
    for code, call in WAITS:
        if frame.f_code is code:
            line = linecache.getline(code.co_filename, frame.f_lineno).split("#")[0]
            return call not in line
    return True


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP while the block runs, and raise :class:`Interrupted` after it.

    For calls into libraries that an exception thrown in mid-call would leave broken (numba's
    compiler). Outside the main thread, which never runs signal handlers, it does nothing.
    """
    global _depth
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _depth += 1
    try:
        yield
    finally:
        _depth -= 1
        if not _depth and _held:
            raise Interrupted(_held.pop())


REDELIVER_S = 0.02  # how long after a swallowed signal it is sent again
LOCK_REDELIVER_S = 0.001  # the same after a signal that found the main thread taking a lock (microseconds' work)


def _redeliver(signum: int, delay: float = REDELIVER_S) -> None:
    """Send ``signum`` again in ``delay`` seconds, as a first signal (from the helper thread: the handler only
    runs in the main thread, between its bytecodes)."""
    _received.clear()
    _requests.put((_AGAIN, signum, delay))


def _unraisable(previous):
    def hook(unraisable) -> None:
        exc = unraisable.exc_value
        if not isinstance(exc, Interrupted):
            previous(unraisable)
            return
        # Raised inside a finaliser and swallowed: deliver it again once the finaliser is done.
        _redeliver(exc.signum)
    hook.pyramid_redelivers = True
    return hook


def _start_helper() -> None:
    global _helper
    _helper = threading.Thread(target=_serve, name="pyramid-signals", daemon=True)
    _helper.start()


def install() -> None:
    """Handle SIGINT, SIGTERM and SIGHUP by raising :class:`Interrupted`; ignore SIGXFSZ.

    Call once at start-up, from the main thread (elsewhere it does nothing). Signals that the
    parent process ignores (``nohup``, ``trap '' TERM``) stay ignored.
    """
    if threading.current_thread() is not threading.main_thread():
        return
    _received.clear()
    _held.clear()
    _lock_since.clear()
    if _helper is None:  # started here, in plain code: never from a handler or a finaliser (see _requests)
        _start_helper()
        os.register_at_fork(after_in_child=_start_helper)  # a forked child has no thread but the one that forked
    if not getattr(sys.unraisablehook, "pyramid_redelivers", False):
        sys.unraisablehook = _unraisable(sys.unraisablehook)
    for name in HANDLED:
        signum = getattr(signal, name, None)
        if signum is None:
            continue
        if signal.getsignal(signum) == signal.SIG_IGN:
            continue  # nohup and friends: keep ignoring
        signal.signal(signum, _handler)
    if hasattr(signal, "SIGXFSZ"):
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


class _Guarded:
    """A text stream whose writes are dropped once its reader has gone (EPIPE); the rest is the stream's."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text):
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._drop()
            return len(text)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._drop()

    def _drop(self) -> None:
        # /dev/null under the same descriptor: what the stream still buffers, and every later write, goes there
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, self._stream.fileno())
        finally:
            os.close(null)

    def __getattr__(self, name):
        return getattr(self._stream, name)


def guard_streams() -> None:
    """Make a closed standard output or error drop what is written to it instead of raising
    BrokenPipeError (the console script calls this once, at start-up)."""
    for name in ("stdout", "stderr"):
        stream = getattr(sys, name)
        if stream is not None and not isinstance(stream, _Guarded):
            setattr(sys, name, _Guarded(stream))


def end(code: object) -> None:
    """End the console script's process now with ``code``, skipping the interpreter's teardown.

    After a signal (``code`` its 128 + N status): at once, the clean-up being done, without atexit handlers,
    finalisers or C++ static destructors. After a run that ended otherwise: as the interpreter's own exit begins
    (the threads that are not daemons joined, then the atexit handlers), then without its teardown: freeing every
    module and object, and the libraries' destructors, takes 0.1 to 0.2 s of a run that loaded numba's kernels
    (docs/performance.md, "Fixed costs"). Either way the standard streams are flushed first; one that cannot be
    is exit 120, as Python's own exit makes it. Returns (the interpreter exits its own way) where ``code`` is not
    an exit status, the caller is not the main thread, or this Python lacks the hooks used.
    """
    if not isinstance(code, int) and code is not None:
        return
    status = code or 0
    if not (_received and status >= 128):
        shutdown, exitfuncs = getattr(threading, "_shutdown", None), getattr(atexit, "_run_exitfuncs", None)
        if shutdown is None or exitfuncs is None or threading.current_thread() is not threading.main_thread():
            return
        try:
            shutdown()   # what Python's exit does first: join the threads that are not daemons
            exitfuncs()
        except KeyboardInterrupt as e:  # a signal while finishing (every file already written): its status
            status = exit_code(e)
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None:
                stream.flush()
        except KeyboardInterrupt as e:
            status = exit_code(e)
        except Exception:
            status = status if status >= 128 else 120
    os._exit(status)


def exit_code(exc: BaseException) -> int:
    """The exit status for an interruption: 128 + signal number (130 for a plain KeyboardInterrupt)."""
    return exc.exit_code if isinstance(exc, Interrupted) else 128 + signal.SIGINT


def describe(exc: BaseException) -> str:
    """One line for stderr: ``interrupted`` or ``terminated by SIGTERM``."""
    if isinstance(exc, Interrupted) and exc.signum != signal.SIGINT:
        return f"terminated by {exc.name}"
    return "interrupted"
