"""The jobs of a batch: one input and its output each, the report of what became of them, and the inputs
a command line names (globs expanded). The batch runner (:mod:`pyramid_cli.run.batch`) and frame sequences
(:mod:`pyramid_cli.run.sequence`) both build on these.
"""

from __future__ import annotations

import glob
import os
from dataclasses import dataclass, field

from pyramid_cli.core.errors import InputError, PyramidError

#: The characters that make an input a glob pattern (expanded here, so Makefiles need no shell globbing).
GLOB_CHARS = set("*?[")


@dataclass
class Job:
    """One input and the output it becomes."""

    input: str
    output: str


@dataclass
class Report:
    """What a batch did: the jobs done, skipped (up to date) and failed (with their errors)."""

    done: list[Job] = field(default_factory=list)
    skipped: list[Job] = field(default_factory=list)
    failed: list[tuple[Job, PyramidError]] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        return self.failed[0][1].exit_code if self.failed else 0

    def extend(self, other: Report) -> None:
        """Add what ``other`` did (a later part of the same batch)."""
        self.done += other.done
        self.skipped += other.skipped
        self.failed += other.failed


def expand(patterns: list[str]) -> list[str]:
    """Input paths; quoted glob patterns are expanded here (sorted), so Makefiles need no shell globbing."""
    out: list[str] = []
    for p in patterns:
        if GLOB_CHARS & set(p):
            found = sorted(glob.glob(p))
            if not found:
                raise InputError(f"{p}: no file matches this pattern")
            out += found
        else:
            out.append(p)
    return out


def is_fresh(job: Job) -> bool:
    """Is the output newer than its input (make's rule)?"""
    try:
        return os.path.getmtime(job.output) >= os.path.getmtime(job.input)
    except OSError:
        return False


__all__ = ["GLOB_CHARS", "Job", "Report", "expand", "is_fresh"]
