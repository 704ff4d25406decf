"""The sizes of the GL executor's textures, known without a context or the executor.

Memory budgets (:func:`pyramid_cli.run.stream.estimate`) and ``auto``'s estimates
(:mod:`pyramid_cli.exec.auto`) count them before any context is made; a run on the CPU executor then never
imports the executor and its shader generator (about 5 ms of a fresh process).
"""

from __future__ import annotations


def _pow2(n: int) -> int:
    return 1 << max(0, n - 1).bit_length()


def texture_size(stored: tuple[int, int]) -> tuple[int, int]:
    """Texture (rows, columns) for a stored extent: powers of two, one spare texel when there is room."""
    return _pow2(stored[0]), _pow2(stored[1])


def texture_bytes(extent: tuple[int, int]) -> int:
    """Bytes of the texture that holds a stored (rows, columns) extent: power-of-two sides, RGBA32F at most
    (host memory on llvmpipe, which ``--memory`` budgets count: :func:`pyramid_cli.run.stream.estimate`)."""
    rows, cols = texture_size(extent)
    return rows * cols * 16


__all__ = ["texture_bytes", "texture_size"]
