"""What a picture's run will hold, weighed from its header before it runs: the weight a batch gives each picture
(:func:`weigh`), and the whole run of a MIP map made from its 8/16-bit codes (:func:`mip_codes_bytes`), whose
level 0 is written as read (:mod:`pyramid_cli.run.mip_whole`).

:func:`pyramid_cli.run.stream.estimate` counts a whole run as every image of its plan in float32 at once. A MIP map
from codes holds far less: level 0 as read, the coarser levels as stored, and the scheduler's bands. Counted as
float32, an 8K 8-bit PNG's ``.tx`` was said to need 1,013 MiB where it held 156 MiB (``tracemalloc``), so inside
a container it streamed (slower, and larger) where the whole run would have fitted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pyramid_cli.plan import Plan
from pyramid_cli.run.codec_budget import Codecs
from pyramid_cli.run.stream import (
    choose,
    costs,
    estimate,
    open_input,
    output_sizes,
    reads_codes,
    speed_band,
    streamable,
    write_options,
)

LEVEL0_ROWS = 256  # level 0's rows a MIP map's writer is handed at a time (run.mip_whole.write_levels)
HASHERS = 2        # threads hashing level 0's blocks of rows while it is read (run.mip_whole.level0_as_read)


@dataclass(frozen=True)
class Weight:
    """What a batch weighs a picture by (:func:`pyramid_cli.run.local.run_in_budget`): ``whole``, the bytes its
    whole run holds (``Choice.whole``: :func:`~pyramid_cli.run.stream.estimate` and OpenEXR's codecs for its
    files; a MIP map from codes: :func:`mip_codes_bytes`); ``streamed``, the pixels of its widest output where
    :func:`~pyramid_cli.run.stream.choose` streams it, fitting, because bands are faster (``Choice.faster``: what
    :func:`~pyramid_cli.run.stream.run_job` would do with it), else 0."""

    whole: int
    streamed: int = 0


def weigh(in_path: str, work, session, read=None, output: str | None = None, write=None,
          tile: int = 0) -> Weight | None:
    """The :class:`Weight` of ``work``'s run of ``in_path`` to ``output`` (written as ``write`` asks; a MIP file in
    tiles of ``tile``, which streams only where it would not fit), from the header: :func:`choose`'s choice with
    no limit on the budget; None where no plan says it (the reference backend, a job of several inputs, a header
    that cannot be read: the run itself reports why)."""
    from pyramid_cli import imageio as io
    from pyramid_cli.core.errors import PyramidError
    from pyramid_cli.run.settings import ReadOptions

    executor = None if session is None else session.executor
    if executor is None or work.n_inputs != 1:
        return None
    try:
        with open_input(in_path, read or ReadOptions()) as st:
            h, w, c = st.shape
            plan = session.plan(work, [(h, w)])
            if plan is None:
                return None
            size = (h, w) if tile else output_sizes(work, plan, h, w)[-1]
            options = write_options(write, in_path)
            codecs = Codecs.of([st], [] if output is None else [(output, size)], st.info, c, options, tile)
            if tile and output is not None and mip_from_codes(st, output, options, executor):
                return Weight(codecs.first + mip_codes_bytes(plan, st, executor))
            streams = not tile and streamable(work) and (output is None or io.streams_to(output))
            choice = choose(plan, c, 1 << 62, in_bytes=st.dtype.itemsize, out_bytes=4, where=in_path,
                            keeps_input=work.keeps_input, prefer=speed_band(plan, executor) if streams else None,
                            codecs=codecs.first, **costs(executor))
    except PyramidError:
        return None
    widest = max(a * b for a, b in (plan.images[k].size for k in plan.outputs))
    return Weight(choice.whole, widest if choice.faster else 0)


def stored_codes(st, out_path: str, options: dict) -> np.ndarray | None:
    """The float32 value of every code of the open :class:`~pyramid_cli.imageio.ImageStream` ``st`` where its rows
    are 8/16-bit codes decoded code by code (:func:`pyramid_cli.imageio.read.code_table`) that the MIP file
    ``out_path``, written as ``options`` ask, stores unchanged (:meth:`~pyramid_cli.imageio.ImageStream.keeps_stored`):
    level 0 is then written as read; else None."""
    from pyramid_cli import imageio as io
    from pyramid_cli.imageio.read import code_table

    c = st.shape[2]
    table = code_table(st.info, st.stored_dtype, c)
    if table is None or not st.keeps_stored(io.Encoder(out_path, st.info, c, check_path=False, **options)):
        return None
    return table


def mip_from_codes(st, out_path: str, options: dict, executor) -> bool:
    """Whether a whole MIP run of ``st`` to ``out_path`` is made from its codes (:func:`stored_codes`, on an
    executor that reads them: :func:`~pyramid_cli.run.stream.reads_codes`), as
    :func:`~pyramid_cli.run.mip_whole.run_whole` makes it."""
    return reads_codes(executor) and stored_codes(st, out_path, options) is not None


def mip_codes_bytes(plan: Plan, st, executor) -> int:
    """Bytes a whole MIP run of ``plan`` from the codes of ``st`` holds (:func:`mip_from_codes`): level 0's codes,
    held until its header is known and it is written, and the larger of what comes beside them while it is read
    (each hashing thread's block of rows as float32, and a block as read) and after (the coarser levels as
    stored, the scheduler's bands with copies of the codes, or a picture too small for bands run whole, and
    the rows of level 0 its writer has in hand)."""
    from pyramid_cli.workflows.mip import SHA1_BLOCK

    h, w, c = st.shape
    item = st.stored_dtype.itemsize
    row = w * c
    block = min(h, SHA1_BLOCK)
    reading = HASHERS * block * row * 4 + block * row * item
    coarse = sum(a * b for a, b in (plan.images[k].size for k in plan.outputs)) * c * item
    written = 2 * min(h, LEVEL0_ROWS) * row * item
    band = speed_band(plan, executor)
    # whole, the executor reads the codes held as level 0 where they are; in bands, the scheduler joins copies
    levels = coarse + estimate(plan, c, band, in_bytes=item if band else 0) + written
    return h * row * item + max(reading, levels)


__all__ = ["HASHERS", "LEVEL0_ROWS", "Weight", "mip_codes_bytes", "mip_from_codes", "stored_codes", "weigh"]
