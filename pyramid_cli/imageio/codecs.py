"""The memory OpenEXR's codecs hold, and a limit on their threads for runs within a memory budget.

OpenEXR decodes and encodes a file's chunks on a pool of threads that OpenImageIO sizes from the machine
(``exr_threads``, by default every core, whatever the process's affinity or its container's limits). Each open
file's codec holds line buffers and compressor state: some with its first thread, more with each further one. A
chunk is 16 rows of a zip file, 32 of piz, B44 or DWAA, 256 of DWAB, or one tile; the DWA compressors also hold
about 13 MiB a thread whatever the picture's width. That memory grows with the cores, not with the picture's
height, so a band-streamed run sized to ``--memory`` can exceed it: a 1536-pixel-wide half RGBA zip EXR streamed
within 16 MiB took 18 MiB over the interpreter's own peak with 2 codec threads and 48 MiB on a 16-core machine (an
H100 host); a 3840-wide DWAB file took 113 MiB more than an uncompressed one even on one thread.

:data:`EXR_CODEC_MEMORY` was measured on 2026-11-27 (``bench/codec_memory.py``; ``docs/performance.md``, "What
OpenEXR's codecs hold"): the peak memory of ``blur --levels 5`` streamed from and to 1920- and 3840-wide half RGBA
files of each compression,
against the same run on uncompressed files, with OpenImageIO told to use 1, 2, 8 and 16 threads; the entries
are those of one file, rounded up, so that two files (the input and the output) are at or above what was
measured.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass

import OpenImageIO as oiio

MIB = 1 << 20
# OpenEXR's rows per chunk of a scanline file, by compression (ImfCompression.h); others: the largest
EXR_CHUNK_ROWS = {"none": 1, "rle": 1, "zips": 1, "zip": 16, "pxr24": 16, "piz": 32, "b44": 32, "b44a": 32,
                  "dwaa": 32, "dwab": 256}
UNKNOWN_CHUNK_ROWS = 256
# What one open file's codec holds, by compression: ((bytes, chunks) with its first thread, (bytes, chunks) for
# each further thread). Measured per file (see the module), at 1920 and 3840 pixels wide: zip 1.4 MiB at either
# width (within the measurement's noise of a MiB: three chunks are counted), then 1.3 and 2.1 MiB a
# thread; piz 2.2 and 4.3 MiB, then 3.8 and 4.9; DWAA 14 and 16.5 MiB, then 14.5 and 16.2; DWAB 28 and 56 MiB (7.5
# chunks), then 32 and 30 MiB for a second thread, 3 to 9 MiB a thread beyond it; B44 0.8 and 3.2 MiB, then 2.0 and
# 4.0; pxr24 0.6 and 1.0 MiB, then 1.5 and 2.2; rle and zips 0.25 MiB a thread; uncompressed, nothing measurable.
EXR_CODEC_MEMORY = {
    "none": ((0, 0.0), (0, 0.0)),
    "rle": ((0, 2.0), (MIB // 4, 2.0)),
    "zips": ((0, 2.0), (MIB // 4, 2.0)),
    "zip": ((0, 3.0), (MIB // 2, 3.5)),
    "pxr24": ((0, 3.0), (MIB, 3.0)),
    "piz": ((0, 4.5), (3 * MIB, 2.5)),
    "b44": ((0, 5.0), (MIB // 4, 4.0)),
    "b44a": ((0, 5.0), (MIB // 4, 4.0)),
    "dwaa": ((12 * MIB, 5.5), (13 * MIB, 4.0)),
    "dwab": ((0, 7.5), (13 * MIB, 4.0)),
}
UNKNOWN_CODEC_MEMORY = ((12 * MIB, 7.5), (13 * MIB, 4.0))  # a compression not measured: the most of any above


@dataclass(frozen=True)
class CodecMemory:
    """Bytes the codecs of open files hold: with their first thread, and for each further one."""

    first: int = 0
    further: int = 0

    def at(self, threads: int) -> int:
        """Bytes held when the codecs run ``threads`` threads (at least one)."""
        return self.first + self.further * (max(1, threads) - 1)

    def __add__(self, other: CodecMemory) -> CodecMemory:
        return CodecMemory(self.first + other.first, self.further + other.further)


def exr_codec_memory(spec: oiio.ImageSpec, fmt: str) -> CodecMemory:
    """What OpenEXR's codec holds for a file of ``spec`` in format ``fmt`` (nothing for a file that is not an
    OpenEXR one): :data:`EXR_CODEC_MEMORY` by its compression (OpenImageIO's default zip when it names none), in
    chunks of its rows or tiles at its stored type's size."""
    if fmt != "openexr":
        return CodecMemory()
    value_bytes = max([spec.format.size()] + [t.size() for t in spec.channelformats])
    name = (spec.get_string_attribute("compression") or "zip").split(":")[0].strip().lower()
    if spec.tile_width > 0 and spec.tile_height > 0:
        pixels = spec.tile_width * spec.tile_height
    else:
        pixels = EXR_CHUNK_ROWS.get(name, UNKNOWN_CHUNK_ROWS) * spec.width
    chunk = pixels * spec.nchannels * value_bytes
    (a, ac), (b, bc) = EXR_CODEC_MEMORY.get(name, UNKNOWN_CODEC_MEMORY)
    return CodecMemory(a + int(ac * chunk + 0.5), b + int(bc * chunk + 0.5))


def exr_threads() -> int:
    """The threads OpenEXR codes with now (OpenImageIO's ``exr_threads``, resolved to a count)."""
    n = oiio.get_int_attribute("exr_threads")
    return n if n > 0 else max(1, oiio.get_int_attribute("threads"))


@contextlib.contextmanager
def limited_exr_threads(n: int | None) -> Iterator[None]:
    """OpenEXR codes the files opened inside the block with at most ``n`` threads, and OpenImageIO's own pool
    (its conversions and parallel writes) has as many (None: as they would). Its pool's threads hold memory
    too: a 2048² half EXR's MIP file streamed within 16 MiB took 36 MiB over the process's own size with
    OpenEXR limited to one thread and the pool at 16, 28 MiB with both limited. The settings are OpenImageIO's,
    for the whole process: they are restored when the block ends."""
    if n is None or n >= exr_threads():
        yield
        return
    before = {name: oiio.get_int_attribute(name) for name in ("threads", "exr_threads")}
    for name in before:
        oiio.attribute(name, max(1, int(n)))
    try:
        yield
    finally:
        for name, value in before.items():
            oiio.attribute(name, value)


__all__ = ["CodecMemory", "EXR_CHUNK_ROWS", "EXR_CODEC_MEMORY", "exr_codec_memory", "exr_threads",
           "limited_exr_threads"]
