"""Choose an executor and run plans on it: GL through EGL, or numpy on the CPU.

``auto`` tries GL and falls back to the CPU with a one-line warning when no
EGL/OpenGL context can be made; ``gl`` fails instead (exit code 6).
"""

from __future__ import annotations

import sys

import numpy as np

from .border import Border
from .errors import BackendError, DataError
from .expr import Expr
from .plan import Plan

BACKENDS = ["auto", "gl", "cpu"]


class Runner:
    """Holds one executor (one GL context, one program cache) for a whole command or batch."""

    def __init__(self, backend: str = "auto", precision: str = "float", warn=None):
        self.requested = backend
        self.precision = precision
        self._gl = None
        self._warn = warn or (lambda msg: print(f"pyramid: warning: {msg}", file=sys.stderr))
        if backend in ("gl", "auto"):
            from . import gl

            executor = gl.GLExecutor(precision=precision)
            try:
                _ = executor.ctx  # makes the context now, so a missing EGL shows here
                self._gl = executor
            except BackendError as e:
                if backend == "gl":
                    raise
                self._warn(f"{e.message}; running on the CPU")

    def run_plan(self, plan: Plan, pixels: np.ndarray, dtype=np.float32) -> np.ndarray:
        """Execute a plan; ``dtype`` (float32 or float16) out."""
        return self.run_outputs(plan, [pixels], dtype)[-1]

    def run_outputs(self, plan: Plan, images, dtype=np.float32) -> list[np.ndarray]:
        """Execute a plan with one image per ``plan.inputs``; every image of ``plan.outputs``.

        Inputs may be float16 (half files); outputs are ``dtype``, float32 or float16, the
        latter rounded to nearest even from the float result (as writing a half file would).
        """
        images = images if isinstance(images, (list, tuple)) else [images]
        if self._gl is not None:
            try:
                return self._gl.run_outputs(plan, images, dtype)
            except DataError as e:  # larger than the GL texture limit
                if self.requested == "gl":
                    raise
                self._warn(f"{e.message}; running this image on the CPU")
        from . import emulate

        return [_rounded(o, dtype) for o in emulate.run_outputs(plan, images)]

    def prepare(self, plan: Plan) -> None:
        """Get ready to run ``plan`` (GL: programs compiled, textures allocated); best effort, never fails."""
        if self._gl is not None:
            try:
                self._gl.prepare(plan)
            except (BackendError, DataError):
                pass  # the run itself reports it, or falls back

    def run_expr(self, expr: Expr, pixels: np.ndarray, border: str = "clamp", dtype=np.float32) -> np.ndarray:
        """Execute an expression: planned on GL, the numpy reference on the CPU (and for non-clamp borders)."""
        if self._gl is not None and border == "clamp":
            from .plan import plan

            return self.run_plan(plan(expr, pixels.shape[:2]), pixels, dtype)
        from . import reference

        return _rounded(reference.run(expr, pixels, Border.parse(border)), dtype)

    def run_blur(self, pixels: np.ndarray, levels: int, analysis: str, synthesis: str,
                 quasi: bool = False, dtype=np.float32) -> np.ndarray:
        """Pyramid blur: one planned GL job, or the reference composed level by level on the CPU."""
        from . import pyramids

        if self._gl is not None:
            plan = pyramids.blur_plan(pixels.shape[:2], levels, analysis, synthesis, quasi)
            return self.run_plan(plan, pixels, dtype)
        return _rounded(pyramids.blur_reference(pixels, levels, analysis, synthesis, quasi), dtype)

    @property
    def on_gl(self) -> bool:
        """Whether plans run on the GL executor (else numpy on the CPU)."""
        return self._gl is not None

    @property
    def name(self) -> str:
        if self._gl is None:
            return "cpu"
        info = self._gl.info()
        return f"gl ({info.get('renderer', 'OpenGL')})"

    def close(self) -> None:
        if self._gl is not None:
            self._gl.close()


def _rounded(values: np.ndarray, dtype) -> np.ndarray:
    """A CPU result (float64) as ``dtype``, through float32 as the GL path rounds: float64 → float32 → half."""
    return values.astype(np.float32).astype(dtype, copy=False)


def execute(expr: Expr, pixels: np.ndarray, backend: str = "auto", border: str = "clamp") -> tuple[np.ndarray, str]:
    """One-shot helper: run ``expr`` on ``pixels``; returns (float32 result, backend used)."""
    runner = Runner(backend)
    try:
        return runner.run_expr(expr, pixels, border), runner.name
    finally:
        runner.close()
