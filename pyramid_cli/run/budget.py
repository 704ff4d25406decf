"""The memory budget of a streamed run: ``--memory SIZE``, or what the process may use where it runs.

Without ``--memory`` every limit the process is under gives a budget and the smallest wins
(:func:`default_budget`):

- a cgroup v2 ``memory.max`` (the process's cgroup and each ancestor's: the one with the least left wins),
- a cgroup v1 ``memory.limit_in_bytes`` (and ancestors', and ``hierarchical_memory_limit`` of ``memory.stat``),
- ``RLIMIT_AS`` (address space: numba, LLVM and the threads' stacks reserve far more than they touch) and
  ``RLIMIT_DATA``,
- the memory available on the machine (``MemAvailable`` of /proc/meminfo).

A hard limit (a cgroup's, an rlimit) kills or fails the process when it is crossed, and the process is
typically alone under it (a container, a Slurm job): the budget is :data:`HARD_FRACTION` of what is left under
it after a :data:`RESERVE` for what a run adds beyond the working set the stream estimates
(:func:`pyramid_cli.run.stream.estimate`). The machine's memory is shared: the budget is a quarter of what is
available, at least :data:`FLOOR`, as before. "max" and huge values (cgroup v1's unlimited is
``PAGE_COUNTER_MAX`` pages) mean no limit; files that cannot be read give none.

Everything is read under a root folder (``root``, "/" by default) so that tests can feed made-up
/proc and /sys trees.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

from pyramid_cli.core.errors import DataError, UsageError
from pyramid_cli.core.machine import cgroup_chain, cgroup_paths, mounts, read_file

_UNITS = {"": 1, "B": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}
MIB = 1 << 20
FLOOR = 256 * MIB         # the least budget outside hard limits (the machine's memory), as before
SHARED_FRACTION = 0.25    # of the machine's available memory: other processes and the page cache keep the rest
HARD_FRACTION = 0.6       # of what is left under a hard limit, less its reserve: the estimate's error (see below)
#: Bytes kept back under each hard limit before :data:`HARD_FRACTION` is taken: what a run adds besides the
#: working set the stream estimates (an executor loaded after the budget is read, numba's kernels, the writers'
#: buffers: 30-100 MiB measured); address space (RLIMIT_AS) also takes the threads' stacks and malloc arenas
#: (350-450 MiB more than the working set, measured).
RESERVE = {"cgroup v2": 128 * MIB, "cgroup v1": 128 * MIB, "RLIMIT_DATA": 256 * MIB, "RLIMIT_AS": 512 * MIB}
UNLIMITED = 1 << 60       # limits at or above this are none (cgroup v1 writes 2**63 - 4096 for "no limit")


def parse_size(text: str) -> int:
    """Bytes in ``512M``, ``2G``, ``1.5GiB``, ``800000000`` (binary units; UsageError otherwise)."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([KMGT]?)(?:I?B)?\s*", str(text).upper())
    if not m:
        raise UsageError(f"--memory: expected a size such as 512M or 2G, not {text!r}")
    value = int(float(m.group(1)) * _UNITS[m.group(2)])
    if value <= 0:
        raise UsageError(f"--memory: the size must be positive, not {text!r}")
    return value


