"""SIGTERM sent to real runs at several moments: the one check every streamed and whole write passes."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Callable, Iterable
from pathlib import Path

TIMEOUT = 120  # seconds a stopped run may take to clean up; past it the run is stuck, and its stacks are shown
PREVIOUS = b"previous output\n"


def interrupt_runs(cmd: list, out: Path, delays: Iterable[float], complete: Callable[[Path], bool]) -> int:
    """Start ``cmd`` once per delay and send SIGTERM after it; return how many runs the signal stopped.

    Each run must leave ``out``'s previous content or a new file with ``complete(out)`` true, and
    exit 0 (then with the new file) or 143 (a signal after the rename still exits 143); -15 is the
    default handler before ours are installed or after Python restores them at shutdown. Never a
    traceback, never a temporary left beside ``out``.
    """
    out.write_bytes(PREVIOUS)
    stopped = 0
    for delay in delays:
        p = subprocess.Popen([str(c) for c in cmd], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             env=dict(os.environ, PYTHONFAULTHANDLER="1"))
        time.sleep(delay)
        p.send_signal(signal.SIGTERM)
        _, err = finish(p, f"SIGTERM after {delay} s")
        assert p.returncode in (0, 143, -signal.SIGTERM), err.decode()
        assert b"Traceback" not in err and b"Exception ignored" not in err, err.decode()
        assert b"has not ended in" not in err, err.decode()  # the clean-up got stuck: its threads' stacks follow
        assert not [f for f in os.listdir(out.parent) if ".tmp-" in f]
        kept = out.read_bytes() == PREVIOUS
        if p.returncode == 0:
            assert not kept, "exit 0 but the output was not written"
        if not kept:
            assert complete(out), "the output was replaced by an incomplete file"
            out.write_bytes(PREVIOUS)
        stopped += kept
    return stopped


def finish(p: subprocess.Popen, what: str) -> tuple[bytes, bytes]:
    """``p.communicate()``; a run still going after :data:`TIMEOUT` seconds fails the test with every thread's
    stack (SIGABRT, which ``PYTHONFAULTHANDLER`` in its environment turns into Python tracebacks)."""
    try:
        return p.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        p.send_signal(signal.SIGABRT)
        _, err = p.communicate(timeout=30)
        raise AssertionError(f"{what}, the run was still going {TIMEOUT} s later; its threads:\n"
                             + err.decode(errors="replace")[-6000:]) from None
