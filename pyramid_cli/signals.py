"""SIGTERM and SIGHUP handled like Ctrl-C, so that interrupted writes clean up.

A render farm or CI job that times out sends SIGTERM; a closed terminal sends SIGHUP. By
default Python dies at once on both, leaving ``.NAME.tmp-XXXX.EXT`` files beside the outputs.
After :func:`install` each raises :class:`Interrupted` (a KeyboardInterrupt) in the main
thread, so the same ``finally``/``except BaseException`` clean-up as Ctrl-C runs (the
temporary is removed, the previous output is untouched) and the process exits with
``128 + signal number``: 130 for SIGINT, 143 for SIGTERM, 129 for SIGHUP
(:func:`exit_code`). A second signal while cleaning up ends the process the default way.

``install`` also ignores SIGXFSZ, so that a file size limit (``ulimit -f``) makes writes
fail with EFBIG, reported as exit 4, instead of killing the process mid-write.
"""

from __future__ import annotations

import os
import signal
import threading

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


def _handler(signum, frame):  # noqa: ARG001 - the signal module's signature
    if _received:
        # A second signal while the first is being handled: give up cleaning, die the default way.
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
        return
    _received.append(signum)
    raise Interrupted(signum)


def install() -> None:
    """Handle SIGINT, SIGTERM and SIGHUP by raising :class:`Interrupted`; ignore SIGXFSZ.

    Call once at start-up, from the main thread (elsewhere it does nothing). Signals that the
    parent process ignores (``nohup``, ``trap '' TERM``) stay ignored.
    """
    if threading.current_thread() is not threading.main_thread():
        return
    _received.clear()
    for name in HANDLED:
        signum = getattr(signal, name, None)
        if signum is None:
            continue
        if signal.getsignal(signum) == signal.SIG_IGN:
            continue  # nohup and friends: keep ignoring
        signal.signal(signum, _handler)
    if hasattr(signal, "SIGXFSZ"):
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


def exit_code(exc: BaseException) -> int:
    """The exit status for an interruption: 128 + signal number (130 for a plain KeyboardInterrupt)."""
    return exc.exit_code if isinstance(exc, Interrupted) else 128 + signal.SIGINT


def describe(exc: BaseException) -> str:
    """One line for stderr: ``interrupted`` or ``terminated by SIGTERM``."""
    if isinstance(exc, Interrupted) and exc.signum != signal.SIGINT:
        return f"terminated by {exc.name}"
    return "interrupted"
