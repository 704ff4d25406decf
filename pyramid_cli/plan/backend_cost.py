"""Which executor finishes a job first: each backend's fixed and per-pixel costs on this machine.

``auto`` (:mod:`pyramid_cli.exec.auto`) estimates the same job on the compiled CPU executor and on
the GL executor and runs the cheaper. Reading and writing the files costs the same on both and is
left out. With ``values`` a pass's written floats (stored target pixels × channels) and ``linear``,
``nearest`` the bilinear and single-texel fetches a pixel executes (:func:`pyramid_cli.plan.pass_measures`)::

    cpu = import_s (numba, once a process) + loads · kernel_load_s + compiles · kernel_compile_s
        + jobs · Σ_passes [pass_s + values · (value_s + linear · linear_s + nearest · nearest_s)] · threads₀ / threads
        + fresh · fresh_byte_s
    gl  = context_s (moderngl and an EGL context, once a process) + programs · program_s
        + jobs · groups · [uploaded · upload_s + Σ_passes pass model + read back · readback_s]
        + fresh · fresh_byte_s

``groups`` is ⌈channels / 4⌉ (GL runs RGBA textures), the pass model is the planner's
(:mod:`pyramid_cli.plan.cost`), ``fresh`` the bytes a first job touches for the first time (new
arrays, the texture pool: page faults, about a second per GB on these machines), ``threads₀`` the
threads the CPU constants were measured with.

The constants ship in ``backend_costs.json`` beside this module, measured on the machine the
package was calibrated on; ``make calibrate`` (``bench/calibrate.py --write``) measures them
on the user's machine and stores them in the cache folder (:func:`machine_file`), where
:func:`load` finds them first. Pure Python: no GL, no numba, no numpy.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, fields
from functools import cache
from pathlib import Path

from pyramid_cli.core import cache as disk
from pyramid_cli.core import resources
from pyramid_cli.plan import cost
from pyramid_cli.plan.estimate import pass_measures
from pyramid_cli.plan.model import Plan

COSTS_FILE = "backend_costs.json"
CACHE_FOLDER = "calibration"
CACHE_ENTRY = "backends.json"
BYTES_PER_VALUE = 4      # float32 intermediates on both executors
TEXEL_BYTES = 16         # an RGBA32F texel


@dataclass(frozen=True)
class CPUCosts:
    """The compiled CPU executor's constants (seconds; see the module)."""

    import_s: float          # importing numba (and llvmlite) in a fresh process
    kernel_load_s: float     # per kernel loaded from numba's disk cache
    kernel_compile_s: float  # per kernel compiled (a machine's first run)
    pass_s: float            # per pass: calls, border windows, thread hand-offs
    value_s: float           # per written float (pixel × channel)
    linear_s: float          # per written float per bilinear fetch (up to four texel reads)
    nearest_s: float         # per written float per single-texel fetch
    fresh_byte_s: float      # per byte of new arrays (page faults of a first job)
    threads: int = 2         # the threads the per-value constants were measured with


@dataclass(frozen=True)
class GLCosts:
    """The GL executor's constants beside the planner's pass model (seconds; see the module)."""

    context_s: float         # importing moderngl and making the EGL context
    program_s: float         # per program compiled (one per pass shape)
    upload_s: float          # per input texel uploaded (through the staging band)
    readback_s: float        # per output texel read back
    fresh_byte_s: float      # per byte of the texture pool's new textures (page faults on llvmpipe)


@dataclass(frozen=True)
class BackendCosts:
    """Both backends' constants, and where they were measured."""

    cpu: CPUCosts
    gl: GLCosts
    passes: cost.CostModel   # the GL passes' model (the planner's, or this machine's calibration)
    renderer: str            # the GL renderer the GL constants were measured on
    source: str = "shipped"  # "shipped" (the package's defaults) or the machine file's path


@dataclass(frozen=True)
class Estimate:
    """Seconds a backend is estimated to take for a job (I/O left out)."""

    backend: str
    fixed_s: float    # once a process: imports, context, kernels or programs
    first_s: float    # once a batch: fresh memory of the first job
    job_s: float      # every job
    jobs: int = 1

    @property
    def seconds(self) -> float:
        """The whole estimate: fixed + first + jobs · job."""
        return self.fixed_s + self.first_s + self.jobs * self.job_s


def cpu_estimate(c: CPUCosts, plan: Plan, channels: int, *, jobs: int = 1, threads: int | None = None,
                 loads: int = 0, compiles: int = 0, imported: bool = False) -> Estimate:
    """The CPU executor's :class:`Estimate` of ``jobs`` runs of ``plan`` on ``channels``-channel inputs:
    ``loads`` kernels loaded and ``compiles`` compiled first, numba ``imported`` already or not."""
    scale = c.threads / max(1, threads) if threads else 1.0
    job = fresh = 0.0
    for ps in plan.passes:
        _, (h, w), linear, nearest, _ = pass_measures(plan.images, ps)
        values = h * w * channels
        job += c.pass_s + values * (c.value_s + linear * c.linear_s + nearest * c.nearest_s) * scale
        fresh += values * BYTES_PER_VALUE
    fixed = (0.0 if imported else c.import_s) + loads * c.kernel_load_s + compiles * c.kernel_compile_s
    return Estimate("cpu", fixed, fresh * c.fresh_byte_s, job, jobs)


