"""The layering, checked: import-linter's contracts (pyproject.toml), shown to fail when broken, and the
house rules the contracts cannot say (module sizes, private names, glcontext, what loads at import).

The contracts count every import statement, function-level ones included. Dynamically, in a fresh
interpreter: the core (expressions, parser, catalogue, algebra, sigma, planning) and the jobs load no
third-party module at all, neither does ``import pyramid_cli``, and the CLI starts without numpy.
"""

from __future__ import annotations

import ast
import json
import os
import pathlib
import shutil
import subprocess
import sys

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    tomllib = pytest.importorskip("tomli")

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "pyramid_cli"
CORE = ["core.expr", "core.parse", "core.catalogue", "core.algebra", "core.geometry", "core.border", "core.options",
        "core.errors", "core.sigma", "core.version", "plan", "plan.model", "plan.lower", "plan.report", "plan.cost",
        "plan.resample", "workflows.pyramids", "workflows.limits", "jobs.work", "jobs.texture"]
MAX_LINES = 700
MAX_FLAT = 15

pytest.importorskip("importlinter")


def contracts() -> dict[str, dict]:
    """The contracts of pyproject.toml by type (one of each type is enough to break)."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]
    out: dict[str, dict] = {}
    for c in config["contracts"]:
        out.setdefault(c["type"], c)
    return out


def lint_imports(root: pathlib.Path) -> subprocess.CompletedProcess:
    """``lint-imports`` on the package under ``root`` (first on the path), with the contracts of ``root``."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])}
    code = "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())"
    return subprocess.run([sys.executable, "-c", code, "--no-cache", "--no-logo", str(root / "pyproject.toml")],
                          cwd=root, env=env, capture_output=True, text=True, timeout=300)


def test_every_contract_is_kept():
    run = lint_imports(ROOT)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "BROKEN" not in run.stdout


# kind -> (module to edit, the import added inside a function, a word the report names)
BREAKS = {
    "layers": ("core/errors.py", "import pyramid_cli.cli", "pyramid_cli.core.errors -> pyramid_cli.cli"),
    "forbidden": ("reference/filters.py", "from pyramid_cli.plan.lower import plan",
                  "pyramid_cli.reference.filters -> pyramid_cli.plan.lower"),
    "protected": ("core/geometry.py", "import moderngl", "pyramid_cli.core.geometry -> moderngl"),
    "acyclic_siblings": ("core/border.py", "from pyramid_cli.core import options", "pyramid_cli.core"),
}


@pytest.mark.parametrize("kind", sorted(BREAKS))
@pytest.mark.slow
def test_each_kind_of_contract_fails_when_broken(tmp_path, kind):
    """A copy of the package with one violating import (in a function body, where cycles hide) breaks the
    first contract of that kind, and the report names the import."""
    contract = contracts()[kind]
    shutil.copytree(PACKAGE, tmp_path / "pyramid_cli", ignore=shutil.ignore_patterns("__pycache__", "*.so"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    module, statement, named = BREAKS[kind]
    path = tmp_path / "pyramid_cli" / module
    path.write_text(path.read_text(encoding="utf-8") + f"\n\ndef _broken():\n    {statement}\n", encoding="utf-8")
    run = lint_imports(tmp_path)
    assert run.returncode != 0
    assert f"{contract['name']} BROKEN" in run.stdout, run.stdout
    report = run.stdout.split("Broken contracts", 1)[1]
    section = report.split(contract["name"], 1)[1]
    assert named in section, section


def package_modules() -> dict[str, pathlib.Path]:
    """Every module of the package by dotted name ("pyramid_cli.exec.gl", "pyramid_cli.plan.lower")."""
    found = {}
    for p in PACKAGE.rglob("*.py"):
        parts = ("pyramid_cli", *p.relative_to(PACKAGE).with_suffix("").parts)
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    return found


def test_no_module_is_too_long_and_few_sit_flat():
    long = {name: n for name, p in package_modules().items()
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert long == {}, f"modules over {MAX_LINES} lines"
    flat = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(flat) <= MAX_FLAT, flat


def private_imports(path: pathlib.Path, module: str) -> list[str]:
    """``from pyramid_cli.x import _name`` (absolute or relative) in ``path``: private names of another module."""
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
            source = f"{base}.{node.module}" if node.module else base
        else:
            source = node.module or ""
        if source.split(".")[0] != "pyramid_cli":
            continue
        out += [f"{module} imports {source}.{a.name}" for a in node.names
                if a.name.startswith("_") and not (a.name.startswith("__") and a.name.endswith("__"))]
    return out


def test_no_private_name_is_imported_across_modules():
    bad = [line for name, path in package_modules().items() for line in private_imports(path, name)]
    assert bad == []


def test_the_private_name_scan_catches_one(tmp_path):
    src = tmp_path / "m.py"
    src.write_text("from pyramid_cli.plan.recipes import _chain\nfrom pyramid_cli import __version__\n")
    assert private_imports(src, "pyramid_cli.plan.m") == ["pyramid_cli.plan.m imports pyramid_cli.plan.recipes._chain"]


@pytest.mark.slow
def test_glcontext_loads_only_through_the_gl_executor():
    """moderngl's EGL backend; not in the import graph (nothing names it), so no contract can protect it."""
    bad = []
    for name, path in package_modules().items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            if any(n.split(".")[0] == "glcontext" for n in names) and not name.startswith("pyramid_cli.exec.gl"):
                bad.append(name)
    assert bad == []


def loaded_third_party(statement: str) -> list[str]:
    code = ("import sys, json\n" + statement + "\n"
            "std = set(sys.stdlib_module_names)\n"
            "names = {m.split('.')[0] for m in sys.modules} - std - {'pyramid_cli'}\n"
            "print(json.dumps(sorted(n for n in names if not n.startswith('_'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


@pytest.mark.parametrize("statement", ["import pyramid_cli", "import pyramid_cli as pyr; pyr.__doc__"] +
                         [f"import pyramid_cli.{m}" for m in CORE] +
                         ["from pyramid_cli.core.parse import parse; from pyramid_cli.plan import plan; "
                          "plan(parse('quadratic *v g'), (33, 17))",
                          "from pyramid_cli.core.sigma import sigma_blend; sigma_blend(3.0)"])
def test_the_core_loads_no_third_party_module(statement):
    assert loaded_third_party(statement) == []


def test_the_cli_starts_without_numpy_gl_or_image_io():
    loaded = loaded_third_party("import pyramid_cli.cli")
    assert "click" in loaded and not {"numpy", "moderngl", "OpenImageIO", "numba"} & set(loaded)
