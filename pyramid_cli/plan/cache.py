"""Plans made once: kept in this process and on disk, by job, sizes, strategy and planner.

A plan is exact Fraction algebra (recipes checked against their masks, bilinear fits, guard
bands, a MIP level's resampling tables), redone by every process that runs the same job: a
few milliseconds for a blur, 0.1–0.2 s for a fill or a blend, up to a second for the MIP map
of an odd-sized picture. :func:`cached` keeps each plan in a small in-process memo (a batch of
same-sized files plans once) and as an entry of the cache folder's ``plans`` sub-folder
(:func:`pyramid_cli.core.cache.folder`), so the next process reads it back instead.

An entry's name is a digest of everything that determines the plan (:func:`plan_key`): the
job's canonical description (its class and compared fields, recursively; an expression's
source position is not one), the input sizes, the strategy, the cost model's constants (for
the strategy that weighs recipes by them), the package version, a digest of the planner's
sources (:func:`pyramid_cli.core.fingerprint.sources`: an edited checkout never reads a stale
plan) and :data:`FORMAT`. The entry is JSON written by :func:`encode` for the Plan's own
classes only (no pickle: nothing in the folder can run code), repeats that key in full, and is
read back by :func:`decode`, which checks every value's type and the plan's invariants; an
entry that is truncated, corrupt, of another version or of another key is recomputed and
rewritten, never trusted. Writes are atomic (:func:`pyramid_cli.core.cache.write`); a folder
that cannot be written only costs the speed-up. The folder keeps at most :data:`MAX_ENTRIES`
entries, the least recently used going first.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import os
import threading
from collections import OrderedDict
from collections.abc import Callable
from fractions import Fraction

from pyramid_cli.core import cache as disk
from pyramid_cli.core import fingerprint
from pyramid_cli.core.version import __version__
from pyramid_cli.plan.model import Image, Pass, Plan, PointwisePass, ResamplePass, Tap, check

FORMAT = 1            # the entry's layout: raise it when encode's output changes meaning
FOLDER = "plans"      # the sub-folder of the cache root
MEMO_SIZE = 64        # plans kept in this process
MAX_ENTRIES = 512     # entries kept on disk (the least recently used are removed beyond it)
SOURCES = ("core", "plan", "workflows", "jobs")  # the package folders whose code makes plans
MODEL_FREE = ("paper", "fused")  # strategies that plan without the cost model

_memo: OrderedDict[str, Plan | None] = OrderedDict()
_lock = threading.Lock()


# ---------------------------------------------------------------- the key
def canonical(value: object) -> object:
    """A value's description for a key: dataclasses by class and compared fields, enums by class and
    value, containers element-wise (dicts sorted); anything else by ``repr``."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        cls = type(value)
        return (f"{cls.__module__}.{cls.__qualname__}",
                tuple((f.name, canonical(getattr(value, f.name))) for f in dataclasses.fields(value) if f.compare))
    if isinstance(value, enum.Enum):
        return (f"{type(value).__module__}.{type(value).__qualname__}", value.value)
    if isinstance(value, (tuple, list)):
        return tuple(canonical(v) for v in value)
    if isinstance(value, dict):
        return tuple(sorted((repr(k), canonical(v)) for k, v in value.items()))
    return repr(value)


def plan_key(work: object, sizes, strategy: str) -> str:
    """The full description of a plan (see the module): what an entry's name digests and its text repeats.

    The cost model's constants are part of it where the strategy consults them: every strategy but
    :data:`MODEL_FREE` ("paper" and "fused" never weigh recipes, so a CPU run never loads the model)."""
    sizes = tuple(tuple(int(n) for n in s[:2]) for s in sizes)
    model = None
    if strategy not in MODEL_FREE:
        from pyramid_cli.plan import cost

        model = canonical(cost.model())
    return repr(("plan", FORMAT, __version__, fingerprint.sources(*SOURCES), canonical(work), sizes, strategy,
                 model))


