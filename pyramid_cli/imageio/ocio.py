"""Colour spaces as OpenColorIO names them, through OpenImageIO's :class:`ColorConfig`: the one place that
loads a config, resolves names, decides an input's space and an output's, and converts pixels.

A config is a file (``--colorconfig``), else ``$OCIO``, else OpenImageIO's built-in ACES config. Names are
anything the config resolves (a colour space, an alias, a role); ``linear`` and ``srgb`` are also the
Rec.709 pair (the config's ``lin_rec709_scene`` and ``srgb_rec709_scene``, or its ``scene_linear`` and
``color_picking`` roles where it has no such names).

Pixels are filtered in linear light (:func:`working_space`): a linear input as it is, an sRGB-curve Rec.709
input in linear Rec.709 (through the exact tables of :mod:`pyramid_cli.imageio.colour`), a data input as
stored, anything else in the config's ``scene_linear``. Every pass of a plan is linear per channel, so
filtering in the input's own linear primaries and converting primaries once at the output gives what
converting to ``scene_linear`` first gives.
"""

from __future__ import annotations

import difflib
import os
import tempfile
from functools import cache

import numpy as np
import OpenImageIO as oiio

from pyramid_cli.core import cache as disk_cache
from pyramid_cli.core.errors import UsageError

BUILTIN = "ocio://default"

# The built-in config's Rec.709 pair by the names files and options use most, known without loading the
# config (about 25 ms): an sRGB PNG in and out never loads it (tests/imageio/test_ocio.py checks the table).
BUILTIN_REC709 = {"Linear Rec.709 (sRGB)": "linear", "sRGB Encoded Rec.709 (sRGB)": "srgb"}
_BUILTIN_NAMES = {"linear": "Linear Rec.709 (sRGB)", "lin_rec709_scene": "Linear Rec.709 (sRGB)",
                  "srgb": "sRGB Encoded Rec.709 (sRGB)", "srgb_rec709_scene": "sRGB Encoded Rec.709 (sRGB)",
                  **{name: name for name in BUILTIN_REC709}}

# The Rec.709 pair by their OpenImageIO names: the labels written for "linear" and "srgb".
LABELS = {"linear": "lin_rec709_scene", "srgb": "srgb_rec709_scene"}
_FALLBACK_ROLES = {"linear": ("scene_linear",), "srgb": ("color_picking", "texture_paint")}


def config_path(colorconfig: str | None = None) -> str:
    """The config file in force: ``colorconfig``, else ``$OCIO``, else :data:`BUILTIN`."""
    return colorconfig or os.environ.get("OCIO") or BUILTIN


@cache
def _load(path: str) -> oiio.ColorConfig:
    config = oiio.ColorConfig(path)
    message = config.geterror()
    if message or config.configname() == "built-in":
        first = next((ln.strip() for ln in (message or "").splitlines() if ln.strip()), "it does not load")
        raise UsageError(f"cannot load colour config {path}: {first}")
    return config


def load(colorconfig: str | None = None) -> oiio.ColorConfig:
    """The loaded config (cached per file). UsageError (exit 2) with OCIO's message when it does not load."""
    return _load(config_path(colorconfig))