def pool_bytes(plan: Plan, texture_bytes) -> int:
    """Bytes of the textures one run of ``plan`` puts in the GL executor's pool (held at once, reused by
    size as :meth:`~pyramid_cli.exec.gl.GLExecutor.prepare` does); ``texture_bytes(stored)`` per image."""
    free: dict[int, int] = {}
    total = 0

    def acquire(k: int) -> int:
        nonlocal total
        size = texture_bytes(plan.images[k].stored)
        if free.get(size):
            free[size] -= 1
        else:
            total += size
        return size

    held = {k: acquire(k) for k in plan.inputs}
    for ps, done in zip(plan.passes, plan.releases(), strict=True):
        held[ps.target] = acquire(ps.target)
        for s in done:
            size = held.pop(s, None)
            if size is not None:
                free[size] = free.get(size, 0) + 1
    return total


def gl_estimate(c: GLCosts, passes: cost.CostModel, plan: Plan, channels: int, *, jobs: int = 1,
                programs: int = 0, opened: bool = False, texture_bytes=None) -> Estimate:
    """The GL executor's :class:`Estimate` of ``jobs`` runs of ``plan`` on ``channels``-channel inputs,
    ``programs`` compiled first, the context ``opened`` already or not; ``texture_bytes(stored)``: the
    bytes of an image's texture (default: RGBA32F of its stored extent)."""
    groups = max(1, math.ceil(channels / 4))
    uploaded = sum(plan.images[k].stored[0] * plan.images[k].stored[1] for k in plan.inputs)
    read = sum(plan.images[k].size[0] * plan.images[k].size[1] for k in plan.outputs if k not in plan.inputs)
    rendering = sum(passes.pass_seconds(*pass_measures(plan.images, ps)) for ps in plan.passes)
    job = groups * (uploaded * c.upload_s + rendering + read * c.readback_s)
    sizes = texture_bytes or (lambda stored: stored[0] * stored[1] * TEXEL_BYTES)
    fixed = (0.0 if opened else c.context_s) + programs * c.program_s
    return Estimate("gl", fixed, pool_bytes(plan, sizes) * c.fresh_byte_s, job, jobs)


# ------------------------------------------------------------------ the constants
def from_dict(d: dict, source: str = "shipped") -> BackendCosts:
    """:class:`BackendCosts` from the JSON object ``bench/calibrate.py`` writes; ValueError when malformed."""
    try:
        cpu = CPUCosts(**{f.name: d["cpu"][f.name] for f in fields(CPUCosts)})
        gl = GLCosts(**{f.name: d["gl"][f.name] for f in fields(GLCosts)})
        passes = cost.from_dict(d["passes"]) if "passes" in d else cost.model()
        renderer = str(d["renderer"])
    except (KeyError, TypeError) as e:
        raise ValueError(f"{COSTS_FILE}: missing or malformed {e}") from None
    for part in (cpu, gl):
        for f in fields(part):
            v = getattr(part, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= 0:
                raise ValueError(f"{COSTS_FILE}: {f.name} must be a non-negative number, not {v!r}")
    if not isinstance(cpu.threads, int) or cpu.threads < 1:
        raise ValueError(f"{COSTS_FILE}: cpu.threads must be an integer >= 1, not {cpu.threads!r}")
    return BackendCosts(cpu, gl, passes, renderer, source)


def shipped_dict() -> dict:
    """The package's ``backend_costs.json`` as a dict."""
    return resources.json_file(__package__, COSTS_FILE)


def machine_file() -> Path:
    """Where ``make calibrate`` stores this machine's constants (the cache folder's ``calibration``)."""
    return disk.folder(CACHE_FOLDER) / CACHE_ENTRY


def load(driver_key: str | None = None) -> BackendCosts:
    """This machine's constants (:func:`machine_file`) when there are any, valid and measured with this
    ``driver_key`` (:func:`pyramid_cli.exec.gl.context.driver_key`) when one is given; else the shipped ones.
    Read once per process (per cache folder and key)."""
    return _load(str(machine_file()), driver_key)


@cache
def _load(path: str, driver_key: str | None) -> BackendCosts:
    try:
        raw = Path(path).read_bytes()
    except OSError:
        raw = None
    if raw is not None:
        try:
            d = json.loads(raw)
            if driver_key is None or d.get("driver_key") == driver_key:
                return from_dict(d, source=path)
        except (ValueError, AttributeError):
            pass  # corrupt or of another driver: the shipped defaults
    return from_dict(shipped_dict())


__all__ = ["BackendCosts", "CPUCosts", "GLCosts", "Estimate", "cpu_estimate", "gl_estimate", "pool_bytes", "from_dict",
           "shipped_dict", "machine_file", "load", "COSTS_FILE", "CACHE_FOLDER", "CACHE_ENTRY"]
