"""OpenEXR's codecs in a run's memory budget (``pyramid_cli.run.codec_budget``): what the files hold, the limit
on the further threads, streamed (``within``) and whole (``hold``)."""

from __future__ import annotations

import contextlib

import OpenImageIO as oiio
import pytest

import pyramid_cli.imageio as io
from helpers.images import noise, write
from pyramid_cli.run.codec_budget import Codecs, holds_codec_limits
from pyramid_cli.run.stream import Choice


class Stream:
    """An open input as Codecs sees it: what its codec holds, and a count of its reopenings."""

    def __init__(self, first: int, further: int):
        self.memory, self.reopened = (first, further), 0

    def codec_memory(self):
        from pyramid_cli.imageio.codecs import CodecMemory

        return CodecMemory(*self.memory)

    def reopen(self) -> None:
        self.reopened += 1


@pytest.fixture
def sixteen():
    """OpenImageIO told that OpenEXR codes with 16 threads (as on a 16-core machine), and put back after."""
    before = oiio.get_int_attribute("exr_threads")
    oiio.attribute("exr_threads", 16)
    yield
    oiio.attribute("exr_threads", before)


def test_the_files_add_up_and_other_formats_hold_nothing(tmp_path):
    src = write(tmp_path / "in.exr", noise(20, 300, seed=1), "half", compression="dwaa")
    with io.open_stream(src, keep_half=True) as st:
        alone = Codecs.of([st])
        both = Codecs.of([st], [(str(tmp_path / "o.exr"), (20, 300))], st.info, 4, {})
        png = Codecs.of([], [(str(tmp_path / "o.png"), (20, 300))], st.info, 4, {})
    assert alone.first == st.codec_memory().first > 12 << 20  # DWAA's compressor alone
    assert both.first == 2 * alone.first and both.further == 2 * alone.further
    assert (png.first, png.further) == (0, 0) and png.limit(Choice(1, 0, 8, 1)) is None


def test_the_further_threads_get_what_the_working_set_leaves(sixteen):
    codecs = Codecs((), first=10, further=4)
    assert codecs.limit(Choice(100, 0, 8, 45, codecs=10)) == (1 + 55 // 4, 4)  # 55 left: 13 more
    assert codecs.limit(Choice(100, 0, 8, 95, codecs=10)) == (2, 4)
    assert codecs.limit(Choice(100, 0, 8, 100, codecs=10)) == (1, 4)  # none left: one thread each
    assert codecs.limit(Choice(100, 0, 8, 40, codecs=10)) is None  # 60 left: room for 15 more, all 16
    # a choice made without the codecs: their first threads come out of what it leaves
    assert codecs.limit(Choice(100, 0, 8, 40)) == (1 + 50 // 4, 4)


def test_within_limits_the_block_and_reopens_the_inputs(sixteen):
    said = []
    st = Stream(10, 4)
    codecs = Codecs((st,), first=10, further=4)
    with codecs.within(Choice(100, 0, 8, 92, codecs=10), type("R", (), {"detail": said.append})(), "in.exr"):
        assert oiio.get_int_attribute("exr_threads") == 3 and st.reopened == 1
    assert oiio.get_int_attribute("exr_threads") == 16
    assert said == ["in.exr: OpenEXR codes with 3 of its 16 threads: each further one holds about 4 B, and the "
                    "working set leaves 8 B of the memory budget"]
    with codecs.within(Choice(100, 0, 8, 0, codecs=10)):  # room for every thread: nothing changes
        assert oiio.get_int_attribute("exr_threads") == 16 and st.reopened == 1


def test_hold_keeps_the_limit_until_the_caller_s_stack_closes(sixteen):
    st = Stream(10, 4)
    codecs = Codecs((st,), first=10, further=4)
    whole = Choice(100, 92, None, 92, codecs=10)
    codecs.hold(None, whole)  # no stack: a run that holds nothing
    assert oiio.get_int_attribute("exr_threads") == 16 and st.reopened == 0
    with contextlib.ExitStack() as limits:
        codecs.hold(limits, whole)
        assert oiio.get_int_attribute("exr_threads") == 3 and st.reopened == 1
    assert oiio.get_int_attribute("exr_threads") == 16


def test_holds_codec_limits_gives_the_call_a_stack_it_closes_after():
    seen = []

    @holds_codec_limits
    def run(x, *, limits=None):
        seen.append(limits)
        limits.callback(seen.append, "closed")
        return x * 2

    assert run(21) == 42
    assert isinstance(seen[0], contextlib.ExitStack) and seen[1:] == ["closed"]