def format_size(n: float) -> str:
    """``n`` bytes in binary units, one decimal (``310.2 MiB``)."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if abs(n) < 1024 or unit == "TiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n} B"  # pragma: no cover - the loop always returns


@dataclass(frozen=True)
class Limit:
    """A limit the process is under: ``kind`` (``cgroup v2``, ``cgroup v1``, ``RLIMIT_AS``, ``RLIMIT_DATA``,
    ``available``), its ``size`` in bytes (None for the machine's available memory, which is no limit), the
    bytes ``left`` under it now, and ``where`` it was read (a file, or ``getrlimit``)."""

    kind: str
    size: int | None
    left: int
    where: str

    @property
    def hard(self) -> bool:
        """Whether crossing it kills or fails the process (every limit but the machine's available memory)."""
        return self.size is not None


@dataclass(frozen=True)
class Budget:
    """The bytes a run may hold (``size``) and what set them: ``limit`` (None when ``--memory`` gave them)."""

    size: int
    limit: Limit | None = None

    @property
    def source(self) -> str:
        """The limit's kind, or ``--memory``."""
        return "--memory" if self.limit is None else self.limit.kind

    def describe(self) -> str:
        """One line: the budget and the limit that set it."""
        head = f"memory budget {format_size(self.size)}"
        lim = self.limit
        if lim is None:
            return f"{head}: given by --memory"
        if lim.size is None:  # not hard: the machine's available memory
            return (f"{head}: a quarter of the {format_size(lim.left)} available on this machine ({lim.where}), "
                    f"at least {format_size(FLOOR)}")
        under = (f"the {format_size(lim.left)} left under the {lim.kind} limit of {format_size(lim.size)} "
                 f"({lim.where})")
        reserve = f"{format_size(RESERVE[lim.kind])} kept back for the process itself"
        usable = lim.left - RESERVE[lim.kind]
        if usable <= 0:
            return f"{head}: {under} is no more than the {reserve}"
        return f"{head}: {HARD_FRACTION:.0%} of {format_size(usable)}: {under}, less {reserve}"

    def refusal(self, err: DataError) -> DataError:
        """``err``, a job refused for not fitting this budget, naming what set the budget when a limit did (a
        container's limit is not the user's choice: the one line says where it came from)."""
        return err if self.limit is None else DataError(f"{err.message}; {self.describe()}")

    def to_json(self) -> dict:
        """``{"budget": bytes, "source": kind, "limit": bytes, "left": bytes, "where": text}`` (no limit's keys
        for ``--memory``)."""
        doc = {"budget": self.size, "source": self.source}
        if self.limit is not None:
            doc.update(limit=self.limit.size, left=self.limit.left, where=self.limit.where)
        return doc


def _number(text: str | None) -> int | None:
    """A limit file's value: None for "max", huge values and unreadable or malformed text."""
    if text is None:
        return None
    try:
        value = int(text.split()[0])
    except (ValueError, IndexError):
        return None
    return value if 0 <= value < UNLIMITED else None


def _stat(text: str | None) -> dict[str, int]:
    out = {}
    for line in (text or "").splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[1].isdigit():
            out[parts[0]] = int(parts[1])
    return out


def _proc_field(root: str, name: str) -> int | None:
    """A ``kB`` field of /proc/self/status (``VmSize``, ``VmData``), in bytes."""
    for line in (read_file(root, "/proc/self/status") or "").splitlines():
        if line.startswith(name + ":"):
            try:
                return int(line.split()[1]) * 1024
            except (ValueError, IndexError):
                return None
    return None


def memory_cgroups(root: str = "/") -> dict[str, str]:
    """The folders of the process's own cgroup where memory is limited: ``{"cgroup v2": folder}`` when the
    unified hierarchy is mounted, ``{"cgroup v1": folder}`` when the v1 memory controller is (either or both)."""
    paths = cgroup_paths(root)
    out: dict[str, str] = {}
    if "" in paths:
        for mount_root, point, _ in mounts(root, "cgroup2"):
            out.setdefault("cgroup v2", cgroup_chain(mount_root, point, paths[""])[0])
    if "memory" in paths:
        for mount_root, point, options in mounts(root, "cgroup"):
            if "memory" in options:
                out.setdefault("cgroup v1", cgroup_chain(mount_root, point, paths["memory"])[0])
    return out


def _tightest(limits: list[Limit]) -> Limit | None:
    return min(limits, key=lambda lim: lim.left, default=None)


def cgroup_v2(root: str = "/") -> Limit | None:
    """The tightest ``memory.max`` of the process's cgroup v2 and its ancestors: ``left`` is the limit less
    ``memory.current`` of the same cgroup (less its reclaimable ``inactive_file`` page cache)."""
    path = cgroup_paths(root).get("")
    if path is None:
        return None
    found = []
    for mount_root, point, _ in mounts(root, "cgroup2"):
        for folder in cgroup_chain(mount_root, point, path):
            size = _number(read_file(root, os.path.join(folder, "memory.max")))
            used = _number(read_file(root, os.path.join(folder, "memory.current")))
            if size is None or used is None:
                continue
            used -= min(used, _stat(read_file(root, os.path.join(folder, "memory.stat"))).get("inactive_file", 0))
            found.append(Limit("cgroup v2", size, max(0, size - used), os.path.join(folder, "memory.max")))
    return _tightest(found)


def cgroup_v1(root: str = "/") -> Limit | None:
    """The tightest ``memory.limit_in_bytes`` of the process's cgroup v1 memory controller and its ancestors,
    or ``hierarchical_memory_limit`` of ``memory.stat`` (ancestors above the mount): ``left`` is the limit less
    ``memory.usage_in_bytes`` (less its reclaimable ``total_inactive_file`` page cache)."""
    path = cgroup_paths(root).get("memory")
    if path is None:
        return None
    found = []
    for mount_root, point, options in mounts(root, "cgroup"):
        if "memory" not in options:
            continue
        for i, folder in enumerate(cgroup_chain(mount_root, point, path)):
            used = _number(read_file(root, os.path.join(folder, "memory.usage_in_bytes")))
            if used is None:
                continue
            stat = _stat(read_file(root, os.path.join(folder, "memory.stat")))
            used -= min(used, stat.get("total_inactive_file", stat.get("inactive_file", 0)))
            size = _number(read_file(root, os.path.join(folder, "memory.limit_in_bytes")))
            if size is not None:
                found.append(Limit("cgroup v1", size, max(0, size - used),
                                   os.path.join(folder, "memory.limit_in_bytes")))
            hierarchical = _number(str(stat["hierarchical_memory_limit"])) if (
                i == 0 and "hierarchical_memory_limit" in stat) else None
            if hierarchical is not None and hierarchical != size:
                found.append(Limit("cgroup v1", hierarchical, max(0, hierarchical - used),
                                   os.path.join(folder, "memory.stat") + " hierarchical_memory_limit"))
    return _tightest(found)


def rlimits(root: str = "/") -> list[Limit]:
    """``RLIMIT_AS`` (less ``VmSize``) and ``RLIMIT_DATA`` (less ``VmData``) where set (soft limits)."""
    try:
        import resource
    except ImportError:  # pragma: no cover - not POSIX
        return []
    out = []
    for name, field in (("RLIMIT_AS", "VmSize"), ("RLIMIT_DATA", "VmData")):
        try:
            soft = resource.getrlimit(getattr(resource, name))[0]
        except (AttributeError, ValueError, OSError):
            continue
        if soft == resource.RLIM_INFINITY or soft < 0 or soft >= UNLIMITED:
            continue
        used = _proc_field(root, field) or 0
        out.append(Limit(name, soft, max(0, soft - used), f"getrlimit({name}), {field} from /proc/self/status"))
    return out


def available(root: str = "/") -> Limit:
    """The memory available on the machine now: ``MemAvailable`` of /proc/meminfo, else physical memory."""
    for line in (read_file(root, "/proc/meminfo") or "").splitlines():
        if line.startswith("MemAvailable:"):
            try:
                return Limit("available", None, int(line.split()[1]) * 1024, "MemAvailable of /proc/meminfo")
            except (ValueError, IndexError):
                break
    try:
        physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        physical = 4 << 30
    return Limit("available", None, physical, "physical memory")


def limits(root: str = "/") -> list[Limit]:
    """Every limit the process is under (see the module), the machine's available memory last."""
    found = [cgroup_v2(root), cgroup_v1(root), *rlimits(root)]
    return [lim for lim in found if lim is not None] + [available(root)]


def budget_under(limit: Limit) -> int:
    """The budget a limit gives: :data:`HARD_FRACTION` of what is left under a hard limit after its
    :data:`RESERVE`; :data:`SHARED_FRACTION` of the machine's available memory, at least :data:`FLOOR`."""
    if limit.hard:
        return max(0, int(HARD_FRACTION * (limit.left - RESERVE[limit.kind])))
    return max(FLOOR, int(SHARED_FRACTION * limit.left))


def default_budget(root: str = "/") -> Budget:
    """The budget without ``--memory``: the smallest any limit gives (:func:`budget_under`), and that limit."""
    best = min(limits(root), key=budget_under)
    return Budget(budget_under(best), best)


def resolve(memory: int | None, root: str = "/") -> Budget:
    """``memory`` bytes as given (``--memory``), else :func:`default_budget`."""
    return Budget(memory) if memory is not None else default_budget(root)


def available_memory() -> int:
    """Bytes of memory available on the machine now (``MemAvailable`` of /proc/meminfo; else physical memory)."""
    return available().left


def default_memory() -> int:
    """The budget's bytes when ``--memory`` is not given (:func:`default_budget`)."""
    return default_budget().size


__all__ = ["Budget", "Limit", "parse_size", "format_size", "memory_cgroups", "cgroup_v2", "cgroup_v1", "rlimits",
           "available", "limits", "budget_under", "default_budget", "resolve", "available_memory", "default_memory"]
