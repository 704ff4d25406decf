"""The memory OpenEXR's codec threads hold, and a limit on them for runs within a memory budget.

OpenEXR decodes and encodes a file's chunks on a pool of threads that OpenImageIO sizes from the machine
(``exr_threads``, by default every core, whatever the process's affinity or its container's limits). Each
open file keeps line buffers for its threads: a few chunks each, where a chunk is 16 rows of a zip file,
32 of piz, 256 of DWAB, or one tile. That memory grows with the cores, not with the picture's height, so a
band-streamed run sized to ``--memory`` can exceed it on a machine with many cores: a 1536-pixel-wide half
RGBA EXR streamed within 16 MiB took 18 MiB over the interpreter's own peak with 2 codec threads and 48 MiB
on a 16-core machine (an H100 host, 2026-11-27; 38 and 55 MiB here with OpenImageIO told to use 16 and 64),
about a megabyte per thread for the input and the output together, where each holds a 192 KiB chunk.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import OpenImageIO as oiio

# OpenEXR's rows per chunk of a scanline file, by compression (ImfCompression.h); others: the largest
EXR_CHUNK_ROWS = {"none": 1, "rle": 1, "zips": 1, "zip": 16, "pxr24": 16, "piz": 32, "b44": 32, "b44a": 32,
                  "dwaa": 32, "dwab": 256}
UNKNOWN_CHUNK_ROWS = 256
# Bytes a codec thread holds per open file, in chunks (measured above: about 5 per file, rounded up)
CHUNKS_PER_THREAD = 6


def exr_thread_bytes(spec: oiio.ImageSpec, fmt: str) -> int:
    """Bytes one OpenEXR codec thread holds for a file of ``spec`` in format ``fmt`` (0: not an OpenEXR file,
    whose codec holds no buffers per thread): :data:`CHUNKS_PER_THREAD` chunks of its rows (by its compression,
    OpenImageIO's default zip when it names none) or tiles, at its stored type's size."""
    if fmt != "openexr":
        return 0
    value_bytes = max([spec.format.size()] + [t.size() for t in spec.channelformats])
    if spec.tile_width > 0 and spec.tile_height > 0:
        pixels = spec.tile_width * spec.tile_height
    else:
        name = (spec.get_string_attribute("compression") or "zip").split(":")[0].strip().lower()
        pixels = EXR_CHUNK_ROWS.get(name, UNKNOWN_CHUNK_ROWS) * spec.width
    return CHUNKS_PER_THREAD * pixels * spec.nchannels * value_bytes


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


__all__ = ["CHUNKS_PER_THREAD", "EXR_CHUNK_ROWS", "exr_thread_bytes", "exr_threads", "limited_exr_threads"]
