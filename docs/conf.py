"""Sphinx configuration of the bilinear-pyramid documentation (``make docs``).

The site is built with ``-W --keep-going -n``: warnings are errors and every cross-reference to a
``pyramid_cli`` object must resolve. Intersphinx is not used (the build runs offline), so references to
other projects' objects (numpy, click, the standard library) are not checked: see ``nitpick_ignore_regex``.
"""

from __future__ import annotations

import sys
import types
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

# ``python -m pyramid_cli.cli`` runs the command when imported; autosummary's recursive walk imports every
# module, so it sees a stand-in that it skips (a module marked as mocked).
_main = types.ModuleType("pyramid_cli.cli.__main__")
_main.__sphinx_mock__ = True  # type: ignore[attr-defined]
sys.modules.setdefault("pyramid_cli.cli.__main__", _main)

project = "bilinear-pyramid"
author = "the bilinear-pyramid authors"
copyright = "2026, " + author

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "sphinx_click",
    "myst_parser",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_scripts", "Thumbs.db", ".DS_Store"]
templates_path = ["_templates"]

# Markdown pages: `(label)=` targets, heading anchors for links like design.md#3-errata-the-papers-arrows,
# tables, and `$…$` maths left as text.
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3

# The API reference: every module under pyramid_cli, found by walking the package (not a list kept by hand).
autosummary_generate = True
autosummary_imported_members = False
autosummary_ignore_module_all = True  # every module member is listed, so autodoc documents them all too
autodoc_default_options = {"members": True, "undoc-members": True, "ignore-module-all": True,
                           "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # numpydoc's Parameters sections say the types
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# Nitpicky, but only about this project: names of other projects' objects cannot be checked offline.
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(?!pyramid_cli)(?!~pyramid_cli).*"),
]

html_theme = "alabaster"
html_static_path = ["_static"]
html_title = "bilinear-pyramid"
html_theme_options = {"description": "Image pyramids as bilinear texture passes", "fixed_sidebar": True}
suppress_warnings = ["myst.header"]


def _home(target: str) -> str | None:
    """Where the object named ``target`` is defined, when a package re-exports it under another name
    (``pyramid_cli.plan.Plan`` is ``pyramid_cli.plan.model.Plan``); None when it cannot be found."""
    import importlib

    parts = target.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for name in parts[i:]:
                obj = getattr(obj, name)
        except AttributeError:
            return None
        module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
        if module and qualname and f"{module}.{qualname}" != target:
            return f"{module}.{qualname}"
        if i < len(parts) and not qualname:  # data: defined where its module's source assigns it
            return _data_home(".".join(parts[:i]), parts[i:])
        return None
    return None


def _data_home(module: str, names: list[str]) -> str | None:
    """A re-exported constant (``pyramid_cli.plan.POINTWISE_OPS``): the module it was imported from."""
    import importlib

    obj = importlib.import_module(module)
    value = getattr(obj, names[0], None)
    for sub in sorted(sys.modules):
        if sub.startswith(module + ".") and getattr(sys.modules[sub], names[0], None) is value:
            source = getattr(sys.modules[sub], "__file__", "") or ""
            if f"{names[0]} =" in Path(source).read_text(encoding="utf-8") if source.endswith(".py") else False:
                return ".".join([sub, *names])
    return None


def _resolve_reexports(app, env, node, contnode):
    """Resolve a reference to a re-exported ``pyramid_cli`` name at the object's home (the API reference
    documents each object once, in the module that defines it)."""
    if node.get("refdomain") != "py" or not node.get("reftarget", "").lstrip("~.").startswith("pyramid_cli"):
        return None
    target = node["reftarget"].lstrip("~")
    domain = env.get_domain("py")
    home = _home(target)
    if home is not None:
        for reftype in (node["reftype"], "obj"):
            found = domain.resolve_xref(env, node["refdoc"], app.builder, reftype, home, node, contnode)
            if found is not None:
                return found
    # a constant with no doc comment has no entry of its own: link to the module that defines it
    module = _existing_module_of(home or target)
    if module is not None:
        return domain.resolve_xref(env, node["refdoc"], app.builder, "mod", module, node, contnode)
    return None


def _existing_module_of(target: str) -> str | None:
    """The module part of ``target`` when the rest names an existing attribute of it (else None: a broken
    reference stays broken)."""
    import importlib

    parts = target.split(".")
    for i in range(len(parts) - 1, 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        module = obj.__name__
        try:
            for name in parts[i:]:
                obj = getattr(obj, name)
        except AttributeError:
            return None
        return module
    return None


def _plain_help(app, ctx, lines: list[str]) -> None:
    """The commands' help is plain text for a terminal (``'in/*.exr'``): escape what reST would read as
    markup, keeping sphinx-click's own line-block bars and directives."""
    import re

    for i, line in enumerate(lines):
        if line.lstrip().startswith(".. "):
            continue
        bar = re.match(r"\s*\| ?", line)  # a line block's bar, from click's \b paragraphs
        head, rest = (line[:bar.end()], line[bar.end():]) if bar else ("", line)
        rest = re.sub(r"([*`|\\])", r"\\\1", rest)
        lines[i] = head + re.sub(r"(\w)_(?!\w)", r"\1\\_", rest)  # `band_` is not a link


def _numpydoc_template_once() -> None:
    """numpydoc compiles its docstring template anew for every docstring it renders (``get_doc_object`` makes a
    fresh Jinja environment each call): 4,000 compilations, a quarter of this site's build. The same template,
    compiled once per builder, renders the same text."""
    import numpydoc.docscrape_sphinx as scrape
    import numpydoc.numpydoc as numpydoc

    compiled = {}

    def get_doc_object(obj, what=None, doc=None, config=None, builder=None):
        config = {} if config is None else config
        if id(builder) not in compiled:
            scrape.get_doc_object(None, "object", "", config, builder)  # numpydoc's own loader and environment
            compiled[id(builder)] = config["template"]
        config["template"] = compiled[id(builder)]
        return scrape.get_doc_object_orig(obj, what=what, doc=doc, config=config, class_doc=scrape.SphinxClassDoc,
                                          func_doc=scrape.SphinxFunctionDoc, obj_doc=scrape.SphinxObjDoc)

    numpydoc.get_doc_object = get_doc_object


def setup(app):
    _numpydoc_template_once()
    app.connect("missing-reference", _resolve_reexports)
    for what in ("description", "options", "arguments", "envvars", "epilog"):  # usage is a literal block
        app.connect(f"sphinx-click-process-{what}", _plain_help)
