"""Decode, compute and encode at once: a reader thread ahead of the band scheduler, a writer thread behind it.

A streamed run (:mod:`pyramid_cli.run.stream`) asks its input for rows in order and hands its outputs'
rows over in order. Done on one thread, decoding band k+1, computing band k and encoding band k−1 wait
for each other. Here the decoding runs on a :class:`Reader` thread that decodes fixed steps of rows
ahead into a bounded queue, and the encoding and writing on a :class:`Writer` thread that takes calls
from a bounded queue and makes them in order; the scheduler and its executor keep the calling thread.
OpenImageIO's reads and writes, numpy's conversions and the CPU executor's kernels release the GIL, so
the three overlap on separate cores.

The pixels are those of the one-threaded run: the rows are decoded pixel by pixel whatever the step, and
each writer gets its rows in the same order (:class:`pyramid_cli.imageio.BandWriter` groups them for
dithering and tiles itself). The queues are bounded (``depth`` items), so at most that many bands are in
flight beyond the scheduler's own. An error on either thread is raised on the calling thread at its next
hand-over, as it would have been raised there; an error or interruption (Ctrl-C, SIGTERM: raised on the
calling thread) on the calling thread stops both threads, and :func:`overlapped` joins them before
the exception goes on, so that the writers' temporaries are removed only once nothing writes into them.
No thread outlives the block.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Callable, Iterator

import numpy as np

POLL = 0.05   # seconds between checks of the other side's state while a queue is full or empty
DEPTH = 1     # items waiting in each queue (besides the one being made and the one being used)
_END = object()


class _Side:
    """A daemon thread with a bounded queue, a stop flag and the first error it met."""

    def __init__(self, name: str, depth: int):
        self.queue: queue.Queue = queue.Queue(maxsize=max(1, depth))
        self.stop = threading.Event()
        self.error: BaseException | None = None
        self.busy = 0.0  # CPU seconds of the thread's work (thread time: what it cost, whatever the load)
        self.thread = threading.Thread(target=self._guarded, name=name, daemon=True)

    def _guarded(self) -> None:
        try:
            self._loop()
        except BaseException as exc:  # noqa: BLE001 - handed to the calling thread, which raises it
            self.error = exc

    def _loop(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def _put(self, item) -> bool:
        """Put ``item``, waiting while the queue is full; False once stopped or failed."""
        while not self.stop.is_set() and self.error is None:
            try:
                self.queue.put(item, timeout=POLL)
                return True
            except queue.Full:
                continue
        return False

    def halt(self) -> None:
        """Stop the thread and wait for it (what it is doing now ends first)."""
        self.stop.set()
        while self.thread.is_alive():
            with contextlib.suppress(queue.Empty):
                while True:
                    self.queue.get_nowait()  # unblock a put
            self.thread.join(POLL)


class Reader(_Side):
    """Rows ``0 .. height − 1`` of ``read(y0, y1)`` decoded ``step`` rows at a time on a thread of their own,
    at most ``depth`` steps ahead; :meth:`rows` hands them out in order."""

    def __init__(self, read: Callable[[int, int], np.ndarray], height: int, step: int, depth: int = DEPTH):
        super().__init__("pyramid-read", depth)
        self.read, self.height, self.step = read, height, max(1, int(step))
        self._held: np.ndarray | None = None  # rows decoded, not handed out yet
        self._at = 0                           # the first row of _held (rows before it were handed out)

    def _loop(self) -> None:
        for y in range(0, self.height, self.step):
            if self.stop.is_set():
                return
            t = time.thread_time()
            rows = self.read(y, min(self.height, y + self.step))
            self.busy += time.thread_time() - t
            if not self._put(rows):
                return
        self._put(_END)

    def _next(self) -> np.ndarray:
        while True:
            if self.error is not None:
                raise self.error
            try:
                item = self.queue.get(timeout=POLL)
            except queue.Empty:
                if not self.thread.is_alive() and self.queue.empty() and self.error is None:
                    raise RuntimeError("the reader thread ended early") from None
                continue
            if item is _END:
                raise RuntimeError(f"rows past {self.height} asked for")
            return item

    def rows(self, y0: int, y1: int) -> np.ndarray:
        """Rows ``y0 .. y1 − 1``; ``y0`` is at or past the first row not handed out yet (rows skipped are
        dropped)."""
        parts = self.parts(y0, y1)
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def parts(self, y0: int, y1: int) -> list[np.ndarray]:
        """:meth:`rows` as the consecutive pieces of the steps they were decoded in (views, no copy)."""
        if y0 < self._at:
            raise ValueError(f"rows are read in order: row {self._at} or later expected, not {y0}")
        parts = []
        while True:
            held = self._held
            if held is not None and self._at + len(held) > y0:
                lo = y0 - self._at
                hi = min(len(held), y1 - self._at)
                parts.append(held[lo:hi])
                y0 = self._at + hi
                if y0 >= y1:
                    self._held, self._at = held[y1 - self._at:], y1
                    return parts
            self._at += 0 if held is None else len(held)
            self._held = self._next()


class Writer(_Side):
    """Calls made in order on a thread of their own, at most ``depth`` waiting (:meth:`call`)."""

    def __init__(self, depth: int = DEPTH):
        super().__init__("pyramid-write", depth)

    def _loop(self) -> None:
        while True:
            try:
                item = self.queue.get(timeout=POLL)
            except queue.Empty:
                if self.stop.is_set():
                    return
                continue
            if item is _END or self.stop.is_set():
                return
            fn, args = item
            t = time.thread_time()
            fn(*args)
            self.busy += time.thread_time() - t

    def call(self, fn: Callable, *args) -> None:
        """``fn(*args)`` on the thread, after every earlier call; raises the thread's error if it failed."""
        if self.error is not None:
            raise self.error
        if not self._put((fn, args)):
            if self.error is not None:
                raise self.error
            raise RuntimeError("the writer thread was stopped")

    def drain(self) -> None:
        """Wait until every call is made and the thread ended; raises its error if one failed."""
        self._put(_END)
        while self.thread.is_alive():
            self.thread.join(POLL)
        if self.error is not None:
            raise self.error


@contextlib.contextmanager
def overlapped(read: Callable[[int, int], np.ndarray] | None, height: int, step: int,
               depth: int = DEPTH) -> Iterator[tuple[Reader | None, Writer]]:
    """A started :class:`Reader` of ``read`` (None: no reader) and :class:`Writer`. On leaving normally every
    write is made (its error raised); on an error or interruption both threads are stopped and joined
    before it goes on."""
    reader = Reader(read, height, step, depth) if read is not None else None
    writer = Writer(depth)
    sides = [s for s in (reader, writer) if s is not None]
    for s in sides:
        s.thread.start()
    try:
        yield reader, writer
        writer.drain()
    finally:
        for s in sides:
            s.halt()


__all__ = ["Reader", "Writer", "overlapped", "DEPTH"]
