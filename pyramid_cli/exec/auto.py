"""What ``auto`` compares: one job's estimated seconds on the compiled CPU executor and on GL.

:class:`~pyramid_cli.exec.session.Session` asks :func:`estimates` once it knows the job (its plan,
the inputs' sizes and channels, how many files a batch holds) and runs the backend of the
smaller estimate (:mod:`pyramid_cli.plan.backend_cost` has the model and its constants).
Nothing here opens a GL context or imports numba: the renderer comes from the cache
(:func:`pyramid_cli.exec.gl.context.machine_gl`), and which kernels the CPU executor would load
or compile from the files in its cache folder.
"""

from __future__ import annotations

import sys

from pyramid_cli.exec.gl.context import is_software_renderer
from pyramid_cli.plan import backend_cost
from pyramid_cli.plan.backend_cost import BackendCosts, Estimate
from pyramid_cli.plan.cost import format_seconds
from pyramid_cli.plan.model import Plan, ResamplePass
from pyramid_cli.plan.shapes import shape


def cpu_kernels(plan: Plan) -> tuple[int, int]:
    """(kernels loaded from numba's disk cache, kernels compiled) before the CPU executor can run ``plan``
    (:func:`~pyramid_cli.exec.cpu.executor.kernel_digest` of each pass). Kernels this process has loaded
    already, and those built ahead of time (:mod:`pyramid_cli.exec.cpu.aot`: imported in a fraction of a
    millisecond, without numba), count as neither."""
    from pyramid_cli.exec.cpu import aot
    from pyramid_cli.exec.cpu.compile import cache_dir, loaded, on_disk
    from pyramid_cli.exec.cpu.executor import kernel_digest

    folder = cache_dir()
    todo = [d for d in {kernel_digest(ps) for ps in plan.passes} if not loaded(d) and not aot.ready(folder, d)]
    compiles = sum(not on_disk(folder, d) for d in todo)
    return len(todo) - compiles, compiles


def gl_programs(plan: Plan) -> int:
    """Programs the GL executor compiles for ``plan`` in a fresh context (one per pass shape and border)."""
    return len({("resample", ps.axis) if isinstance(ps, ResamplePass) else shape(ps, plan.images)
                for ps in plan.passes})


def estimates(cpu_plan: Plan | None, gl_plan: Plan | None, channels: int, *, jobs: int = 1, threads: int | None = None,
              gl_opened: bool = False, costs: BackendCosts | None = None,
              texture_bytes=None) -> dict[str, Estimate]:
    """Each backend's :class:`~pyramid_cli.plan.backend_cost.Estimate` of ``jobs`` runs of its plan (the
    CPU executor's ``cpu_plan``, GL's ``gl_plan``; None leaves that backend out) on inputs of ``channels``."""
    costs = costs or backend_cost.load()
    out = {}
    if cpu_plan is not None:
        try:
            loads, compiles = cpu_kernels(cpu_plan)
        except Exception:  # noqa: BLE001 - an estimate only: assume every kernel is loaded from the cache
            loads, compiles = len(cpu_plan.passes), 0
        # numba is imported only for kernels not built ahead of time
        imported = "numba" in sys.modules or loads + compiles == 0
        out["cpu"] = backend_cost.cpu_estimate(costs.cpu, cpu_plan, channels, jobs=jobs, threads=threads, loads=loads,
                                               compiles=compiles, imported=imported)
    if gl_plan is not None:
        out["gl"] = backend_cost.gl_estimate(costs.gl, costs.passes, gl_plan, channels, jobs=jobs,
                                             programs=gl_programs(gl_plan), opened=gl_opened,
                                             texture_bytes=texture_bytes)
    return out


def calibrated_for(costs: BackendCosts, renderer: str) -> bool:
    """Whether ``costs``' GL constants can stand for ``renderer``: measured on it, or both are software
    renderers (llvmpipe is llvmpipe). A hardware GPU measured nowhere is not estimated from llvmpipe's."""
    return costs.renderer == renderer or (is_software_renderer(costs.renderer) and is_software_renderer(renderer))


def line(found: dict[str, Estimate], names: dict[str, str], chosen: str) -> str:
    """``auto: cpu 1.92 s, gl (llvmpipe …) 1.31 s (est.) → gl``: each backend's estimate and the choice."""
    parts = ", ".join(f"{names.get(b, b)} {format_seconds(e.seconds)}" for b, e in sorted(found.items()))
    return f"auto: {parts} (est.) → {chosen}"


__all__ = ["cpu_kernels", "gl_programs", "estimates", "calibrated_for", "line"]
