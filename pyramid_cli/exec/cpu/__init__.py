"""The compiled CPU executor: plans as generated numba kernels.

:mod:`.codegen` writes a pass shape as the Python source of a numba kernel,
:mod:`.compile` compiles it once per machine (numba's disk cache beside the source),
:mod:`.aot` builds it ahead of time for later processes, which then load it without numba, and
:mod:`.executor` runs plans with it (:class:`CPUExecutor`). numba is imported only in this
package, and only when a kernel runs through numba, is compiled, or :func:`available` is asked.
"""

from __future__ import annotations

from pyramid_cli.exec.cpu.codegen import Term, factor, kernel_source, phase_terms
from pyramid_cli.exec.cpu.compile import CACHE_ENV, INSTALL_HINT, available, cache_dir, fallback_cache
from pyramid_cli.exec.cpu.executor import SMALL, CPUExecutor, default_threads

__all__ = ["CPUExecutor", "available", "cache_dir", "default_threads", "fallback_cache", "kernel_source", "phase_terms",
           "factor", "Term", "CACHE_ENV", "INSTALL_HINT", "SMALL"]
