"""Memory budgets of streamed runs in tests: what OpenEXR's codecs add to a run's working set.

A streamed run counts the bytes OpenEXR's codecs hold on one thread for its files in its working set
(:class:`pyramid_cli.run.codec_budget.Codecs`). Tests whose ``--memory`` is chosen to land a run in one branch
(the coarser levels in memory or spilled, level 0 read once or twice) add these bytes, so that the branch does not
depend on the files' compression.
"""

from __future__ import annotations

from pyramid_cli.run import stream
from pyramid_cli.run.codec_budget import Codecs
from pyramid_cli.run.settings import ReadOptions, WriteOptions


def codecs(src, outputs=(), tile: int = 0, inputs=(), **write) -> int:
    """Bytes the codecs hold on one thread for reading ``src`` (and ``inputs``) and writing ``outputs``: paths, or
    (path, (rows, columns)) pairs (a path alone: ``src``'s size), as the write options ``write`` ask, in tiles of
    ``tile`` pixels where not 0 (a MIP file)."""
    with stream.open_input(str(src), ReadOptions()) as st:
        h, w, c = st.shape
        outs = [(str(o), (h, w)) if not isinstance(o, tuple) else (str(o[0]), o[1]) for o in outputs]
        options = WriteOptions(**write).for_inputs([str(src)])
        first = Codecs.of([st], outs, st.info, c, options, tile).first
    for path in inputs:
        with stream.open_input(str(path), ReadOptions()) as more:
            first += more.codec_memory().first
    return first