@cache
def _names(path: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(colour spaces, every name the config knows: spaces, aliases, roles)."""
    config = _load(path)
    spaces = tuple(config.getColorSpaceNames())
    known = list(spaces)
    for s in spaces:
        known += list(config.getAliases(s))
    known += list(config.getRoles())
    return spaces, tuple(dict.fromkeys(known))


@cache
def _canonical(path: str, name: str) -> str | None:
    if path == BUILTIN and name in _BUILTIN_NAMES:
        return _BUILTIN_NAMES[name]
    config = _load(path)
    spaces, known = _names(path)
    got = config.resolve(name)
    if got in spaces:
        return got
    lower = {k.lower(): k for k in known}
    if name.lower() in lower:
        got = config.resolve(lower[name.lower()])
        if got in spaces:
            return got
    for role in _FALLBACK_ROLES.get(name.lower(), ()):
        got = config.getColorSpaceNameByRole(role)
        if got in spaces:
            return got
    return None


def canonical(name: str, colorconfig: str | None = None) -> str:
    """The config's own name of the space ``name`` (a space, alias or role) resolves to.

    Raises
    ------
    UsageError
        Exit 2: the config has no such space; the message names the nearest it has.
    """
    path = config_path(colorconfig)
    got = _canonical(path, name)
    if got is None:
        _, known = _names(path)
        lower = {k.lower(): k for k in reversed(known)}  # the first spelling of each
        near = [lower[n] for n in difflib.get_close_matches(name.lower(), list(lower), 4, 0.5)]
        hint = f"; nearest: {', '.join(near)}" if near else f"; it has {', '.join(_names(path)[0][:8])}, …"
        raise UsageError(f"unknown colour space {name!r} in the colour config {_shown(path)}{hint}")
    return got


def _shown(path: str) -> str:
    return "built into OpenImageIO" if path == BUILTIN else path


def check_names(*names: str | None, colorconfig: str | None = None) -> None:
    """Refuse (UsageError, exit 2) before any work a config that does not load or a name it does not know
    (``None`` and ``"auto"`` are not names)."""
    if config_path(colorconfig) != BUILTIN:
        load(colorconfig)
    for name in names:
        if name is not None and name != "auto":
            canonical(name, colorconfig)


def known(name: str, colorconfig: str | None = None) -> bool:
    """Does the config resolve ``name``?"""
    return bool(name) and _canonical(config_path(colorconfig), name) is not None


@cache
def _rec709(path: str) -> dict[str, str | None]:
    """The config's linear Rec.709 and sRGB Rec.709 spaces (sRGB only where both are: the fast path decodes
    into linear Rec.709)."""
    config = _load(path)
    spaces = _names(path)[0]
    resolved, srgb = (config.resolve(LABELS[k]) for k in ("linear", "srgb"))
    lin = resolved if resolved in spaces else None
    return {"linear": lin, "srgb": srgb if lin and srgb in spaces else None}


@cache
def _kind(path: str, space: str) -> str:
    if path == BUILTIN and space in BUILTIN_REC709:
        return BUILTIN_REC709[space]
    config = _load(path)
    if config.isData(space):
        return "data"
    for short, rec709 in _rec709(path).items():
        if space == rec709:
            return short
    return "linear-other" if config.isColorSpaceLinear(space) else "encoded"


def short_name(name: str, colorconfig: str | None = None) -> str:
    """``"linear"`` or ``"srgb"`` for the Rec.709 pair, else the config's name of the space."""
    space = canonical(name, colorconfig)
    k = _kind(config_path(colorconfig), space)
    return k if k in ("linear", "srgb") else space


def kind(name: str, colorconfig: str | None = None) -> str:
    """How pixels in this space are handled: ``"data"`` (never converted), ``"linear"`` (linear Rec.709),
    ``"srgb"`` (the sRGB curve on Rec.709: the exact tables), ``"linear-other"`` (another linear space) or
    ``"encoded"`` (anything else: OCIO converts it)."""
    return _kind(config_path(colorconfig), canonical(name, colorconfig))


def is_linear(name: str, colorconfig: str | None = None) -> bool:
    """Is the space linear light (or data, filtered as stored)?"""
    return kind(name, colorconfig) in ("linear", "linear-other", "data")


def equivalent(a: str, b: str, colorconfig: str | None = None) -> bool:
    """Do the two names resolve to the same space of the config?"""
    return known(a, colorconfig) and known(b, colorconfig) and \
        canonical(a, colorconfig) == canonical(b, colorconfig)


def working_space(space: str, colorconfig: str | None = None) -> str:
    """The linear space pixels of ``space`` are filtered in (short names as :func:`short_name`)."""
    k = kind(space, colorconfig)
    if k == "srgb":
        return "linear"
    if k in ("linear", "linear-other", "data"):
        return short_name(space, colorconfig)
    return short_name("scene_linear", colorconfig)


def label(space: str, colorconfig: str | None = None) -> str:
    """The ``oiio:ColorSpace`` written for ``space``: OpenImageIO's name for the Rec.709 pair, else the
    config's."""
    s = short_name(space, colorconfig)
    return LABELS.get(s, s)


def input_space(meta: object, path: str, integer: bool, colorspace: str,
                colorconfig: str | None = None) -> tuple[str, str]:
    """An input's space and how it was found: ``(short name, "option" | "metadata" | "file rule" | "default")``.

    ``colorspace`` other than ``"auto"`` is the option; ``auto`` reads ``oiio:ColorSpace`` (``meta``) when the
    config knows it, then the config's file rules (a rule other than the default), then the type's default
    (integers: sRGB, floats: linear).
    """
    if colorspace != "auto":
        return short_name(colorspace, colorconfig), "option"
    if isinstance(meta, str) and known(meta.strip(), colorconfig):
        return short_name(meta.strip(), colorconfig), "metadata"
    config = load(colorconfig) if path else None  # no file rule without a file name: no config to load
    if config is not None and not config.filepathOnlyMatchesDefaultRule(path):
        rule = config.getColorSpaceFromFilepath(path)
        if known(rule, colorconfig):
            return short_name(rule, colorconfig), "file rule"
    return short_name("srgb" if integer else "linear", colorconfig), "default"


