"""The ``pyramid`` group: its help, its version, one line per error with the exit code of its kind, and the
console script's entry point. The commands are added to it by :mod:`pyramid_cli.cli`."""

from __future__ import annotations

import gc
import os
import sys

import click

from pyramid_cli.core.errors import EXIT_CODES, PyramidError
from pyramid_cli.core.version import __version__

EXIT_CODE_HELP = "\b\nExit codes:\n" + "\n".join(f"  {code}  {text}" for code, text in EXIT_CODES.values())


class Group(click.Group):
    """The command group: a :class:`~pyramid_cli.core.errors.PyramidError` is one line and its exit code; Ctrl-C
    and SIGTERM/SIGHUP are one line and 130/143/129."""

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except PyramidError as e:
            click.echo(f"pyramid: error: {e}", err=True)
            ctx.exit(e.exit_code)
        except KeyboardInterrupt as e:  # Ctrl-C, and SIGTERM/SIGHUP after signals.install()
            from pyramid_cli.core.signals import describe, exit_code
            click.echo(f"pyramid: {describe(e)}", err=True)
            ctx.exit(exit_code(e))


@click.group(cls=Group, epilog=EXIT_CODE_HELP,
             context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, package_name="bilinear-pyramid", prog_name="pyramid")  # no metadata read
def main() -> None:
    """Image pyramids from bilinear texture passes (Kraus & Strengert, GRAPP 2007).

    \b
    Expressions use the paper's notation or an ASCII spelling:
      ⊗  *  (x)     convolution           h_Bartlett ⊗ g      bartlett * g
      ⊗↓ *v (x)v    analysis (reduce)     h_quadratic ⊗↓ g    quadratic *v g
      ⊗↓ᵐ *v^m      one step of stride 2ᵐ h_box ⊗↓² g         box *v^2 g
      ⊗↑ *^ (x)^    synthesis (expand)    h_Doo-Sabin ⊗↑ g    doosabin *^ g
      (h)ᵐ (h)^m    m repeated steps      (h_box^{4×4})² ⊗↓ g (box4)^2 *v g
      box↘ box\\ box^se, box↖ box^nw; 1/4 [1 1; 1 1] is a written mask.
    Chains are right-associative: 'box\\ *v bartlett' is box↘ ⊗↓ (bartlett ⊗ g).

    \b
    Filters: box box↖ bartlett gauss5 gauss7 quasi (⊗); box box4 quadratic
    cubic (⊗↓); nearest midpoint doosabin cubic fourpoint (⊗↑).

    \b
    Example:
      pyramid explain 'h_box^↘ ⊗↓ (h_Bartlett ⊗ g)'
      pyramid apply 'quadratic *v g' in.exr half.exr
      pyramid blur --levels 5 in.exr soft.exr
    """


def run() -> None:
    """The console script's entry point (``pyramid``).

    Every run ends without the interpreter's teardown (:func:`~pyramid_cli.core.signals.end`). An interrupted
    one, once its own clean-up is done (temporaries removed, outputs closed, the one line said): libraries' C++
    destructors at exit (OpenImageIO's and OpenEXR's thread pools) could find a thread still busy and abort the
    process ("terminate called without an active exception", SIGABRT instead of exit 143). Any other, after
    the atexit handlers: the teardown only frees what the process is about to give back, 0.1 to 0.2 s where
    numba's kernels were loaded."""
    # No BLAS call is made, but numpy's OpenBLAS starts a thread per core at import that spins for a while: 0.05 to
    # 0.16 CPU seconds of a run (measured, fresh processes interleaved). Only where the user has not chosen.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    reuse_freed_blocks()
    _startup_without_collector()
    from pyramid_cli.core.signals import end, guard_streams, install
    install()  # SIGTERM/SIGHUP clean up like Ctrl-C (exit 143/129); SIGXFSZ ignored
    guard_streams()  # a reader closing stdout (| head) drops the lines, not the frames
    try:
        main(prog_name="pyramid")
    except SystemExit as e:
        end(e.code)
        raise


# glibc's mallopt parameters (malloc.h) and what reuse_freed_blocks sets them to
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
MMAP_THRESHOLD, TRIM_THRESHOLD = 32 << 20, 64 << 20


def reuse_freed_blocks() -> None:
    """glibc's malloc made to keep the blocks a run frees, up to 32 MiB each, for the blocks it asks for next.

    Left to itself, glibc maps every block over a threshold it raises to the largest block freed so far, and
    unmaps it when freed: a band engine's next band of the same size then starts on fresh pages the kernel must
    zero. Where the input's bands were smaller than a level's (8-bit codes), every level band of an 8K Deep Zoom
    did: 46,000 page faults, 0.31–0.34 s of system time. With the mapping threshold fixed at 32 MiB and the
    heap's top trimmed past 64 MiB free: 0.18–0.23 s, 8–11 % less CPU and time at the same peak memory (12
    interleaved fresh runs, 2026-11-28). Linux with glibc only, and not where the user set
    ``MALLOC_MMAP_THRESHOLD_`` or ``MALLOC_TRIM_THRESHOLD_``."""
    if not sys.platform.startswith("linux") or any(k in os.environ for k in (
            "MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_")):
        return
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc
        return
    mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)
    mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD)


_COLLECTOR = {"off": False}  # whether run() turned the cyclic garbage collector off for the imports


def _startup_without_collector() -> None:
    """The cyclic garbage collector off while a command imports what it runs with (numpy, OpenImageIO, the run
    layer: 31,000 objects that live as long as the process, at an 8K ``pyramid tiles``'s first band), back on
    with them frozen when its work starts (:func:`collector_on`). It walked them in 84 collections: 25 ms of
    that run's start (the median ``time.process_time`` at its first band, 25 fresh runs each way)."""
    if gc.isenabled():
        gc.disable()
        _COLLECTOR["off"] = True


def collector_on() -> None:
    """The cyclic garbage collector back on where :func:`run` turned it off (a command's work starts: its session
    is opened, or it has no session), the objects made so far frozen out of its walks (:func:`gc.freeze`);
    nothing otherwise (``main`` called from Python, a test's runner)."""
    if _COLLECTOR["off"]:
        _COLLECTOR["off"] = False
        gc.freeze()
        gc.enable()


__all__ = ["EXIT_CODE_HELP", "Group", "collector_on", "main", "reuse_freed_blocks", "run"]
