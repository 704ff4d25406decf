"""OpenEXR's codecs in a run's memory budget: what the open files' codecs hold, and their threads limited to it.

A job's :class:`Codecs` is made once from its open inputs and the outputs it will write
(:mod:`pyramid_cli.imageio.codecs` measures what each holds with its first thread and each further one). The
choice of bands counts the first threads in its working set (``choose(..., codecs=Codecs.first)`` in
:mod:`pyramid_cli.run.stream`, which refuses a budget they do not fit before any work); the further threads get
what the working set leaves: inside a streamed run's block (:meth:`Codecs.within`), or, for a picture run whole,
until the caller's ``limits`` close (:meth:`Codecs.hold`; :func:`holds_codec_limits` keeps them for a call).
OpenImageIO starts one codec thread per core of the machine, whatever the process's limits: a whole run of a
1024-wide DWAA picture on 16 threads held 13 MiB a thread for each file, 260 MiB over a budget of 64 MiB.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar, cast

from pyramid_cli.run.budget import format_size

_Run = TypeVar("_Run", bound=Callable[..., Any])


class _Choice(Protocol):  # pyramid_cli.run.stream.Choice (that module imports this one)
    @property
    def budget(self) -> int: ...
    @property
    def working_set(self) -> int: ...
    @property
    def codecs(self) -> int: ...


@dataclass(frozen=True)
class Codecs:
    """The open inputs ``streams`` of a job (opened again under a limit: OpenEXR counts a file's threads when it
    opens) and what the codecs of all its files hold: ``first`` with one thread each, ``further`` for each more."""

    streams: tuple = ()
    first: int = 0
    further: int = 0

    @classmethod
    def of(cls, streams: Sequence, outputs: Sequence[tuple[str, tuple[int, int]]] = (), info=None, channels: int = 0,
           options: dict | None = None, tile: int = 0) -> Codecs:
        """The codecs of the open inputs ``streams`` and of the ``outputs`` (path, (rows, columns)) written from
        ``info`` with ``channels`` as the write ``options`` ask, in tiles of ``tile`` pixels where not 0 (a MIP
        file); nothing for files that are not OpenEXR ones."""
        from pyramid_cli import imageio as io
        from pyramid_cli.imageio.codecs import CodecMemory

        held = sum((st.codec_memory() for st in streams), CodecMemory())
        held = sum((io.output_codec_memory(p, info, channels, size, tile, **(options or {})) for p, size in outputs),
                   held)
        return cls(tuple(streams), held.first, held.further)

    def limit(self, choice: _Choice) -> tuple[int, int] | None:
        """(threads, bytes each further one holds) to code the files with where the threads OpenEXR would use hold
        more than ``choice``'s working set leaves of its budget; None where they fit, or no file is an OpenEXR one.

        The first threads are in the working set where the choice counted them (``Choice.codecs``); a choice made
        without them (one given to :func:`pyramid_cli.run.stream.stream_file`) leaves them less room. One thread
        each is the least the files are coded with."""
        from pyramid_cli import imageio as io

        left = choice.budget - choice.working_set - max(0, self.first - choice.codecs)
        if self.further == 0 or self.further * (io.exr_threads() - 1) <= left:
            return None
        return 1 + max(0, left) // self.further, self.further

    @contextlib.contextmanager
    def within(self, choice: _Choice, reporter=None, where: str = "") -> Iterator[None]:
        """Run the block with OpenEXR's codec threads (and OpenImageIO's pool) limited to what ``choice`` leaves
        them (:meth:`limit`), the inputs opened again under the limit and the outputs opened inside the block."""
        from pyramid_cli import imageio as io

        limit = self.limit(choice)
        if limit is None:
            yield
            return
        self._say(choice, limit, reporter, where)
        with io.limited_exr_threads(limit[0]):
            for st in self.streams:
                st.reopen()
            yield

    def hold(self, limits: contextlib.ExitStack | None, choice: _Choice, reporter=None, where: str = "") -> None:
        """For a whole run of ``choice``: the threads limited as :meth:`within` limits them, until ``limits`` (the
        caller's, held around the whole run) closes; nothing without ``limits``."""
        from pyramid_cli import imageio as io

        limit = self.limit(choice) if limits is not None else None
        if limits is None or limit is None:
            return
        self._say(choice, limit, reporter, where)
        limits.enter_context(io.limited_exr_threads(limit[0]))
        for st in self.streams:
            st.reopen()

    @staticmethod
    def _say(choice: _Choice, limit: tuple[int, int], reporter, where: str) -> None:
        from pyramid_cli import imageio as io

        if reporter is not None:
            reporter.detail(f"{where}: OpenEXR codes with {limit[0]} of its {io.exr_threads()} threads: each "
                            f"further one holds about {format_size(limit[1])}, and the working set leaves "
                            f"{format_size(choice.budget - choice.working_set)} of the memory budget")


def holds_codec_limits(run: _Run) -> _Run:
    """``run`` called with ``limits``: an ExitStack held around the whole call, in which a whole run's codec limit
    (:meth:`Codecs.hold`) stays until ``run`` returns (``run`` takes ``limits=None`` when called without it)."""
    @functools.wraps(run)
    def holding(*args, **kwargs):
        with contextlib.ExitStack() as limits:
            return run(*args, limits=limits, **kwargs)

    return cast(_Run, holding)


__all__ = ["Codecs", "holds_codec_limits"]