# ---------------------------------------------------------------- the entry
class _Fractions:
    """Each distinct Fraction once: an entry stores indices into a table of ``[numerator, denominator]``."""

    def __init__(self) -> None:
        self.index: dict[Fraction, int] = {}
        self.table: list[list[int]] = []

    def __call__(self, f: Fraction) -> int:
        if type(f) is not Fraction:
            raise TypeError(f"a plan holds Fractions here, not {type(f).__name__}")
        i = self.index.get(f)
        if i is None:
            i = self.index[f] = len(self.table)
            self.table.append([f.numerator, f.denominator])
        return i


def _pair(v) -> list[int]:
    a, b = v
    return [int(a), int(b)]


def encode(p: Plan | None) -> dict:
    """A plan as plain JSON data (TypeError for anything a Plan does not hold)."""
    if p is None:
        return {"plan": None}
    frac = _Fractions()
    passes = []
    for ps in p.passes:
        if type(ps) is Pass:
            phases = [[*_pair(ph), [[t.source, frac(t.offset[0]), frac(t.offset[1]), frac(t.weight), bool(t.linear)]
                                    for t in taps]] for ph, taps in ps.phases.items()]
            passes.append(["pass", ps.label, ps.target, _pair(ps.period), _pair(ps.stride), phases, ps.why])
        elif type(ps) is PointwisePass:
            passes.append(["pointwise", ps.label, ps.target, ps.op, list(ps.srcs), frac(ps.param), ps.why])
        elif type(ps) is ResamplePass:
            passes.append(["resample", ps.label, ps.target, ps.source, ps.axis, list(ps.starts),
                           [[frac(w) for w in row] for row in ps.weights], ps.why])
        else:
            raise TypeError(f"no encoding for a {type(ps).__name__}")
    if p.paper_fetches is not None and type(p.paper_fetches) is not float:
        raise TypeError("paper_fetches is a float or None")
    images = [[*_pair(im.size), [int(g) for g in im.guard], im.border] for im in p.images]
    return {"plan": {"images": images, "passes": passes, "expression": p.expression, "paper": p.paper_fetches,
                     "outputs": list(p.outputs), "inputs": list(p.inputs), "border": p.border,
                     "fractions": frac.table}}


def _ints(*values) -> None:
    for v in values:
        if type(v) is not int:
            raise ValueError(f"an integer, not {v!r}")


def _strs(*values) -> None:
    for v in values:
        if type(v) is not str:
            raise ValueError(f"a string, not {v!r}")


def _ints2(v) -> tuple[int, int]:
    a, b = v
    _ints(a, b)
    return a, b


def decode(doc: dict) -> Plan | None:
    """The plan :func:`encode` described, every value of its type (anything else raises ValueError,
    TypeError, KeyError or IndexError)."""
    d = doc["plan"]
    if d is None:
        return None
    fr = []
    for n, m in d["fractions"]:
        _ints(n, m)
        fr.append(Fraction(n, m))

    def f(i) -> Fraction:
        _ints(i)
        if not 0 <= i < len(fr):
            raise IndexError(f"no fraction {i}")
        return fr[i]

    def row_of(indices) -> tuple[Fraction, ...]:  # a resampling table's row at once (MIP maps hold thousands)
        if not all(type(i) is int for i in indices) or (indices and min(indices) < 0):
            raise ValueError("a table row holds fraction indices")
        return tuple(map(fr.__getitem__, indices))

    passes: list[Pass | ResamplePass | PointwisePass] = []
    for e in d["passes"]:
        kind = e[0]
        if kind == "pass":
            _, label, target, period, stride, phases, why = e
            _ints(target)
            _strs(label, why)
            table = {}
            for r, c, taps in phases:
                _ints(r, c)
                table[(r, c)] = [Tap(s, (f(o0), f(o1)), f(w), lin) for s, o0, o1, w, lin in taps]
                for s, *_, lin in taps:
                    _ints(s)
                    if type(lin) is not bool:
                        raise ValueError(f"a bool, not {lin!r}")
            passes.append(Pass(label, target, _ints2(period), _ints2(stride), table, why))
        elif kind == "pointwise":
            _, label, target, op, srcs, param, why = e
            _ints(target, *srcs)
            _strs(label, op, why)
            passes.append(PointwisePass(label, target, op, tuple(srcs), f(param), why))
        elif kind == "resample":
            _, label, target, source, axis, starts, weights, why = e
            _ints(target, source, axis, *starts)
            _strs(label, why)
            passes.append(ResamplePass(label, target, source, axis, tuple(starts),
                                       tuple(map(row_of, weights)), why))
        else:
            raise ValueError(f"unknown pass kind {kind!r}")
    images = []
    for r, c, guard, border in d["images"]:
        _ints(r, c, *guard)
        _strs(border)
        if len(guard) != 4:
            raise ValueError("a guard band has four sides")
        images.append(Image((r, c), list(guard), border))
    paper = d["paper"]
    if paper is not None and type(paper) is not float:
        raise ValueError(f"paper fetches {paper!r}")
    _ints(*d["outputs"], *d["inputs"])
    _strs(d["expression"], d["border"])
    p = Plan(images, passes, d["expression"], paper, list(d["outputs"]), list(d["inputs"]), d["border"])
    check(p)  # the invariants every executor relies on (AssertionError)
    return p


