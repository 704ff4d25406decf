"""run.overlap: the reader and writer threads hand rows over in order, raise their errors on the calling
thread, and never outlive their block."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from pyramid_cli.core.errors import InputError, OutputError
from pyramid_cli.run.overlap import Reader, overlapped

ROWS = np.arange(50 * 3, dtype=np.float32).reshape(50, 3, 1)


def read(y0, y1):
    return ROWS[y0:y1].copy()


def ours():
    return [t for t in threading.enumerate() if t.name in ("pyramid-read", "pyramid-write")]


@pytest.mark.parametrize("step", [1, 7, 8, 50, 64])
def test_rows_come_in_order_whatever_the_step(step):
    got, calls = [], []
    with overlapped(read, 50, step) as (reader, writer):
        for y0, y1 in ((0, 3), (3, 11), (11, 12), (15, 40), (40, 50)):  # rows 12..14 skipped
            px = reader.rows(y0, y1)
            assert np.array_equal(px, ROWS[y0:y1])
            writer.call(got.append, px)
            writer.call(calls.append, y0)
    assert calls == [0, 3, 11, 15, 40] and len(got) == 5
    assert not ours()


def test_rows_before_the_last_handed_out_are_refused():
    with overlapped(read, 50, 8) as (reader, _):
        reader.rows(0, 10)
        with pytest.raises(ValueError, match="in order"):
            reader.rows(5, 12)
    assert not ours()


def test_a_read_error_is_raised_on_the_calling_thread():
    def bad(y0, y1):
        if y0 >= 16:
            raise InputError("cannot read in.png: truncated")
        return read(y0, y1)

    with pytest.raises(InputError, match="truncated"), overlapped(bad, 50, 8) as (reader, _):
        reader.rows(0, 16)
        reader.rows(16, 20)
    assert not ours()


def test_a_write_error_is_raised_at_the_next_call_or_at_the_end():
    def fail(_):
        raise OutputError("cannot write out.png: No space left on device")

    with pytest.raises(OutputError, match="No space"), overlapped(None, 0, 1) as (_, writer):
        writer.call(fail, 1)
        for i in range(100):  # the writer stopped taking calls: one of these raises, or the drain does
            writer.call(lambda _: None, i)
    assert not ours()


def test_an_interruption_stops_both_threads():
    slow = threading.Event()

    def wait(_):
        slow.wait(0.2)

    with pytest.raises(KeyboardInterrupt), overlapped(read, 50, 1) as (reader, writer):
        reader.rows(0, 2)
        writer.call(wait, 0)
        writer.call(wait, 1)
        raise KeyboardInterrupt
    assert not ours()


def test_a_reader_without_a_block_stops_when_halted():
    r = Reader(read, 50, 1, depth=1)
    r.thread.start()
    assert np.array_equal(r.rows(0, 1), ROWS[:1])
    r.halt()
    assert not r.thread.is_alive()