def convert(values: np.ndarray, src: str, dst: str, colorconfig: str | None = None) -> np.ndarray:
    """``values`` (…, C) colour channels converted from ``src`` to ``dst`` by the config (float32, a new array).

    Three or more channels: the first three are converted as RGB, the rest kept (as OpenImageIO does); one or
    two: each is converted as a grey (R = G = B) and the mean of the result kept.
    """
    a, b = canonical(src, colorconfig), canonical(dst, colorconfig)
    v = np.ascontiguousarray(values, dtype=np.float32)
    if a == b or v.size == 0:
        return v.copy()
    shape = v.shape
    n = shape[-1]
    flat = v.reshape(-1, n)
    rgb = flat[:, :3] if n >= 3 else np.repeat(flat.reshape(-1, 1), 3, axis=1)
    buf = oiio.ImageBuf(np.ascontiguousarray(rgb.reshape(1, -1, 3)))
    path = config_path(colorconfig)
    out = oiio.ImageBufAlgo.colorconvert(buf, a, b, False, "", "", path)
    if out.has_error:
        raise UsageError(f"cannot convert {a} to {b}: {out.geterror().strip()}")
    got = np.asarray(out.get_pixels(oiio.FLOAT), dtype=np.float32).reshape(-1, 3)
    if n >= 3:
        res = flat.copy()
        res[:, :3] = got
        return res.reshape(shape)
    return got.mean(axis=1).reshape(shape).astype(np.float32)


@cache
def _holds(fmt: str, ext: str, pixel_type: str, space: str, path: str) -> bool:
    """:func:`_probe`, kept in the cache folder (``colour/``) under OpenImageIO's version and the config's
    identity (its file's size and time): one probe per machine, not per process."""
    try:
        st = os.stat(path)
        identity: tuple = (path, st.st_size, st.st_mtime_ns)
    except OSError:
        identity = (path,)
    entry = f"holds-{disk_cache.key(oiio.__version__, identity, fmt, ext, pixel_type, space)}"
    known_answer = disk_cache.read("colour", entry)
    if known_answer in (b"0", b"1"):
        return known_answer == b"1"
    answer = _probe(fmt, ext, pixel_type, space, path)
    disk_cache.write("colour", entry, b"1" if answer else b"0")
    return answer


def _probe(fmt: str, ext: str, pixel_type: str, space: str, path: str) -> bool:
    """Write a 2×2 file labelled ``space``, read it back: does our ``auto`` read find the same space?"""
    with tempfile.TemporaryDirectory(prefix="pyramid-colour-") as tmp:
        name = os.path.join(tmp, f"probe.{ext}")
        spec = oiio.ImageSpec(2, 2, 3, pixel_type)
        spec.attribute("oiio:ColorSpace", label(space, path))
        out = oiio.ImageOutput.create(name)
        if out is None or not out.open(name, spec):
            oiio.geterror()
            return True  # no probe possible: the write itself will say what is wrong
        out.write_image(np.zeros((2, 2, 3), dtype=np.uint8 if pixel_type == "uint8" else np.float32))
        out.close()
        inp = oiio.ImageInput.open(name)
        if inp is None:
            oiio.geterror()
            return True
        meta = inp.spec().get_string_attribute("oiio:ColorSpace")
        inp.close()
    got, _ = input_space(meta, "", pixel_type in ("uint8", "uint16"), "auto", path)
    return canonical(got, path) == canonical(space, path)


def holds(fmt: str, ext: str, pixel_type: str, space: str, colorconfig: str | None = None) -> bool:
    """Can a ``fmt`` file of ``pixel_type`` say that it holds ``space`` (read back, its label names it)?"""
    return fmt == "openexr" or _holds(fmt, ext, pixel_type, canonical(space, colorconfig),
                                      config_path(colorconfig))


def output_space(info_space: str, working: str, in_integer: bool, fmt: str, ext: str, out_type: str,
                 colorconfig: str | None = None) -> str:
    """The default space of an output (short name): the input's when the output holds it, else what the format
    conventionally holds (integers: sRGB-encoded Rec.709; floats: the linear space filtered in).

    An integer output holds an encoded (non-linear) space, or the space of an integer input; a float output
    holds the space of a float input. Data stays data.
    """
    out_int = out_type in ("uint8", "uint16")
    k = kind(info_space, colorconfig)
    if k == "data":
        return short_name(info_space, colorconfig)
    if out_int:
        if (in_integer or k not in ("linear", "linear-other")) and holds(fmt, ext, out_type, info_space, colorconfig):
            return short_name(info_space, colorconfig)
        return short_name("srgb", colorconfig)
    if not in_integer and holds(fmt, ext, out_type, info_space, colorconfig):
        return short_name(info_space, colorconfig)
    if holds(fmt, ext, out_type, working, colorconfig):
        return working
    return short_name("linear", colorconfig)


def describe(space: str, source: str, colorconfig: str | None = None) -> str:
    """How ``-v`` names a space: ``"ACEScct (metadata)"``, with the config's name for the Rec.709 pair."""
    return f"{canonical(space, colorconfig)} ({source})" if source else canonical(space, colorconfig)
