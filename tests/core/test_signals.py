"""Signals as exit codes and one-line messages (pyramid_cli.core.signals); real signals: tests/system/test_faults.py."""

import signal

from pyramid_cli.core import signals


def test_a_keyboard_interrupt_exits_130_and_says_interrupted():
    assert signals.exit_code(KeyboardInterrupt()) == 128 + signal.SIGINT == 130
    assert signals.describe(KeyboardInterrupt()) == "interrupted"
    assert set(signals.HANDLED) == {"SIGINT", "SIGTERM", "SIGHUP"}