def entry_name(key: str) -> str:
    """The file name of the entry of ``key``."""
    return disk.key(key) + ".json"


def load(key: str) -> tuple[bool, Plan | None]:
    """``(True, plan)`` from the entry of ``key``; ``(False, None)`` when there is none, or it is
    unreadable, corrupt, or another key's (another version's, another format's)."""
    data = disk.read(FOLDER, entry_name(key))
    if data is None:
        return False, None
    try:
        doc = json.loads(data.decode("utf-8"))
        if doc["key"] != key:
            return False, None
        p = decode(doc)
    except Exception:  # anything wrong with an entry (truncated, corrupt, tampered with) means recompute it
        return False, None
    try:  # the least recently used entries go first when the folder is pruned
        os.utime(disk.folder(FOLDER) / entry_name(key))
    except OSError:
        pass
    return True, p


def store(key: str, p: Plan | None) -> bool:
    """Write the entry of ``key`` (False when the plan cannot be encoded or the folder not written)."""
    try:
        doc = {"key": key, **encode(p)}
    except (TypeError, ValueError):
        return False
    data = json.dumps(doc, ensure_ascii=False, separators=(",", ":")).encode("utf-8")
    if not disk.write(FOLDER, entry_name(key), data):
        return False
    prune()
    return True


def prune(keep: int = MAX_ENTRIES) -> None:
    """Remove the least recently used entries beyond ``keep`` (silently: another process may race)."""
    try:
        with os.scandir(disk.folder(FOLDER)) as it:
            entries = [e for e in it if e.name.endswith(".json") and not e.name.startswith(".")]
        if len(entries) <= keep:
            return
        entries.sort(key=lambda e: e.stat().st_mtime_ns)
        for e in entries[:len(entries) - keep]:
            os.unlink(e.path)
    except OSError:
        pass


# ---------------------------------------------------------------- the cache
def cached(work: object, sizes, strategy: str, build: Callable[[], Plan | None]) -> Plan | None:
    """``work``'s plan for inputs of ``sizes`` by ``strategy``: from this process's memo, else the
    disk entry, else ``build()`` (then kept in both). The same key gives the same plan object in
    one process, as the planner's own caches did. A job class defined outside the package (a caller's
    own :class:`~pyramid_cli.jobs.work.Work`) is kept in the process only: its code is not in the key."""
    key = plan_key(work, sizes, strategy)
    with _lock:
        if key in _memo:
            _memo.move_to_end(key)
            return _memo[key]
    # on disk only the package's own jobs: the digest of the sources covers their code, not a caller's subclass
    persist = type(work).__module__.startswith("pyramid_cli.")
    found, p = load(key) if persist else (False, None)
    if not found:
        p = build()
        if persist:
            store(key, p)
    with _lock:
        p = _memo.setdefault(key, p)
        while len(_memo) > MEMO_SIZE:
            _memo.popitem(last=False)
    return p


def clear_memo() -> None:
    """Forget the plans kept in this process (the disk entries stay)."""
    with _lock:
        _memo.clear()


__all__ = ["FORMAT", "FOLDER", "MAX_ENTRIES", "MEMO_SIZE", "SOURCES", "MODEL_FREE", "canonical", "plan_key",
           "encode", "decode", "entry_name", "load", "store", "prune", "cached", "clear_memo"]
