"""The layering, checked (after click's own tests/test_imports.py).

Statically (every import statement of every module, function-level ones included):
moderngl only in the GL executor, OpenImageIO only in I/O, click only in the CLI,
numba only in the CPU executor, and the reference imports neither algebra nor planning
(it is the oracle that catches their mistakes). Dynamically, in a fresh interpreter:
the core (expressions, parser, catalogue, algebra, planning) loads no third-party
module at all, and neither does ``import pyramid_cli``.
"""

from __future__ import annotations

import ast
import json
import pathlib
import subprocess
import sys

import pytest

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "pyramid_cli"
CORE = ["core.expr", "core.parse", "core.catalogue", "core.algebra", "plan", "plan.lower", "plan.report",
        "core.geometry", "core.border", "core.options", "core.errors", "plan.cost", "jobs.work"]

# third-party package -> the modules allowed to import it
ONLY_IN = {
    "moderngl": {"exec.gl"},
    "glcontext": {"exec.gl"},
    "OpenImageIO": {"imageio"},
    "click": {"cli"},
    "numba": {"exec.cpu"},
}


def modules() -> dict[str, pathlib.Path]:
    """Every module of the package by dotted name relative to it ("exec.gl", "plan.lower", "exec.gl.shaders")."""
    found = {}
    for p in PACKAGE.rglob("*.py"):
        parts = p.relative_to(PACKAGE).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    return found


def imports_of(path: pathlib.Path) -> set[str]:
    """Top-level names of every module ``path`` imports; the package's own modules by their dotted name
    relative to it (``.core.algebra``)."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = (node.module or "").split(".")[0]
                out |= {f".{base}"} if base else {f".{a.name}" for a in node.names}
            elif (node.module or "").startswith("pyramid_cli."):
                out.add(node.module[len("pyramid_cli"):])
            else:
                out.add((node.module or "").split(".")[0])
    return out


def violations(found: dict[str, set[str]]) -> list[str]:
    bad = []
    for module, names in found.items():
        for package, allowed in ONLY_IN.items():
            if package in names and not any(module == a or module.startswith(a + ".") for a in allowed):
                bad.append(f"{module} imports {package} (only {', '.join(sorted(allowed))} may)")
    for module, names in found.items():
        if module == "reference" or module.startswith("reference."):
            for forbidden in (".core.algebra", ".plan"):
                if any(n == forbidden or n.startswith(forbidden + ".") for n in names):
                    bad.append(f"{module} imports {forbidden[1:]}")
    return bad


def test_third_party_packages_load_only_through_their_layer():
    assert violations({name: imports_of(path) for name, path in modules().items()}) == []


def test_the_check_catches_a_forbidden_import(tmp_path):
    """Adding `import moderngl` to the planner, or `from .plan import plan` to the reference, is caught."""
    found = {name: imports_of(path) for name, path in modules().items()}
    plan_src = tmp_path / "lower.py"
    lower = (PACKAGE / "plan" / "lower.py").read_text(encoding="utf-8")
    plan_src.write_text(lower + "\n\ndef f():\n    import moderngl\n")
    ref_src = tmp_path / "filters.py"
    ref_src.write_text((PACKAGE / "reference" / "filters.py").read_text(encoding="utf-8")
                       + "\nfrom pyramid_cli.plan import plan\n")
    found["plan.lower"], found["reference.filters"] = imports_of(plan_src), imports_of(ref_src)
    assert violations(found) == ["plan.lower imports moderngl (only exec.gl may)", "reference.filters imports plan"]


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
                          "plan(parse('quadratic *v g'), (33, 17))"])
def test_the_core_loads_no_third_party_module(statement):
    assert loaded_third_party(statement) == []


def test_the_cli_starts_without_numpy_gl_or_image_io():
    loaded = loaded_third_party("import pyramid_cli.cli")
    assert "click" in loaded and not {"numpy", "moderngl", "OpenImageIO", "numba"} & set(loaded)
