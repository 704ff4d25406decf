"""Border modes and their one name table (docs/design.md §1: clamp is the default).

Each mode maps a 1-based index, possibly outside ``1..n``, to a 1-based index
inside, or to ``0`` meaning "zero outside" (the convention for masks treated as
images).
"""

from __future__ import annotations

from enum import Enum

from pyramid_cli.core.errors import UsageError


class Border(Enum):
    CLAMP = "clamp"     # GL CLAMP_TO_EDGE, Halide repeat_edge
    MIRROR = "mirror"   # GL MIRRORED_REPEAT, Halide mirror_image: 1 2 3 | 3 2 1
    WRAP = "wrap"       # GL REPEAT, Halide repeat_image
    ZERO = "zero"       # GL CLAMP_TO_BORDER with 0, Halide constant_exterior

    @classmethod
    def parse(cls, name: str) -> Border:
        return cls(name.lower())


BORDER_NAMES = [b.value for b in Border]

# Other libraries' names for our modes, each exactly equal (the API accepts them; the CLI takes ours): numpy.pad's
# and scikit-image's "edge" and "symmetric" (d c b a | a b c d, the edge sample repeated: GL's MIRRORED_REPEAT) and
# "wrap"; scipy.ndimage's "nearest", "grid-mirror", "grid-wrap", "grid-constant"; OpenCV's "replicate";
# "constant" with its default value 0; maketx's "periodic" and "black" (--wrap).
BORDER_ALIASES: dict[str, str] = {
    "edge": "clamp", "nearest": "clamp", "replicate": "clamp",
    "symmetric": "mirror", "grid-mirror": "mirror",
    "periodic": "wrap", "grid-wrap": "wrap",
    "constant": "zero", "grid-constant": "zero", "black": "zero",
}

def aliases_text() -> str:
    """Each mode with its aliases, as the API's docstrings list them: ``clamp (edge, nearest, replicate), …``."""
    return ", ".join(f"{mode} ({', '.join(a for a, m in BORDER_ALIASES.items() if m == mode)})"
                     for mode in dict.fromkeys(BORDER_ALIASES.values()))


# Names that mean another mode in another library, or a mode we do not have: refused, saying which of ours is near.
BORDER_REFUSED: dict[str, str] = {
    "reflect": "means two things: numpy's and scikit-image's 'reflect' (d c b | a b c d, the edge sample not "
               "repeated) is not a mode here, and scipy.ndimage's and OpenCV's 'reflect' (d c b a | a b c d) is "
               "'mirror' (numpy's 'symmetric')",
    "reflect_101": "(OpenCV's BORDER_REFLECT_101, numpy's 'reflect': the edge sample not repeated) is not a mode "
                   "here; 'mirror' (numpy's 'symmetric') repeats it",
    "reflect101": "(OpenCV's BORDER_REFLECT_101, numpy's 'reflect': the edge sample not repeated) is not a mode "
                  "here; 'mirror' (numpy's 'symmetric') repeats it",
}


def canonical(name: str) -> str:
    """Our name of the border mode ``name``: one of :data:`BORDER_NAMES`, or an alias of :data:`BORDER_ALIASES`.

    Raises
    ------
    UsageError
        A name of :data:`BORDER_REFUSED` (another library's mode that is not exactly one of ours) or an unknown
        one, with the names that are accepted.
    """
    key = name.lower() if isinstance(name, str) else name
    if key in BORDER_NAMES:
        return key
    if key in BORDER_ALIASES:
        return BORDER_ALIASES[key]
    if key in BORDER_REFUSED:
        raise UsageError(f"border {name!r} {BORDER_REFUSED[key]}")
    raise UsageError(f"border must be one of {', '.join(BORDER_NAMES)} (or {', '.join(BORDER_ALIASES)}), "
                     f"not {name!r}")


def fold_index(i: int, n: int, border: Border) -> int:
    """One 1-based index folded into ``1..n``; 0 means "outside, reads zero"."""
    if border is Border.CLAMP:
        return min(max(i, 1), n)
    if border is Border.WRAP:
        return (i - 1) % n + 1
    if border is Border.MIRROR:
        k = (i - 1) % (2 * n)
        return (k if k < n else 2 * n - 1 - k) + 1
    return i if 1 <= i <= n else 0


def fold(index, n: int, border: Border):
    """:func:`fold_index` for a numpy array of 1-based indices."""
    import numpy as np

    index = np.asarray(index, dtype=np.int64)
    if border is Border.CLAMP:
        return np.clip(index, 1, n)
    if border is Border.WRAP:
        return (index - 1) % n + 1
    if border is Border.MIRROR:
        k = (index - 1) % (2 * n)
        return np.where(k < n, k, 2 * n - 1 - k) + 1
    return np.where((index >= 1) & (index <= n), index, 0)
