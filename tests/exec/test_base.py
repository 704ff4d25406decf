"""The executor protocol (``pyramid_cli.exec.base``): what every executor offers the session, the tile
scheduler and the streaming runner."""

from __future__ import annotations

import numpy as np

from pyramid_cli.exec.session import Session
from pyramid_cli.jobs.work import Blur


def test_every_executor_follows_the_executor_protocol():
    """The session, the tile scheduler and the streaming runner use only what exec.base.Executor names."""
    from pyramid_cli.exec.base import Executor
    from pyramid_cli.exec.emulate import Emulator
    from pyramid_cli.exec.gl import GLExecutor

    executors = [Emulator(), GLExecutor()]  # GLExecutor makes no context until it runs
    with Session("cpu") as s:
        executors.append(s.executor)
        for ex in executors:
            assert isinstance(ex, Executor), ex
            assert ex.backend in ("gl", "cpu") and ex.strategy in ("cost", "fused")
        assert s.executor.max_texture_size is None and not s.executor.host_textures
        assert s.executor.texture_bytes((5, 5)) == 0
    emulated = Emulator().run_outputs(Blur(levels=1).plan([(5, 4)]), [np.ones((5, 4))], np.float32)
    assert emulated[0].dtype == np.float32 and Emulator.work_dtype == np.float64
