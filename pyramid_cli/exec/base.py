"""What every executor of plans offers: the :class:`Executor` protocol.

An executor runs a :class:`~pyramid_cli.plan.model.Plan` on arrays and returns the logical
pixels of its outputs. There are three: the numpy plan emulator
(:class:`pyramid_cli.exec.emulate.Emulator`, float64, the living definition of a plan), the
compiled CPU executor (:class:`pyramid_cli.exec.cpu.CPUExecutor`) and the GL executor
(:class:`pyramid_cli.exec.gl.GLExecutor`). The session (:mod:`pyramid_cli.exec.session`),
the tile scheduler (:mod:`pyramid_cli.exec.tiles`) and the streaming runner
(:mod:`pyramid_cli.run.stream`) use only what this protocol names, so a new executor is a
class with these members.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from pyramid_cli.plan.model import Plan


@runtime_checkable
class Executor(Protocol):
    """An executor of plans (see the module notes).

    Attributes
    ----------
    backend : str
        The ``--backend`` name it serves: ``"gl"`` or ``"cpu"`` (the emulator stands in for the
        compiled CPU executor where numba is missing).
    strategy : str
        How its plans are best made (:func:`pyramid_cli.plan.lower.plan`'s ``strategy``): ``"cost"``
        (the calibrated cost model) or ``"fused"`` (one pass per written filter).
    work_dtype : numpy.dtype
        What it keeps intermediates and the tile scheduler's bands as: float32, or float64 (the emulator).
    writes_into : bool
        Whether its ``run_outputs`` takes ``out=``, an array the last output's pixels are written into (the
        compiled CPU executor: its last pass writes them there, so the tile scheduler makes each band of an image
        in its place in that image's buffer instead of copying it there).
    """

    backend: str
    strategy: str
    work_dtype: np.dtype
    writes_into: bool

    @property
    def name(self) -> str:
        """What runs the plans, for messages: ``gl (llvmpipe …)``, ``cpu (numba …)``."""
        ...

    @property
    def max_texture_size(self) -> int | None:
        """The largest side of an image it holds whole (GL_MAX_TEXTURE_SIZE), or None for no limit."""
        ...

    @property
    def host_textures(self) -> bool:
        """Whether it keeps textures in host memory beyond the pictures (GL on a software renderer): then
        memory budgets count :meth:`texture_bytes`."""
        ...

    def texture_bytes(self, extent: tuple[int, int]) -> int:
        """Bytes of the texture it keeps for an image of stored (rows, columns) ``extent`` (0: none)."""
        ...

    def run_outputs(self, plan: Plan, images, dtype=np.float32) -> list[np.ndarray]:
        """The logical pixels of every ``plan.outputs`` image, as ``dtype``, from one array per ``plan.inputs``."""
        ...

    def prepare(self, plan: Plan) -> None:
        """Get ready to run ``plan`` (compile, allocate); nothing is computed."""
        ...

    def uncached(self, plan: Plan, dtype=np.float32) -> int:
        """How many programs it must compile before it can run ``plan`` (a first run's wait; 0: none)."""
        ...

    def close(self) -> None:
        """Release what it holds (threads, a GL context); it can be used again afterwards."""
        ...


__all__ = ["Executor"]
